"""The two ways a run ends early, each with its exit code in the CLI."""


class SceneError(ValueError):
    """Invalid scene or mesh: the CLI exits 2."""


class ConvergenceError(RuntimeError):
    """A step did not converge after all cut-backs: the CLI exits 3."""

"""The four ways a run ends early, each with its exit code in the CLI."""


class SceneError(ValueError):
    """Invalid scene or mesh, or a checkpoint that does not fit the scene: the CLI exits 2."""


class ConvergenceError(RuntimeError):
    """A step did not converge after all cut-backs: the CLI exits 3."""


class Interrupted(RuntimeError):
    """A signal (SIGTERM, SIGINT, SIGUSR1) ended the run at a safe point, with the last converged
    state kept: the CLI exits 4 (``system/signals.py``)."""

    def __init__(self, message: str, signal: str = "") -> None:
        super().__init__(message)
        self.signal = signal


class OutputError(OSError):
    """The output folder could not be written (a full disk, no permission) or a picture could
    not be drawn, on every rank together, with what was written before kept: the CLI exits 5."""

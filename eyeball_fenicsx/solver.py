"""Newton (PETSc SNES, direct MUMPS solve) and the incremental load path with cut-back.

PETSc options live under the prefix ``eye_``: pass ``-eye_snes_monitor``,
``-eye_snes_linesearch_type basic``, ``-eye_mat_mumps_icntl_4 2`` ... on the command line.
Our defaults are set only where the user gave nothing.
"""
import dataclasses
import time

import numpy as np
from petsc4py import PETSc

from .errors import ConvergenceError, SceneError

PREFIX = "eye_"
DEFAULT_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": 1e-9,
    "snes_atol": 1e-11,
    "snes_stol": 0.0,
    "snes_max_it": 12,
    "ksp_type": "preonly",
    "pc_type": "lu",
    "pc_factor_mat_solver_type": "mumps",
    "mat_mumps_icntl_14": 80,  # room for the delayed pivots of the saddle-point system
}
_REASONS = {value: name for name, value in vars(PETSc.SNES.ConvergedReason).items() if not name.startswith("_")}


@dataclasses.dataclass
class SolverSettings:
    """Load stepping of each step of the load path.

    Args:
        increments: initial number of equal load increments of a step.
        max_cutbacks: the smallest increment is the initial one halved this many times;
            an increment that fails at that size ends the run.
        growth: factor by which the increment grows after an easy one.
        easy_iterations: an increment that took at most this many Newton iterations is easy.
        predictor: extrapolate the previous increment to start Newton (secant predictor).
    """

    increments: int = 10
    max_cutbacks: int = 10
    growth: float = 2.0
    easy_iterations: int = 4
    predictor: bool = True

    def __post_init__(self):
        if isinstance(self.increments, bool) or not isinstance(self.increments, int) or self.increments < 1:
            raise SceneError(f"solver.increments must be a positive integer, got {self.increments!r}")


class NewtonSolver:
    """SNES on a ``Problem``, solving one load increment at a time."""

    def __init__(self, problem, prefix=PREFIX):
        self.problem = problem
        opts = PETSc.Options()
        for key, value in DEFAULT_OPTIONS.items():
            if not opts.hasName(prefix + key):
                opts[prefix + key] = value
        self.snes = snes = PETSc.SNES().create(problem.comm)
        snes.setOptionsPrefix(prefix)
        snes.setFunction(problem.F, problem.b)
        snes.setJacobian(problem.J, problem.A)
        snes.setFromOptions()
        snes.getKSP().setFromOptions()
        self.residual_norms = []
        snes.setMonitor(lambda snes, its, norm: self.residual_norms.append(norm))

    def update_pattern(self):
        """Give the features their per-increment update; follow a new matrix if one was made."""
        if self.problem.update_pattern():
            self.snes.setJacobian(self.problem.J, self.problem.A)
            self.snes.getKSP().reset()
            self.snes.setFromOptions()

    def solve(self, x):
        """Newton from x (updated in place); returns (converged, iterations, residual, reason)."""
        self.residual_norms = []
        self.problem.inverted = None
        self.snes.solve(None, x)
        reason = self.snes.getConvergedReason()
        norm = self.residual_norms[-1] if self.residual_norms else float("nan")
        converged = reason > 0 and np.isfinite(norm)
        return converged, self.snes.getIterationNumber(), norm, _REASONS.get(reason, str(reason))


def ramp(feature_step, step_index, t):
    """Load factor of a feature that ramps in ``feature_step`` at time t of ``step_index``."""
    if step_index < feature_step:
        return 0.0
    return t if step_index == feature_step else 1.0


@dataclasses.dataclass
class Increment:
    load_factor: float
    newton_iterations: int
    residual_norm: float
    wall_s: float


def run_step(problem, newton, settings, step_index, step_name, increments, log):
    """Advance one step of the load path from t = 0 to 1 with adaptive increments.

    Returns the list of converged ``Increment``; raises ``ConvergenceError`` (with the
    converged ones attached as ``.increments``) when the cut-backs are exhausted.
    """
    problem.begin_step(step_index)
    x = problem.x
    problem.state_to_vector(x)
    x_old, x_prev = x.duplicate(), None
    t, dt, dt_prev = 0.0, 1.0 / increments, None
    smallest, done = 1.0 / increments / 2**settings.max_cutbacks, []
    use_predictor = settings.predictor
    while t < 1.0 - 1e-12:
        dt = min(dt, 1.0 - t)
        x.copy(x_old)
        problem.set_load_factor([ramp(f.step, step_index, t + dt) for f in problem.features])
        if use_predictor and x_prev is not None:
            x.axpy(dt / dt_prev, x_old - x_prev)
        start = time.perf_counter()
        newton.update_pattern()
        converged, its, norm, reason = newton.solve(x)
        wall = time.perf_counter() - start
        if converged:
            t += dt
            done.append(Increment(t, its, norm, wall))
            log(f"step {step_name}: load factor {t:.4f}  Newton iterations {its:2d}  residual {norm:.2e}  {wall:.2f} s")
            if x_prev is None:
                x_prev = x.duplicate()
            x_old.copy(x_prev)
            dt_prev = dt
            use_predictor = settings.predictor
            if its <= settings.easy_iterations:
                dt *= settings.growth
            continue
        x_old.copy(x)
        problem.vector_to_state(x)
        where = ""
        if problem.inverted is not None:
            where = f"; an element inverted (det F = {problem.inverted[0]:.3g}) near {np.round(problem.inverted[1], 4).tolist()}"
        log(f"step {step_name}: load factor {t + dt:.4f} failed ({reason}{where}); cutting the increment back")
        if dt <= smallest * (1 + 1e-9):
            error = ConvergenceError(
                f"step {step_name!r} did not converge beyond load factor {t:.4g}, even with the increment "
                f"cut back {settings.max_cutbacks} times (last try: {reason}{where}); use more increments, check the loads and supports, or "
                f"pass -{PREFIX}snes_monitor to see the Newton iterations")
            error.increments = done
            raise error
        dt /= 2
        use_predictor = False
    problem.set_load_factor([ramp(f.step, step_index, 1.0) for f in problem.features])
    return done

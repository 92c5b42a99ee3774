"""The load path: each step from load factor 0 to 1 in adaptive increments, with cut-back.

* A feature ramps in its step (``ramp``) and is held after it.
* Predictor: the last increment's change, extrapolated, starts Newton; shortened where it would
  close a contact gap too far or invert an element, dropped where it still would.
* After Newton converges, features may ask for another solve (``Problem.augment``: the
  augmented Lagrangian of contact); those solves start from the last factorization.
* Increment size: after a converged increment that factorized n tangents, the next one is
  scaled by ``easy_iterations / n``, clipped to [1 / ``growth``, ``growth``], never below the
  smallest cut-back: a rule aimed at ``easy_iterations`` tangents per increment, as FEBio's
  auto time stepper aims at ``opt_iter`` iterations (``FECore/FETimeStepController.cpp``,
  which scales by the square root of that ratio and relaxes toward its largest step).
* A failed increment is halved, at most ``max_cutbacks`` times; then the run ends with a
  ``ConvergenceError`` that keeps the converged increments.
"""
import dataclasses
import time

import numpy as np

from ..errors import ConvergenceError, SceneError


@dataclasses.dataclass
class SolverSettings:
    """Load stepping of each step of the load path.

    Args:
        increments: initial number of equal load increments of a step.
        max_cutbacks: the smallest increment is the initial one halved this many times;
            an increment that fails at that size ends the run.
        growth: the largest factor by which an increment grows after a converged one; it
            shrinks by at most its inverse (1: equal increments, cut back only where one fails).
        easy_iterations: the target of the step-size rule: the next increment is this increment
            times easy_iterations / (tangents it factorized), within [1 / growth, growth] (with
            factorization reuse, the cheap chord steps do not count).
        predictor: extrapolate the previous increment to start Newton (secant predictor).
        reuse_contraction: reuse the factorization for the next Newton step after a step that
            multiplied the residual norm by at most this factor (0: a new tangent every step).
    """

    increments: int = 2
    max_cutbacks: int = 10
    growth: float = 2.0
    easy_iterations: int = 5
    predictor: bool = True
    reuse_contraction: float = 0.1

    def __post_init__(self):
        if isinstance(self.increments, bool) or not isinstance(self.increments, int) or self.increments < 1:
            raise SceneError(f"solver.increments must be a positive integer, got {self.increments!r}")
        if not self.growth >= 1:
            raise SceneError(f"solver.growth must be at least 1 (1: equal increments), got {self.growth!r}")


def ramp(feature_step, step_index, t):
    """Load factor of a feature that ramps in ``feature_step`` at time t of ``step_index``."""
    if step_index < feature_step:
        return 0.0
    return t if step_index == feature_step else 1.0


def next_increment_factor(tangents, settings):
    """The step-size rule: easy_iterations / tangents, within [1 / growth, growth]."""
    return float(np.clip(settings.easy_iterations / max(tangents, 1), 1 / settings.growth, settings.growth))


@dataclasses.dataclass
class Increment:
    load_factor: float
    newton_iterations: int
    residual_norm: float
    wall_s: float
    factorizations: int  # new tangents factorized; the other iterations reused one


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
    newton.reuse_contraction = settings.reuse_contraction
    while t < 1.0 - 1e-12:
        dt = min(dt, 1.0 - t)
        x.copy(x_old)
        problem.set_load_factor([ramp(f.step, step_index, t + dt) for f in problem.features])
        if use_predictor and x_prev is not None:  # extrapolated, but not through a contact nor an inversion
            step = x_prev - x_old  # the secant, as the step x_old -> x_old - step
            step.scale(dt / dt_prev)
            if newton.limits_steps:
                problem.F(None, x_old, problem.b)
                step.scale(problem.step_fraction(-step.array_r, problem.b.array_r))
            if newton.shorten_while_inverting(x_old, step) is not None:
                x.axpy(-1.0, step)
        start, factorized = time.perf_counter(), newton.factorizations
        newton.update_pattern()
        problem.set_increment(t + dt >= 1.0 - 1e-12)
        converged, its, norm, reason = newton.solve(x)
        while converged and not problem.augment():  # augmented Lagrangian: Newton again
            converged, more, norm, reason = newton.solve(x, chord_start=True)
            its += more
        wall, factorized = time.perf_counter() - start, newton.factorizations - factorized
        if converged:
            t += dt
            done.append(Increment(t, its, norm, wall, factorized))
            log(f"step {step_name}: load factor {t:.4f}  Newton iterations {its:2d} ({factorized} factorized)  "
                f"residual {norm:.2e}  {wall:.2f} s")
            if x_prev is None:
                x_prev = x.duplicate()
            x_old.copy(x_prev)
            dt_prev = dt
            use_predictor = settings.predictor
            dt = max(dt * next_increment_factor(factorized, settings), smallest)
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
                f"pass -{newton.prefix}snes_monitor to see the Newton iterations")
            error.increments = done
            raise error
        dt /= 2
        use_predictor = False
    problem.set_load_factor([ramp(f.step, step_index, 1.0) for f in problem.features])
    return done

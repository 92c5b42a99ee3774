"""The load path: each step from load factor 0 to 1 in adaptive increments, with cut-back.

* A feature ramps in its step (``ramp``) and is held after it.
* Predictor: the last increment's change, extrapolated, starts Newton; shortened where it would
  close a contact gap too far or invert an element, dropped where it still would.
* After Newton converges, if an active set's last search no longer covers the state (a
  contact point moved past the reach of its candidates: ``Problem.search_covers``), the
  active sets search again at that state and Newton solves again from it, at most
  ``MAX_SEARCHES`` times in an increment (then it is cut back). While the augmentations below
  still move the multipliers, their next update is taken at that state too, and one solve
  serves both: it starts from a new tangent anyway (the new search changed the contacts).
* After Newton converges, features may ask for another solve (``Problem.augment``: the
  augmented Lagrangian of contact, which solves again in a step's last increment only). Those
  solves, and the first one of a step's last increment when the scene has active sets, are
  loose (``NewtonSolver.solve``: the residual cut by 1 / LOOSE_RTOL; the augmentations' from
  the last factorization, unless a new search came with them) while the multipliers move, as
  in inexact Uzawa methods (Elman and Golub, SIAM J. Numer. Anal. 31 (1994) 1645), and the
  last, once the features accept the state, is at the usual tolerances, from the last
  factorization too (unless a new search came with it; a new tangent once a chord step
  contracts less than Newton's reuse rule asks, ``system/newton.py``); the features then check
  the state again.
* The last increment of a step takes what is left of the step if that is less than
  ``STRETCH`` times its size (no sliver of an increment left over).
* Increment size: after a converged increment that factorized n tangents, the next one is
  scaled by ``easy_iterations / n``, clipped to [1 / ``growth``, ``growth``], never below the
  smallest cut-back: a rule aimed at ``easy_iterations`` tangents per increment, as FEBio's
  auto time stepper aims at ``opt_iter`` iterations (``FECore/FETimeStepController.cpp``,
  11 by default, counting its quasi-Newton updates too; it scales by the square root of that
  ratio and relaxes toward its largest step).
* A failed increment is halved, at most ``max_cutbacks`` times; then the run ends with a
  ``ConvergenceError`` that keeps the converged increments.
* A run asked to stop (``stop``: system/signals.py) stops after the next increment that
  converges, unless it ends the step, with an ``Interrupted`` that keeps the converged
  increments: the state and the load factors are that increment's.

The settings named here are the fields of ``SolverSettings`` (system/settings.py).

Data path: ``run_step`` sets the features' load factors on the problem (system/problem.py),
predicts, calls Newton (system/newton.py) per increment and returns the converged increments to
the scene, whose observers then read the state. Each increment's line is logged at INFO on this
module's logger (``logging.getLogger(__name__)``; output/console.py prints it on rank 0).
"""
from __future__ import annotations

import dataclasses
import logging
import time
from collections.abc import Callable

import numpy as np
from petsc4py import PETSc

from ..errors import ConvergenceError, Interrupted
from .newton import NewtonSolver
from .problem import Problem
from .settings import SolverSettings

log = logging.getLogger(__name__)
STRETCH = 1.5  # an increment that would leave less than half its size to the step's end takes that too
MAX_SEARCHES = 3  # searches again in one increment, after converged states its search did not cover


def ramp(feature_step: int, step_index: int, t: float) -> float:
    """Load factor of a feature that ramps in ``feature_step`` at time t of ``step_index``."""
    if step_index < feature_step:
        return 0.0
    return t if step_index == feature_step else 1.0


def next_increment_factor(tangents: int, settings: SolverSettings) -> float:
    """The step-size rule: easy_iterations / tangents, within [1 / growth, growth]."""
    return float(np.clip(settings.easy_iterations / max(tangents, 1), 1 / settings.growth, settings.growth))


@dataclasses.dataclass
class Increment:
    load_factor: float
    newton_iterations: int
    residual_norm: float
    wall_s: float
    factorizations: int  # new tangents factorized; the other iterations reused one
    krylov_iterations: int  # of the iterative linear solver (0 for MUMPS)
    mumps_memory_MB: int  # MUMPS' INFOG(21) after the increment, the most one process used (iterative: its block's)


@dataclasses.dataclass
class FailedIncrement:
    """An increment Newton did not converge: in step ``step_name``, from the converged load
    factor ``t`` by ``dt``, for Newton's ``reason``."""

    step_name: str
    t: float
    dt: float
    reason: str


def run_step(problem: Problem, newton: NewtonSolver, settings: SolverSettings, step_index: int, step_name: str,
             increments: int, stop: Callable[[], str | None] | None = None) -> list[Increment]:
    """Advance one step of the load path from t = 0 to 1 with adaptive increments.

    Returns the list of converged ``Increment``; raises ``ConvergenceError`` (with the
    converged ones attached as ``.increments``) when the cut-backs are exhausted, and
    ``Interrupted`` (likewise) when ``stop`` (collective: ``StopRequests.requested``) names a
    signal after an increment that does not end the step.
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
        dt = 1.0 - t if 1.0 - t < STRETCH * dt else dt  # no sliver of an increment left over
        x.copy(x_old)
        problem.set_load_factor([ramp(f.step, step_index, t + dt) for f in problem.features])
        if use_predictor and x_prev is not None:
            _predict(problem, newton, x, x_old, x_prev, dt / dt_prev)
        converged, increment, reason = _solve_increment(problem, newton, x, t + dt)
        if converged:
            t = increment.load_factor
            done.append(increment)
            log.info("step %s: load factor %.4f  Newton iterations %2d (%d factorized)  residual %.2e  %.2f s",
                     step_name, t, increment.newton_iterations, increment.factorizations, increment.residual_norm,
                     increment.wall_s)
            if x_prev is None:
                x_prev = x.duplicate()
            x_old.copy(x_prev)
            dt_prev = dt
            use_predictor = settings.predictor
            dt = max(dt * next_increment_factor(increment.factorizations, settings), smallest)
            _stop_if_asked(stop, step_name, t, done)
            continue
        _restore_or_give_up(problem, newton, settings, x, x_old, FailedIncrement(step_name, t, dt, reason), smallest,
                            done)
        dt /= 2
        use_predictor = False
    problem.set_load_factor([ramp(f.step, step_index, 1.0) for f in problem.features])
    return done


def _stop_if_asked(stop: Callable[[], str | None] | None, step_name: str, t: float, done: list[Increment]) -> None:
    """Raise ``Interrupted`` (with the converged increments) if ``stop`` names a signal, at load
    factor t of a step not yet done (collective)."""
    if stop is None or t >= 1.0 - 1e-12:
        return
    signal = stop()
    if signal:
        error = Interrupted(f"interrupted by {signal} in step {step_name!r} at load factor {t:.4g}", signal)
        error.increments = done
        raise error


def _predict(problem: Problem, newton: NewtonSolver, x: PETSc.Vec, x_old: PETSc.Vec, x_prev: PETSc.Vec,
             scale: float) -> None:
    """Secant predictor: x = x_old + scale (x_old - x_prev), the step shortened where it would
    close a contact gap too far (``step_fraction``) and dropped where it would still invert an
    element."""
    step = x_prev - x_old  # the secant, as the step x_old -> x_old - step
    step.scale(scale)
    if problem.limits_steps:
        problem.F(None, x_old, problem.b)
        step.scale(problem.step_fraction(-step.array_r, problem.b.array_r))
    if newton.shorten_while_inverting(x_old, step) is not None:
        x.axpy(-1.0, step)


def _solve_increment(problem: Problem, newton: NewtonSolver, x: PETSc.Vec,
                     load_factor: float) -> tuple[bool, Increment, str]:
    """Newton on the increment ending at ``load_factor``, then again after a new search where the
    last one no longer covers the state, and while a feature augments (the augmented Lagrangian
    of contact), the augmentations' from the last factorization; a new search during the
    augmentations is solved with their next update. Returns (converged, the increment's
    ``Increment``, Newton's reason)."""
    start, factorized, krylov = time.perf_counter(), newton.factorizations, newton.krylov_iterations
    newton.update_pattern()
    final = load_factor >= 1.0 - 1e-12
    problem.set_increment(final)
    loose = final and bool(problem.active_sets)  # x will converge at the loose tolerances only
    converged, its, norm, reason = newton.solve(x, loose=loose)
    settled, searches, abandoned = x.duplicate(), 0, False
    while converged:
        # a point moved past its search's reach: search at this state, solve again (while the
        # augmentations are loose, with their next update)
        searched = not problem.search_covers()
        if searched:
            if searches == MAX_SEARCHES:
                converged, reason = False, f"contact points still outrun their search after {searches} more"
                break
            newton.update_pattern()
            searches += 1
            if not loose:  # else the augmentation's update comes with the new search, in one solve
                converged, more, norm, reason = newton.solve(x, again=True)
                its += more
                continue
        done = problem.augment(solving=loose)
        if done and not loose:
            break
        # an augmentation's solve is loose until the multipliers settle; one more, at the
        # usual tolerances, then ends the increment (the augmentation checks it again)
        x.copy(settled)
        before = norm, reason, loose
        converged, more, norm, reason = newton.solve(x, chord_start=not searched, loose=not done, again=True)
        its, loose = its + more, not done
        if not converged and not abandoned and problem.abandon_augmentation():  # an update (a pass, or the
            settled.copy(x)                                 # free last one) taken back: the state before it stands
            problem.vector_to_state(x)
            converged, (norm, reason, loose), abandoned = True, before, True
    settled.destroy()
    wall, factorized = time.perf_counter() - start, newton.factorizations - factorized
    increment = Increment(load_factor, its, norm, wall, factorized, newton.krylov_iterations - krylov, newton.memory_mb)
    return converged, increment, reason


def _restore_or_give_up(problem: Problem, newton: NewtonSolver, settings: SolverSettings, x: PETSc.Vec,
                        x_old: PETSc.Vec, failure: FailedIncrement, smallest: float, done: list[Increment]) -> None:
    """After a failed increment: back to the last converged state x_old, and a
    ``ConvergenceError`` if the increment was already the smallest."""
    x_old.copy(x)
    problem.vector_to_state(x)
    where = ""
    if problem.inverted is not None:
        where = (f"; an element inverted (det F = {problem.inverted[0]:.3g}) near "
                 f"{np.round(problem.inverted[1], 4).tolist()}")
    log.info("step %s: load factor %.4f failed (%s%s); cutting the increment back", failure.step_name,
             failure.t + failure.dt, failure.reason, where)
    if failure.dt <= smallest * (1 + 1e-9):
        error = ConvergenceError(
            f"step {failure.step_name!r} did not converge beyond load factor {failure.t:.4g}, even with the increment "
            f"cut back {settings.max_cutbacks} times (last try: {failure.reason}{where}); use more increments, check "
            f"the loads and supports, or pass -{newton.prefix}snes_monitor to see the Newton iterations")
        error.increments = done
        raise error

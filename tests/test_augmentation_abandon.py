"""What an increment does when the Newton solve after an augmentation fails (system/stepping.py):
the augmentation is taken back, the converged state before it stands, and one solve at the usual
tolerances ends the increment, judged at the increment's scales as they were before the failed
solve (``NewtonSolver.solve`` keeps a failed solve's norms out of them:
tests/test_solver_globalization.py); a failed solve with nothing to take back fails the increment at
once. A search again during the augmentations comes with the next update of the multipliers, in one
solve. A scripted problem and Newton solver stand in for the real ones, so each path is taken for sure."""
import numpy as np
from petsc4py import PETSc

from eyeball_fenicsx.system import stepping

SETTLED, FAILED = 1.0, 99.0  # the state a solve leaves x at, when it converges or fails


class ScriptedProblem:
    """An active set whose augmentations follow ``passes`` (False: another pass)."""

    def __init__(self, passes, taken_back, covers=(), events=None):
        self.active_sets, self.passes, self.taken_back = [object()], list(passes), taken_back
        self.covers, self.events = list(covers), [] if events is None else events
        self.abandoned, self.states = 0, []

    def set_increment(self, final):
        pass

    def search_covers(self):
        return self.covers.pop(0) if self.covers else True

    def augment(self, solving):
        self.events.append("augment")
        return self.passes.pop(0)

    def abandon_augmentation(self):
        self.abandoned += 1
        return self.taken_back

    def vector_to_state(self, x):
        self.states.append(x.getArray().copy())


class ScriptedNewton:
    """Solves that converge or fail as ``outcomes`` say; a converged one folds its norms into the
    increment's scales, a failed one (its norms blown up) does not, as ``NewtonSolver.solve``."""

    factorizations = krylov_iterations = memory_mb = 0

    def __init__(self, outcomes, events=None):
        self.outcomes, self.increment_scales, self.scales_seen = list(outcomes), None, []
        self.events = [] if events is None else events

    def update_pattern(self):
        self.events.append("search")

    def solve(self, x, chord_start=False, loose=False, again=False):
        self.events.append(("loose solve" if loose else "solve") + (" (chord)" if chord_start else ""))
        if not again:
            self.increment_scales = np.array([1.0])
        self.scales_seen.append(self.increment_scales.copy())
        converged = self.outcomes.pop(0)
        if converged:
            self.increment_scales = np.maximum(self.increment_scales, 1.0)
        x.set(SETTLED if converged else FAILED)
        return converged, 2, 1e-12 if converged else 1e3, "scripted"


def _increment(passes, outcomes, taken_back=True, covers=(), load_factor=1.0):
    events = []
    problem, newton = ScriptedProblem(passes, taken_back, covers, events), ScriptedNewton(outcomes, events)
    x = PETSc.Vec().createSeq(3, comm=PETSc.COMM_SELF)
    converged, _, _ = stepping._solve_increment(problem, newton, x, load_factor)
    return converged, problem, newton, x.getArray().copy()


def test_a_failed_pass_is_taken_back_and_the_last_solve_judged_at_the_scales_before_it():
    # the increment's solve converges; a pass (False) whose solve fails; settled (True): the solve
    # at the usual tolerances converges; settled again: done
    converged, problem, newton, x = _increment([False, True, True], [True, False, True])
    assert converged and problem.abandoned == 1
    assert np.all(x == SETTLED) and np.all(problem.states[0] == SETTLED)  # the state before the pass
    assert [s[0] for s in newton.scales_seen] == [1.0, 1.0, 1.0]  # not the failed solve's 1e4


def test_a_failed_solve_with_nothing_to_take_back_fails_the_increment_at_once():
    # settled with no update (True), the solve at the usual tolerances fails: no second try
    converged, problem, newton, _ = _increment([True], [True, False], taken_back=False)
    assert not converged and problem.abandoned == 1 and newton.outcomes == []


def test_a_search_again_during_the_augmentations_comes_with_the_next_update():
    # the increment's loose solve outruns its search: search, update the multipliers, one loose solve
    # from a new tangent (the search changed the matrix); settled: the solve at the usual tolerances,
    # from the last factorization; settled again: done (a spare pass and solve left over)
    converged, problem, _, _ = _increment([False, True, True, False], [True] * 4, covers=[False])
    assert converged
    assert problem.events == ["search", "loose solve", "search", "augment", "loose solve", "augment",
                              "solve (chord)", "augment"]


def test_a_search_again_at_the_usual_tolerances_is_solved_before_the_augmentation_is_asked():
    # an increment inside a step (no augmentation solves): the search's own solve, from a new
    # tangent, then the update
    converged, problem, _, _ = _increment([True], [True, True], covers=[False], load_factor=0.5)
    assert converged and problem.events == ["search", "solve", "search", "solve", "augment"]

"""The settings of the load stepping: system/stepping.py walks each step of the load path with
them (its docstring states the step-size rule and the cut-back they tune), and system/newton.py
takes its default factorization reuse and its linear solver from them.
"""
import dataclasses

from .. import checks
from ..errors import SceneError

LINEAR_SOLVERS = ("mumps", "mumps-blr", "iterative")  # system/linear_solvers.py: what each is, when to use it


@dataclasses.dataclass
class SolverSettings:
    """Load stepping of each step of the load path.

    Args:
        increments: initial number of equal load increments of a step. 1: each step is tried
            whole, and cut back where that fails (the planning matrix of the buckle scenes takes
            0.9 of the time it takes from 2, benchmarks/README.md); the smallest increment is
            then 1/1024 of a step.
        max_cutbacks: the smallest increment is the initial one halved this many times;
            an increment that fails at that size ends the run.
        growth: the largest factor by which an increment grows after a converged one; it
            shrinks by at most its inverse (1: equal increments, cut back only where one fails).
        easy_iterations: the target of the step-size rule: the next increment is this increment
            times easy_iterations / (tangents it factorized), within [1 / growth, growth] (with
            factorization reuse, the cheap chord steps do not count). 8: a contact onset alone
            takes about 10 (the first increment of the encircling operation's "pressurize"), and
            the increment after it need not be halved for that.
        predictor: extrapolate the previous increment to start Newton (secant predictor).
        reuse_contraction: reuse the factorization for the next Newton step after a step that
            multiplied the residual norm by at most this factor (0: a new tangent every step).
        linear: the linear solver of the Newton steps, one of ``LINEAR_SOLVERS``
            (system/linear_solvers.py); they give the same converged answer.
    """

    increments: int = 1
    max_cutbacks: int = 10
    growth: float = 2.0
    easy_iterations: int = 8
    predictor: bool = True
    reuse_contraction: float = 0.1
    linear: str = "mumps"

    def __post_init__(self) -> None:
        checks.integer(self.increments, "solver.increments")
        checks.known(self.linear, LINEAR_SOLVERS, "linear", "linear solver", "linear solvers", in_order=True)
        if checks.number(self.growth, "solver.growth") < 1:
            raise SceneError(f"solver.growth must be at least 1 (1: equal increments), got {self.growth!r}")

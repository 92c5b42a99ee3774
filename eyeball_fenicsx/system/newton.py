"""Newton (PETSc SNES) for one load increment (``stepping.py`` walks the load path); each Newton
step solved by the scene's linear solver (``linear_solvers.py``: MUMPS, MUMPS with block low-rank
compression, or FGMRES with an augmented-Lagrangian preconditioner).

PETSc options live under the prefix ``eye_``: pass ``-eye_snes_monitor``,
``-eye_snes_linesearch_type basic``, ``-eye_mat_mumps_icntl_4 2`` ... on the command line.
Our defaults are set only where the user gave nothing.

With a direct solver (MUMPS), the numeric factorization is almost all of the cost of a Newton
iteration (``benchmarks/sphere_scaling.py``), so the solver spends as few as it can, without
changing the converged answer (the residual tolerances decide it); the iterative solver
keeps a tangent's preconditioner for chord steps the same way:

* symmetric tangent -> MUMPS LDL^T (``pc_type cholesky``): half the flops of LU. Used when every
  feature with hand-assembled terms declares ``symmetric_tangent = True``
  (``Problem.symmetric_tangent``) and the assembled matrix is symmetric to round-off, checked at
  the first Jacobian of every increment (a follower pressure on a surface with free edges is not);
* factorization reuse (chord steps): after a Newton step that cut the residual by at least
  ``settings.SolverSettings.reuse_contraction``, the next step reuses the factorization instead of
  assembling and factorizing a new tangent; a reused step that contracts less ends the reuse.
  A tangent whose contact points changed since it was assembled is reused only in a solve that
  started from the last factorization (``chord_start``: an augmentation's, or the one at the
  usual tolerances that ends them, near the converged state, where a multiplier update moves a
  few points), by any of its steps, and then with the closing step (``ActiveSet.closing_step``),
  which gives its steps the state's pressing points; other solves (an increment's first, one
  after a new search) assemble a new one.
  A chord step converges linearly, so it would stop just below the tolerance, where Newton's
  quadratic last step lands far below it: after a reused factorization, convergence needs a
  residual ``POLISH`` times below the tolerance (or a chord step that no longer contracts, at
  round-off), which costs a triangular solve at most: the chord steps of the encircling
  operation contract the residual 30 times or more, and its eye measures with POLISH = 0.1 are
  those with 1e-3 to 1e-12 (``benchmarks/encircling_operation.py``);
* loose solves (``solve(loose=True)``: the augmented Lagrangian's while its multipliers still
  move, ``stepping.py``) end once the residual, each block in units of its tolerance, is
  ``LOOSE_RTOL`` times what it was at the start: an inexact inner solve of Uzawa's iteration,
  whose last solve is at the usual tolerances.

Globalization, so that a hard increment ends quickly, either converged or cut back:

* convergence is judged block by block (``Problem.residual_blocks``: forces, prescribed
  displacements, incompressibility, each cavity's liquid law), so that no block's units hide
  another's: a block has converged when its 2-norm is at most ``snes_rtol`` times the largest
  norm it had in this Newton solve, or at most ``snes_atol`` (in its own units: N, mm or mm^3
  for a model in mm and MPa). The largest norm, not the first, is the block's scale: a block
  that starts at zero (the pressure rows of a displacement-driven increment) is judged
  against the imbalance Newton's first step gave it. A solve of the same increment again (after
  a new contact search, or the one that ends its augmentations) takes the largest norm over all
  the increment's converged solves: it starts near convergence, and its own largest norm would
  ask for round-off (a failed one's, an abandoned augmentation's, would loosen it). Every block
  must have converged;
* stagnation: a Newton solve whose residual, each block divided by its tolerance, has not
  reached a new minimum in ``STAGNATION_WINDOW`` iterations (a cycle, or steps that no longer
  help) stops at once as "stagnated", and the increment is cut back. Minima are counted among
  the Newton iterates, not the starting point: its residual is the increment's load alone, which
  the first steps of a contact onset raise a hundredfold before they bring it down. Unless the whole
  residual has met PETSc's default test (its 2-norm at most ``snes_rtol`` times its first, or
  ``snes_atol``): then a block has stalled at its round-off, which its own tolerance can lie
  below when its terms are far larger than its imbalance, and the solve has converged;
* a Newton step that would invert an element (det F <= 0 at a quadrature point or the
  midpoint of an element, as ``mechanics.solid.JacobianGuard`` watches) is halved before the
  line search, up to ``MAX_STEP_HALVINGS`` times, whatever the line search (after the contact
  onset limit, ``ActiveSet.step_fraction``); one that still inverts ends the solve ("inverting
  step") with the element's location. A secant predictor that would invert an element is
  halved alike, or dropped;
* swings: a Newton step whose largest change of a free displacement component is more than
  MAX_STEP_GROWTH times the solve's first step's (as solved and given its contact closing step,
  ``ActiveSet.closing_step``, before any limit) and more than
  MIN_STEP_WATCHED of the body's diagonal ends the solve at once ("a Newton step 3 times the first"), and the
  increment is cut back: the first step is the linear response to the increment's load, and
  the steps after it correct it; steps that grow are a soft mode taking over (the buckled eye
  swinging sideways on its optic nerve, several millimetres a step, while the band's contact
  is not yet all round) or a load beyond the structure's limit, which stagnation would stop
  only some iterations later.
"""
from __future__ import annotations

import contextlib

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .linear_solvers import linear_solver
from .problem import Problem
from .settings import SolverSettings

PREFIX = "eye_"
DEFAULT_OPTIONS = {
    "snes_type": "newtonls",
    "snes_linesearch_type": "bt",
    "snes_rtol": 1e-9,
    "snes_atol": 1e-11,
    "snes_stol": 0.0,
    "snes_max_it": 12,
}
LOOSE_RTOL = 1e-3  # the relative tolerance of a loose solve (an augmentation's, while the multipliers move)
POLISH = 0.1  # after a chord step, converged means this far below the tolerances
STAGNATION_WINDOW = 4  # Newton iterations without a new smallest scaled residual: stagnated
MAX_STEP_HALVINGS = 6  # a step that inverts an element is halved at most this often (to 1/64)
MAX_STEP_GROWTH = 3.0  # a Newton step this many times the solve's first ends it (a swing, not a correction)
MIN_STEP_WATCHED = 0.01  # ... unless no displacement component changes by this fraction of the body's diagonal
_CHORD_STEPS = 30  # a bound on the chord steps of one solve, beyond snes_max_it
_SYMMETRY_TOLERANCE = 1e-12  # |A - A^T| entrywise, relative to the largest row sum of |A|
_SYMMETRY_CHECK = PETSc.Log.Event("EyeSymmetryCheck")
_REASON = PETSc.SNES.ConvergedReason
_REASONS = {value: name for name, value in vars(PETSc.SNES.ConvergedReason).items() if not name.startswith("_")}


class NewtonSolver:
    """SNES on a ``Problem``, solving one load increment at a time."""

    def __init__(self, problem: Problem, prefix: str = PREFIX, linear: str = "mumps"):
        self.problem = problem
        self.linear = linear_solver(linear, problem)
        opts = PETSc.Options()
        defaults = dict(DEFAULT_OPTIONS, **self.linear.options)
        defaults.update(problem.newton_options)  # an active set's own (contact: ``contact/policy.py``)
        self.prefix, self.defaults = prefix, defaults
        self.choose_factorization = self.linear.direct and not opts.hasName(prefix + "pc_type")  # else the user's
        self.divergence = PETSc.Options(prefix).getReal("snes_divergence_tolerance", 1e4)
        self.reuse_contraction = SolverSettings.reuse_contraction
        self.reused = False  # the last Newton step reused a factorization
        self.chord_start = False  # the next solve starts with the last factorization
        X = problem.solid.mesh_data.mesh.geometry.x
        lo, hi = np.empty(3), np.empty(3)
        problem.comm.Allreduce(X.min(axis=0, initial=np.inf), lo, op=MPI.MIN)  # a rank may hold no node
        problem.comm.Allreduce(X.max(axis=0, initial=-np.inf), hi, op=MPI.MAX)
        self.body_size = float(np.linalg.norm(hi - lo))
        self.snes = snes = PETSc.SNES().create(problem.comm)
        snes.setOptionsPrefix(prefix)
        snes.setFunction(problem.F, problem.b)
        snes.setJacobian(self._jacobian, problem.A)
        snes.setConvergenceTest(self._converged)
        snes.setLineSearchPreCheck(self._limit_step)
        if self.linear.direct:
            snes.getKSP().getPC().setType("lu")
        self._set_from_options()
        self.residual_norms = []
        self.step_halvings = []
        self.factorizations = 0  # new tangents (a factorization, or a new preconditioner)
        self.krylov_iterations = 0  # of every solve so far
        self.memory_mb = 0  # MUMPS' INFOG(21) after the last solve (the iterative path's: its block's)
        self.increment_scales = None  # the blocks' largest norms over the increment's converged solves (solve)
        self._responses = (problem.b.duplicate(), problem.b.duplicate())  # respond's residual change and state change
        snes.setMonitor(self._monitor)

    @contextlib.contextmanager
    def _our_defaults(self):
        """Our defaults in PETSc's options database while PETSc reads it (options, factorization),
        and out of it again: left there, they would be the next solver's user options (a scene
        without contact would give its line search to a scene with contact in the same process)."""
        opts = PETSc.Options()
        added = [key for key in self.defaults if not opts.hasName(self.prefix + key)]
        for key in added:
            opts[self.prefix + key] = self.defaults[key]
        try:
            yield
        finally:
            for key in added:
                opts.delValue(self.prefix + key)

    def _set_from_options(self):
        """Read the options; ``snes_max_it`` counts the steps with a new tangent, and the chord
        steps come on top (each cuts the residual by 1 / reuse_contraction, so they are few)."""
        with self._our_defaults():
            self.snes.setFromOptions()
            self.snes.getKSP().setFromOptions()
            self.linear.setup(self.snes.getKSP())
        self.max_tangents = self.snes.getTolerances()[3]
        self.snes.setTolerances(max_it=self.max_tangents + _CHORD_STEPS)

    def update_pattern(self) -> None:
        """Give the features their per-increment update; follow a new matrix if one was made."""
        if self.problem.update_pattern():
            self.snes.setJacobian(self._jacobian, self.problem.A)
            self.snes.getKSP().reset()
            self._set_from_options()

    def _monitor(self, snes, its, norm):
        self.residual_norms.append(norm)

    def _jacobian(self, snes, x, A, P):
        """Assemble a new tangent, or leave A untouched so that the KSP keeps its factorization
        (PCSetUp factorizes only a matrix whose state changed)."""
        norms = self.residual_norms
        first = snes.getIterationNumber() == 0
        contracted = self.chord_start if first else norms[-1] <= self.reuse_contraction * norms[-2]
        # a tangent whose contact points changed since: reused only in a solve that started from the
        # last factorization (near a converged state), with the closing step giving it the state's points
        self.reused = contracted and not self.problem.tangent_outdated(self.chord_start and self._holds_factorization())
        if self.reused:
            return
        self.problem.J(snes, x, A, P)
        self.factorizations += 1
        self.tangents += 1
        if snes.getIterationNumber() == 0 and self.choose_factorization:
            self._set_factorization("cholesky" if self._symmetric(A) else "lu")

    def _limit_step(self, x, y):
        """Line-search precheck: press at once the contact points the Newton step x -> x - y
        closes and release those it opens (``ActiveSet.closing_step``), then shorten it where it
        would still close a contact gap too far (``ActiveSet.step_fraction``) or invert an element
        (``shorten_while_inverting``); returns whether y changed. A step that inverts an element
        however short, or that swings (``_swings``), is not taken: y is zeroed and the solve ends."""
        fraction, closed, residual = 1.0, False, self.snes.getFunction()[0].array_r
        if self.problem.limits_steps:
            self.problem.vector_to_state(x)
            if self._holds_factorization():  # of the step's tangent
                closed = self.problem.close_gaps(y, self.respond)
        if self.first_step is None:  # the Newton step as solved and closing gaps, before any limit
            self.first_step = self._step_length(y)
        if self.problem.limits_steps:
            fraction = self.problem.step_fraction(-y.array_r, residual)
            if fraction < 1.0:
                y.scale(fraction)
        halvings = self.shorten_while_inverting(x, y)
        self.step_halvings.append(halvings)
        if halvings is None:
            self.stopped = f"inverting step, halved {MAX_STEP_HALVINGS} times"
        elif self._swings(y):
            self.stopped = f"a Newton step {MAX_STEP_GROWTH:g} times the first"
        if self.stopped:
            y.zeroEntries()  # the line search fails (bt), or Newton stays at x and stops (basic)
            return True
        return closed or fraction < 1.0 or halvings != 0

    def _holds_factorization(self) -> bool:
        """Whether the linear solver solves with a factorization (``respond`` needs one)."""
        ksp = self.snes.getKSP()
        return ksp.getType() == "preonly" and ksp.getPC().getType() in ("lu", "cholesky")

    def respond(self, rows: np.ndarray, values: np.ndarray) -> np.ndarray:
        """The state change (local entries of the bordered vector) that cancels a change of the
        residual (``values`` at global ``rows``; none at Dirichlet rows) through the last factorized
        tangent: one triangular solve (collective; a factorization only, as ``_limit_step`` checks:
        an iterative solve per product would cost more than the Newton iterations it saves)."""
        change, solution = self._responses
        change.set(0.0)
        change.setValues(rows, values, addv=PETSc.InsertMode.ADD_VALUES)
        change.assemble()
        change.array[self.problem.bc_rows] = 0.0
        self.snes.getKSP().solve(change, solution)
        return -solution.array_r

    def _step_length(self, y):
        """The largest change of a free displacement component in the step y (collective)."""
        rows = dict(self.problem.residual_blocks)["force"]
        return self.problem.comm.allreduce(float(np.abs(y.array_r[rows]).max(initial=0.0)), op=MPI.MAX)

    def _swings(self, y):
        """Whether the step y, as it will be taken, is a swing: longer than MAX_STEP_GROWTH times
        the solve's first step and than MIN_STEP_WATCHED of the body's diagonal (collective)."""
        first = self.first_step if np.isfinite(self.first_step) else 0.0
        return self._step_length(y) > max(MAX_STEP_GROWTH * first, MIN_STEP_WATCHED * self.body_size)

    def shorten_while_inverting(self, x: PETSc.Vec, y: PETSc.Vec) -> int | None:
        """Halve the step x -> x - y while it would invert an element (det F <= 0 at one of its
        quadrature points or its midpoint, ``mechanics.solid.JacobianGuard``), at most
        MAX_STEP_HALVINGS times; returns the number of halvings, or None if x - y still inverts
        (then ``Problem.inverted`` tells where the full step did). Leaves the solid at x
        (collective)."""
        full_step = self._inversion_at(x, y)
        det_min, halvings = full_step[0], 0
        while not det_min > 0 and halvings < MAX_STEP_HALVINGS:
            y.scale(0.5)
            halvings += 1
            det_min = self._inversion_at(x, y)[0]
        self._set_displacement(x.array_r[: self.problem.n_owned])  # back to x, which the features' caches describe
        if det_min > 0:
            return halvings
        if self.problem.inverted is None:  # the first inversion of this solve: where it began
            self.problem.inverted = full_step
        return None

    def _inversion_at(self, x, y):
        """(min det F, its location) of the solid at x - y (collective); leaves the solid there."""
        n = self.problem.n_owned
        self._set_displacement(x.array_r[:n] - y.array_r[:n])
        return self.problem.guard.check()

    def _set_displacement(self, owned):
        w = self.problem.solid.w
        w.x.array[: self.problem.n_owned] = owned
        w.x.scatter_forward()

    def _block_norms(self, r):
        """2-norms of the residual's blocks (``Problem.residual_blocks``; collective)."""
        local = np.array([np.sum(r[rows] ** 2) for _, rows in self.problem.residual_blocks])
        return np.sqrt(self.problem.comm.allreduce(local))

    def _converged(self, snes, its, norms):
        """Every block of the residual below its tolerance, max(snes_rtol * its largest norm
        in this solve, snes_atol), POLISH times stricter after a chord step that still
        contracted (see the module docstring); at most ``max_tangents`` steps with a new
        tangent; stagnation, inverting steps and swings end the solve."""
        xnorm, step, fnorm = norms
        rtol, atol, stol, _ = snes.getTolerances()
        if its == 0:
            self.initial_norm = fnorm
        if self.stopped:  # by the line-search precheck
            return _REASON.DIVERGED_FUNCTION_DOMAIN
        if not np.isfinite(fnorm):
            return _REASON.DIVERGED_FNORM_NAN
        blocks = self._block_norms(snes.getFunction()[0].array_r)
        self.block_norms.append(blocks)
        self.block_scales = np.maximum(self.block_scales, blocks)
        tolerances = np.maximum(rtol * self.block_scales, atol)
        contracting = its and fnorm <= self.reuse_contraction * self.residual_norms[-2]
        polish = POLISH if self.reused and contracting else 1.0
        if self.loose_rtol and self._loosely_converged(its, np.max(blocks / tolerances)):
            return _REASON.CONVERGED_FNORM_RELATIVE
        if np.all(blocks <= polish * tolerances):
            return _REASON.CONVERGED_FNORM_ABS if np.all(blocks <= polish * atol) else _REASON.CONVERGED_FNORM_RELATIVE
        if its and step < stol * xnorm:
            return _REASON.CONVERGED_SNORM_RELATIVE
        if its and 0 < self.divergence and fnorm > self.divergence * self.initial_norm:
            return _REASON.DIVERGED_DTOL
        if self._stagnated(tolerances):
            # a block can stall at its round-off above its tolerance (its terms are far larger
            # than its imbalance); then the whole residual decides, as PETSc's default test
            if fnorm <= max(rtol * self.initial_norm, atol):
                return _REASON.CONVERGED_FNORM_RELATIVE
            self.stopped = "stagnated"
            return _REASON.DIVERGED_LOCAL_MIN
        if self.tangents >= self.max_tangents and not contracting:  # the next step needs a new one
            return _REASON.DIVERGED_MAX_IT
        return _REASON.ITERATING

    def _loosely_converged(self, its, scaled):
        """A loose solve's test: the residual, each block in units of its tolerance, LOOSE_RTOL
        times what it was at the start of the solve."""
        if its == 0:
            self.loose_start = scaled
        return its > 0 and scaled <= self.loose_rtol * self.loose_start

    def _stagnated(self, tolerances):
        """No new minimum of the residual, each block in units of its tolerance, in the last
        STAGNATION_WINDOW iterations: a cycle of period up to that, or steps that no longer help."""
        if len(self.block_norms) <= STAGNATION_WINDOW + 1:
            return False
        scaled = np.max(np.array(self.block_norms[1:]) / tolerances, axis=1)  # the iterates, not the start
        return scaled[-STAGNATION_WINDOW:].min() >= scaled[:-STAGNATION_WINDOW].min()

    def _symmetric(self, A):
        with _SYMMETRY_CHECK:
            return self.problem.symmetric_tangent and A.isSymmetric(
                _SYMMETRY_TOLERANCE * A.norm(PETSc.NormType.INFINITY))

    def _set_factorization(self, pc_type):
        pc = self.snes.getKSP().getPC()
        if pc.getType() != pc_type:
            pc.setType(pc_type)  # drops the old factorization and its symbolic analysis
            with self._our_defaults():
                pc.setFromOptions()

    def solve(self, x: PETSc.Vec, chord_start: bool = False, loose: bool = False,
              again: bool = False) -> tuple[bool, int, float, str]:
        """Newton from x (updated in place); returns (converged, iterations, residual, reason).
        ``chord_start``: the first step reuses the last factorization (Newton again from a
        converged state whose loads changed a little: an augmentation, or the solve that ends
        them, unless a new contact search came with it), and the later ones too while they
        contract, though contact points changed (module docstring). ``loose``: converged once the residual
        is LOOSE_RTOL times its start, each block in units of its tolerance (an augmentation's
        solve, inexact while the multipliers still move). ``again``: the same increment solved
        again (after a new search, or an augmentation); unless loose, each block's scale is then
        the largest norm it had in any of the increment's converged solves, so the tolerances are
        the increment's, not those of a solve that starts near convergence."""
        self.chord_start, self.loose_rtol = chord_start, LOOSE_RTOL if loose else 0.0
        self.residual_norms = []
        if not again or self.increment_scales is None:  # an increment's first solve
            self.increment_scales = np.zeros(len(self.problem.residual_blocks))
        keep = again and not loose
        self.block_scales = self.increment_scales.copy() if keep else np.zeros_like(self.increment_scales)
        self.block_norms = []
        self.tangents = 0
        self.step_halvings = []  # per Newton step: halvings of the step (None: it inverted however short)
        self.stopped = None  # or why the solve stopped where PETSc has no reason of its own
        self.first_step = None
        self.problem.inverted = None
        with self._our_defaults():  # MUMPS reads its options when it factorizes
            self.snes.solve(None, x)
        reason = self.snes.getConvergedReason()
        ksp = self.snes.getKSP()
        self.krylov_iterations += 0 if self.linear.direct else self.snes.getLinearSolveIterations()
        self.memory_mb = self.linear.memory_mb(ksp)
        if reason == _REASON.DIVERGED_LINEAR_SOLVE:
            self.stopped = self.linear.krylov_failure(ksp)
        norm = self.residual_norms[-1] if self.residual_norms else float("nan")
        converged = reason > 0 and np.isfinite(norm)
        if converged:  # a failed solve's norms (an abandoned augmentation's) loosen no later solve
            self.increment_scales = np.maximum(self.increment_scales, self.block_scales)
        return converged, self.snes.getIterationNumber(), norm, self.stopped or _REASONS.get(reason, str(reason))

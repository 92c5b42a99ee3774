"""The linear solver of each Newton step (``[solver] linear``, ``--linear-solver``): three ways to
solve the bordered system of ``problem.py``, the same converged answer (Newton's residual
tolerances decide it, ``newton.py``).

* ``"mumps"`` (the default): a sparse direct factorization, MUMPS (Amestoy, Duff, L'Excellent and
  Koster, SIAM J. Matrix Anal. Appl. 23:15, 2001) through PETSc's ``pc_type lu`` / ``cholesky``;
  Newton chooses LDL^T for a symmetric tangent and reuses factorizations (chord steps).
* ``"mumps-blr"``: the same factorization with block low-rank compression of the frontal matrices
  (MUMPS ``ICNTL(35) = 2``: BLR in the factorization and the solve; Amestoy, Buttari, L'Excellent
  and Mary, ACM TOMS 45:2, 2019): off-diagonal blocks of the fronts are kept as low-rank products
  up to the dropping parameter ``CNTL(7)``, relative to the matrix's norm. The factors, so the
  memory and the flops, shrink on large fronts (fine 3D meshes); the solve is then exact to about
  ``CNTL(7)``, an inexact Newton step whose error the next Newton step removes, so the converged
  answer is the residual tolerances', as with the chord steps.
* ``"iterative"``: Newton-Krylov. FGMRES (right preconditioned, so its tolerance is on the true
  residual; Saad, SIAM J. Sci. Comput. 14:461, 1993) with the augmented-Lagrangian block
  preconditioner of ``al_preconditioner.py``: the displacement block penalized element by element
  by alpha times the element's shear modulus, factorized by MUMPS' LDL^T, and diagonal pressure
  and cavity blocks. Newton keeps a tangent and its preconditioner for chord steps as it keeps a
  factorization, so both paths take the same Newton steps and increments, except where a step
  closes contact gaps (the closing step needs a factorization, ``newton.py``): their answers then
  agree to the augmentations' tolerance. The Krylov tolerance
  is ``ITERATIVE_RTOL`` of the residual, so each Newton step contracts the residual by that factor
  at least, and the last one lands far below Newton's tolerance, as a direct solve's does. A
  Krylov solve that does not reach it ends the Newton solve with a message that says so
  (``krylov_failure``).
  Limitation: the displacement block is still factorized, about half of the memory of MUMPS'
  factorization of the whole matrix, but each Krylov iteration (40 to 71 per Newton step on
  the eye) is a triangular solve with those factors, so the path is slower than MUMPS at every
  size measured (README, "Which linear solver when"); algebraic multigrid on the block
  (``-eye_al_u_pc_type gamg``) needs 60 to 460 CG iterations per solve on the coarse Q1P0 eye's
  block (alpha 1 to 100; the eye has thin layers and a stiffness contrast of 1e4).

All options are PETSc's, under the scene's prefix ``eye_`` and only where the user gave none:
``-eye_ksp_monitor``, ``-eye_al_alpha 50``, ``-eye_al_u_pc_type gamg``, ``-eye_mat_mumps_cntl_7 1e-6`` ...
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from .al_preconditioner import AugmentedLagrangian, pressure_weights
from .problem import Problem
from .settings import LINEAR_SOLVERS

ITERATIVE_RTOL = 1e-8  # each Krylov solve cuts the linear residual by this factor
_MUMPS = {
    "ksp_type": "preonly",
    "pc_factor_mat_solver_type": "mumps",
    "mat_mumps_icntl_14": 80,  # room for the delayed pivots of the saddle-point system
}
_BLR = {
    "mat_mumps_icntl_35": 2,  # BLR in the factorization and the solve
    "mat_mumps_cntl_7": 1e-8,  # the BLR dropping parameter
}
_ITERATIVE = {
    "ksp_type": "fgmres",
    "ksp_rtol": ITERATIVE_RTOL,
    "ksp_atol": 0.0,
    "ksp_max_it": 400,
    "ksp_gmres_restart": 100,
}


class LinearSolver:
    """A linear solver's PETSc defaults, its set-up of the PC and what it reports per Newton solve.

    ``direct``: a factorization, which Newton may choose (LU or LDL^T). With every solver Newton
    may keep a tangent and what the PC made of it for chord steps (a factorization, or the
    iterative path's preconditioner, with which the Krylov solve takes a chord step too)."""

    direct = True

    def __init__(self, name: str, problem: Problem):
        self.name = name
        self.problem = problem
        self.options = dict(_MUMPS, **(_BLR if name == "mumps-blr" else {}))

    def setup(self, ksp: PETSc.KSP) -> None:
        """After the options are read and whenever the KSP was reset (a new matrix)."""
        if ksp.getPC().getType() not in ("lu", "cholesky"):
            ksp.getPC().setType("lu")

    def memory_mb(self, ksp: PETSc.KSP) -> int:
        """MUMPS' INFOG(21), the largest memory (MB) one process used in the last factorization,
        or 0 if there was none."""
        pc = ksp.getPC()
        if pc.getType() not in ("lu", "cholesky") or pc.getFactorSolverType() != "mumps":
            return 0
        try:
            return int(pc.getFactorMatrix().getMumpsInfog(21))
        except PETSc.Error:  # not factorized yet
            return 0

    def krylov_failure(self, ksp: PETSc.KSP) -> str | None:
        return None


class IterativeSolver(LinearSolver):
    """Newton-Krylov: FGMRES with the augmented-Lagrangian preconditioner (``al_preconditioner.py``)."""

    direct = False

    def __init__(self, name: str, problem: Problem):
        super().__init__(name, problem)
        self.options = dict(_ITERATIVE)
        fields, coordinates = self._split(problem)
        coords = PETSc.Vec().createMPI((coordinates.size, PETSc.DECIDE), bsize=3, comm=problem.comm)
        coords.array[:] = coordinates.ravel()
        self.near_null_space = PETSc.NullSpace().createRigidBody(coords)
        coords.destroy()
        weights = pressure_weights(problem.solid, problem.n_owned)[self.pressure_rows]
        self.preconditioner = AugmentedLagrangian(fields, weights, self.near_null_space, problem.last)

    def _split(self, problem: Problem) -> tuple[tuple[PETSc.IS, PETSc.IS, PETSc.IS], np.ndarray]:
        """((global rows of the owned displacement dofs, node by node, x y z; of the owned
        pressures; of the border rows), the displacement nodes' coordinates). Keeps the local
        pressure rows (``pressure_rows``)."""
        V, dofs = problem.solid.W.sub(0).collapse()
        dofs = np.asarray(dofs, dtype=np.int64).reshape(-1, 3)
        owned = np.flatnonzero(dofs[:, 0] < problem.n_owned)
        owned = owned[np.argsort(dofs[owned, 0])]  # sorted rows, as PETSc's sub-matrices want
        nodes = V.tabulate_dof_coordinates()[owned]
        u_rows = dofs[owned].ravel()
        assert np.all(np.diff(u_rows) > 0), "a node's displacement dofs are not consecutive"
        self.pressure_rows = np.setdiff1d(np.arange(problem.n_owned), u_rows)
        border = problem.n_global + np.arange(problem.n_extra_local)
        rows = (problem.offset + u_rows, problem.offset + self.pressure_rows, border)
        return tuple(PETSc.IS().createGeneral(r.astype(PETSc.IntType), comm=problem.comm) for r in rows), nodes

    def setup(self, ksp: PETSc.KSP) -> None:
        """The preconditioner, unless the user chose another (``-eye_pc_type``)."""
        if not PETSc.Options().hasName(ksp.getOptionsPrefix() + "pc_type"):
            ksp.getPC().setType("python")
            ksp.getPC().setPythonContext(self.preconditioner)

    def memory_mb(self, ksp: PETSc.KSP) -> int:
        """MUMPS' INFOG(21) of the displacement block's factorization, or 0."""
        solver = self.preconditioner.ksp
        return super().memory_mb(solver) if solver is not None and ksp.getPC().getType() == "python" else 0

    def krylov_failure(self, ksp: PETSc.KSP) -> str | None:
        """Why the last Krylov solve failed, in words, or None if it converged."""
        reason = ksp.getConvergedReason()
        if reason >= 0:
            return None
        names = {value: name for name, value in vars(PETSc.KSP.ConvergedReason).items() if not name.startswith("_")}
        return (f"the iterative linear solver did not converge ({names.get(reason, reason)} after "
                f"{ksp.getIterationNumber()} Krylov iterations, the linear residual {ksp.getResidualNorm():.2e}); "
                "pass -eye_ksp_monitor to see it, or use the direct solver (--linear-solver mumps)")


def linear_solver(name: str, problem: Problem) -> LinearSolver:
    """The linear solver named ``name`` (one of ``LINEAR_SOLVERS``) for the problem (collective)."""
    if name not in LINEAR_SOLVERS:
        raise ValueError(f"unknown linear solver {name!r}: choose one of {LINEAR_SOLVERS}")
    return IterativeSolver(name, problem) if name == "iterative" else LinearSolver(name, problem)

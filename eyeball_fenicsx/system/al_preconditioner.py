"""The augmented-Lagrangian preconditioner of the Newton-Krylov path (``linear_solvers.py``).

The bordered Newton matrix (``problem.py``), its unknowns split into the displacements u, the
element pressures p and the global (cavity) unknowns c:

    A = [ K   B^T  b ]      K: the displacement block (contact, sutures, liquid loads in it)
        [ B   -C   0 ]      B: the incompressibility rows; C: from -p^2 / (2 mu) in a compressible
        [ r^T  0   d ]      region (there B = 0); b, r, d: the cavities' border (r = 0 while
                            a cavity fills).

Augmented Lagrangian (Fortin and Glowinski, Augmented Lagrangian Methods, North-Holland 1983;
the preconditioner of Benzi and Olshanskii, SIAM J. Sci. Comput. 28:2095, 2006): with a
diagonal weight W >= 0 on the pressure rows, the system T A x = T f, T = [[I, B^T W, 0], [0, I,
0], [0, 0, I]], has the same solution, and its displacement block K_g = K + B^T W B is K with
a penalty on the volume change of each element. For the block upper-triangular

    P = [ K_g  B^T  b ]
        [ 0    S_p  0 ]     S_p = -diag(C) - W^+,   s = d - r^T K_g^-1 b (m x m, dense),
        [ 0    0    s ]

(W^+: 1 / W where W > 0, else 0) the Schur complement of T A is S_p up to O(1 / gamma) (Benzi
and Olshanskii), so the preconditioned operator's spectrum clusters as gamma grows. This module applies y = P^-1 T x
as the right preconditioner of FGMRES: A P^-1 T is similar to T A P^-1, so the iteration counts
are those of the augmented system, while the Newton matrix and residual stay the scene's.

The weight is per element: gamma_e = alpha mu_e with mu_e the element's initial shear modulus
(its material's ``shear_modulus``), W = gamma_e / M_e (M_e the pressure mass matrix' diagonal,
the element's volume for P0), so every tissue's K_g is compressible elasticity with
lambda / mu = alpha, whatever the stiffness contrast between tissues, and alpha is a number
without units. With K_g factorized, one global gamma of alpha MPa takes as many
iterations (on one tangent of the default eye: 76, 34, 212 for 10, 100, 1000 MPa); what makes
the iteration converge at all is T (without it, none of these converged in 400 iterations).
A compressible region has W = 0 (its pressure is idle, B = 0). alpha trades the outer
iterations against the conditioning of K_g: ``ALPHA`` (``-eye_al_alpha``; on one tangent of the
default eye with K_g factorized, alpha 10, 30, 50, 100, 200, 300, 1000 took 77, 50, 42, 34, 32,
42, 212 FGMRES iterations).

K_g is solved by a sparse factorization, MUMPS' LDL^T of its upper triangle (K_g is symmetric
up to the contact and filling terms; a preconditioner need not be exact): about half of the
memory of the LU factorization of A with its delayed pivots, as the README's measurements show.
Its sub-solver is a PETSc KSP with the prefix ``eye_al_u_`` (``-eye_al_u_pc_type gamg`` gives
algebraic multigrid, with the rigid-body near-null space set on K_g; on the coarse Q1P0 eye it
needs 60 to 460 CG iterations per solve, README "Which linear solver when"). The cavity's Schur
complement s costs m solves with K_g per new tangent.
"""
from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_matrix
from petsc4py import PETSc

ALPHA = 100.0  # gamma_e / mu_e, the augmentation's lambda / mu


def pressure_weights(solid, n_owned: int) -> np.ndarray:
    """W / alpha (``mu_e / M_e``, 0 in compressible regions) on the owned rows of the mixed
    space (zero on displacement rows), from the diagonals of the pressure mass matrices
    with and without mu (collective)."""
    mesh = solid.mesh_data.mesh
    Q, dofs = solid.W.sub(1).collapse()
    mu = fem.Function(fem.FunctionSpace(mesh, ("DG", 0)))
    for region, law in solid.laws.items():
        mu.x.array[solid.mesh_data.cells(region)] = float(law.shear_modulus) if law.incompressible else 0.0
    p, q = ufl.TrialFunction(Q), ufl.TestFunction(Q)
    diagonals = []
    for coefficient in (1.0, mu):
        M = assemble_matrix(fem.form(coefficient * p * q * ufl.dx(domain=mesh)))
        M.assemble()
        diagonals.append(M.getDiagonal().array_r.copy())
        M.destroy()
    mass, mu_mass = diagonals
    weights = np.zeros(n_owned)
    weights[np.asarray(dofs)[: len(mass)]] = mu_mass / mass**2
    return weights


class AugmentedLagrangian:
    """petsc4py's context of a ``python`` PC: ``setUp`` on a new tangent, ``apply`` per Krylov
    iteration (see the module docstring).

    Args:
        fields: the owned global rows (PETSc ISs) of u (node by node), p and c.
        weights: W / alpha on the rows of ``fields[1]``, in their order (``pressure_weights``).
        near_null_space: the rigid-body modes of u, for a multigrid K_g solver.
        last: the rank that owns the cavity unknowns.
    """

    def __init__(self, fields, weights, near_null_space, last):
        self.u, self.p, self.c = fields
        self.unit_weights = weights
        self.near_null_space = near_null_space
        self.last = last
        self.K_g = None
        self.ksp = None
        self.work = None

    def setUp(self, pc: PETSc.PC) -> None:
        A, _ = pc.getOperators()
        comm = A.getComm().tompi4py()
        self.A = A
        self.weights = PETSc.Options(pc.getOptionsPrefix()).getReal("al_alpha", ALPHA) * self.unit_weights
        diagonal = A.getDiagonal()
        App = diagonal.getSubVector(self.p)
        augmented = self.weights > 0
        self.S_p = App.array_r - np.where(augmented, 1 / np.where(augmented, self.weights, 1.0), 0.0)
        diagonal.restoreSubVector(self.p, App)
        diagonal.destroy()
        self._augment(A)
        if self.ksp is None:
            self.ksp = PETSc.KSP().create(comm)
            self.ksp.setOptionsPrefix(pc.getOptionsPrefix() + "al_u_")
            self.ksp.setType("preonly")
            factor = self.ksp.getPC()
            factor.setType("cholesky")
            factor.setFactorSolverType("mumps")
            self.ksp.setOperators(self.K_g)
            self.ksp.setFromOptions()
        else:
            self.ksp.setOperators(self.K_g)
        self.ksp.setUp()
        if self.work is None:
            self.work = A.createVecLeft(), A.createVecLeft()
        self._cavity_schur(A, comm)

    def reset(self, pc: PETSc.PC) -> None:
        """A new matrix (its pattern may differ): K_g, its factorization and the work vectors are made anew."""
        for obj in (self.K_g, self.ksp, *(self.work or ())):
            if obj is not None:
                obj.destroy()
        self.K_g = self.ksp = self.work = None

    def _augment(self, A):
        """K_g = K + B^T W B, in place of the last one (its pattern: element couplings, K's)."""
        B = A.createSubMatrix(self.p, self.u)
        WB = B.copy()
        w = B.createVecLeft()
        w.array[:] = self.weights
        WB.diagonalScale(L=w)
        BtWB = B.transposeMatMult(WB)
        for matrix in (B, WB, w):
            matrix.destroy()
        self.K_g = A.createSubMatrix(self.u, self.u, submat=self.K_g)
        self.K_g.axpy(1.0, BtWB, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
        BtWB.destroy()
        self.K_g.setNearNullSpace(self.near_null_space)

    def _cavity_schur(self, A, comm):
        """s = d - r^T K_g^-1 b on the last rank (m solves with K_g; r = 0 while filling)."""
        rows = self.c.getIndices()
        self.s_inverse = np.zeros((len(rows), len(rows)))
        m = comm.allreduce(len(rows))
        if not m:
            return
        b = A.createSubMatrix(self.u, self.c)
        r = A.createSubMatrix(self.c, self.u)
        unit, column, solution, product = b.createVecRight(), b.createVecLeft(), b.createVecLeft(), r.createVecLeft()
        rows_all = np.concatenate(comm.allgather(rows))
        s = A.getValues(rows, rows) if len(rows) else None
        for j, row in enumerate(rows_all):
            unit.zeroEntries()
            if comm.rank == self.last:
                unit.array[j] = 1.0
            b.mult(unit, column)
            self.ksp.solve(column, solution)
            r.mult(solution, product)
            if comm.rank == self.last:
                s[:, j] -= product.array_r
        if comm.rank == self.last:
            self.s_inverse = np.linalg.inv(s)
        for obj in (b, r, unit, column, solution, product):
            obj.destroy()

    def apply(self, pc: PETSc.PC, x: PETSc.Vec, y: PETSc.Vec) -> None:
        """y = P^-1 T x: y_c = s^-1 x_c, y_p = S_p^-1 x_p, and
        y_u = K_g^-1 (x_u + B^T W x_p - B^T y_p - b y_c) (one product with A, one K_g solve)."""
        z, Az = self.work
        z.zeroEntries()
        xp = x.getSubVector(self.p)
        yp = xp.array_r / self.S_p
        zp = z.getSubVector(self.p)
        zp.array[:] = yp - self.weights * xp.array_r
        z.restoreSubVector(self.p, zp)
        x.restoreSubVector(self.p, xp)
        xc = x.getSubVector(self.c)
        yc = self.s_inverse @ xc.array_r
        x.restoreSubVector(self.c, xc)
        zc = z.getSubVector(self.c)
        zc.array[:] = yc
        z.restoreSubVector(self.c, zc)
        self.A.mult(z, Az)
        Az.aypx(-1.0, x)  # its u rows: x_u - B^T (y_p - W x_p) - b y_c
        y.zeroEntries()
        for rows, values in ((self.p, yp), (self.c, yc)):
            sub = y.getSubVector(rows)
            sub.array[:] = values
            y.restoreSubVector(rows, sub)
        ru, yu = Az.getSubVector(self.u), y.getSubVector(self.u)
        self.ksp.solve(ru, yu)
        Az.restoreSubVector(self.u, ru)
        y.restoreSubVector(self.u, yu)

"""The Newton system: the solid plus every feature the scene holds, on one PETSc matrix.

Block order of the unknowns (written down here, and only here):

    x = [ w (the mixed (u, p) dofs of the solid, DOLFINx numbering) | g_1 .. g_m ]

where g_k are the global scalar unknowns of the features (one liquid pressure per
cavity). Rank r owns its DOLFINx dofs; the last rank also owns g_1 .. g_m, so the global
numbering of the DOLFINx dofs is unchanged and the bordered matrix

    [ K     B ]   K: Jacobian of the UFL forms (+ custom contact terms)
    [ C^T   D ]   B, C: one sparse column / row per global unknown, D: m x m

is one MPIAIJ matrix that MUMPS factorizes directly (the seed's "new algorithm"). It is
preallocated exactly from the DOLFINx sparsity pattern plus the borders and every entry the
custom tangents declare (``coupling``), and those entries are given zeros at the matrix's first
assembly: PETSc drops the room a final assembly left unused, and a tangent that reaches one of
them later (a liquid's condensed block once it stops filling, a contact point on a new
segment, a suture that comes taut) would then cost a malloc and MUMPS a new symbolic analysis.
So assembly does no mallocs, and MUMPS reuses its analysis while the pattern stays the same.

The rows of the residual fall into blocks of different units (``residual_blocks``), which
Newton judges one by one: the free displacement rows (forces), the prescribed ones
(x - g, lengths), the solid's pressure rows (the integral of J - 1 over an element, or of
-p / mu in a compressible region: volumes), and one block per global unknown (a cavity's
liquid law: a volume).

The features are sorted once, when the problem is built, by the roles they play
(``features/roles.py``), into lists in scene order; each callback loops over the lists it
needs, in that order, so the terms are summed as the scene lists them. The nodal roles
(``nodal_residuals``: residual by global index; ``nodal_tangents``: tangent by global index) cost what
they need only when a scene holds them: without them the residual needs no assembly by global
index, and the matrix may not grow beyond its preallocation. Either way the residual's Dirichlet
rows are the misfit x - g, written over whatever was added to them.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import apply_lifting, assemble_matrix, assemble_vector, set_bc
from mpi4py import MPI
from petsc4py import PETSc

from ..arrays import distinct_pairs
from ..features.base import Feature
from ..features.roles import (
    ActiveSet,
    Constraint,
    FormTerm,
    GlobalUnknowns,
    NodalResidual,
    NodalTangent,
    StateDependent,
    check_whole_role,
)
from ..mechanics.solid import JacobianGuard, MixedSolid


class Problem:
    """Residual and Jacobian of the solid and its features, as SNES callbacks."""

    def __init__(self, solid: MixedSolid, features: Sequence[Feature]):
        self.solid = solid
        self.features = list(features)
        self.comm = comm = solid.comm
        for f in self.features:
            f.setup(solid)
        self._sort_by_role()
        residual = ufl.derivative(solid.potential(), solid.w, ufl.TestFunction(solid.W))
        for f in self.form_terms:
            residual = residual + f.residual(solid)
        self.R_form = fem.form(residual)
        self.J_form = fem.form(ufl.derivative(residual, solid.w, ufl.TrialFunction(solid.W)))
        self.m = sum(f.num_unknowns for f in self.global_unknowns)

        index_map = solid.W.dofmap.index_map
        self.n_owned = index_map.size_local
        self.n_global = index_map.size_global
        self.last = comm.size - 1
        self.n_extra_local = self.m if comm.rank == self.last else 0
        self.offset = index_map.local_range[0]
        self.extra_global = self.n_global + np.arange(self.m, dtype=np.int32)
        local_to_global = np.concatenate([index_map.local_to_global(
            np.arange(self.n_owned + index_map.num_ghosts, dtype=np.int32)), self.extra_global]).astype(PETSc.IntType)
        self.lgmap = PETSc.LGMap().create(local_to_global, comm=comm)

        self.b_w = fem.petsc.create_vector(self.R_form)
        self.scratch = self.b_w.duplicate()  # the prescribed values' misfit (F)
        self._nnz = None
        self.A = self._create_matrix()
        self.x, self.b = self.A.createVecs()
        self.guard = JacobianGuard(solid)
        self.bcs = []
        self.inverted = None
        self._displacement_rows, self._pressure_rows = (self._owned_rows(solid.W.sub(i)) for i in range(2))

    def _sort_by_role(self):
        """The features of each role (``features/roles.py``), in scene order: the one place that
        asks what a feature is (after ``setup``, which may create what a role needs). A feature
        that defines some of a role's methods but lacks a member of it is an error, not a
        feature silently left out of the role."""
        def playing(role):
            for f in self.features:
                check_whole_role(f, role)
            return [f for f in self.features if isinstance(f, role)]
        self.form_terms = playing(FormTerm)
        self.constraints = playing(Constraint)  # the features that impose Dirichlet conditions
        self.nodal_residuals = playing(NodalResidual)
        self.nodal_tangents = playing(NodalTangent)
        self.global_unknowns = playing(GlobalUnknowns)
        self.state_dependent = playing(StateDependent)
        self.active_sets = playing(ActiveSet)

    @property
    def limits_steps(self) -> bool:
        """Whether a feature may shorten Newton's steps (``ActiveSet.step_fraction``)."""
        return bool(self.active_sets)

    @property
    def newton_options(self) -> dict:
        """The PETSc options the active sets ask of Newton (merged in scene order)."""
        return {key: value for f in self.active_sets for key, value in f.newton_options.items()}

    @property
    def symmetric_tangent(self) -> bool:
        """Whether every hand-assembled part of the tangent is declared symmetric (the UFL part
        is checked numerically by the solver)."""
        return all(f.symmetric_tangent for f in self.nodal_tangents + self.global_unknowns)

    def _owned_rows(self, subspace):
        """Owned local indices in W (block size 1) of a subspace's dofs (collective: collapses it)."""
        rows = np.asarray(subspace.collapse()[1], dtype=np.int32)
        return np.sort(rows[rows < self.n_owned])

    # -- the matrix ----------------------------------------------------------------------
    def _form_nnz(self):
        """Entries per owned row (diagonal block, off-diagonal block) of the forms' pattern and the
        borders: computed once (the mesh's pattern never changes), copied for each matrix."""
        if self._nnz is None:
            n, m = self.n_owned, self.m
            pattern = fem.create_sparsity_pattern(self.J_form)
            pattern.assemble()
            graph = pattern.graph
            rows = np.repeat(np.arange(len(graph.offsets) - 1), np.diff(graph.offsets))
            owned = rows < n  # the pattern also lists ghost rows
            d_nnz = np.zeros(n + self.n_extra_local, dtype=PETSc.IntType)
            o_nnz = np.zeros_like(d_nnz)
            d_nnz[:n] = np.bincount(rows[owned & (graph.array < n)], minlength=n)
            o_nnz[:n] = np.bincount(rows[owned], minlength=n) - d_nnz[:n]
            if m:  # every row may meet each border column; border rows may be full
                (d_nnz if self.comm.rank == self.last else o_nnz)[:n] += m
                d_nnz[n:] = n + m
                o_nnz[n:] = self.n_global - n
            self._nnz = d_nnz, o_nnz
        return self._nnz[0].copy(), self._nnz[1].copy()

    def _create_matrix(self):
        n, m, comm = self.n_owned, self.m, self.comm
        d_nnz, o_nnz = self._form_nnz()
        rows, cols = self._coupling()
        d_extra = np.bincount(rows[(cols >= self.offset) & (cols < self.offset + n)] - self.offset, minlength=n)
        d_nnz[:n] += d_extra[:n]
        o_nnz[:n] += np.bincount(rows - self.offset, minlength=n)[:n] - d_extra[:n]
        size = (n + self.n_extra_local, self.n_global + m)
        A = PETSc.Mat().createAIJ((size, size), nnz=(d_nnz, o_nnz), comm=comm)
        A.setLGMap(self.lgmap, self.lgmap)
        A.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, not self.nodal_tangents)
        A.setOption(PETSc.Mat.Option.KEEP_NONZERO_PATTERN, True)
        self._room = rows, cols  # zeros at the first assembly (module docstring)
        return A

    def _coupling(self):
        """Distinct extra (row, col) entries of the custom tangents, on the rows' owners."""
        pairs = [f.coupling() for f in self.nodal_tangents]
        pairs = [np.column_stack(p).astype(np.int64) for p in pairs if p is not None]
        pairs = np.concatenate(pairs) if pairs else np.empty((0, 2), dtype=np.int64)
        ranges = np.array(self.comm.allgather(self.offset) + [self.n_global])
        owner = np.searchsorted(ranges, pairs[:, 0], side="right") - 1
        order = np.argsort(owner, kind="stable")
        chunks = np.split(pairs[order], np.searchsorted(owner[order], np.arange(1, self.comm.size)))
        mine = np.concatenate(self.comm.alltoall(chunks)).reshape(-1, 2)
        return distinct_pairs(mine[:, 0], mine[:, 1])

    def update_pattern(self) -> bool:
        """Start of an increment: let the active sets search; re-preallocate if their coupling
        changed. Returns True if the matrix was created anew (collective)."""
        changed = [f.begin_increment() for f in self.active_sets]
        if not self.comm.allreduce(any(changed), op=MPI.LOR):
            return False
        self.A.destroy()
        self.A = self._create_matrix()
        return True

    def tangent_outdated(self, corrected: bool = False) -> bool:
        """Collective: an active set changed since the last tangent (its factorization then is
        no Newton step); every feature is asked, so that their collectives stay aligned."""
        return any([f.tangent_outdated(corrected) for f in self.active_sets])

    # -- steps ---------------------------------------------------------------------------
    def begin_step(self, step_index: int) -> None:
        for f in self.features:
            f.begin_step(step_index)
        self.bcs = [bc for f in self.constraints for bc in f.dirichlet_bcs()]
        rows = [bc.dof_indices()[0][: bc.dof_indices()[1]] for bc in self.bcs]
        self.bc_rows = np.unique(np.concatenate(rows)) if rows else np.empty(0, dtype=np.int32)
        self.residual_blocks = self._residual_blocks()

    def _residual_blocks(self):
        """[(name, owned local rows)] of the residual's blocks (see the module docstring); the
        same names on every rank, a global unknown's rows on the last rank only."""
        prescribed = np.isin(self._displacement_rows, self.bc_rows)
        blocks = [("force", self._displacement_rows[~prescribed]), ("prescribed", self._displacement_rows[prescribed]),
                  ("incompressibility", self._pressure_rows)]
        index = self.n_owned
        for f in self.global_unknowns:
            for k in range(f.num_unknowns):
                rows = np.array([index] if self.comm.rank == self.last else [], dtype=np.int32)
                blocks.append((f.name if f.num_unknowns == 1 else f"{f.name} [{k}]", rows))
                index += 1
        return blocks

    def set_load_factor(self, factors: Sequence[float]) -> None:
        """factors: one ramp value per feature, in the order of ``self.features``."""
        for f, factor in zip(self.features, factors):
            f.set_load_factor(factor)

    # -- state transfer ------------------------------------------------------------------
    def state_to_vector(self, x: PETSc.Vec) -> None:
        # x and b have no ghosts: their .array is the owned part
        x.array[: self.n_owned] = self.solid.w.x.array[: self.n_owned]
        x.array[self.n_owned:] = self.global_values()

    def global_values(self) -> np.ndarray:
        values = np.concatenate([f.unknowns for f in self.global_unknowns]) if self.global_unknowns else np.empty(0)
        return values if self.comm.rank == self.last else np.empty(0)

    def vector_to_state(self, x: PETSc.Vec) -> None:
        w = self.solid.w
        w.x.array[: self.n_owned] = x.array_r[: self.n_owned]
        w.x.scatter_forward()
        if self.m:
            values = self.comm.bcast(x.array_r[self.n_owned:].copy() if self.comm.rank == self.last else None,
                                     root=self.last)
            start = 0
            for f in self.global_unknowns:
                f.unknowns = values[start: start + f.num_unknowns]
                start += f.num_unknowns
        for f in self.state_dependent:
            f.state_changed()

    def step_fraction(self, du: np.ndarray, residual: np.ndarray) -> float:
        """The largest fraction (at most 1) of the state change du that every active set allows
        in one step, given the residual at the current state (local arrays of bordered vectors;
        collective)."""
        return min([f.step_fraction(du[: self.n_owned], residual[: self.n_owned]) for f in self.active_sets],
                   default=1.0)

    def set_increment(self, final: bool) -> None:
        for f in self.active_sets:
            f.set_increment(final)

    def augment(self, solving: bool) -> bool:
        """After Newton converged: True if no active set needs another solve (``solving``: Newton
        solves again anyway; collective)."""
        return all([f.augment(solving) for f in self.active_sets])

    def close_gaps(self, y: PETSc.Vec, respond: Callable) -> bool:
        """Newton's step x -> x - y (a bordered vector) changed for the contacts it makes and
        breaks, by each active set in turn (``ActiveSet.closing_step``; the state at x); returns
        whether y changed (collective)."""
        changed = False
        for f in self.active_sets:
            change = f.closing_step(-y.array_r, respond)
            if change is not None:
                y.array[:] -= change
                changed = True
        return changed

    def search_covers(self) -> bool:
        """After Newton converged: True if no active set must search again (collective)."""
        return all([f.search_covers() for f in self.active_sets])

    def abandon_augmentation(self) -> bool:
        """The solve after the last augmentation failed: the active sets take it back; returns whether
        any had an update to take back (collective)."""
        return any([f.abandon_augmentation() for f in self.active_sets])

    # -- SNES callbacks ------------------------------------------------------------------
    def assemble_residual_unconstrained(self) -> PETSc.Vec:
        """The residual vector of the UFL forms, ghosts accumulated, no BC treatment."""
        with self.b_w.localForm() as bl:
            bl.set(0.0)
        assemble_vector(self.b_w, self.R_form)
        self.b_w.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        if self.nodal_residuals:  # contact, sutures and nodal forces act on constrained nodes too
            b = self.b.duplicate()
            b.array[: self.n_owned] = self.b_w.array_r[: self.n_owned]
            for f in self.nodal_residuals:
                f.add_to_residual(b)
            b.assemble()
            self.b_w.array[: self.n_owned] = b.array_r[: self.n_owned]
        return self.b_w

    def F(self, snes: PETSc.SNES | None, x: PETSc.Vec, b: PETSc.Vec) -> None:
        self.vector_to_state(x)
        det_min, where = self.guard.check()
        if not det_min > 0:
            if self.inverted is None:  # the first inversion of this Newton solve: where it began
                self.inverted = (det_min, where)
            b.set(np.inf)
            return
        with self.scratch.localForm() as sl:  # the Dirichlet rows' misfit x - g
            sl.set(0.0)
        set_bc(self.scratch, self.bcs, self.solid.w.vector, -1.0)
        with self.b_w.localForm() as bl:
            bl.set(0.0)
        assemble_vector(self.b_w, self.R_form)
        # the lifting adds -J (g - x) over the Dirichlet columns: exactly nothing once x = g there
        # (every Newton iterate after an increment's first), so it is skipped then
        if self.comm.allreduce(bool(np.any(self.scratch.array_r[self.bc_rows] != 0.0)), op=MPI.LOR):
            apply_lifting(self.b_w, [self.J_form], [self.bcs], x0=[self.solid.w.vector], scale=-1.0)
        self.b_w.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        b.array[: self.n_owned] = self.b_w.array_r[: self.n_owned]
        b.array[self.n_owned:] = self._border_residuals()
        if self.nodal_residuals:  # added by global index
            for f in self.nodal_residuals:
                f.add_to_residual(b)
            b.assemble()
        b.array[self.bc_rows] = self.scratch.array_r[self.bc_rows]  # over whatever was added to them

    def _border_residuals(self):
        values = [f.unknown_residuals() for f in self.global_unknowns]
        if self.comm.rank != self.last or not values:
            return np.empty(0)
        return np.concatenate(values)

    def J(self, snes: PETSc.SNES | None, x: PETSc.Vec, A: PETSc.Mat, P: PETSc.Mat) -> None:
        A.zeroEntries()
        assemble_matrix(A, self.J_form, self.bcs, diagonal=1.0)
        if self.global_unknowns or self.nodal_tangents:
            A.assemble(PETSc.Mat.AssemblyType.FLUSH)  # the BC diagonal was inserted, the rest adds
        index = self.n_global
        for f in self.global_unknowns:
            for dofs, column, row, diagonal in f.border():
                self._set_border(A, index, dofs, column, row, diagonal)
                index += 1
        if self._room is not None and len(self._room[0]):
            rows, cols = (np.asarray(a, dtype=PETSc.IntType)[:, None] for a in self._room)
            A.setValuesRCV(rows, cols, np.zeros((len(rows), 1, 1)), addv=PETSc.InsertMode.ADD_VALUES)
        self._room = None
        for f in self.nodal_tangents:
            f.add_to_jacobian(A)
        A.assemble()
        if self.nodal_tangents:
            A.zeroRows(self.lgmap.apply(self.bc_rows), diag=1.0)

    def _set_border(self, A, index, dofs, column, row, diagonal):
        """Insert the border column and row of global unknown ``index`` over the owned dofs
        ``dofs`` (local indices), and its diagonal entry."""
        globals_ = self.lgmap.apply(np.asarray(dofs, dtype=PETSc.IntType))
        column = np.where(np.isin(dofs, self.bc_rows), 0.0, column)  # constrained rows keep their identity
        A.setValues(globals_, [index], column[:, None], addv=PETSc.InsertMode.ADD_VALUES)
        A.setValues([index], globals_, np.asarray(row)[None, :], addv=PETSc.InsertMode.ADD_VALUES)
        if self.comm.rank == self.last:
            A.setValues([index], [index], [diagonal], addv=PETSc.InsertMode.ADD_VALUES)

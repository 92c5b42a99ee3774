"""Boundary conditions: prescribed displacement, follower pressure, nodal forces.

A prescribed displacement is a Dirichlet condition (role ``Constraint``); the follower
pressure -p J F^-T N dA on the deformed surface (Nanson's formula) is a UFL term
(``FormTerm``), whose derivative gives its tangent; a dead nodal force adds to the assembled
residual (``NodalResidual``) and has no tangent.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from .. import checks
from ..errors import SceneError
from ..mechanics.solid import MaterialNode, MixedSolid
from .base import AXES, Feature


class Dirichlet(Feature):
    """Prescribed displacement components on a surface, reached linearly over its step.

    Args:
        surface: surface group name.
        components: {"x": value, ...}; only the listed components are constrained.
    """

    def __init__(self, surface: str, components: dict[str, float], step: int = 0):
        what = f"dirichlet on {surface!r}"
        if not components or set(components) - set(AXES):
            raise SceneError(f"{what}: give one or more of x, y, z, got {sorted(components)}")
        self.name = self.surface = surface
        self.components = {AXES[c]: checks.number(v, f"{what}: {c}") for c, v in components.items()}
        self.step = step

    def setup(self, solid: MixedSolid) -> None:
        self.solid = solid
        self.dofs = solid.surface_dofs(self.surface)
        self._bcs, self._values = [], []
        msh = solid.mesh_data.mesh
        facets = solid.mesh_data.facets(self.surface)
        for i in self.components:
            Wi = solid.W.sub(0).sub(i)
            Vi, _ = solid.component(i)
            g = fem.Function(Vi)
            dofs = fem.locate_dofs_topological((Wi, Vi), msh.topology.dim - 1, facets)
            self._bcs.append(fem.dirichletbc(g, dofs, Wi))
            self._values.append((i, g, dofs))
        self.active = False
        self._start = None  # per component, the values the ramp starts from (set in its step)

    def begin_step(self, step_index: int) -> None:
        self.active = step_index >= self.step
        if step_index == self.step:
            # ramp from where the surface is now (zero in the first step) to the target
            self._start = {}
            for i, g, (in_W, _) in self._values:
                self._start[i] = self.solid.w.x.array[in_W].copy()

    def set_load_factor(self, factor: float) -> None:
        if not self.active:
            return
        for i, g, (_, collapsed) in self._values:
            start = self._start[i]
            g.x.array[collapsed] = start + factor * (self.components[i] - start)

    def dirichlet_bcs(self) -> list:
        return self._bcs if self.active else []

    # -- a checkpoint (output/checkpoint.py) ----------------------------------------------
    def checkpoint_state(self) -> dict:
        """The values the ramp started from, as a dof array of the mixed space (None before the
        step): held after the step, the prescribed values are start + 1 * (target - start), which
        a resumed run must compute from the same start to the bit."""
        if self._start is None:
            return {"start": None}
        start = np.zeros(len(self.solid.w.x.array))
        for i, _, (in_W, _) in self._values:
            start[in_W] = self._start[i]
        return {"start": start}

    def restore_state(self, state: dict) -> None:
        if state["start"] is not None:
            self._start = {i: state["start"][in_W].copy() for i, _, (in_W, _) in self._values}

    def reaction(self, residual_array: np.ndarray) -> list[float]:
        """Total reaction force on the surface from the unconstrained residual (local array):
        only the constrained components (a sliding support carries no tangential force)."""
        owned = self.solid.num_owned
        local = [residual_array[d[d < owned]].sum() if i in self.components else 0.0 for i, d in enumerate(self.dofs)]
        return self.solid.comm.allreduce(np.array(local), op=MPI.SUM).tolist()


class Pressure(Feature):
    """Follower pressure on the deformed surface, pushing along the solid's inward normal."""

    def __init__(self, surface: str, value: float, step: int = 0):
        self.name = self.surface = surface
        self.value = checks.number(value, f"pressure on {surface!r}: value")
        self.step = step

    def setup(self, solid: MixedSolid) -> None:
        self.pressure = fem.Constant(solid.mesh_data.mesh, 0.0)
        solid.mesh_data.facets(self.surface)  # an unknown surface is a SceneError now

    def residual(self, solid: MixedSolid) -> ufl.Form:
        # -(external virtual work) of traction -p n da = -p J F^-T N dA
        ds = solid.ds(solid.mesh_data.surfaces[self.surface])
        return self.pressure * ufl.inner(solid.current_normal_area(), solid.v) * ds

    def set_load_factor(self, factor: float) -> None:
        self.pressure.value = factor * self.value


class NodalForce(Feature):
    """A total force spread in equal parts over the nodes of a surface (a dead load).

    With ``point`` instead of ``surface``, the whole force acts at the mesh node nearest to
    that reference point.
    """

    def __init__(self, value: Sequence[float], surface: str | None = None, point: Sequence[float] | None = None,
                 step: int = 0):
        if (surface is None) == (point is None):
            raise SceneError("force: give exactly one of surface or point")
        self.surface, self.point = surface, None if point is None else checks.vector(point, "force: point")
        self.name = surface or f"node near {point}"
        self.force = np.asarray(checks.vector(value, f"force on {self.name!r}: value"))
        self.step = step
        self.factor = 0.0

    def setup(self, solid: MixedSolid) -> None:
        owned = solid.num_owned
        if self.surface is not None:
            dofs = [d[d < owned] for d in solid.surface_dofs(self.surface)]
        else:
            dofs = list(MaterialNode(solid, self.point).local.T)  # its owner's one node, none elsewhere
        self.dofs = dofs
        self.num_nodes = solid.comm.allreduce(len(dofs[0]), op=MPI.SUM)

    def set_load_factor(self, factor: float) -> None:
        self.factor = factor

    def add_to_residual(self, b: PETSc.Vec) -> None:
        for i, d in enumerate(self.dofs):  # owned dofs: local index = index in b's owned array
            b.array[d] -= self.factor * self.force[i] / self.num_nodes


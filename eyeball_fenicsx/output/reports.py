"""What a step's entry of summary.json holds besides the increments: the displacement at the
probes, the reactions of the active supports and every feature's report.

Data path: when the scene is built, ``Probes`` finds the cell of each point (a point outside
the mesh is an error of the scene); after each step it reads the solid's displacement there, and
``FeatureReports`` assembles the residual of the problem without its Dirichlet rows once, sums
it over each active constraint's dofs (the reaction, as the support holds the solid) and asks
every feature for its report, in the scene's order (observers: output/observer.py).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from dolfinx import geometry
from mpi4py import MPI

from ..errors import SceneError
from .observer import Observer

if TYPE_CHECKING:
    from ..mechanics.solid import MixedSolid
    from ..system.problem import Problem


class Probes(Observer):
    """Displacement at material points given by their reference coordinates, under "probes".

    The lowest rank whose owned cells hold a point evaluates the displacement there and
    broadcasts it."""

    def __init__(self, points: dict[str, list[float]]) -> None:
        self.points = points

    def setup(self, solid: MixedSolid, problem: Problem) -> None:
        """Find the owned cell and the owning rank of each point (collective)."""
        self.solid = solid
        msh = solid.mesh_data.mesh
        tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
        num_owned_cells = msh.topology.index_map(msh.topology.dim).size_local
        self.cells = {}
        for name, point in self.points.items():
            x = np.asarray(point, dtype=float).reshape(1, 3)
            candidates = geometry.compute_collisions(tree, x)
            cells = geometry.compute_colliding_cells(msh, candidates, x).links(0)
            cells = cells[cells < num_owned_cells]
            owner = solid.comm.allreduce(solid.comm.rank if len(cells) else solid.comm.size, op=MPI.MIN)
            if owner == solid.comm.size:
                raise SceneError(f"probe {name!r}: point {list(point)} is not inside the mesh {solid.mesh_data.source}")
            self.cells[name] = (x, cells[0] if solid.comm.rank == owner else None, owner)

    def displacements(self) -> dict[str, list[float]]:
        """Collective: {probe: its displacement}."""
        u = self.solid.w.sub(0)
        result = {}
        for name, (x, cell, owner) in self.cells.items():
            value = u.eval(x, [cell])[:3] if cell is not None else None
            result[name] = [float(v) for v in self.solid.comm.bcast(value, root=owner)]
        return result

    def after_step(self, step: str, index: int, entry: dict, converged: bool) -> None:
        entry["probes"] = self.displacements()


class FeatureReports(Observer):
    """The reactions of the active constraints under "reactions", and each feature's report:
    under its ``section`` and ``name``, or merged into its ``section`` if its name is None."""

    def setup(self, solid: MixedSolid, problem: Problem) -> None:
        self.problem = problem

    def after_step(self, step: str, index: int, entry: dict, converged: bool) -> None:
        residual = self.problem.assemble_residual_unconstrained().array_r
        entry["reactions"] = {f.name: f.reaction(residual) for f in self.problem.constraints if f.active}
        for f in self.problem.features:
            report = f.report()
            if report is not None and f.name is None:  # the report is the whole section
                entry.setdefault(f.section, {}).update(report)
            elif report is not None:
                entry.setdefault(f.section, {})[f.name] = report

"""What contact needs to know of the solid: its nodes, the facets of a named surface, and
the stiffness of the elements under them (for the default penalty)."""
from __future__ import annotations

import dataclasses

import numpy as np
import ufl
from dolfinx import cpp, fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from .. import checks
from ..errors import SceneError
from ..mechanics.solid import MixedSolid
from .policy import PENALTY_FACTOR
from .segments import Quad, Triangle


class SolidTables:
    """Per node (indexed by the local dof of its x component, ghosts included): its 3 local
    dofs, their global numbers and its reference coordinates; per local cell: volume and
    Young's modulus (3 mu for the incompressible laws)."""

    def __init__(self, solid: MixedSolid):
        W, md = solid.W, solid.mesh_data
        if W.sub(0).ufl_element().degree() != 1:
            raise SceneError(f"contact needs first-order displacements (element Q1P0 on hexahedra or P1P0 on "
                             f"tetrahedra), not {solid.element}; choose the element accordingly")
        index_map = W.dofmap.index_map
        size = index_map.size_local + index_map.num_ghosts
        self.num_owned = index_map.size_local
        cell_dofs = [W.sub(0).sub(k).dofmap.list.array.reshape(-1, W.sub(0).sub(k).dofmap.dof_layout.num_dofs)
                     for k in range(3)]
        self.cell_nodes = cell_dofs[0]
        self.dofs = np.full((size, 3), -1, dtype=np.int32)
        for k in range(3):
            self.dofs[cell_dofs[0].ravel(), k] = cell_dofs[k].ravel()
        V0, to_W = solid.component(0)
        self.X = np.zeros((size, 3))
        self.X[to_W] = V0.tabulate_dof_coordinates()
        self.global_index = index_map.local_to_global(np.arange(size, dtype=np.int32)).astype(PETSc.IntType)

        Q = fem.FunctionSpace(md.mesh, ("DG", 0))
        volume = fem.Function(Q)
        assemble_vector(volume.vector, fem.form(ufl.TestFunction(Q) * ufl.dx))
        volume.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        volume.vector.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        self.volume = volume.x.array.copy()
        self.modulus = np.zeros(len(self.volume))
        for region, law in solid.laws.items():
            self.modulus[md.cells(region)] = law.youngs_modulus


@dataclasses.dataclass
class Surface:
    """A named surface on this rank.

    Attributes:
        kind: segment type, ``Quad`` or ``Triangle``.
        facets: local x-dofs of the facets this rank owns, counter-clockwise seen from
            outside (m, k).
        area: reference area of each facet (m,); thickness: h = V / A of the element under
            it (m,); stiffness: E / h of that element (m,).
        nodes: local x-dofs of the surface nodes this rank owns (n,), with their tributary
            areas ``node_area`` (n,) and area-weighted E / h ``node_stiffness`` (n,).
        mean_stiffness: area-weighted mean E / h over the whole surface (all ranks).
    """

    kind: type
    facets: np.ndarray
    area: np.ndarray
    thickness: np.ndarray
    stiffness: np.ndarray
    nodes: np.ndarray
    node_area: np.ndarray
    node_stiffness: np.ndarray
    mean_stiffness: float


def surface(solid: MixedSolid, tables: SolidTables, name: str) -> Surface:
    """The ``Surface`` of the named surface group (collective)."""
    md, W = solid.mesh_data, solid.W
    msh = md.mesh
    facets = np.asarray(md.facets(name))
    msh.topology.create_connectivity(2, 3)
    msh.topology.create_connectivity(3, 2)
    facets = facets[facets < msh.topology.index_map(2).size_local]
    f2c, c2f = msh.topology.connectivity(2, 3), msh.topology.connectivity(3, 2)
    cells = f2c.array[f2c.offsets[facets]]
    per_cell = cpp.mesh.cell_num_entities(msh.topology.cell_type, 2)
    local_facet = np.argmax(c2f.array.reshape(-1, per_cell)[cells] == facets[:, None], axis=1)
    layout = W.sub(0).sub(0).dofmap.dof_layout
    closure = np.array([layout.entity_closure_dofs(2, i) for i in range(per_cell)])
    segments = tables.cell_nodes[cells[:, None], closure[local_facet]].reshape(len(facets), closure.shape[1])
    kind = Quad if segments.shape[1] == 4 else Triangle
    if kind is Quad:
        segments = segments[:, [0, 1, 3, 2]]  # DOLFINx orders a quad's vertices tensor-product
    x = tables.X[segments]
    if kind is Quad:
        normal = 0.5 * np.cross(x[:, 2] - x[:, 0], x[:, 3] - x[:, 1])
    else:
        normal = 0.5 * np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    area = np.linalg.norm(normal, axis=1)
    # outward: away from the centroid of the element the facet bounds
    inward = np.einsum("ij,ij->i", normal, x.mean(axis=1) - tables.X[tables.cell_nodes[cells]].mean(axis=1)) < 0
    segments[inward] = segments[inward][:, ::-1]
    thickness = tables.volume[cells] / area
    stiffness = tables.modulus[cells] / thickness

    # nodal areas and area-weighted stiffness, summed on the owners
    scratch = fem.Function(W)
    corners = kind.corners
    share = np.repeat(area / corners, corners)
    np.add.at(scratch.x.array, segments.ravel(), share)
    np.add.at(scratch.x.array, tables.dofs[segments.ravel(), 1], share * np.repeat(stiffness, corners))
    scratch.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    values = scratch.x.array
    candidates = np.unique(tables.cell_nodes)
    candidates = candidates[candidates < tables.num_owned]
    nodes = candidates[values[candidates] > 0]
    node_area = values[nodes]
    totals = solid.comm.allreduce(np.array([area.sum(), (area * stiffness).sum()]), op=MPI.SUM)
    if totals[0] == 0:
        raise SceneError(f"contact surface {name!r} of {md.source} has no facets")
    return Surface(kind, segments, area, thickness, stiffness, nodes, node_area,
                   values[tables.dofs[nodes, 1]] / node_area, totals[1] / totals[0])


def check_penalty(name: str, penalty: float | None) -> float | None:
    """A scene's penalty, checked (None: the default)."""
    if penalty is None:
        return None
    what = f"contact {name!r}: penalty"
    if not checks.number(penalty, what) > 0:
        raise SceneError(f"{what} must be a positive number (pressure per unit penetration), got {penalty!r}")
    return float(penalty)


def default_penalty(slave_stiffness: np.ndarray, master_stiffness: float) -> np.ndarray:
    """PENALTY_FACTOR times the series stiffness k_s k_m / (k_s + k_m) of the slave's and the
    master's surface elements (k = E / h; a rigid master: k_m infinite)."""
    if np.isinf(master_stiffness):
        return PENALTY_FACTOR * slave_stiffness
    return PENALTY_FACTOR * slave_stiffness * master_stiffness / (slave_stiffness + master_stiffness)

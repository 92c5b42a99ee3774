"""The mixed displacement-pressure formulation of incompressible hyperelasticity.

Total potential of the solid (the seed's Phi, with its 2 lambda written -p):

    Pi(u, p) = sum over regions  integral of  W(F) - p (J - 1)  dV

for incompressible regions; the Lagrange multiplier p is the hydrostatic pressure
(compression positive, sigma = dev part - p I). In a compressible region the pressure
unknown is idle and pinned to zero by the term -p^2 / (2 mu).

Elements: on hexahedra the seed's Q1/P0 (8-node trilinear displacement, one pressure per
element); on tetrahedra P2/P0 (quadratic displacement, one pressure per element, which is
inf-sup stable). Other pairs can be named for convergence studies.

A region's rest state may be changed by a prescribed deformation F_g (``prestretch``: a band
shortened by the surgeon): its law is then ``materials.Prestretched``. The solid owns the laws
in force (``laws``); the materials it was given stay as they were.
"""
from __future__ import annotations

import dataclasses

import basix
import numpy as np
import ufl
from dolfinx import fem, jit
from dolfinx.mesh import compute_midpoints
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SceneError
from .kinematics import cauchy_stress, cofactor, deformation_gradient, determinant, von_mises
from .materials import MooneyRivlin, Prestretched

# A rank that finds another process compiling the same form waits for it; DOLFINx 0.5 gives
# up after 10 s, too short for the eye's forms on a machine with few cores.
jit.DOLFINX_DEFAULT_JIT_PARAMETERS["timeout"] = (600, jit.DOLFINX_DEFAULT_JIT_PARAMETERS["timeout"][1])
# The kernels' C: DOLFINx's -O2, and libm need not set errno: sqrt becomes one instruction with
# no fallback call, and the calls to pow and exp have no side effects, so the compiler need not
# reload memory around them. No rounding changes: the seed operation's measures agree with -O2
# alone as two runs of one build do (1e-13). The UFL parts of its residual
# and Newton matrix assemble in 0.53 and 0.87 of the time (benchmarks/README.md).
JIT_COMPILE_ARGS = ["-O2", "-g0", "-fno-math-errno"]
jit.DOLFINX_DEFAULT_JIT_PARAMETERS["cffi_extra_compile_args"] = (
    JIT_COMPILE_ARGS, jit.DOLFINX_DEFAULT_JIT_PARAMETERS["cffi_extra_compile_args"][1])

# name -> (displacement degree, pressure family, pressure degree). Q2P1 is the quadratic
# hexahedron with a discontinuous linear pressure (DPC1), the optimal inf-sup stable pair.
ELEMENTS = {"Q1P0": (1, "DG", 0), "Q2P0": (2, "DG", 0), "Q2P1": (2, "DPC", 1), "P2P0": (2, "DG", 0),
            "P1P0": (1, "DG", 0)}
DEFAULT_ELEMENT = {"hexahedron": "Q1P0", "tetrahedron": "P2P0"}


@dataclasses.dataclass
class MixedSolid:
    """The solid: mesh, region materials, the mixed space W = (u, p) and its state w.

    Args:
        mesh_data: the mesh with its named regions and surfaces (``meshing.load.MeshData``).
        materials: region name -> material law (every region needs one).
        element: an ``ELEMENTS`` name; default by cell type.
    """

    mesh_data: object
    materials: dict
    element: str | None = None

    def __post_init__(self):
        md = self.mesh_data
        msh = md.mesh
        cell = msh.ufl_cell()
        cells = msh.topology.index_map(msh.topology.dim)
        if msh.comm.allreduce(cells.size_local == 0, op=MPI.LOR):
            raise SceneError(f"mesh {md.source} has {cells.size_global} cells, too few to share among "
                             f"{msh.comm.size} MPI ranks: use fewer ranks or a finer mesh")
        missing = sorted(set(md.regions) - set(self.materials))
        if missing:
            raise SceneError(f"no material for region(s) {missing} of mesh {md.source}: add [materials.<region>]")
        unknown = sorted(set(self.materials) - set(md.regions))
        if unknown:
            raise SceneError(f"materials given for {unknown}, which are not volume groups of mesh {md.source} "
                             f"(its regions: {sorted(md.regions)})")
        self.element = self.element or DEFAULT_ELEMENT[cell.cellname()]
        if self.element not in ELEMENTS:
            raise SceneError(f"unknown element {self.element!r}: choose one of {sorted(ELEMENTS)}")
        degree, p_family, p_degree = ELEMENTS[self.element]
        Ve = ufl.VectorElement("Lagrange", cell, degree)
        Qe = ufl.FiniteElement(p_family, cell, p_degree)
        self.W = fem.FunctionSpace(msh, ufl.MixedElement([Ve, Qe]))
        self.w = fem.Function(self.W, name="state")
        self.u, self.p = ufl.split(self.w)
        self.v = ufl.TestFunctions(self.W)[0]
        quadrature = {"quadrature_degree": 2 * degree}
        self.dx = ufl.Measure("dx", domain=msh, subdomain_data=md.cell_tags, metadata=quadrature)
        self.ds = ufl.Measure("ds", domain=msh, subdomain_data=md.facet_tags, metadata=quadrature)
        self.F = deformation_gradient(self.u)
        self.X = ufl.SpatialCoordinate(msh)
        self.laws = dict(self.materials)  # the laws in force, region by region (see ``prestretch``)
        self._groups = None

    @property
    def comm(self) -> MPI.Comm:
        return self.mesh_data.mesh.comm

    def prestretch(self, region: str, F_g: ufl.core.expr.Expr) -> None:
        """Change the rest state of ``region`` by the deformation F_g (a UFL tensor, which may
        hold Constants that ramp): its law becomes ``Prestretched(law, F_g)``. Before the forms
        are made (``potential``)."""
        if self._groups is not None:
            raise RuntimeError(f"prestretch of {region!r} after the solid's forms were made")
        self.laws[region] = Prestretched(self.laws[region], F_g)

    def law_groups(self) -> list:
        """[(regions, law)]: regions whose laws differ only in their constants share one law
        with element-wise (DG0) constants, so the eye's seven neo-Hookean tissues make one
        integral, not seven (a smaller compiled form, less assembly work)."""
        if self._groups is None:
            by_kind = {}
            for region, law in self.laws.items():
                key = tuple(sorted(law.c)) if type(law) is MooneyRivlin else region
                by_kind.setdefault(key, []).append(region)
            self._groups = []
            for regions in by_kind.values():
                law = self.laws[regions[0]]
                if len(regions) > 1:
                    fields = {}
                    for exponents in law.c:
                        fields[exponents] = fem.Function(self._cell_space())
                        for region in regions:
                            fields[exponents].x.array[self.mesh_data.cells(region)] = self.laws[region].c[exponents]
                    law = MooneyRivlin(fields)
                self._groups.append((regions, law))
        return self._groups

    def potential(self) -> ufl.Form:
        """The stored energy of all regions with the incompressibility constraint."""
        J = determinant(self.F)
        terms = []
        for regions, law in self.law_groups():
            dx = self.dx(tuple(self.mesh_data.regions[r] for r in regions))
            if law.incompressible:
                terms.append((law.strain_energy(self.F) - self.p * (J - law.volume_ratio)) * dx)
            else:
                terms.append((law.strain_energy(self.F) - self.p**2 / (2 * law.shear_modulus)) * dx)
        return sum(terms)

    def first_piola(self, law) -> ufl.core.expr.Expr:
        """P = dW/dF - p J F^-T (the pressure term only for incompressible laws)."""
        F = ufl.variable(self.F)
        P = ufl.diff(law.strain_energy(F), F)
        if law.incompressible:
            P = P - self.p * cofactor(F)
        return P

    def current_normal_area(self) -> ufl.core.expr.Expr:
        """n da = J F^-T N dA on the boundary (Nanson's formula)."""
        N = ufl.FacetNormal(self.mesh_data.mesh)
        return cofactor(self.F) * N

    def surface_dofs(self, surface: str) -> list[np.ndarray]:
        """Local indices in W of the displacement dofs on a named surface, per component."""
        msh = self.mesh_data.mesh
        facets = self.mesh_data.facets(surface)
        return [fem.locate_dofs_topological(self.W.sub(0).sub(i), msh.topology.dim - 1, facets) for i in range(3)]

    def component(self, i: int) -> tuple:
        """(V_i, its dofs' indices in W) of displacement component i. Collapsed once; the
        first call is collective, so make it during setup."""
        if not hasattr(self, "_components"):
            self._components = [self.W.sub(0).sub(k).collapse() for k in range(3)]
        return self._components[i]

    @property
    def num_owned(self) -> int:
        return self.W.dofmap.index_map.size_local

    def mises_expression(self) -> ufl.core.expr.Expr:
        """Von Mises stress of the Cauchy stress, law by law, as one UFL expression."""
        sigma = 0
        for regions, law in self.law_groups():
            indicator = fem.Function(self._cell_space())
            for region in regions:
                indicator.x.array[self.mesh_data.cells(region)] = 1.0
            sigma = sigma + indicator * cauchy_stress(self.first_piola(law), self.F)
        return von_mises(sigma)

    def _cell_space(self):
        if not hasattr(self, "_dg0"):
            self._dg0 = fem.FunctionSpace(self.mesh_data.mesh, ("DG", 0))
        return self._dg0


class MaterialPoint:
    """A material point of a surface, wherever the nodes are: the nearest point of the surface's
    elements to a reference point, its displacement interpolated by the shape functions of the
    element that holds it, u = sum_i N_i(xi) u_i, so a string tied there pulls its nodes with N_i
    times its force. The element is the surface element whose reference image of the point, xi
    pulled back and clipped to the reference cell, lies nearest to it (a point on a smooth surface
    lies a sagitta off the faceted one).

    Given several points (m, 3), it is their mean, a load spread evenly over them (a suture's bite
    along its length): each point is found as above and node i takes the weight
    w_i = sum_p N_i(xi_p) / m, so u = sum_i w_i u_i and a force f is shared as w_i f, the potential's
    own split. Known on every rank: its nodes' global displacement dofs (node-major, 3 a node),
    their weights w_i (k,), its reference position and ``distance``, the largest of its points'
    from their surface; ``owner`` is the rank that found its first point."""

    CANDIDATES = 8  # elements pulled back, the nearest by their nodes' centroid

    def __init__(self, solid: MixedSolid, point, surface: str):
        self.solid, points = solid, np.atleast_2d(np.asarray(point, dtype=float))
        msh = solid.mesh_data.mesh
        msh.topology.create_connectivity(msh.topology.dim - 1, msh.topology.dim)
        f2c = msh.topology.connectivity(msh.topology.dim - 1, msh.topology.dim)
        facets = solid.mesh_data.facets(surface)
        cells = np.unique(np.concatenate([f2c.links(f) for f in facets] + [np.empty(0, np.int32)]))
        cells = cells[cells < msh.topology.index_map(msh.topology.dim).size_local]
        V0, _ = solid.component(0)
        nodes = V0.dofmap.list.array.reshape(-1, V0.dofmap.dof_layout.num_dofs)[cells]
        X = V0.tabulate_dof_coordinates()[nodes]  # (cells, k, 3)
        element = _element(V0)
        distances, found = np.full(len(points), np.inf), [None] * len(points)
        near = np.argsort(np.linalg.norm(X.mean(axis=1)[None] - points[:, None], axis=2), axis=1)[:, :self.CANDIDATES]
        for c in np.unique(near):  # each candidate element pulls back the points it is a candidate for
            geometry = msh.geometry.x[msh.geometry.dofmap.links(cells[c])]
            group = np.flatnonzero((near == c).any(axis=1))
            xi = _pull_back(msh.geometry.cmap, points[group], geometry)
            group, xi = group[np.isfinite(xi).all(axis=1)], xi[np.isfinite(xi).all(axis=1)]
            if not len(group):
                continue
            N = element.tabulate(0, _clip_to_reference(msh.topology.cell_type.name, xi))[0, :, :, 0]
            for p, Np, distance in zip(group, N, np.linalg.norm(N @ X[c] - points[group], axis=1)):
                if distance < distances[p]:
                    distances[p], found[p] = distance, (c, Np)
        # each point is found by the rank holding its nearest element (ties: the lower rank)
        everyone = np.array(solid.comm.allgather(distances))
        owners = everyone.argmin(axis=0)
        self.distance, self.owner = float(everyone.min(axis=0).max()), int(owners[0])
        if not np.isfinite(self.distance):
            raise SceneError(f"no element on surface {surface!r} near {points[0].tolist()}")
        rows, weights, coordinates = [], [], []  # this rank's share: its points' nodes
        to_W = [np.asarray(solid.component(i)[1]) for i in range(3)]
        for p in np.flatnonzero(owners == solid.comm.rank):
            c, N = found[p]
            keep = np.abs(N) > 1e-14  # the nodes off the point's face carry nothing
            rows.append(np.array([to_W[i][nodes[c][keep]] for i in range(3)]).T)
            weights.append(N[keep] / len(points))
            coordinates.append(X[c][keep])
        self.local = np.concatenate(rows + [np.empty((0, 3), np.int32)]).astype(np.int32)
        self.local_weights = np.concatenate(weights + [np.empty(0)])
        mine = (solid.W.dofmap.index_map.local_to_global(self.local.ravel()).reshape(-1, 3), self.local_weights,
                np.concatenate(coordinates + [np.empty((0, 3))]))
        dofs, w, x = (np.concatenate(parts) for parts in zip(*solid.comm.allgather(mine)))
        first, index = np.unique(dofs[:, 0], return_index=True)  # a node met by several points: one weight
        self.weights = np.bincount(np.searchsorted(first, dofs[:, 0]), weights=w)
        self.dofs = np.asarray(dofs[index].ravel(), dtype=PETSc.IntType)
        self.reference = self.weights @ x[index]

    def position(self) -> np.ndarray:
        """Current position (collective): the weighted positions of its nodes, summed over the ranks."""
        u = self.local_weights @ self.solid.w.x.array[self.local].reshape(-1, 3)
        return self.reference + self.solid.comm.allreduce(u, op=MPI.SUM)


class MaterialNode(MaterialPoint):
    """The mesh node nearest to a reference point (on a surface, if given): a material point whose
    one node carries it whole (weight 1); its global displacement dofs and its current position,
    known on every rank."""

    def __init__(self, solid: MixedSolid, point, surface: str | None = None):
        self.solid = solid
        V0, to_W = solid.component(0)
        x = V0.tabulate_dof_coordinates()
        candidates = np.arange(V0.dofmap.index_map.size_local)
        if surface is not None:
            on_surface = solid.surface_dofs(surface)[0]
            candidates = np.flatnonzero(np.isin(np.asarray(to_W)[candidates], on_surface))
        distance = np.linalg.norm(x[candidates] - np.asarray(point, dtype=float), axis=1)
        best = (distance.min(), solid.comm.rank) if len(candidates) else (np.inf, solid.comm.rank)
        self.distance, self.owner = solid.comm.allreduce(best, op=MPI.MIN)
        if not np.isfinite(self.distance):
            raise SceneError(f"no mesh node on surface {surface!r} near {list(point)}")
        self.local, self.local_weights, data = np.empty((0, 3), np.int32), np.empty(0), None
        if solid.comm.rank == self.owner:
            node = candidates[int(distance.argmin())]
            self.local = np.array([[solid.component(i)[1][node] for i in range(3)]], dtype=np.int32)
            self.local_weights = np.ones(1)
            assert (self.local < solid.num_owned).all()
            data = (solid.W.dofmap.index_map.local_to_global(self.local.ravel()), x[node])
        self.dofs, self.reference = solid.comm.bcast(data, root=self.owner)
        self.dofs = np.asarray(self.dofs, dtype=PETSc.IntType)
        self.weights = np.ones(1)


def _element(V: fem.FunctionSpace):
    """The basix element of a scalar Lagrange space (for its shape functions at reference points)."""
    element = V.ufl_element()
    return basix.create_element(basix.ElementFamily.P, getattr(basix.CellType, element.cell().cellname()),
                                element.degree(), basix.LagrangeVariant.gll_warped)


def _pull_back(cmap, points: np.ndarray, geometry: np.ndarray) -> np.ndarray:
    """The reference coordinates of ``points`` in the element of nodes ``geometry``, NaN where the
    map's Newton fails (a point far outside a distorted element: it would fail the others with it)."""
    try:
        return cmap.pull_back(points, geometry)
    except RuntimeError:
        if len(points) == 1:
            return np.full_like(points, np.nan)
        return np.vstack([_pull_back(cmap, point[None], geometry) for point in points])


def _clip_to_reference(cell: str, xi: np.ndarray) -> np.ndarray:
    """Reference coordinates moved into the reference cell: the unit cube clipped, a simplex's
    negative coordinates zeroed and the rest scaled onto its slanted face."""
    xi = np.maximum(xi, 0.0)
    if cell in ("hexahedron", "quadrilateral"):
        return np.minimum(xi, 1.0)
    total = xi.sum(axis=1, keepdims=True)
    return np.where(total > 1.0, xi / np.maximum(total, 1e-300), xi)


class JacobianGuard:
    """Watches det F where the residual is integrated (the quadrature points of ``solid.dx``)
    and at element midpoints, so that an inverted element stops Newton cleanly: the laws are not
    a number where det F <= 0 (J^(-2/3)), and a distorted hexahedron can invert at a quadrature
    point near a corner while its midpoint does not."""

    def __init__(self, solid: MixedSolid):
        self.solid = solid
        msh = solid.mesh_data.mesh
        cell = getattr(basix.CellType, msh.topology.cell_type.name)
        points = basix.make_quadrature(cell, solid.dx.metadata()["quadrature_degree"])[0]
        self._expr = fem.Expression(determinant(solid.F), np.vstack([points, basix.geometry(cell).mean(axis=0)]))
        num_cells = msh.topology.index_map(msh.topology.dim).size_local
        self._cells = np.arange(num_cells, dtype=np.int32)
        self._midpoints = compute_midpoints(msh, msh.topology.dim, self._cells)

    def check(self) -> tuple[float, np.ndarray]:
        """Return (min det F over the mesh, reference location of that element) on every rank."""
        local = (np.inf, np.zeros(3))
        if len(self._cells):
            values = self._expr.eval(self._cells).reshape(len(self._cells), -1)
            worst = values.min(axis=1)  # per element (NaN where any point is NaN)
            worst[np.isnan(worst)] = -np.inf  # a NaN state is as bad as an inversion
            local = (float(worst.min()), self._midpoints[worst.argmin()])
        return min(self.solid.comm.allgather(local), key=lambda item: item[0])

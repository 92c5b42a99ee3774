"""Node-to-segment penalty contact: between two deformable surfaces, and against rigid shapes.

The seed's formulation ("Contact Treatment Between Deformed Bodies"): a *hitting* node h of
the slave surface that penetrates a *target* segment of the master surface adds the penalty
energy

    pi_P = 1/2 alpha G^2,      G = (x_h - x(xi)) . n   (G < 0: penetration),

with x(xi) = sum_a N_a(xi) x_a the closest-point projection of x_h on the segment (nodes
x_a), n the master's outward unit normal there. Its variation gives the contact force
f_c = alpha G D on the dofs of (h, a = 1..k),

    D = [n, -N_1 n, ..., -N_k n],

and its second variation the consistent tangent K = alpha (D D^T + G H) (Wriggers,
*Computational Contact Mechanics*, 2nd ed. 2006, sects. 4.3 and 9.1, frictionless), with
a_b = dx/dxi_b, metric m_bc = a_b . a_c, curvature b_bc = n . d2x/dxi_b dxi_c,

    H = -(N_b tau^b^T + tau^b N_b^T) - b_bc tau^b tau^c^T - G (m - G b)^-1_bc V_b V_c^T,

    N_b . du = n . sum_a dN_a/dxi_b du_a      (the normal turns with the segment),
    tau^b . du = a^b . (du_h - sum_a N_a du_a)  (a^b = m^-1 a: the projection point slides),
    V_b = N_b + b_bc tau^c.

``node_to_segment`` computes all of it, vectorized over contact elements; it is checked
against finite differences in the tests.

Segments are the facets as the Q1 element sees them: bilinear patches (4 nodes) on
hexahedra, linear triangles on tetrahedra. The seed splits a target into triangles (its D is
12 x 1), but a split quad interpolates the master's displacement differently from the Q1
element under it, and its diagonal is a fold the slave nodes must cross. In the contact
patch test (two blocks, 3 x 3 master and 4 x 4 slave facets, pressed together) the split
quads' corner nodes collected 70 % more load than their share and the nodal contact
pressure ranged over 54-109 % of the exact value; with the bilinear patch, whose normal and
nodal weights are the element's own, over 82-110 % (single-pass node-to-segment contact
is not exact on non-matching meshes either way). The price is a local Newton for the
projection (a few vectorized iterations) and the curvature term b_12 in the tangent.

Penalty (``penalty``): a pressure per unit penetration (MPa/mm), i.e. *per unit area*; the
hitting node i gets alpha_i = penalty * A_i, A_i its tributary area (a quarter of each
adjacent quad, a third of each triangle, reference configuration). By default, per slave
node,

    penalty_i = PENALTY_FACTOR * k_s,i k_m / (k_s,i + k_m),    k = E / h,

the series stiffness of the two surface layers of elements: k_s,i is E/h of the slave
elements around node i (area-weighted), k_m the area-weighted mean E/h over the master
surface (infinite for a rigid body, so penalty = PENALTY_FACTOR * k_s), E = 3 mu for the
incompressible laws (``shear_modulus`` mu) and E for linear-elastic ones, and h = V / A the
thickness of the element under a facet (volume over facet area). The penetration is then
about (contact pressure / E) h / PENALTY_FACTOR, the surface elements' strain times
h / 30: 0.3 % of an element at 10 % strain. The factor 30 is a measured compromise: at 100,
Newton needed 6-11 iterations per increment for a block sliding across a deformable one
(the bt line search crawls through the active-set changes), at 30 it needs 4-5, at 10 3-4;
the penalty's own error in the Hertz test is -0.3 % of the force at 30 (-1.1 % at 10). A
scene's ``penalty`` replaces the default on every node.

Smoothing (``smoothing`` = delta, a length): the sharp law switches a node's stiffness from 0 to
alpha at G = 0, and nodes at the edge of a contact zone flip in and out of contact between
Newton iterations (the residual cycled between two values when the encircling band was
tightened beyond 5 mm). The smoothed law (``normal_law``) has a continuous tangent: the
pressure is alpha delta log(1 + exp(-G / delta)), the sharp one deep in, alpha delta log 2 at
G = 0 and decaying as exp(-G / delta) outside; it acts up to G = ACTIVE_RANGE delta. With a
contact pressure p the surfaces settle about delta log(exp(p / (alpha delta)) - 1) apart
(a small positive gap when p < alpha delta log 2), so delta should be small against what
the scene measures.

Parallel search: the master surface (its segments as global node numbers, and the current
coordinates of its nodes) is gathered on every rank, surface-sized data; each rank then
searches for the slave nodes it owns with a bucket grid (``candidate_pairs``, linear in the
number of nodes). The candidate segments of each slave node are fixed at the start of a load
increment (``begin_increment``: those within about an element of the node, plus twice the
motion of the last increment), which also fixes the matrix pattern (``coupling``). Within a
residual evaluation each node takes its closest candidate segment (keeping the one it had
unless another holds its projection better by ``SWITCH_TOLERANCE``). A node switching
segments at a fold turns its force there, and nodes flipping back and forth can make Newton
cycle (a period-3 residual on the buckled eye when the sutures pulled the band into its
trough). So a Newton solve that has not converged after ``HOLD_AFTER`` iterations holds the
segments (``hold``): each node keeps its own, the bilinear patch extrapolated up to
``OVERHANG_TOLERANCE`` past its edge, and the residual is smooth. After such a solve
``settle`` gives each node its closest segment again; if any node changed, Newton runs again
from there, holding the segments from its start. A node is active iff it penetrates (with a smoothed law, iff its
gap is below ``ACTIVE_RANGE`` smoothing lengths). Contact forces are added by global index; the rows of master nodes owned by
other ranks go to their owners through PETSc's stash.

Contact onset (``step_fraction``): the tangent of an open node is zero, so a Newton step that
closes a gap drives the surfaces through each other by the whole step, far beyond the
penalty's equilibrium penetration (on the buckled eye: the inflating sclera 0.14 mm into the
band, against an equilibrium 4e-5 mm), and the penalty throws them apart again; the bt line
search then crawled and Newton stalled. Before each Newton update, the solver shortens the
step to where the first open node has closed to the depth at which it carries the largest
force already out of balance on the slave surface; from the next iteration on that node is in
the tangent. A Newton step that closes nothing is not touched, so the converged answer and
Newton's quadratic convergence are as before. The predictor is limited the same way.

Frictionless: the normal law is ``normal_law``; the tangential kinematics a friction law
needs (the projection xi, the dual basis, the metric) are in ``NodeToSegment``.
"""
import dataclasses
import time

import numpy as np
import ufl
from mpi4py import MPI
from petsc4py import PETSc

from dolfinx import cpp, fem
from dolfinx.fem.petsc import assemble_vector

from .errors import SceneError
from .feature import Feature

PENALTY_FACTOR = 30.0
SEARCH_FACTOR = 1.0  # candidate segments lie within this many segment sizes of a node
SWITCH_TOLERANCE = 0.01  # hysteresis of a node's segment, as a fraction of the segment's size
OVERHANG_TOLERANCE = 0.25  # a node this far past the master's edge (fraction of a segment) still hits it
ONSET_TOLERANCE = 1e-6  # a node closing in a Newton step may also go this deep (fraction of its size)
ONSET_ITERATIONS = 8  # regula falsi steps to find where along a Newton step the first gap closes
ACTIVE_RANGE = 20.0  # a smoothed law acts up to gaps of this many smoothing lengths (force e^-20)
OPEN_RANGE = 3.0  # ... and its stiffness is below 5 % of the penalty beyond this many: "open" for the limiter
_ADD = PETSc.InsertMode.ADD_VALUES


# -- kinematics ---------------------------------------------------------------------------
class Triangle:
    """Linear triangle: N = (1 - xi_1 - xi_2, xi_1, xi_2)."""

    corners = 3
    centre = (1.0 / 3.0, 1.0 / 3.0)
    bounds = (-1.0, 2.0)
    _dN = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])

    @staticmethod
    def shape(xi):
        """N (n, 3) and dN/dxi (n, 3, 2) at points xi (n, 2)."""
        N = np.column_stack([1.0 - xi[:, 0] - xi[:, 1], xi[:, 0], xi[:, 1]])
        return N, np.broadcast_to(Triangle._dN, (len(xi), 3, 2))

    @staticmethod
    def twist(x_seg):
        """d2x / dxi_1 dxi_2 (n, 3): zero on a flat triangle."""
        return np.zeros((len(x_seg), 3))

    @staticmethod
    def outside(xi):
        """How far outside the segment a projection lies, as a fraction of its size."""
        return np.maximum(0.0, -np.min(Triangle.shape(xi)[0], axis=1))


class Quad:
    """Bilinear quadrilateral on [-1, 1]^2, nodes counter-clockwise."""

    corners = 4
    centre = (0.0, 0.0)
    bounds = (-2.0, 2.0)
    _signs = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])

    @staticmethod
    def shape(xi):
        s = Quad._signs
        f = 1.0 + xi[:, None, :] * s[None, :, :]  # (n, 4, 2): 1 + s_b xi_b
        N = 0.25 * f[:, :, 0] * f[:, :, 1]
        dN = 0.25 * np.stack([s[:, 0] * f[:, :, 1], s[:, 1] * f[:, :, 0]], axis=-1)
        return N, dN

    @staticmethod
    def twist(x_seg):
        """d2x / dxi_1 dxi_2 = (x_1 - x_2 + x_3 - x_4) / 4, constant on the patch."""
        return 0.25 * (x_seg[:, 0] - x_seg[:, 1] + x_seg[:, 2] - x_seg[:, 3])

    @staticmethod
    def outside(xi):
        return np.maximum(0.0, 0.5 * (np.max(np.abs(xi), axis=1) - 1.0))


@dataclasses.dataclass
class NodeToSegment:
    """Contact kinematics of hitting nodes on segments (arrays over contact elements).

    Attributes:
        G: normal gap (n,), negative when penetrating.
        xi: projection point in the segment's coordinates (n, 2); N: shape functions there.
        D: dG/du on (h, 1, .., k), shape (n, 3 + 3k).
        normal: unit normal (n, 3).
        H: d2G/du2, shape (n, 3 + 3k, 3 + 3k), when asked for.
        dual: dual basis a^1, a^2 (n, 2, 3), when asked for.
    """

    G: np.ndarray
    xi: np.ndarray
    N: np.ndarray
    D: np.ndarray
    normal: np.ndarray
    H: np.ndarray = None
    dual: np.ndarray = None


def _dot(u, v):
    return np.sum(u * v, axis=-1)


def _combine(weights, x_seg):
    """sum_a weights[:, a] x_seg[:, a]: (n, k) x (n, k, 3) -> (n, 3)."""
    return np.sum(weights[:, :, None] * x_seg, axis=1)


def _outer(u, v):
    return u[:, :, None] * v[:, None, :]


def node_to_segment(x_h, x_seg, kind, tangent=True, iterations=12):
    """Project nodes x_h (n, 3) on segments x_seg (n, k, 3) of type ``kind`` (``Triangle`` or
    ``Quad``); gap, D and, with ``tangent``, H. The normal is a_1 x a_2 / |a_1 x a_2|."""
    xi = np.tile(np.asarray(kind.centre), (len(x_h), 1))
    twist = kind.twist(x_seg)
    moving = np.arange(len(x_h))  # closest point: (x_h - x(xi)) . a_b = 0, Newton in xi
    for _ in range(iterations):
        x, t = x_seg[moving], twist[moving]
        N, dN = kind.shape(xi[moving])
        a1, a2 = _combine(dN[:, :, 0], x), _combine(dN[:, :, 1], x)
        r = x_h[moving] - _combine(N, x)
        J11, J12, J22 = _dot(a1, a1), _dot(a1, a2) - _dot(r, t), _dot(a2, a2)
        f1, f2 = _dot(a1, r), _dot(a2, r)
        det = J11 * J22 - J12 * J12
        step = np.column_stack([J22 * f1 - J12 * f2, J11 * f2 - J12 * f1]) / det[:, None]
        new = np.clip(xi[moving] + step, *kind.bounds)
        # converged, or stopped by the bounds: far outside the segment, no contact with it
        done = (np.abs(step).max(axis=1) < 1e-13) | np.any(new != xi[moving] + step, axis=1)
        xi[moving] = new
        moving = moving[~done]
        if not len(moving):
            break
    N, dN = kind.shape(xi)
    a1, a2 = _combine(dN[:, :, 0], x_seg), _combine(dN[:, :, 1], x_seg)
    m = np.cross(a1, a2)
    n = m / np.linalg.norm(m, axis=1)[:, None]
    G = _dot(x_h - _combine(N, x_seg), n)
    D = _spread(n, N)
    if not tangent:
        return NodeToSegment(G, xi, N, D, n)
    m11, m12, m22 = _dot(a1, a1), _dot(a1, a2), _dot(a2, a2)
    det = m11 * m22 - m12 * m12
    dual = [(m22[:, None] * a1 - m12[:, None] * a2) / det[:, None],
            (m11[:, None] * a2 - m12[:, None] * a1) / det[:, None]]
    b12 = _dot(n, twist)
    # (m - G b)^-1, with b = [[0, b12], [b12, 0]]
    c12 = m12 - G * b12
    detA = m11 * m22 - c12 * c12
    A_inv = [[m22 / detA, -c12 / detA], [-c12 / detA, m11 / detA]]
    zero = np.zeros_like(n)
    Nb = [np.hstack([zero] + [dN[:, i, b:b + 1] * n for i in range(kind.corners)]) for b in range(2)]
    tau = [_spread(dual[b], N) for b in range(2)]
    V = [Nb[b] + b12[:, None] * tau[1 - b] for b in range(2)]
    H = -b12[:, None, None] * (_outer(tau[0], tau[1]) + _outer(tau[1], tau[0]))
    for b in range(2):
        H -= _outer(Nb[b], tau[b]) + _outer(tau[b], Nb[b])
        for c in range(2):
            H -= (G * A_inv[b][c])[:, None, None] * _outer(V[b], V[c])
    return NodeToSegment(G, xi, N, D, n, H, np.stack(dual, axis=1))


def _spread(v, N):
    """[v, -N_1 v, ..., -N_k v] on the dofs (h, 1, .., k) of contact elements."""
    return np.hstack([v] + [-N[:, i:i + 1] * v for i in range(N.shape[1])])


def normal_law(alpha, G, D, H=None, smoothing=0.0):
    """Penalty pi(G) of the hitting nodes: residual pi' D and tangent pi'' D D^T + pi' H.
    Sharp (``smoothing`` = 0): pi = 1/2 alpha G^2 for G < 0, pi' = alpha G, pi'' = alpha.
    Smoothed over a length delta: pi' = -alpha delta log(1 + exp(-G / delta)),
    pi'' = alpha / (1 + exp(G / delta)) (see ``ACTIVE_RANGE``). The one place a friction law
    would add its tangential terms."""
    if smoothing > 0.0:
        s = -G / smoothing
        slope, stiffness = -alpha * smoothing * np.logaddexp(0.0, s), alpha * 0.5 * (1.0 + np.tanh(0.5 * s))
    else:
        slope, stiffness = alpha * G, alpha
    f = slope[:, None] * D
    if H is None:
        return f, None
    K = stiffness[:, None, None] * _outer(D, D) + slope[:, None, None] * H
    return f, K


# -- search -------------------------------------------------------------------------------
def candidate_pairs(points, lo, hi):
    """All (point, box) index pairs with the point inside the axis-aligned box [lo, hi].

    A bucket grid with cells the size of an average box: every box is entered into the cells
    it overlaps, every point looks up its own cell, so the cost is linear in the number of
    points, boxes and pairs (numpy only, no Python loop).
    """
    empty = np.empty(0, dtype=np.int64)
    if len(points) == 0 or len(lo) == 0:
        return empty, empty
    cell = max(float(np.mean(np.max(hi - lo, axis=1))), 1e-300)
    origin = lo.min(axis=0)
    box_lo = np.floor((lo - origin) / cell).astype(np.int64)
    box_hi = np.floor((hi - origin) / cell).astype(np.int64)
    dims = box_hi.max(axis=0) + 1
    span = box_hi - box_lo + 1
    count = span.prod(axis=1)
    box = np.repeat(np.arange(len(lo)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    sx, sy = span[box, 0], span[box, 1]
    ix, iy, iz = box_lo[box, 0] + k % sx, box_lo[box, 1] + (k // sx) % sy, box_lo[box, 2] + k // (sx * sy)
    key = (ix * dims[1] + iy) * dims[2] + iz
    order = np.argsort(key, kind="stable")
    key, box = key[order], box[order]
    ip = np.floor((points - origin) / cell).astype(np.int64)
    inside = np.all((ip >= 0) & (ip < dims), axis=1)
    point_key = (ip[:, 0] * dims[1] + ip[:, 1]) * dims[2] + ip[:, 2]
    start = np.searchsorted(key, point_key, side="left")
    number = np.where(inside, np.searchsorted(key, point_key, side="right") - start, 0)
    point = np.repeat(np.arange(len(points)), number)
    j = np.arange(number.sum()) - np.repeat(np.cumsum(number) - number, number) + np.repeat(start, number)
    box = box[j]
    keep = np.all((points[point] >= lo[box]) & (points[point] <= hi[box]), axis=1)
    return point[keep], box[keep]


# -- surfaces -----------------------------------------------------------------------------
class _SolidTables:
    """What contact needs to know of the solid, per node and per cell (this rank's part).

    Per node (indexed by the local dof of its x component): its 3 local dofs, their global
    numbers and its reference coordinates; per local cell: volume and Young's modulus.
    """

    def __init__(self, solid):
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
        for region, law in solid.materials.items():
            self.modulus[md.cells(region)] = getattr(law, "E", 3.0 * law.shear_modulus)


@dataclasses.dataclass
class _Surface:
    """A named surface on this rank.

    Attributes:
        kind: segment type, ``Quad`` or ``Triangle``.
        nodes: local x-dofs of the surface nodes this rank owns (n,).
        area: their tributary areas (reference configuration) (n,).
        stiffness: E / h of the elements around each node, area-weighted (n,).
        segments: local x-dofs of the facets this rank owns, counter-clockwise seen from
            outside (m, k).
        thickness: h = V / A of the element under each segment (m,).
        mean_stiffness: area-weighted mean E / h over the whole surface (all ranks).
    """

    kind: type
    nodes: np.ndarray
    area: np.ndarray
    stiffness: np.ndarray
    segments: np.ndarray
    thickness: np.ndarray
    mean_stiffness: float


def _surface(solid, tables, name):
    """Nodes, segments and element stiffness of a named surface (collective)."""
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
    segments = tables.cell_nodes[cells[:, None], closure[local_facet]]
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
    segment_stiffness = tables.modulus[cells] / thickness

    # nodal areas and area-weighted stiffness, summed on the owners
    scratch = fem.Function(W)
    corners = kind.corners
    share = np.repeat(area / corners, corners)
    np.add.at(scratch.x.array, segments.ravel(), share)
    np.add.at(scratch.x.array, tables.dofs[segments.ravel(), 1], share * np.repeat(segment_stiffness, corners))
    scratch.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    values = scratch.x.array
    candidates = np.unique(tables.cell_nodes)
    candidates = candidates[candidates < tables.num_owned]
    nodes = candidates[values[candidates] > 0]
    node_area = values[nodes]
    totals = solid.comm.allreduce(np.array([area.sum(), (area * segment_stiffness).sum()]), op=MPI.SUM)
    if totals[0] == 0:
        raise SceneError(f"contact surface {name!r} of {md.source} has no facets")
    return _Surface(kind, nodes, node_area, values[tables.dofs[nodes, 1]] / node_area, segments, thickness,
                    totals[1] / totals[0])


def _check_penalty(name, penalty):
    if penalty is None:
        return None
    if isinstance(penalty, bool) or not isinstance(penalty, (int, float)) or not np.isfinite(penalty) or penalty <= 0:
        raise SceneError(f"contact {name!r}: penalty must be a positive number (pressure per unit penetration), "
                         f"got {penalty!r}")
    return float(penalty)


def _where_max(comm, depth, X):
    """(largest penetration over all ranks, reference location of that node or None)."""
    local = (float(depth.max()), X[depth.argmax()].tolist()) if len(depth) else (0.0, None)
    best = max(comm.allgather(local), key=lambda item: item[0])
    return best if best[0] > 0 else (0.0, None)


class _ContactFeature(Feature):
    """What both kinds of contact share: activity from their step, assembly, the report.

    Subclasses give ``_state(tangent)``: a dict with the active slave nodes ("node", indices
    into the owned slave nodes), their gaps "G", the element residuals "f" (n, d) and
    tangents "K" (n, d, d) on the global dofs "rows" (n, d), and "contacts", an array that
    changes when the active set (or a node's segment) does.
    """

    section = "contact"
    adds_to_residual = True
    adds_to_jacobian = True
    symmetric_tangent = True  # frictionless: the Hessian of a potential
    limits_steps = True

    def __init__(self, name, slave, penalty, step, smoothing):
        self.name, self.slave_name, self.step = name, slave, step
        self.penalty = _check_penalty(name, penalty)
        self.smoothing = smoothing
        self.reach = ACTIVE_RANGE * smoothing  # nodes with gaps below this carry force
        self.open_gap = OPEN_RANGE * smoothing  # nodes with gaps above this are open for step_fraction
        self.active = False
        # wall seconds, for benchmarks; "gather" (the master surface's displacements, part of
        # search and assembly) includes waiting for the slowest rank
        self.timing = {"search": 0.0, "assembly": 0.0, "gather": 0.0}
        self._contacts = {"residual": None, "jacobian": None}  # who touches what, at the last of each

    def tangent_outdated(self):
        """True (on every rank: collective) if the contacts changed since the last tangent was
        assembled: a factorization of that tangent then is no Newton step, so the solver must
        not reuse it."""
        if not self.active:
            return False
        seen = self._contacts
        same = seen["jacobian"] is not None and seen["residual"] is not None \
            and np.array_equal(seen["jacobian"], seen["residual"])
        return self.solid.comm.allreduce(not same, op=MPI.LOR)

    def begin_step(self, step_index):
        self.active = step_index >= self.step

    def _setup_slave(self, solid, tables, master_stiffness):
        self.solid, self.tables = solid, tables
        s = self.slave = _surface(solid, tables, self.slave_name)
        if self.penalty is not None:
            self.node_penalty = np.full(len(s.nodes), self.penalty)
        else:
            series = s.stiffness if np.isinf(master_stiffness) else \
                s.stiffness * master_stiffness / (s.stiffness + master_stiffness)
            self.node_penalty = PENALTY_FACTOR * series
        self.alpha = self.node_penalty * s.area
        self.slave_dofs = tables.dofs[s.nodes]
        self.slave_global = tables.global_index[self.slave_dofs]
        self.slave_X = tables.X[s.nodes]
        totals = solid.comm.allreduce(np.array([s.area.sum(), (s.area * self.node_penalty).sum()]), op=MPI.SUM)
        self.mean_penalty = totals[1] / totals[0]

    def slave_positions(self):
        return self.slave_X + self.solid.w.x.array[self.slave_dofs]

    def _reserve(self, A):
        """Make room in A for the entries contact may add later (nothing by default)."""

    def step_fraction(self, du, residual):
        """The largest fraction (at most 1) of the state change ``du`` (the owned entries of the
        mixed vector) that closes no open gap by more than the residual allows (collective).

        The tangent knows nothing of open nodes: a Newton step that closes a gap would drive
        the surfaces through each other, far beyond the penalty's equilibrium penetration, and
        the penalty would then throw them apart. So the step stops where the first gap has
        closed to a depth d_i = f / alpha_i, f the largest residual force on the slave nodes
        (``residual``: the owned entries of the residual vector): the closing nodes take no
        more force than is out of balance already, and are active in the next tangent. The
        place is found by regula falsi along the step (Illinois modification)."""
        if not self.active:
            return 1.0
        node = self.gap_nodes
        force = np.abs(residual[self.slave_dofs]).max(initial=0.0)
        depth = self.solid.comm.allreduce(force, op=MPI.MAX) / self.alpha[node] \
            + ONSET_TOLERANCE * np.sqrt(self.slave.area[node])
        gaps = self._gaps_along(du)
        now, new = gaps(0.0) + depth, gaps(1.0) + depth
        closing = (now > depth + self.open_gap) & (new < 0)
        lo, hi, f_lo, f_hi = np.zeros(len(node)), np.ones(len(node)), now, new
        for _ in range(ONSET_ITERATIONS if self.solid.comm.allreduce(closing.any(), op=MPI.LOR) else 0):
            trial = np.where(closing, lo + (hi - lo) * f_lo / (f_lo - f_hi), 1.0)
            f = gaps(trial) + depth
            below = f < 0
            f_lo, lo = np.where(below, 0.5 * f_lo, f), np.where(below, lo, trial)  # Illinois: halve the
            f_hi, hi = np.where(below, f, 0.5 * f_hi), np.where(below, trial, hi)  # end that stays
        return self.solid.comm.allreduce(np.min(hi[closing], initial=1.0), op=MPI.MIN)

    def report(self):
        """Total force on the slave surface, deepest penetration and where (reference
        coordinates), number of nodes in contact (penetrating; with a smoothed law, closer than
        OPEN_RANGE smoothing lengths), mean penalty (per unit area)."""
        comm = self.solid.comm
        if not self.active:  # its step has not come yet
            return {"force": [0.0, 0.0, 0.0], "max_penetration": 0.0, "where": None, "active_nodes": 0,
                    "penalty": float(self.mean_penalty)}
        state = self._state(tangent=False)
        force = comm.allreduce(-state["f"][:, :3].sum(axis=0) if len(state["f"]) else np.zeros(3), op=MPI.SUM)
        depth, where = _where_max(comm, -state["G"], self.slave_X[state["node"]])
        return {"force": force.tolist(), "max_penetration": depth, "where": where,
                "active_nodes": int(comm.allreduce(np.count_nonzero(state["G"] <= self.open_gap), op=MPI.SUM)), "penalty": float(self.mean_penalty)}

    def add_to_residual(self, b):
        if not self.active:
            return
        start = time.perf_counter()
        state = self._state(tangent=False)
        self._contacts["residual"] = state["contacts"]
        b.setValues(state["rows"].ravel(), state["f"].ravel(), addv=_ADD)
        self.timing["assembly"] += time.perf_counter() - start

    def add_to_jacobian(self, A):
        start = time.perf_counter()
        self._reserve(A)
        if self.active:
            state = self._state(tangent=True)
            self._contacts["jacobian"] = state["contacts"]
            for rows, K in zip(state["rows"], state["K"]):
                A.setValues(rows, rows, K, addv=_ADD)
        self.timing["assembly"] += time.perf_counter() - start


# -- deformable pair ----------------------------------------------------------------------
class ContactPair(_ContactFeature):
    """Frictionless node-to-segment penalty contact of two deformable surfaces.

    Args:
        name: name in summary.json.
        slave: surface whose nodes hit ...
        master: ... the segments of this surface (its outward normal faces the slave).
        penalty: pressure per unit penetration (MPa/mm), per unit area of the slave surface;
            default from the element stiffness of both surfaces (module docstring).
        step: index of the load step from which the contact acts.
        smoothing: length (mm) over which the penalty law is smoothed (``normal_law``); 0:
            sharp.

    Make the finer of two meshes the slave: single-pass node-to-segment contact keeps slave
    nodes out of the master, while master nodes may poke between slave nodes.
    """

    def __init__(self, name, slave, master, penalty=None, step=0, smoothing=0.0):
        if slave == master:
            raise SceneError(f"contact {name!r}: slave and master are both {slave!r}; name two surfaces")
        super().__init__(name, slave, penalty, step, smoothing)
        self.master_name = master

    def setup(self, solid):
        comm = solid.comm
        tables = _SolidTables(solid)
        master = _surface(solid, tables, self.master_name)
        self._setup_slave(solid, tables, master.mean_stiffness)
        self.kind = master.kind
        # the master surface on every rank: the nodes each rank owns, in rank order, and the
        # segments as rows of that table
        self.master_dofs = tables.dofs[master.nodes]
        self.master_counts = 3 * np.array(comm.allgather(len(master.nodes)))
        gathered = comm.allgather((tables.global_index[master.nodes], tables.global_index[self.master_dofs],
                                   tables.X[master.nodes], tables.global_index[master.segments], master.thickness))
        node_global = np.concatenate([g[0] for g in gathered]).astype(np.int64)
        self.master_global = np.concatenate([g[1] for g in gathered]).reshape(-1, 3)
        self.master_X = np.concatenate([g[2] for g in gathered]).reshape(-1, 3)
        segments = np.concatenate([g[3] for g in gathered]).reshape(-1, self.kind.corners)
        self.segments = _lookup(node_global, segments)
        self.thickness = np.concatenate([g[4] for g in gathered])
        self.master_node_global = node_global
        x = self.master_X[self.segments]
        self.segment_size = np.sqrt(np.linalg.norm(np.cross(x[:, 2] - x[:, 0], x[:, -1] - x[:, 1]), axis=1))
        self.slave_node_global = self.slave_global[:, 0].astype(np.int64)
        self.segment = np.full(len(self.slave.nodes), -1)  # the segment each node last projected on
        self._selection = None  # (slave and master positions, the nodes in contact, their segments)
        self.held = False  # each node keeps its segment (``hold``)
        self._held_before = None
        self._unreserved = True  # the candidates' entries are not yet in the matrix
        self.motion, self.pattern_keys = 0.0, None
        self._last = (self.slave_positions(), self.master_positions())
        self._search()
        self.pattern_keys = self._keys()

    def master_positions(self):
        """Current coordinates of every master node (collective: gathers the displacements)."""
        return self.master_X + self._gather_master(self.solid.w.x.array)

    def _gather_master(self, values):
        """The master nodes' entries (n, 3) of a mixed vector's local array, from every rank."""
        start = time.perf_counter()
        mine = np.ascontiguousarray(values[self.master_dofs]).ravel()
        u = np.empty(self.master_counts.sum())
        self.solid.comm.Allgatherv(mine, [u, self.master_counts])
        self.timing["gather"] += time.perf_counter() - start
        return u.reshape(-1, 3)

    @property
    def gap_nodes(self):
        """The slave nodes that have a gap: those that project on a segment."""
        return np.flatnonzero(self.segment >= 0)

    def _gaps_along(self, du):
        """The gaps of ``gap_nodes`` at the state changed by fraction * du, as a function of
        fraction (a number, or one per node); the master's positions and change are gathered
        once (collective)."""
        node = self.gap_nodes
        seg = self.segments[self.segment[node]]
        xs, dxs = self.slave_positions()[node], du[self.slave_dofs[node]]
        xm, dxm = self.master_positions()[seg], self._gather_master(du)[seg]

        def gaps(fraction):
            fraction = np.broadcast_to(fraction, node.shape)[:, None]
            return node_to_segment(xs + fraction * dxs, xm + fraction[:, None] * dxm, self.kind, tangent=False).G
        return gaps

    def _search(self):
        """Candidate segments of each owned slave node, from the current positions."""
        start = time.perf_counter()
        xs, xm = self.slave_positions(), self.master_positions()
        moved = max(np.abs(xs - self._last[0]).max(initial=0.0), np.abs(xm - self._last[1]).max(initial=0.0))
        self.motion = self.solid.comm.allreduce(moved, op=MPI.MAX) or self.motion
        self._last = (xs, xm)
        x = xm[self.segments]
        reach = (SEARCH_FACTOR * self.segment_size + 2.0 * self.motion)[:, None]
        node, seg = candidate_pairs(xs, x.min(axis=1) - reach, x.max(axis=1) + reach)
        own = np.any(self.master_node_global[self.segments[seg]] == self.slave_node_global[node][:, None], axis=1)
        self.cand_node, self.cand_seg = node[~own], seg[~own]
        self.timing["search"] += time.perf_counter() - start

    def _keys(self):
        """The candidate (slave node, master node) pairs, as int64 keys."""
        nodes = self.master_node_global[self.segments[self.cand_seg]]
        return np.unique(self.slave_node_global[self.cand_node][:, None] * 2**31 + nodes)

    def _reserve(self, A):
        """Zeros in A for every candidate element, once after each search: PETSc drops the
        preallocated room a final assembly left unused, so a node that touches a new segment
        later in the increment would cost a malloc."""
        if not self._unreserved:
            return
        width = 3 + 3 * self.kind.corners
        rows = np.hstack([self.slave_global[self.cand_node],
                          self.master_global[self.segments[self.cand_seg]].reshape(-1, width - 3)])
        zeros = np.zeros((width, width))
        for element in rows:
            A.setValues(element, element, zeros, addv=_ADD)
        self._unreserved = False

    def begin_increment(self):
        self._search()
        self._unreserved = True
        keys = self._keys()
        if np.all(np.isin(keys, self.pattern_keys, assume_unique=True)):
            return False
        self.pattern_keys = keys
        return True

    def coupling(self):
        """Slave node dofs x master node dofs (both ways), and master x master within each
        candidate segment, for every candidate pair of the pattern."""
        s_dofs = self.slave_global[_lookup(self.slave_node_global, self.pattern_keys // 2**31)]
        m_dofs = self.master_global[_lookup(self.master_node_global, self.pattern_keys % 2**31)]
        cross_rows, cross_cols = np.repeat(s_dofs, 3, axis=1).ravel(), np.tile(m_dofs, (1, 3)).ravel()
        width = 3 * self.kind.corners
        seg_dofs = self.master_global[self.segments[np.unique(self.cand_seg)]].reshape(-1, width)
        own_rows, own_cols = np.repeat(seg_dofs, width, axis=1).ravel(), np.tile(seg_dofs, (1, width)).ravel()
        return np.concatenate([cross_rows, cross_cols, own_rows]), np.concatenate([cross_cols, cross_rows, own_cols])

    def _state(self, tangent):
        xs, xm = self.slave_positions(), self.master_positions()
        node, seg = self._contacts_at(xs, xm)
        kin = node_to_segment(xs[node], xm[self.segments[seg]], self.kind, tangent=tangent)
        f, K = normal_law(self.alpha[node], kin.G, kin.D, kin.H, self.smoothing)
        rows = np.hstack([self.slave_global[node], self.master_global[self.segments[seg]].reshape(-1, 3 * self.kind.corners)])
        return {"node": node, "G": kin.G, "f": f, "K": K, "rows": rows, "contacts": np.column_stack([node, seg])}

    def _contacts_at(self, xs, xm):
        """The nodes in contact at these slave and master positions, and their segments; the
        last selection if it was made at the same state (the tangent after the residual)."""
        last = self._selection
        if last is None or not (np.array_equal(last[0], xs) and np.array_equal(last[1], xm)):
            self._selection = (xs, xm, *self._select(xs, xm, self.held))
        return self._selection[2:]

    def hold(self, held):
        if held != self.held:
            self.held, self._selection = held, None
        if not held:
            self._held_before = None  # the segments of the last solve that held them

    def settle(self):
        """After Newton converged: give each node its closest segment; False (on every rank) if
        any node that carries force changed, so Newton must run again (collective)."""
        if not self.active or not self.held:
            return True
        xs, xm = self.slave_positions(), self.master_positions()
        held = np.column_stack(self._contacts_at(xs, xm))  # the contacts Newton converged with
        before = self.segment.copy()
        closest = np.column_stack(self._select(xs, xm, frozen=False))
        self._selection = None
        changed = not np.array_equal(held, closest)
        # back to the contacts of the solve before, on every rank: nodes on a fold of the master,
        # which either segment's normal pushes across it; they keep the ones they converged on
        returned = changed and self._held_before is not None and np.array_equal(self._held_before, closest)
        if self.solid.comm.allreduce(returned or not changed, op=MPI.LAND):
            self.segment = before
            return True
        self._held_before = held
        return False

    def _select(self, xs, xm, frozen):
        """The penetrating slave nodes and the segment each one hits, among the candidates.
        ``frozen``: a node keeps the segment it had while it projects onto it (or just past its
        edge); else it takes the closest one."""
        node, seg = self.cand_node, self.cand_seg
        trial = node_to_segment(xs[node], xm[self.segments[seg]], self.kind, tangent=False)
        outside = self.kind.outside(trial.xi)
        # the closest segment (plane distance plus how far outside it the projection falls);
        # a node keeps its segment until another one holds its projection better by a thin
        # band, so it never flip-flops across a fold (the force turns there)
        first_of_node = np.flatnonzero(np.r_[True, node[1:] != node[:-1]]) if len(node) else np.empty(0, dtype=int)
        best = np.repeat(np.minimum.reduceat(outside, first_of_node), np.diff(np.r_[first_of_node, len(node)])) \
            if len(node) else outside
        keep = (self.segment[node] == seg) & (outside <= (OVERHANG_TOLERANCE if frozen else best + SWITCH_TOLERANCE))
        score = np.where(keep, -1.0, np.abs(trial.G) + self.segment_size[seg] * outside)
        order = np.lexsort((score, node))
        first = order[np.r_[True, node[order][1:] != node[order][:-1]]] if len(order) else order
        # past the edge of the master surface a node still hits the last segment for a while
        first = first[outside[first] <= OVERHANG_TOLERANCE]
        self.segment[:] = -1
        self.segment[node[first]] = seg[first]
        # penetrating, but not through the whole element under the segment (that is the far side)
        hit = first[(trial.G[first] < self.reach) & (-trial.G[first] <= self.thickness[seg[first]])]
        return node[hit], seg[hit]


def _lookup(table, values):
    """Positions of ``values`` in the unsorted array ``table`` (all present)."""
    sorter = np.argsort(table)
    return sorter[np.searchsorted(table, values, sorter=sorter)]


# -- rigid obstacles ----------------------------------------------------------------------
def _unit(vector, what):
    v = np.asarray(vector, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise SceneError(f"{what} must be a non-zero vector of three numbers, got {vector!r}")
    return v / np.linalg.norm(v)


def _point(value, what):
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise SceneError(f"{what} must be three numbers, got {value!r}")
    return v


class Plane:
    """The half-space the solid must stay in: (x - point) . normal >= 0."""

    def __init__(self, point, normal):
        self.point, self.normal = _point(point, "plane point"), _unit(normal, "plane normal")

    def gap(self, x, shift):
        """Gap g (n,), grad g (n, 3) and Hess g (n, 3, 3; None: zero) at points x (n, 3)."""
        g = (x - self.point - shift) @ self.normal
        return g, np.broadcast_to(self.normal, x.shape), None


class _Round:
    """Sphere or cylinder: g = +-(rho - radius), rho the distance to the centre (or axis)."""

    def __init__(self, radius, inside):
        if isinstance(radius, bool) or not isinstance(radius, (int, float)) or not np.isfinite(radius) or radius <= 0:
            raise SceneError(f"radius must be a positive number, got {radius!r}")
        self.radius, self.sign = float(radius), -1.0 if inside else 1.0

    def gap(self, x, shift):
        r = self._radial(x - self.origin - shift)
        rho = np.linalg.norm(r, axis=1)
        e = r / rho[:, None]
        # Hessian of rho: (I - a a^T - e e^T) / rho, without the a a^T term for a sphere
        hessian = (self._projector - _outer(e, e)) / rho[:, None, None]
        return self.sign * (rho - self.radius), self.sign * e, self.sign * hessian


class Sphere(_Round):
    def __init__(self, center, radius, inside=False):
        super().__init__(radius, inside)
        self.origin, self._projector = _point(center, "sphere center"), np.eye(3)

    def _radial(self, d):
        return d


class Cylinder(_Round):
    def __init__(self, point, axis, radius, inside=False):
        super().__init__(radius, inside)
        self.origin, self.axis = _point(point, "cylinder point"), _unit(axis, "cylinder axis")
        self._projector = np.eye(3) - np.outer(self.axis, self.axis)

    def _radial(self, d):
        return d @ self._projector


SHAPES = {"plane": Plane, "sphere": Sphere, "cylinder": Cylinder}


class RigidContact(_ContactFeature):
    """Frictionless penalty contact of a surface's nodes with a rigid plane, sphere or cylinder.

    Args:
        name: name in summary.json.
        slave: the solid's surface that touches the rigid body.
        shape: "plane" (point, normal: the solid stays on the side the normal points to),
            "sphere" (center, radius) or "cylinder" (point, axis, radius): the solid stays
            outside, or inside with ``inside=True``.
        penalty: pressure per unit penetration (MPa/mm), per unit area of the slave surface;
            default PENALTY_FACTOR * E / h of the slave's elements (module docstring).
        displacement: rigid translation of the body, reached at the end of its step
            (ramped with the load factor); None: it stays.
        step: index of the load step from which the contact acts.
        **shape_params: the shape's parameters.

    Each node i with gap g_i < 0 adds 1/2 alpha_i g_i^2: residual alpha g grad g and the
    exact tangent alpha (grad g grad g^T + g Hess g) (the normal of a sphere or cylinder
    turns with the node); ``smoothing`` as for ``ContactPair``.
    """

    def __init__(self, name, slave, shape, penalty=None, step=0, displacement=(0.0, 0.0, 0.0), smoothing=0.0,
                 **shape_params):
        super().__init__(name, slave, penalty, step, smoothing)
        if shape not in SHAPES:
            raise SceneError(f"contact {name!r}: unknown rigid shape {shape!r}; choose one of {sorted(SHAPES)}")
        try:
            self.shape = SHAPES[shape](**shape_params)
        except TypeError as error:
            raise SceneError(f"contact {name!r}: rigid {shape}: {error}".replace("__init__() ", "")) from None
        except SceneError as error:
            raise SceneError(f"contact {name!r}: rigid {shape}: {error}") from None
        self.displacement = np.zeros(3) if displacement is None else \
            _point(displacement, f"contact {name!r}: displacement")
        self.shift = np.zeros(3)

    def setup(self, solid):
        self._setup_slave(solid, _SolidTables(solid), np.inf)

    def set_load_factor(self, factor):
        self.shift = factor * self.displacement

    @property
    def gap_nodes(self):
        return np.arange(len(self.slave.nodes))

    def _gaps_along(self, du):
        x, dx = self.slave_positions(), du[self.slave_dofs]
        return lambda fraction: self.shape.gap(x + np.broadcast_to(fraction, len(x))[:, None] * dx, self.shift)[0]

    def _state(self, tangent):
        x = self.slave_positions()
        g, grad, hess = self.shape.gap(x, self.shift)
        node = np.flatnonzero(g < self.reach)
        g, grad = g[node], np.ascontiguousarray(grad[node])
        if tangent:
            hess = np.zeros((len(node), 3, 3)) if hess is None else hess[node]
        f, K = normal_law(self.alpha[node], g, grad, hess if tangent else None, self.smoothing)
        return {"node": node, "G": g, "f": f, "K": K, "rows": self.slave_global[node], "contacts": node}

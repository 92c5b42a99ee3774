"""Frictionless contact of two deformable surfaces: slave Gauss points on master segments.

The slave surface is integrated at the Gauss points of its facets (2 x 2 on a
quadrilateral, 3 on a triangle; weights in the reference configuration), as FEBio's
sliding-elastic interface does, so a slave node sitting over a fold of the master is no
longer one point that must choose a side. Each point is projected along the master's
continuous normal field (``geometry.py``) on the candidate segments found at the start of
the increment (``search.py``: within SEARCH_FACTOR times the master's largest segment size
plus the gaps that carry a pressure, coordinate-wise), and takes the segment whose foot lies
on it and is nearest. The candidates hold every segment a point may press on as long as the
points and the master's corners have moved, since the search, by less than that reach less
the range of gaps that carry a pressure (``search_covers``, at every converged state); where
they moved farther, the solver searches again at that state and solves again
(system/stepping.py), so that how far an increment slides changes its cost only. Two
segments at an edge give the same foot there, and exact ties go to the segment with the
smallest reference centroid (lexicographic), a rule that does not depend on the partition.
A point farther inside than the element under the segment is on its far side, not in
contact. With ``adjust``, a point whose gap in the mesh is within that clearance measures its
gap from it and is in the tangent at zero pressure (``law.py``): the surfaces touch from the
start, as Abaqus' contact ADJUST places them, without moving a node. Nothing is remembered
between evaluations but where each projection's Newton starts (the foot found last time on the
same segment, until the next search).

The matrix has room for every (slave facet, segment) pair a search finds; it is preallocated
anew when a search finds a pair it has no room for. On one rank it is also made anew at the
first increment of every step (unless no tangent was assembled in it yet and the search found
the pairs it was made for), so that a step's arithmetic depends on the state it starts from
only: a step resumed from a checkpoint (output/checkpoint.py) repeats the interrupted run's to
the bit (MUMPS' analysis of a matrix on one rank reads its values, so one kept from the step
before would change the round-off). On several ranks no run repeats another to the bit (MUMPS
sums in the order its messages arrive), and the matrix and its analysis are kept from one step
to the next while they have room (the seed's operation: one analysis, not three).

Parallel: each rank owns the slave facets of its cells, and holds of the master surface only
the segments whose search boxes meet the box of its slave points, with the nodes their normal
fields need (``master.py``: a bounding-box exchange at every search, and a scatter of those
nodes' displacements at every evaluation); no rank holds the whole master surface. Forces go to
global rows; rows of nodes owned elsewhere reach their owners through PETSc's stash.
"""
from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from mpi4py import MPI

from .. import checks
from ..arrays import distinct_pairs
from ..errors import SceneError
from ..mechanics.solid import MixedSolid
from .base import ContactFeature, Selection
from .geometry import corner_normals, project, traction
from .master import DistributedMaster
from .policy import SEARCH_FACTOR
from .search import candidate_pairs
from .surface import SolidTables, default_penalty, surface


def _lookup(table, values):
    """Positions of ``values`` in the unsorted array ``table`` (all present)."""
    sorter = np.argsort(table)
    return sorter[np.searchsorted(table, values, sorter=sorter)]


class ContactPair(ContactFeature):
    """Frictionless penalty contact, augmented, of two deformable surfaces.

    Args:
        name: name in summary.json.
        slave: surface whose Gauss points meet ...
        master: ... the segments of this surface (its outward normal faces the slave).
        penalty: pressure per unit penetration (MPa/mm); default: PENALTY_FACTOR times the
            series stiffness E/h of the two surface layers (``policy.py``). An expert's knob:
            the augmented Lagrangian makes the answer independent of it.
        step: index of the load step from which the contact acts.
        smoothing: length (mm) over which the penalty law is smoothed (``law.py``); 0 (the
            default): sharp. An expert's knob.
        symmetry: the axes ("x", "y", "z") whose coordinate planes are symmetry planes of a
            partial model: the master's nodes on them take normals in the plane.
        adjust: a clearance (mm) closed at the start: each point whose gap in the mesh is at most
            this, either way, measures its gap from that one, so the surfaces touch from the start
            (Abaqus' contact ADJUST, done as an offset of the gap instead of moving nodes): a
            buckle meshed clear of the sclera then rests on it. 0 (the default): the mesh's gaps.
    """

    symmetric_tangent = False  # the pressure acts along the smoothed normal, not a gap's gradient

    def __init__(self, name: str, slave: str, master: str, penalty: float | None = None, step: int = 0,
                 smoothing: float = 0.0, symmetry: Sequence[str] = (), adjust: float = 0.0):
        if slave == master:
            raise SceneError(f"contact {name!r}: slave and master are both {slave!r}; name two surfaces")
        if not set(symmetry) <= {"x", "y", "z"}:
            raise SceneError(f"contact {name!r}: symmetry must list axes among 'x', 'y', 'z', got {symmetry!r}")
        adjust = checks.number(adjust, f"contact {name!r}: adjust", "nonnegative")
        super().__init__(name, slave, penalty, step, smoothing)
        self.master_name, self.symmetry, self.adjust = master, tuple(symmetry), adjust

    def setup(self, solid: MixedSolid) -> None:
        comm = solid.comm
        tables = self.tables = SolidTables(solid)
        master, slave = surface(solid, tables, self.master_name), surface(solid, tables, self.slave_name)
        self.kind = master.kind

        # slave points: the Gauss points of the owned slave facets
        kind = slave.kind
        n_gauss = len(kind.gauss_weights)
        N, dN = kind.shape(kind.gauss_points)
        X = tables.X[slave.facets]  # (m, k, 3)
        a = np.einsum("gab,mai->mgbi", dN, X)
        jacobian = np.linalg.norm(np.cross(a[:, :, 0], a[:, :, 1]), axis=2)  # (m, g)
        self.point_facet = np.repeat(np.arange(len(slave.facets)), n_gauss)
        self.point_N = np.tile(N, (len(slave.facets), 1))
        self.weight = (jacobian * kind.gauss_weights).ravel()
        self.point_X = np.einsum("ga,mai->mgi", N, X).reshape(-1, 3)
        self.thickness = slave.thickness[self.point_facet]
        node_penalty = np.full(len(slave.facets), self.penalty) if self.penalty is not None else \
            default_penalty(slave.stiffness, master.mean_stiffness)
        self.alpha = node_penalty[self.point_facet]
        self.facet_dofs = tables.dofs[slave.facets]  # (m, k, 3) local, ghosts included
        self.facet_global = tables.global_index[self.facet_dofs].reshape(len(slave.facets), 3 * slave.kind.corners)
        self.facet_node_global = self.facet_global[:, ::3].astype(np.int64)
        self.slave_dofs = tables.dofs[slave.nodes]
        self.point_nodes = slave.facets[self.point_facet]
        self._setup_common(solid)

        # the master segments near this rank's slave points, exchanged at every search (master.py)
        self.master = DistributedMaster(comm, tables, master, self.symmetry)
        self.largest_segment = comm.allreduce(float(self.master.size.max(initial=0.0)), op=MPI.MAX)
        self._new_step, self._assembled = False, False
        self._last = (self._slave_points(), self.master.corners(self.solid.w.x.array))
        self._offset = np.zeros(len(self.weight))  # each point's gap in the mesh, where adjust closes it
        self._search()
        self._close_clearance()
        self._set_pattern(self._keys())

    def _close_clearance(self):
        """``adjust``: the points whose gap in the mesh (the state at setup) is at most adjust, either
        way, measure their gap from it (collective)."""
        if self.adjust == 0.0:
            return
        if self.adjust > SEARCH_FACTOR * self.largest_segment:
            raise SceneError(f"contact {self.name!r}: adjust {self.adjust:g} mm is beyond the contact search's reach "
                             f"({SEARCH_FACTOR * self.largest_segment:.3g} mm, {SEARCH_FACTOR:g} of the master's "
                             "largest segment): close a smaller clearance")
        sel = self._select(self._positions())
        self.adjusted[sel.point] = np.abs(sel.g) <= self.adjust
        self._offset[sel.point] = np.where(self.adjusted[sel.point], sel.g, 0.0)

    # -- positions -----------------------------------------------------------------------
    def master_positions(self) -> np.ndarray:
        """Current coordinates of the master nodes this rank holds (collective)."""
        return self.table.node_X + self._gather_master(self.solid.w.x.array)

    def _gather_master(self, values):
        """The entries (n, 3) of a mixed dof array at the master nodes this rank holds (collective)."""
        start = time.perf_counter()
        u = self.master.displacements(values)
        self.timing["gather"] += time.perf_counter() - start
        return u

    def _facet_nodes(self, values):
        """Current coordinates (m, k, 3) of the slave facets' nodes, from a ghosted array."""
        return self.tables.X[self.facet_dofs[:, :, 0]] + values[self.facet_dofs]

    def _slave_points(self, values=None):
        """The points interpolated from values (m, k, 3) at the slave facets' nodes: their
        positions (default), or a change of them."""
        values = self._facet_nodes(self.solid.w.x.array) if values is None else values
        return np.einsum("na,nai->ni", self.point_N, values[self.point_facet])

    def _positions(self):
        return self._slave_points(), self.master_positions()

    # -- search and selection ------------------------------------------------------------
    def _search(self):
        """Candidate segments of each point, from the current positions (collective: the master
        segments near this rank's points are exchanged first, master.py)."""
        start = time.perf_counter()
        xs, corners, moved = self._moved()
        self._last = xs, corners
        exchange = time.perf_counter()
        # SEARCH_FACTOR times the largest segment, the same for all (so that ``search_covers`` holds
        # for every segment), and the gaps at which a point carries a pressure
        reach = self.search_reach = SEARCH_FACTOR * self.largest_segment + moved[2]
        table = self.table = self.master.exchange(xs, corners, reach)
        self._selection = None  # its segments were the last table's
        self.timing["exchange"] += time.perf_counter() - exchange
        x = self.master_positions()[table.segments]
        point, seg = candidate_pairs(xs, x.min(axis=1) - reach, x.max(axis=1) + reach)
        # a segment made of the point's own facet's nodes is that facet (surfaces that overlap);
        # segments that only share nodes with it stay: a detached retina meets the choroid facets
        # it shares its rim with, and its Gauss points lie inside its facet, off the shared nodes
        facet_nodes = self.facet_node_global[self.point_facet[point]]
        same = table.node_global[table.segments[seg]][:, :, None] == facet_nodes[:, None, :]
        own = np.all(np.any(same, axis=1), axis=1)
        self.cand_point, self.cand_seg = point[~own], seg[~own]
        self._feet_guess = None  # the centres
        self.timing["search"] += time.perf_counter() - start

    def search_covers(self) -> bool:
        """True if every segment a point may press on now was its candidate at the last search
        (collective; module docstring): the points and the master's corners moved since then,
        coordinate-wise, by less than the search's reach less the range of gaps at which a
        point carries a pressure (the law's reach and the multipliers' shift on the open side,
        the deepest penetration on the other). A point that was deeper than the reach under a
        segment at the search is assumed not to be there (it would have been in contact
        unseen before)."""
        if not self.active:
            return True
        sel, on, _, _ = self._pressures()
        raw = sel.g + self._offset[sel.point]  # the distances the search measured (adjust: the mesh's gap back)
        penetration = self.solid.comm.allreduce(np.max(-raw[on], initial=0.0), op=MPI.MAX)
        slave, master, open_side = self._moved()[2]
        return slave + master + max(open_side, penetration) <= self.search_reach

    def _moved(self):
        """The points' and the master's own corners' positions now, and (over all ranks) how far
        each moved since the last search, coordinate-wise, and the largest gap at which a point
        carries a pressure, as the search measures gaps (adjust's offset added back; collective)."""
        xs, corners = self._slave_points(), self.master.corners(self.solid.w.x.array)
        local = np.array([np.abs(xs - self._last[0]).max(initial=0.0), np.abs(corners - self._last[1]).max(initial=0.0),
                          self.reach + np.max(self._point_multipliers() / self.alpha + self._offset, initial=0.0)])
        largest = np.empty(3)
        self.solid.comm.Allreduce(local, largest, op=MPI.MAX)
        return xs, corners, largest

    def _select(self, positions):
        xs, xm = positions
        point, seg = self.cand_point, self.cand_seg
        patch, k = self.table.patch, self.kind.corners
        # the corners' normals once per segment, not once per candidate pair
        used, inverse = np.unique(seg, return_inverse=True)
        nu = corner_normals(xm[patch.nodes[used]], patch.rows(used), k)[inverse]
        proj = project(xs[point], self.point_N[point], xm[self.table.segments[seg]], None, self.kind,
                       start=self._feet_guess, nu=nu)
        # Newton from the feet found last time, where they were on their segment
        self._feet_guess = np.where(proj.inside[:, None], proj.xi, np.asarray(self.kind.centre))
        ok = proj.inside & (-proj.g <= self.table.thickness[seg])
        point, seg, g = point[ok], seg[ok], proj.g[ok] - self._offset[point[ok]]
        c = self.table.centroid[seg]
        order = np.lexsort((c[:, 2], c[:, 1], c[:, 0], np.abs(g), point))
        first = order[np.r_[True, point[order][1:] != point[order][:-1]]] if len(order) else order
        return Selection(point[first], seg[first], g[first], proj.take(np.flatnonzero(ok)[first]))

    def _forces(self, sel, index, p, k, tangent):
        point, seg = sel.point[index], sel.target[index]
        proj, patch = sel.projection.take(index), self.table.patch
        if tangent:  # the derivatives, from the feet the selection found
            xs, xm = self._selection[0]
            proj = project(xs[point], self.point_N[point], xm[patch.nodes[seg]], patch.rows(seg), self.kind,
                           derivatives=True, start=proj.xi)
        size = patch.nodes.shape[1]
        r, K = traction(self.weight[point], p, k, proj, self.point_N[point], size, tangent)
        rows = np.hstack([self.facet_global[self.point_facet[point]],
                          self.table.node_dofs[patch.nodes[seg]].reshape(len(point), 3 * size)])
        return rows, r, K, proj.normal

    def _gaps_along(self, du):
        """The points that project on a segment now, their gaps now (the selection's), and their
        gaps at the state changed by fraction * du as a function of fraction (a number, or one per
        point) and of which points (default: all), each projection started from the point's foot now."""
        sel = self._selection_now()
        point, seg = sel.point, sel.target
        ghosted = self._ghosted(du)
        positions = self._selection[0]  # the current ones, at which the selection was made
        xs = positions[0][point]
        dxs = self._slave_points(ghosted[self.facet_dofs])[point]
        nodes = self.table.patch.nodes[seg]
        xm, dxm = positions[1][nodes], self._gather_master(du)[nodes]
        rows = self.table.patch.rows(seg)

        def gaps(fraction, index=slice(None)):
            f = np.broadcast_to(fraction, point[index].shape)
            return project(xs[index] + f[:, None] * dxs[index], self.point_N[point[index]],
                           xm[index] + f[:, None, None] * dxm[index], rows.rows(index), self.kind,
                           start=sel.projection.xi[index]).g - self._offset[point[index]]
        return point, sel.g, gaps

    def _loaded_nodes(self, point):
        """How many slave nodes (over all ranks) belong to a facet with a loaded point (collective:
        each node counted by its owner)."""
        weights = self._nodal_sums(point, np.ones(len(point)))
        return int(self.solid.comm.allreduce(np.count_nonzero(weights[: self._num_owned] > 0), op=MPI.SUM))

    # -- the matrix pattern --------------------------------------------------------------
    def _candidate_elements(self):
        """The distinct (slave facet, segment) candidate pairs."""
        return np.column_stack(distinct_pairs(self.point_facet[self.cand_point], self.cand_seg))

    def _keys(self):
        """The (row node, column node) pairs the candidates may couple, as int64 keys."""
        pairs = self._candidate_elements()
        slave = self.facet_node_global[pairs[:, 0]]
        master = self.table.node_global[self.table.patch.nodes[pairs[:, 1]]]
        nodes = np.hstack([slave, master])
        keys = nodes[:, :, None] * 2**31 + nodes[:, None, :]
        return np.unique(keys)

    def add_to_jacobian(self, A) -> None:
        self._assembled = True  # a tangent went into this matrix (``begin_increment``)
        super().add_to_jacobian(A)

    def begin_step(self, step_index: int) -> None:
        super().begin_step(step_index)
        self._new_step = True  # its first increment preallocates the matrix anew (module docstring)

    def begin_increment(self) -> bool:
        self._search()
        keys = self._keys()
        # on one rank a new step's matrix is made anew, unless no tangent went into the one there is
        # and it was made for these very keys (the first increment after ``setup``; module docstring)
        anew = self._new_step and self.solid.comm.size == 1 and (
            self._assembled or not np.array_equal(keys, self.pattern_keys))
        self._new_step = False
        if not anew and np.all(np.isin(keys, self.pattern_keys, assume_unique=True)):
            return False
        self._set_pattern(keys)
        self._assembled = False
        return True

    def _set_pattern(self, keys):
        """The node pairs the matrix has room for, and their global (row, col) dofs, looked up
        now: a later search's table may hold some of their master nodes no more, while the
        matrix keeps them (another feature may ask for a new one first)."""
        self.pattern_keys = keys
        row, col = self._node_dofs(keys // 2**31), self._node_dofs(keys % 2**31)
        self._pattern = np.repeat(row, 3, axis=1).ravel(), np.tile(col, (1, 3)).ravel()

    def coupling(self) -> tuple[np.ndarray, np.ndarray]:
        """Global (row, col) dofs of every node pair the candidates may couple."""
        return self._pattern

    def _node_dofs(self, nodes):
        """The global dofs (n, 3) of slave and master nodes this rank holds, by global node number."""
        node_dofs = np.vstack([self.facet_global.reshape(-1, 3), self.table.node_dofs])
        return node_dofs[_lookup(node_dofs[:, 0].astype(np.int64), nodes)]

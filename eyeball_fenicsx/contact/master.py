"""The master surface of a contact pair, distributed: each rank holds only the segments near its
slave points.

**Setup (once).** Each rank owns the master facets of its cells. A segment's normal field
(``geometry.py``) depends on every facet around its corners, which may belong to other ranks,
so the facets are sent to the owners of their corner nodes, which send back to each facet's
owner the facets around the corners they own: every rank then holds its facets' one-ring and
computes their ``Patches`` exactly. The facets keep a global number (the owner's offset plus
the local index), and the ring is taken in that order, so that every sum over a node's facets
runs in the order the whole surface would give it.

**Search (once per increment).** The ranks exchange the bounding boxes of their slave points
(current positions: six numbers per rank). Each rank then sends to every other rank, in one
``Alltoallv`` (a neighbourhood exchange: a rank whose box meets none of another's segments
sends it nothing), those of its segments whose box, widened by the search's reach (a multiple
of the largest segment's size plus the gaps that carry a pressure, ``pair.py``), meets that
rank's box: exactly the segments the search could pair with one of its points. A segment
travels with its patch: the global numbers, reference coordinates and dofs of the patch's
nodes, the incidences, scales and mirrors of its corners' normals, and the thickness under it.

**Newton iterations.** The received segments' patch nodes take their displacements from their
owners through one PETSc scatter (built after each search), so that a rank reads only the
master nodes it may touch; nothing of the rest of the surface reaches it. This is the global
search of parallel contact codes by processor bounding boxes: each rank ghosts the remote
surface that may reach its own, so memory and traffic grow with the contact zone a rank sees,
not with the surface.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .geometry import Patches, patches


def alltoallv(comm: MPI.Comm, parts: list[np.ndarray]) -> np.ndarray:
    """Send the 2-D array ``parts[q]`` (the same width and dtype on every rank) to rank q;
    return the rows received, in the order of their sources (collective)."""
    width, dtype = parts[0].shape[1], parts[0].dtype
    counts = np.array([p.size for p in parts], dtype=np.int64)
    received = np.empty(comm.size, dtype=np.int64)
    comm.Alltoall(counts, received)
    send = np.ascontiguousarray(np.concatenate([p.ravel() for p in parts]), dtype=dtype)
    out = np.empty(int(received.sum()), dtype=dtype)
    comm.Alltoallv([send, counts], [out, received])
    return out.reshape(-1, width)


def _send(comm, destination, rows):
    """``rows`` (n, w) each sent to ``destination`` (n,), by rank (collective)."""
    order = np.argsort(destination, kind="stable")
    bounds = np.searchsorted(destination[order], np.arange(comm.size + 1))
    return alltoallv(comm, [rows[order[bounds[q]: bounds[q + 1]]] for q in range(comm.size)])


def _first_rows(rows):
    """The rows (n, w) with distinct ids (column 0), each once, in the order of the ids."""
    _, first = np.unique(rows[:, 0], return_index=True)
    return rows[first]


@dataclasses.dataclass
class MasterTable:
    """The master segments this rank may meet until the next search, with the nodes of their
    patches (rows of ``node_*``; ``segments`` and ``patch.nodes`` index them).

    Attributes:
        segments: (m, k) corner nodes; patch: their ``Patches``; thickness, centroid: per
            segment the depth of the element under it and its reference centroid (m, 3).
        node_global: (n,) global node numbers (the x dof's); node_dofs: (n, 3) global dofs;
        node_X: (n, 3) reference coordinates.
    """

    segments: np.ndarray
    patch: Patches
    thickness: np.ndarray
    centroid: np.ndarray
    node_global: np.ndarray
    node_dofs: np.ndarray
    node_X: np.ndarray


class DistributedMaster:
    """The master surface of one contact pair (module docstring).

    Args:
        comm: the solid's communicator.
        tables: the solid's ``SolidTables``.
        master: this rank's ``Surface`` of the master.
        symmetry: the model's symmetry planes, as in ``geometry.patches``.
    """

    def __init__(self, comm: MPI.Comm, tables, master, symmetry):
        self.comm, self.kind = comm, master.kind
        self.corner_dofs = tables.dofs[master.facets]  # (m, k, 3) local, for the owned segments' boxes
        self.corner_X = x = tables.X[master.facets]
        # a segment's size: sqrt(|d1 x d2|) of its diagonals (a square's: 1.41 edges)
        self.size = np.sqrt(np.linalg.norm(np.cross(x[:, 2] - x[:, 0], x[:, -1] - x[:, 1]), axis=1))
        k = self.kind.corners
        self.count = comm.allreduce(len(master.facets), op=MPI.SUM)  # segments over all ranks
        offset = comm.exscan(len(master.facets), op=MPI.SUM) or 0
        first_dof = comm.exscan(tables.num_owned, op=MPI.SUM) or 0  # DOLFINx numbers each rank's dofs contiguously
        starts = np.array(comm.allgather(first_dof) + [np.iinfo(np.int64).max])
        self._owner = lambda g: np.searchsorted(starts, g, side="right") - 1
        facet_starts = np.array(comm.allgather(offset) + [self.count])
        self._facet_owner = lambda f: np.searchsorted(facet_starts, f, side="right") - 1
        # a facet as a row: [id, corner nodes (k), corner dofs (3k)] and [corner X (3k), thickness]
        ints = np.column_stack([offset + np.arange(len(master.facets)), tables.global_index[master.facets],
                                tables.global_index[self.corner_dofs].reshape(-1, 3 * k)]).astype(np.int64)
        floats = np.column_stack([self.corner_X.reshape(-1, 3 * k), master.thickness])
        ring_ints, ring_floats = self._one_ring(ints, floats)
        self._own = self._own_patches(ring_ints, ring_floats, offset + np.arange(len(master.facets)), symmetry)
        self.table, self._scatter = None, None
        self._from = PETSc.Vec().createMPI((tables.num_owned, PETSc.DECIDE), comm=comm)

    # -- setup ---------------------------------------------------------------------------
    def _one_ring(self, ints, floats):
        """Every facet sharing a node with one of this rank's facets, its own included, by id."""
        k, comm = self.kind.corners, self.comm
        both = np.hstack([ints, floats.view(np.int64)])  # one exchange: the floats' bits travel as integers
        # to the owners of their corners (each owner once)
        owners = self._owner(ints[:, 1: 1 + k]).ravel()
        pairs = np.unique(np.column_stack([owners, np.repeat(np.arange(len(ints)), k)]), axis=0)
        star = _send(comm, pairs[:, 0], both[pairs[:, 1]])
        star = _first_rows(star)
        # back to each facet's owner: the facets around the corners of it that this rank owns
        nodes = star[:, 1: 1 + k]
        mine = self._owner(nodes) == comm.rank
        f, c = np.nonzero(mine)
        node = nodes[f, c]
        order = np.argsort(node, kind="stable")
        node_sorted, f_sorted = node[order], f[order]
        lo, hi = np.searchsorted(node_sorted, node, "left"), np.searchsorted(node_sorted, node, "right")
        count = hi - lo
        asker = np.repeat(f, count)  # for every (facet, owned corner), every facet at that corner
        neighbour = f_sorted[np.repeat(lo, count) + np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)]
        pairs = np.unique(np.column_stack([self._facet_owner(star[asker, 0]), neighbour]), axis=0)
        ring = _send(comm, pairs[:, 0], star[pairs[:, 1]])
        ring = _first_rows(ring)  # sorted by facet id
        return ring[:, : 1 + 4 * k], np.ascontiguousarray(ring[:, 1 + 4 * k:]).view(np.float64)

    def _own_patches(self, ring_ints, ring_floats, own_ids, symmetry):
        """Per owned segment, its patch as rows to send: ints [nodes (P), dofs (3P), next, prev,
        mask (kV each)] and floats [node X (3P), scale (k), mirror (9k), thickness]."""
        k = self.kind.corners
        node_ids = ring_ints[:, 1: 1 + k].ravel()
        node_dofs = ring_ints[:, 1 + k: 1 + 4 * k].reshape(-1, 3)
        node_X = ring_floats[:, : 3 * k].reshape(-1, 3)
        nodes, first, inverse = np.unique(node_ids, return_index=True, return_inverse=True)
        rows = np.searchsorted(ring_ints[:, 0], own_ids)
        if len(rows):
            patch = patches(inverse.reshape(-1, k), node_X[first], symmetry).rows(rows)
        else:  # no master facet on this rank
            incidences = np.zeros((0, k, 1), dtype=int)
            patch = Patches(np.zeros((0, k), dtype=int), incidences, incidences, incidences.astype(bool),
                            np.zeros((0, k)), np.zeros((0, k, 3, 3)))
        m, p, v = len(rows), patch.nodes.shape[1], patch.mask.shape[2]
        P, V = self.comm.allreduce(p, op=MPI.MAX), self.comm.allreduce(v, op=MPI.MAX)
        padded = np.hstack([patch.nodes, np.repeat(patch.nodes[:, :1], P - p, axis=1)])
        incidences = [np.pad(a, ((0, 0), (0, 0), (0, V - v))).reshape(m, k * V)
                      for a in (patch.next, patch.prev, patch.mask.astype(np.int64))]
        ints = np.hstack([nodes[padded], node_dofs[first][padded].reshape(m, 3 * P), *incidences]).astype(np.int64)
        floats = np.hstack([node_X[first][padded].reshape(m, 3 * P), patch.scale, patch.mirror.reshape(m, 9 * k),
                            ring_floats[rows, 3 * k:]])
        self.P, self.V = P, V
        return ints, floats

    # -- search --------------------------------------------------------------------------
    def corners(self, values: np.ndarray) -> np.ndarray:
        """Current corners (m, k, 3) of this rank's own segments, from a ghosted dof array."""
        return self.corner_X + values[self.corner_dofs]

    def exchange(self, points: np.ndarray, corners: np.ndarray, reach: float) -> MasterTable:
        """Receive the segments whose box, widened by ``reach``, may hold one of
        this rank's ``points`` (n, 3); build the scatter of their nodes (collective)."""
        lo = points.min(axis=0) if len(points) else np.full(3, np.inf)
        hi = points.max(axis=0) if len(points) else np.full(3, -np.inf)
        boxes = np.array(self.comm.allgather(np.concatenate([lo, hi])))  # (ranks, 6)
        seg_lo, seg_hi = corners.min(axis=1) - reach, corners.max(axis=1) + reach
        meets = np.all(seg_lo[:, None, :] <= boxes[None, :, 3:], axis=2) & \
            np.all(seg_hi[:, None, :] >= boxes[None, :, :3], axis=2)  # (m, ranks)
        segment, rank = np.nonzero(meets)
        ints = _send(self.comm, rank, self._own[0][segment])
        floats = _send(self.comm, rank, np.ascontiguousarray(self._own[1][segment]))
        self.table = self._table(ints, floats)
        self._build_scatter()
        return self.table

    def _table(self, ints, floats):
        k, P, V, m = self.kind.corners, self.P, self.V, len(ints)
        ids, dofs = ints[:, :P], ints[:, P: 4 * P].reshape(m, P, 3)
        X = floats[:, : 3 * P].reshape(m, P, 3)
        node_global, first, inverse = np.unique(ids.ravel(), return_index=True, return_inverse=True)
        nodes = inverse.reshape(m, P)
        nxt, prv, mask = (ints[:, 4 * P + i * k * V: 4 * P + (i + 1) * k * V].reshape(m, k, V) for i in range(3))
        at = 3 * P
        scale, mirror = floats[:, at: at + k], floats[:, at + k: at + 10 * k].reshape(m, k, 3, 3)
        patch = Patches(nodes, nxt, prv, mask.astype(bool), scale, mirror)
        node_X = X.reshape(-1, 3)[first]
        x = node_X[nodes[:, :k]]
        return MasterTable(nodes[:, :k], patch, floats[:, at + 10 * k], x.mean(axis=1), node_global,
                           dofs.reshape(-1, 3)[first].astype(PETSc.IntType), node_X)

    def _build_scatter(self):
        if self._scatter is not None:
            self._scatter.destroy()
            self._to.destroy()
        dofs = self.table.node_dofs.ravel()
        self._to = PETSc.Vec().createSeq(len(dofs), comm=PETSc.COMM_SELF)
        index = PETSc.IS().createGeneral(dofs.astype(PETSc.IntType), comm=PETSc.COMM_SELF)
        self._scatter = PETSc.Scatter().create(self._from, index, self._to, None)
        index.destroy()

    # -- every Newton iteration ----------------------------------------------------------
    def displacements(self, values: np.ndarray) -> np.ndarray:
        """The table's nodes' entries (n, 3) of a mixed dof array (its owned entries are read;
        collective)."""
        owned = self._from.getLocalSize()
        self._from.array[:] = values[:owned]
        self._scatter.scatter(self._from, self._to, addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        return self._to.array.copy().reshape(-1, 3)

"""Whether the wetted surfaces of a cavity enclose a volume.

A surface encloses a volume when every edge of its facets is shared by two of them; a partial
model (an octant, a half eye) cuts it open along its symmetry planes, whose mirror images close
it. So every edge that only one facet holds must lie on a declared symmetry plane (its midpoint
within 1e-8 times the largest coordinate of the plane). Each edge is counted on one rank (its
first node's number modulo the ranks), to which every rank sends the edges of its facets: no
rank holds the whole surface.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from dolfinx import cpp
from mpi4py import MPI

from ..errors import SceneError
from ..mechanics.solid import MixedSolid


def check_closed(solid: MixedSolid, surfaces: Sequence[str], symmetry: Sequence[int], name: str) -> None:
    """Every boundary edge of the wetted surfaces must lie on a declared symmetry plane."""
    md = solid.mesh_data
    msh = md.mesh
    fdim = msh.topology.dim - 1
    facets = np.unique(np.concatenate([md.facets(s) for s in surfaces]))
    surface = surfaces[0] if len(surfaces) == 1 else surfaces
    msh.topology.create_connectivity(fdim, msh.topology.dim)
    nodes = cpp.mesh.entities_to_geometry(msh._mesh, fdim, facets, False)
    ids = np.asarray(msh.geometry.input_global_indices)[nodes].astype(np.int64)
    coords = msh.geometry.x[nodes]
    corners = ids.shape[1]
    pairs = [(0, 1), (0, 2), (1, 3), (2, 3)] if corners == 4 else [(0, 1), (1, 2), (0, 2)]
    # every edge, with the facet it bounds, to the rank that counts it (an edge's rank: its first
    # node's number modulo the ranks); the facets of one edge meet there, nothing is gathered
    facet = np.sort(ids, axis=1)
    edges = np.concatenate([np.sort(ids[:, list(p)], axis=1) for p in pairs])
    middles = np.concatenate([coords[:, list(p)].mean(axis=1) for p in pairs])
    rows = np.hstack([edges, np.tile(facet, (len(pairs), 1)), middles.view(np.int64)])
    order = np.argsort(edges[:, 0] % msh.comm.size, kind="stable")
    bounds = np.searchsorted((edges[:, 0] % msh.comm.size)[order], np.arange(msh.comm.size + 1))
    mine = np.concatenate(msh.comm.alltoall([rows[order[bounds[q]: bounds[q + 1]]] for q in range(msh.comm.size)]))
    mine = np.unique(mine, axis=0)  # a ghost facet's edges arrive twice
    _, inverse, counts = np.unique(mine[:, :2], axis=0, return_inverse=True, return_counts=True)
    middles = np.ascontiguousarray(mine[:, 2 + corners:]).view(np.float64)
    scale = msh.comm.allreduce(np.abs(coords).max(initial=0.0), op=MPI.MAX)
    on_plane = np.zeros(len(middles), dtype=bool)
    for axis in symmetry:
        on_plane |= np.abs(middles[:, axis]) <= 1e-8 * scale
    bad = (counts[inverse.ravel()] == 1) & ~on_plane
    count = msh.comm.allreduce(int(bad.sum()), op=MPI.SUM)
    if count:
        where = [np.round(middles[bad][0], 4).tolist()] if bad.any() else []
        where = next(w for w in msh.comm.allgather(where) if w)[0]
        raise SceneError(f"cavity {name!r}: surface {surface!r} is not closed: {count} open edge(s), "
                         f"e.g. near {where}; close it in the mesh or declare symmetry planes (symmetry = [...])")

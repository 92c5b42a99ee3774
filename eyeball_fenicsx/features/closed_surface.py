"""Whether the wetted surfaces of a cavity enclose a volume.

A surface encloses a volume when every edge of its facets is shared by two of them; a partial
model (an octant, a half eye) cuts it open along its symmetry planes, whose mirror images close
it. So every edge that only one facet holds must lie on a declared symmetry plane (its midpoint
within 1e-8 times the largest coordinate of the plane). The facets are gathered on rank 0,
which judges, and the verdict is broadcast.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from dolfinx import cpp

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
    ids = np.asarray(msh.geometry.input_global_indices)[nodes]
    coords = msh.geometry.x[nodes]
    gathered = msh.comm.gather((ids, coords), root=0)
    message = None
    if msh.comm.rank == 0:
        ids = np.concatenate([g[0] for g in gathered])
        coords = np.concatenate([g[1] for g in gathered])
        _, first = np.unique(np.sort(ids, axis=1), axis=0, return_index=True)  # ghosts appear twice
        ids, coords = ids[first], coords[first]
        corners = ids.shape[1]
        pairs = [(0, 1), (0, 2), (1, 3), (2, 3)] if corners == 4 else [(0, 1), (1, 2), (0, 2)]
        edges = np.concatenate([np.sort(ids[:, list(p)], axis=1) for p in pairs])
        middles = np.concatenate([coords[:, list(p)].mean(axis=1) for p in pairs])
        _, inverse, counts = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
        open_edges = counts[inverse.ravel()] == 1
        scale = np.abs(coords).max()
        on_plane = np.zeros(len(middles), dtype=bool)
        for axis in symmetry:
            on_plane |= np.abs(middles[:, axis]) <= 1e-8 * scale
        bad = open_edges & ~on_plane
        if bad.any():
            where = np.round(middles[bad][0], 4).tolist()
            message = (f"cavity {name!r}: surface {surface!r} is not closed: {int(bad.sum())} open edge(s), "
                       f"e.g. near {where}; close it in the mesh or declare symmetry planes (symmetry = [...])")
    message = msh.comm.bcast(message, root=0)
    if message:
        raise SceneError(message)

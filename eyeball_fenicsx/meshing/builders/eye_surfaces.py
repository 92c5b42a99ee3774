"""The eye's named boundary surfaces (eyeball_fenicsx/meshing/builders/eye.py), found from its hexahedra.

The boundary is the set of hexahedron faces that belong to one element only. In a wedge model its
faces on the planes azimuth 0 and ``sector_deg`` are the cuts "cut_0" and "cut_1"; the rest falls
apart into edge-connected pieces, each named by the tissues it touches and by the sign of the volume
it encloses (:func:`hexes.enclosed_volume`, negative for the outside of the eye): the outside is
"sclera_outer", "cornea_outer", "optic_nerve_side" and "optic_nerve_end" (at the nerve's cut
end); the cavity walls are "vitreous_wall" (touching the retina) and "anterior_chamber_wall"
(touching the cornea: anterior and posterior chamber, there is no iris); a detachment's gap is
"retina_outer" and "choroid_inner" (touching both). A cavity is closed when its wall has no open
edge but on the cut planes.
"""
import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .eye_meridian import Meridian
from .hexes import enclosed_volume, faces, open_edges

TOLERANCE = 1e-9  # mm: nodes closer than this to a plane are on it (they are placed on it exactly)


def _on_plane(points, azimuth):
    """Whether points (shape (..., 3)) lie on the half-plane through the z axis at ``azimuth`` (rad)."""
    normal = np.array([-math.sin(azimuth), math.cos(azimuth), 0.0])
    along = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
    return (np.abs(points @ normal) < TOLERANCE) & (points @ along > -TOLERANCE)


def on_cut_planes(points: np.ndarray, sector_deg: float) -> np.ndarray:
    """Whether points (shape (..., 3)) lie on one of the cut planes of a wedge of ``sector_deg``."""
    return _on_plane(points, 0.0) | _on_plane(points, math.radians(sector_deg))


def name_surfaces(nodes: np.ndarray, hexes: np.ndarray, regions: np.ndarray, m: Meridian,
                  sector_deg: float) -> dict[str, np.ndarray]:
    """Named boundary surfaces: cut planes first, then the edge-connected pieces of the rest of the
    boundary, named by the tissues they touch and the sign of the volume they enclose."""
    quads, face_id = faces(hexes)
    owner = np.repeat(regions, 6)
    boundary = np.flatnonzero(np.bincount(face_id)[face_id] == 1)
    surfaces = {}
    if sector_deg < 360.0:
        for name, azimuth in (("cut_0", 0.0), ("cut_1", math.radians(sector_deg))):
            on = np.all(_on_plane(nodes[quads[boundary]], azimuth), axis=1)
            surfaces[name] = quads[boundary[on]]
            boundary = boundary[~on]
    edges = np.sort(np.concatenate([quads[boundary][:, [k, (k + 1) % 4]] for k in range(4)]), axis=1)
    _, edge_id = np.unique(edges, axis=0, return_inverse=True)
    edge_id = edge_id.ravel()
    face_of_edge = np.tile(np.arange(len(boundary)), 4)
    size = len(boundary) + edge_id.max() + 1
    graph = coo_matrix((np.ones(len(edge_id)), (face_of_edge, len(boundary) + edge_id)), shape=(size, size))
    _, piece = connected_components(graph, directed=False)
    piece = piece[:len(boundary)]
    for label in np.unique(piece):
        piece_faces = boundary[piece == label]
        tissues = set(owner[piece_faces].tolist())
        volume = enclosed_volume(nodes, quads[piece_faces])
        if volume < 0:  # the outside of the eye
            for tissue, name in (("sclera", "sclera_outer"), ("cornea", "cornea_outer")):
                surfaces[name] = quads[piece_faces[owner[piece_faces] == tissue]]
            nerve = quads[piece_faces[owner[piece_faces] == "optic_nerve"]]
            end = np.all(np.abs(nodes[nerve][..., 2] - m.z_nerve_end) < TOLERANCE, axis=1)
            surfaces["optic_nerve_end"], surfaces["optic_nerve_side"] = nerve[end], nerve[~end]
        elif "choroid" in tissues:
            surfaces["retina_outer"] = quads[piece_faces[owner[piece_faces] == "retina"]]
            surfaces["choroid_inner"] = quads[piece_faces[owner[piece_faces] == "choroid"]]
        elif "cornea" in tissues:
            surfaces["anterior_chamber_wall"] = quads[piece_faces]
        elif "retina" in tissues:
            surfaces["vitreous_wall"] = quads[piece_faces]
        else:
            raise RuntimeError(f"eye: unexpected piece of boundary touching {sorted(tissues)}")
    order = ["sclera_outer", "cornea_outer", "optic_nerve_side", "optic_nerve_end", "vitreous_wall",
             "anterior_chamber_wall", "retina_outer", "choroid_inner", "cut_0", "cut_1"]
    return {name: surfaces[name] for name in order if name in surfaces}


def check_closed(nodes: np.ndarray, surfaces: dict[str, np.ndarray], sector_deg: float, detached: bool) -> None:
    """Raise RuntimeError unless the cavities, and the subretinal gap of a detachment, are closed but for their
    cuts by the symmetry planes."""
    cavities = {"vitreous_wall": surfaces["vitreous_wall"], "anterior_chamber_wall": surfaces["anterior_chamber_wall"]}
    if detached:
        cavities["subretinal gap"] = np.concatenate([surfaces["retina_outer"], surfaces["choroid_inner"]])
    for name, quads in cavities.items():
        if not np.all(on_cut_planes(nodes[open_edges(quads)], sector_deg)):
            raise RuntimeError(f"eye: the {name} is not closed")

"""A retinal detachment in the eye mesh (eyeball_fenicsx/meshing/builders/eye.py): a subretinal gap of constant width.

Over a spherical cap of the retina-choroid interface the retina gets its own nodes, moved by
``gap`` toward the centre of the eye with the whole retinal thickness, so that the gap between
"retina_outer" and "choroid_inner" is constant. On the rim of the cap the retina and the choroid
keep their shared nodes: the gap closes over one ring of elements, whose hexahedra are sheared by
gap / element size, not collapsed (a gap tapering to zero over the whole cap, as in a real bullous
detachment, would degenerate the elements at the rim). The vitreous wall stays the inner surface
of the retina, closed.

The cap is given by its centre (polar angle from the posterior pole and azimuth, seen from the
centre of the eye) and its angular radius ``extent_deg``. A cap centred on the posterior pole is
whole rings of faces, and its rim is moved onto the cap's circle (the wall's nodes lie on lines
through the centre of the eye, and the lines of the rim turn onto the cone of the cap). Any other
cap is the set of faces nearest to its centre whose solid angle, seen from the centre of the eye,
is the cap's, 2 pi (1 - cos extent): its outline is a staircase of element edges (which could not
be moved onto the cap's circle without collapsing the edges that cross it), its area that of the
cap within about one element. A wedge model is mirrored across its cut planes, so a detachment in
it must be centred on the axis, or in a half model on a cut plane.
"""
import math

import numpy as np
from scipy.spatial import cKDTree

from ...checks import is_number
from ...errors import SceneError
from .eye_meridian import Meridian, unit
from .eye_surfaces import on_cut_planes
from .hexes import check, faces, open_edges, quad_areas

DETACHMENT_KEYS = ("polar_deg", "azimuth_deg", "extent_deg", "gap")
_TOO_SMALL = "eye: the detachment is smaller than one element; increase extent_deg or refine"


def check_detachment(detachment: dict, m: Meridian, sector_deg: float) -> dict:
    """The detachment with its azimuth_deg (default 0) and every value a float, checked.

    Raises:
        SceneError: unless it is a table of numbers with the keys :data:`DETACHMENT_KEYS`, its gap at
            most 0.5 mm, its cap in the retina, and (in a wedge model) symmetric about the cut planes.
    """
    if not isinstance(detachment, dict) or set(detachment) - set(DETACHMENT_KEYS) \
            or not {"polar_deg", "extent_deg", "gap"} <= set(detachment):
        raise SceneError(f"eye: detachment must be None or a table with {', '.join(DETACHMENT_KEYS)} "
                         f"(azimuth_deg optional), got {detachment!r}")
    detachment = {"azimuth_deg": 0.0, **detachment}
    for key in DETACHMENT_KEYS:
        value = detachment[key]
        if not is_number(value):
            raise SceneError(f"eye: detachment {key} must be a number, got {value!r}")
    check("eye", "detachment gap", detachment["gap"], "positive number")
    check("eye", "detachment extent_deg", detachment["extent_deg"], "positive number")
    if detachment["gap"] > 0.5:
        raise SceneError(f"eye: detachment gap must be at most 0.5 mm, got {detachment['gap']}")
    ora_deg = math.degrees(m.s_ora / m.Ro)
    if not (0.0 <= detachment["polar_deg"] and detachment["polar_deg"] + detachment["extent_deg"] < ora_deg - 2.0):
        raise SceneError(f"eye: the detachment must lie in the retina: polar_deg + extent_deg below the ora "
                         f"serrata at {ora_deg - 2.0:.0f} deg from the posterior pole, got "
                         f"{detachment['polar_deg']} + {detachment['extent_deg']}")
    azimuth = detachment["azimuth_deg"] % 360.0
    symmetric = (detachment["polar_deg"] == 0.0 or sector_deg == 360.0
                 or (sector_deg == 180.0 and azimuth in (0.0, 180.0)))
    if not symmetric:
        raise SceneError("eye: a wedge model is mirrored across its cut planes, so its detachment must be too: "
                         "centre on the axis (polar_deg = 0) or, in a half model, azimuth_deg 0 or 180")
    return {key: float(detachment[key]) for key in DETACHMENT_KEYS}


def detach(nodes: np.ndarray, hexes: np.ndarray, regions: np.ndarray, m: Meridian, detachment: dict,
           sector_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Open the subretinal gap (see the module docstring); returns the new nodes and hexahedra.

    ``nodes`` and ``hexes`` are changed in place too (the rim of a cap on the axis is moved, the
    retina's hexahedra take the retina's new nodes).
    """
    interface = _interface(hexes, regions)
    polar, azimuth = np.radians(detachment["polar_deg"]), np.radians(detachment["azimuth_deg"])
    centre = np.array([math.sin(polar) * math.cos(azimuth), math.sin(polar) * math.sin(azimuth), -math.cos(polar)])
    face_centres = nodes[interface].mean(axis=1)
    angle = np.arccos(np.clip(unit(face_centres) @ centre, -1.0, 1.0))
    extent = math.radians(detachment["extent_deg"])
    on_axis = detachment["polar_deg"] == 0.0 and extent * m.Ro > 1.01 * m.s_nerve
    if on_axis:
        # Whole rings of faces about the axis, beyond the butterfly core; their rim is moved onto
        # the cone of the cap below.
        rim, interior, _ = _split(nodes, interface[angle < extent], sector_deg)
    else:
        rim, interior = _cap_of_solid_angle(nodes, interface, face_centres, angle, extent, sector_deg)
    if len(interior) == 0:
        raise SceneError(_TOO_SMALL)
    if on_axis:
        _move_rim_onto_cone(nodes, hexes, regions, rim, centre, extent)
    return _open_gap(nodes, hexes, regions, interior, detachment["gap"])


def _interface(hexes, regions):
    """The retina's faces on the choroid (outward from the retina)."""
    quads, face_id = faces(hexes)
    owner = np.repeat(regions, 6)
    retina_side = np.flatnonzero(owner == "retina")
    choroid_faces = set(face_id[owner == "choroid"].tolist())
    return quads[retina_side[np.fromiter((f in choroid_faces for f in face_id[retina_side]), bool,
                                         len(retina_side))]]


def _split(nodes, detached, sector_deg):
    """Rim and interior nodes of a set of detached faces, and the faces that really open (those
    with an interior node; a face with all its nodes on the rim stays bonded)."""
    rim_edges = open_edges(detached)
    if sector_deg < 360.0:  # the cuts by the symmetry planes are not rim
        rim_edges = rim_edges[~np.all(on_cut_planes(nodes[rim_edges], sector_deg), axis=1)]
    rim = np.unique(rim_edges)
    return rim, np.setdiff1d(np.unique(detached), rim), detached[~np.all(np.isin(detached, rim), axis=1)]


def _cap_of_solid_angle(nodes, interface, face_centres, angle, extent, sector_deg):
    """Rim and interior nodes of the faces nearest to the centre whose solid angle (seen from the centre
    of the eye) is that of the cap: a staircase of element edges cannot be moved onto the cap's circle
    without collapsing the edges that cross it, so the cap keeps its area, not its exact outline."""
    inside = 1.0 if sector_deg == 360.0 else 0.5  # a wedge cuts the cap through its centre
    cap = 2 * np.pi * (1 - math.cos(extent)) * inside
    order = np.argsort(angle)
    solid = quad_areas(nodes, interface[order]) / np.sum(face_centres[order] ** 2, axis=1)
    guess = int(np.argmin(np.abs(np.cumsum(solid) - cap))) + 1
    best = None
    for count in range(max(1, guess - 8), guess + 9):
        rim, interior, opened = _split(nodes, interface[order[:count]], sector_deg)
        error = abs(np.sum(quad_areas(nodes, opened) / np.sum(nodes[opened].mean(axis=1) ** 2, axis=1)) - cap)
        if len(interior) and (best is None or error < best[0]):
            best = (error, rim, interior)
    if best is None or best[0] > cap:  # the smallest patch that opens is over twice the cap
        raise SceneError(_TOO_SMALL)
    _, rim, interior = best
    return rim, interior


def _move_rim_onto_cone(nodes, hexes, regions, rim, centre, extent):
    """The wall's nodes lie on lines through the centre of the eye: the lines of the rim's ring turn
    onto the cone of half-angle extent about ``centre``, which makes the rim the cap's circle (in place)."""
    wall = np.unique(hexes[np.isin(regions, ("sclera", "choroid", "retina"))])
    lines = cKDTree(unit(nodes[wall]))
    for direction in unit(nodes[rim]):
        on_line = wall[lines.query_ball_point(direction, 1e-9)]
        off_axis = unit(direction - (direction @ centre) * centre)
        nodes[on_line] = np.linalg.norm(nodes[on_line], axis=1)[:, None] * (
            math.cos(extent) * centre + math.sin(extent) * off_axis)


def _open_gap(nodes, hexes, regions, interior, gap):
    """The retina's nodes on the lines of the interior nodes move inward by the gap; those on the
    interface are copied first, the choroid keeps the originals. Returns the new nodes and hexahedra."""
    retina_hexes = regions == "retina"
    retina_nodes = np.unique(hexes[retina_hexes])
    directions = cKDTree(unit(nodes[interior]))
    distance, _ = directions.query(unit(nodes[retina_nodes]), distance_upper_bound=1e-9)
    moving = retina_nodes[np.isfinite(distance)]
    copy = np.full(len(nodes), -1)
    copy[interior] = len(nodes) + np.arange(len(interior))
    nodes = np.concatenate([nodes, nodes[interior]])
    retina = hexes[retina_hexes]
    hexes[retina_hexes] = np.where(copy[retina] >= 0, copy[retina], retina)
    moving = np.concatenate([np.setdiff1d(moving, interior), copy[interior]])
    nodes[moving] -= gap * unit(nodes[moving])
    return nodes, hexes

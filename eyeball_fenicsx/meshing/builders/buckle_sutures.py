"""The sutures that hold the scleral buckle of eyeball_fenicsx/meshing/builders/buckled_eye.py: their end points.

The seed's suture treatment ties the top edges of the buckle to points of the sclera beside it.
Here each suture is a string from a *sclera bite point* on the sclera's outer surface, at arc
length ``suture_width`` / 2 in front of or behind the buckle's centre line (the seed's "suture
width", wider than the buckle, so that the tightened strings press the buckle into the eye), to a
*buckle point*, a point of the top edge on the same side (front or back) of the sutured body: the
tire if there is one, else the band (the loop holds the point of the body's base under it against
sliding along the sclera: features/sutures.py says why the base). At each azimuth there are two
sutures, "front" and "back", as the two arms of a mattress suture. By default the bites are
``SUTURE_MARGIN`` = 1 mm beyond each edge of the widest body: mattress sutures are placed 1 mm
beyond each edge of the element, "so that the indent occurs when the buckle is tightened"
(Cybersight/Orbis, "Simulated surgery: placing the sutures for a scleral buckle": 9 mm apart for a
7 mm buckle).

A radial sponge (laid along the meridian) is tied across instead: at each of ``count`` polar
angles along its length, two sutures ("side_0" and "side_1", at its smaller and larger azimuth)
from bites on the sclera ``suture_width`` / 2 to either side of its middle azimuth (measured along
the sclera's circle of latitude) to the points of its top edges there.

Each end is the point itself, wherever the mesh's nodes are: the Suture feature ties the point
of its surface nearest to it, its motion interpolated from the element there
(``mechanics.solid.MaterialPoint``), so a suture is where the surgeon puts it on every mesh.

In a wedge model a suture on a cut plane is kept with ``share`` 1/2 (its mirror image holds the
other half): dropping it can leave the buckle with a single suture azimuth, whose two strings meet
the buckle in one meridian and leave it free to slide along the sclera before contact holds it (a
singular tangent).
"""
import math
from collections.abc import Sequence

import numpy as np

from ...errors import SceneError
from .buckle_placement import BuckleBody, BuckleLayout, buckle_layout
from .eye_meridian import LIMBUS_BLEND
from .hexes import check

SUTURE_MARGIN = 1.0
_SUTURE_SIDES = ("back", "front")


def suture_points(parameters: dict | None = None, count: int = 4, suture_width: float | None = None,
                  azimuth_deg: Sequence[float] | None = None) -> list[dict]:
    """Reference points of the buckle's sutures (see the module docstring for the convention).

    Args:
        parameters: the keyword arguments of :func:`buckled_eye.build_buckled_eye` (a dict; missing
            ones take their defaults).
        count: number of suture positions (along a radial sponge: see the module docstring); of
            suture azimuths over the whole eye: 360 (k + 1/2) / count degrees for a
            ring (45, 135, 225, 315 for 4: one in each oblique quadrant, between the rectus
            muscles), spread the same way over the arc of a segmental tire. In a wedge model
            those on a cut plane are kept at half share, those in the mirror image dropped.
        suture_width: distance between the two bites of a suture, measured along the sclera's
            meridian (default: the widest buckle body's footprint plus ``SUTURE_MARGIN`` on each
            side); it must exceed the widest body's footprint.
        azimuth_deg: explicit azimuths (degrees) instead of ``count`` (not for a radial sponge).

    The points lie on the smooth surfaces (the sclera's sphere of radius R_o, the body's edges);
    the Suture feature ties the nearest point of each surface's elements (the module docstring).

    Returns:
        A list of dicts, two per azimuth ("back" then "front"): {"name": "suture_<azimuth>_<side>",
        "azimuth_deg", "side", "share" (1, or 1/2 on a cut plane of a wedge), "sclera": bite point
        (x, y, z), "buckle": buckle point, "hold": the point of the buckle's base under it,
        "sclera_surface": "sclera_outer", "buckle_surface": "<body>_outer", "hold_surface":
        "<body>_inner"} -- ready for ``Suture(name, first=sclera, second=buckle, first_surface=...,
        second_surface=..., hold=..., hold_surface=...)``.
    """
    layout = buckle_layout(**(parameters or {}))
    body = layout.bodies[layout.sutured]
    if body.radial:
        if azimuth_deg is not None:
            raise SceneError("buckled_eye: a radial sponge's sutures cross it along its length: give their count, "
                             "not azimuths")
        return _across_sponge(layout, body, count, suture_width)
    half = _half_width(layout, suture_width)
    sector = math.radians(layout.eye["sector_deg"])
    wedge = sector < 2 * np.pi
    Ro, theta_c = layout.globe_radius, layout.centre_theta
    sutures = []
    for phi in _azimuths(layout, body, count, azimuth_deg):
        share = 0.5 if wedge and not 1e-9 < phi < sector - 1e-9 else 1.0  # on a cut plane: half in the wedge
        direction = np.array([math.cos(phi), math.sin(phi)])
        for side, sign in zip(_SUTURE_SIDES, (-1, 1)):
            bite, edge = theta_c + sign * half, body.theta[1 if sign > 0 else 0]
            sclera = Ro * np.array([*(math.sin(bite) * direction), -math.cos(bite)])
            edge_direction = np.array([*(math.sin(edge) * direction), -math.cos(edge)])
            degrees = round(math.degrees(phi), 9)
            sutures.append({"name": f"suture_{degrees:g}_{side}", "azimuth_deg": degrees, "side": side,
                            "share": share, "sclera": tuple(sclera.tolist()), **_edge(body, edge_direction)})
    return sutures


def _across_sponge(layout: BuckleLayout, body: BuckleBody, count, suture_width):
    """The sutures of a radial sponge: ``count`` pairs across it, spread along its length."""
    check("buckled_eye", "count", count, "positive integer")
    Ro = layout.globe_radius
    width = Ro * (body.azimuths[-1] - body.azimuths[0]) * math.sin(layout.centre_theta)
    if suture_width is None:
        suture_width = width + 2 * SUTURE_MARGIN
    check("buckled_eye", "suture_width", suture_width, "positive number")
    if not suture_width > width:
        raise SceneError(f"buckled_eye: suture_width {suture_width} must exceed the sponge's width {width:.3f} mm "
                         "on the sclera")
    middle = math.radians(body.azimuth_deg)
    sutures = []
    for theta in body.theta[0] + (body.theta[1] - body.theta[0]) * (np.arange(count) + 0.5) / count:
        half = suture_width / 2 / (Ro * math.sin(theta))
        for side, sign, edge in zip(("side_0", "side_1"), (-1, 1), (body.azimuths[0], body.azimuths[-1])):
            bite = middle + sign * half
            sclera = Ro * np.array([math.sin(theta) * math.cos(bite), math.sin(theta) * math.sin(bite),
                                    -math.cos(theta)])
            edge_direction = np.array([math.sin(theta) * math.cos(edge), math.sin(theta) * math.sin(edge),
                                       -math.cos(theta)])
            sutures.append({"name": f"suture_{math.degrees(theta):.4g}_{side}", "azimuth_deg": body.azimuth_deg,
                            "polar_deg": math.degrees(theta), "side": side, "share": 1.0,
                            "sclera": tuple(sclera.tolist()), **_edge(body, edge_direction)})
    return sutures


def _edge(body: BuckleBody, direction: np.ndarray) -> dict:
    """The buckle's end of a suture on the edge of the body seen from the origin along ``direction``
    (a unit vector): its top edge ("buckle", on the outer surface), and under it the base that the
    loop holds against sliding ("hold", on the inner surface: features/sutures.py)."""
    return {"buckle": tuple((body.outer_radius * direction).tolist()),
            "hold": tuple((body.inner_radius * direction).tolist()),
            "sclera_surface": "sclera_outer", "buckle_surface": f"{body.name}_outer",
            "hold_surface": f"{body.name}_inner"}


def _half_width(layout: BuckleLayout, suture_width):
    """Half the distance between the bites of a suture, as an angle (rad), checked; by default the
    bites are ``SUTURE_MARGIN`` beyond the edges of the widest body."""
    Ro, theta_c = layout.globe_radius, layout.centre_theta
    footprint = max(Ro * (b.theta[1] - b.theta[0]) for b in layout.bodies.values())
    if suture_width is None:
        suture_width = footprint + 2 * SUTURE_MARGIN
    check("buckled_eye", "suture_width", suture_width, "positive number")
    if not suture_width > footprint:
        raise SceneError(f"buckled_eye: suture_width {suture_width} must exceed the buckle's footprint "
                         f"{footprint:.3f} mm on the sclera")
    half = suture_width / 2 / Ro
    if Ro * (theta_c - half) < layout.nerve_arc or Ro * (theta_c + half) > layout.limbus_arc - LIMBUS_BLEND:
        raise SceneError(f"buckled_eye: suture_width {suture_width} puts a bite off the spherical sclera")
    return half


def _azimuths(layout: BuckleLayout, body: BuckleBody, count, azimuth_deg):
    """The suture azimuths in the model (rad), each inside the sutured body's arc; in a wedge, those
    of its mirror image left out."""
    if azimuth_deg is None:
        check("buckled_eye", "count", count, "positive integer")
        fractions = (np.arange(count) + 0.5) / count
        # Over the whole eye: a ring, or the whole arc of a segmental tire (mirrored in a wedge).
        azimuth_deg = body.azimuth_deg + body.arc_deg * (fractions - 0.5) if body.arc_deg < 360.0 \
            else 360.0 * fractions
    azimuths, sector = [], math.radians(layout.eye["sector_deg"])
    for phi in np.radians(np.asarray(azimuth_deg, dtype=float)) % (2 * np.pi):
        phi = 0.0 if phi > 2 * np.pi - 1e-9 else float(phi)
        if sector < 2 * np.pi and not phi <= sector + 1e-9:
            continue  # in the mirror image of the wedge
        off_middle = abs(np.angle(np.exp(1j * (phi - math.radians(body.azimuth_deg)))))
        if body.arc_deg < 360.0 and off_middle > math.radians(body.arc_deg) / 2 + 1e-9:
            raise SceneError(f"buckled_eye: no suture at azimuth {math.degrees(phi):.1f} deg, outside the tire")
        if all(abs(phi - other) > 1e-9 for other in azimuths):
            azimuths.append(phi)
    return azimuths

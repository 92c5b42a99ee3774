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

Each end is where the surgeon puts it, wherever the mesh's nodes are: the Suture feature ties the
point of its surface nearest to each of its points, its motion interpolated from the element there
(``mechanics.solid.MaterialPoint``). And it is a *bite*, not a point: the thread passes through the
sclera along the buckle's edge (along the circle of latitude; along the meridian beside a radial
sponge) and pulls that whole pass, so each end is spread evenly over ``bite`` mm there
(``BITE_LENGTH`` by default; points ``BITE_SPACING`` apart), and the knot's end over the same arc of
the buckle's top edge, which the loop's two crossings span. A point force would not do: a
continuum's displacement under one has no limit as the mesh is refined, and with point ends the
segmental tire's indentation moved by a third between meshes and did not settle (README, "Sutures
where the surgeon puts them"). A bite is at most as long as the arc between neighbouring sutures, so
that two never overlap, and is cut at the ends of a tire and at a wedge's cut planes. A suture on a
cut plane, at half share, spreads over the half of its bite in the model, so its string runs from
that half's mean, off the plane (across it, 4-5 % of the tension): such a half model is close to,
not exactly, half of the whole eye (no shipped scene has one). ``BITE_LENGTH`` = 3 mm
is our choice, not a published figure: we found none in the sources we could read; a scene sets its
own (``[buckle_sutures] bite``; 0 ties each end at its point, for comparison).

The sclera between a bite and the buckle's edge, 1 mm wide with the usual margin, bends as the
sutures pull the buckle in, and an eye with the usual 0.8 mm elements along the meridian is too
stiff there: it overstated a segmental tire's indentation by about 45 % (README, "The eye graded
around the sutures"). So where the sutures alone push the buckle in (a tire without an encircling
band; with a band, the band's tightening does), the eye is graded along the meridian at the edges
of the body on the sclera and at the bites' circles of latitude
(:func:`suture_grading`, the eye's ``graded_at``; ``[mesh] graded`` in a scene). Beside a radial
sponge the strip between its side and the bites runs along the meridian, so the eye is graded
across the meridians instead, at the sponge's sides and the bites' meridians (the eye's
``graded_azimuths``), only from ``GRADED_MARGIN`` in front of the sponge to as far behind it (the
eye's ``graded_between``; its azimuths coarsen beyond, eye_revolution.py).

In a wedge model a suture on a cut plane is kept with ``share`` 1/2 (its mirror image holds the
other half): dropping it can leave the buckle with a single suture azimuth, whose two strings meet
the buckle in one meridian and leave it free to slide along the sclera before contact holds it (a
singular tangent).
"""
import math
from collections.abc import Sequence

import numpy as np

from ...checks import is_number
from ...errors import SceneError
from .buckle_placement import BuckleBody, BuckleLayout, buckle_layout
from .eye_meridian import LIMBUS_BLEND
from .hexes import check

SUTURE_MARGIN = 1.0
BITE_LENGTH = 3.0  # mm along the sclera: our choice, not a published figure (the module docstring)
BITE_SPACING = 0.1  # mm between the points a bite's load is spread over
GRADED_MARGIN = 2.0  # mm along the meridian beyond a radial sponge and its bites that the eye stays graded around it
_SUTURE_SIDES = ("back", "front")


def suture_points(parameters: dict | None = None, count: int = 4, suture_width: float | None = None,
                  azimuth_deg: Sequence[float] | None = None, bite: float = BITE_LENGTH) -> list[dict]:
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
        bite: the length of each bite along the sclera (mm), see the module docstring.

    The points lie on the smooth surfaces (the sclera's sphere of radius R_o, the body's edges);
    the Suture feature ties the nearest point of each surface's elements (the module docstring).

    Returns:
        A list of dicts, two per azimuth ("back" then "front"): {"name": "suture_<azimuth>_<side>",
        "azimuth_deg", "side", "share" (1, or 1/2 on a cut plane of a wedge), "sclera": bite point
        (x, y, z), "buckle": buckle point, "hold": the point of the buckle's base under it,
        "sclera_surface": "sclera_outer", "buckle_surface": "<body>_outer", "hold_surface":
        "<body>_inner", "sclera_bite" and "buckle_bite": the points each end is spread over, around
        "sclera" and "buckle"} -- ready for ``Suture(name, first=sclera_bite, second=buckle_bite,
        first_surface=..., second_surface=..., hold=..., hold_surface=...)``.
    """
    layout = buckle_layout(**(parameters or {}))
    body = layout.bodies[layout.sutured]
    if body.radial:
        if azimuth_deg is not None:
            raise SceneError("buckled_eye: a radial sponge's sutures cross it along its length: give their count, "
                             "not azimuths")
        return _across_sponge(layout, body, count, suture_width, bite)
    half = _half_width(layout, suture_width)
    sector = math.radians(layout.eye["sector_deg"])
    wedge = sector < 2 * np.pi
    Ro, theta_c = layout.globe_radius, layout.centre_theta
    azimuths = _azimuths(layout, body, count, azimuth_deg)
    neighbours, low, high = _bite_range(body, azimuths, sector)
    sutures = []
    for phi in azimuths:
        share = 0.5 if wedge and not 1e-9 < phi < sector - 1e-9 else 1.0  # on a cut plane: half in the wedge
        # the bite's middle taken to the range of its limits (a tire across azimuth 0)
        middle = phi if low is None else _near(phi, 0.5 * (low + high))
        for side, sign in zip(_SUTURE_SIDES, (-1, 1)):
            bite_theta, edge = theta_c + sign * half, body.theta[1 if sign > 0 else 0]
            latitude = Ro * math.sin(bite_theta)  # the radius of the bite's circle of latitude
            spread = _spread(middle, _bite_span(bite, neighbours, latitude), latitude, low, high)
            degrees = round(math.degrees(phi), 9)
            sutures.append({"name": f"suture_{degrees:g}_{side}", "azimuth_deg": degrees, "side": side,
                            "share": share, "sclera": tuple(_on_sphere(Ro, bite_theta, phi).tolist()),
                            **_edge(body, _on_sphere(1.0, edge, phi)),
                            "sclera_bite": _on_sphere(Ro, bite_theta, spread).tolist(),
                            "buckle_bite": _on_sphere(body.outer_radius, edge, spread).tolist()})
    return sutures


def suture_grading(parameters: dict | None = None, sutures: list[dict] | None = None,
                   graded: bool | None = None) -> dict:
    """The eye's grading for the sutures (the module docstring says why): the eye parameters to add
    to ``parameters``. For a tire or a band, ``graded_at`` (:func:`eye.build_eye`, mm behind the
    limbus): the circles of latitude of the body's edges on the sclera and of the sutures' bites.
    For a radial sponge, ``graded_azimuths`` (degrees): the meridians of its sides and of the bites;
    and ``graded_between``: those azimuths only from ``GRADED_MARGIN`` in front of the sponge and its
    bites to as far behind them (mm behind the limbus), coarser away from there.

    Args:
        parameters: as :func:`suture_points`.
        sutures: the sutures, as :func:`suture_points` gives them (by default its defaults').
        graded: grade the mesh; by default, when the sutures alone push the buckle in: a tire or a
            sponge without an encircling band (a band's tightening does it with a band).

    Returns:
        ``{}`` if not graded, else ``{"graded_at": [...]}`` or ``{"graded_azimuths": [...],
        "graded_between": [front, back]}``.
    """
    layout = buckle_layout(**(parameters or {}))
    body = layout.bodies[layout.sutured]  # the body on the sclera
    if graded is None:
        graded = "band" not in layout.bodies
    if not graded:
        return {}
    bites = np.array([suture["sclera"] for suture in (suture_points(parameters) if sutures is None else sutures)])
    thetas = np.array([*body.theta, *np.arccos(-bites[:, 2] / np.linalg.norm(bites, axis=1))])
    behind = layout.limbus_arc - layout.globe_radius * thetas  # mm behind the limbus
    if body.radial:
        lines = np.degrees([*body.azimuths[[0, -1]], *np.arctan2(bites[:, 1], bites[:, 0])])
        return {"graded_azimuths": _distinct(lines),
                "graded_between": [float(behind.min() - GRADED_MARGIN), float(behind.max() + GRADED_MARGIN)]}
    return {"graded_at": _distinct(behind)}


def _distinct(values) -> list[float]:
    """The values sorted, each of those within 1e-9 of the one before dropped (a suture's bites repeat
    their circle or meridian)."""
    values = np.sort(values)
    return [float(v) for v in values[np.append(True, np.diff(values) > 1e-9)]]


def _across_sponge(layout: BuckleLayout, body: BuckleBody, count, suture_width, bite):
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
    thetas = body.theta[0] + (body.theta[1] - body.theta[0]) * (np.arange(count) + 0.5) / count
    span = _bite_span(bite, thetas, Ro)  # the bites run along the meridian, beside the sponge's sides
    sutures = []
    for theta in thetas:
        half = suture_width / 2 / (Ro * math.sin(theta))
        spread = _spread(theta, span, Ro, *body.theta)
        for side, sign, edge in zip(("side_0", "side_1"), (-1, 1), (body.azimuths[0], body.azimuths[-1])):
            bite_phi = middle + sign * half
            sutures.append({"name": f"suture_{math.degrees(theta):.4g}_{side}", "azimuth_deg": body.azimuth_deg,
                            "polar_deg": math.degrees(theta), "side": side, "share": 1.0,
                            "sclera": tuple(_on_sphere(Ro, theta, bite_phi).tolist()),
                            **_edge(body, _on_sphere(1.0, theta, edge)),
                            "sclera_bite": _on_sphere(Ro, spread, bite_phi).tolist(),
                            "buckle_bite": _on_sphere(body.outer_radius, spread, edge).tolist()})
    return sutures


def _on_sphere(radius, polar, azimuth) -> np.ndarray:
    """Points of the sphere of ``radius`` about the origin at polar angles from the -z axis and azimuths
    (rad; either may be an array)."""
    polar, azimuth = np.broadcast_arrays(polar, azimuth)
    return radius * np.stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), -np.cos(polar)],
                             axis=-1)


def _edge(body: BuckleBody, direction: np.ndarray) -> dict:
    """The buckle's end of a suture on the edge of the body seen from the origin along ``direction``
    (a unit vector): its top edge ("buckle", on the outer surface), and under it the base that the
    loop holds against sliding ("hold", on the inner surface: features/sutures.py)."""
    return {"buckle": tuple((body.outer_radius * direction).tolist()),
            "hold": tuple((body.inner_radius * direction).tolist()),
            "sclera_surface": "sclera_outer", "buckle_surface": f"{body.name}_outer",
            "hold_surface": f"{body.name}_inner"}


def _near(angle, centre) -> float:
    """The angle (rad) equal to ``angle`` modulo 2 pi that lies within pi of ``centre``."""
    return centre + float(np.angle(np.exp(1j * (angle - centre))))


def _bite_range(body: BuckleBody, azimuths, sector):
    """The azimuths a bite must not overlap (a wedge's mirror images among them) and the range
    [low, high] a bite stays in: the tire's arc, the wedge, or (None, None) on a whole ring."""
    azimuths = np.asarray(azimuths)
    wedge = sector < 2 * np.pi
    neighbours = np.concatenate([azimuths, -azimuths, 2 * sector - azimuths]) if wedge else azimuths
    low, high = (body.azimuths[0], body.azimuths[-1]) if body.arc_deg < 360.0 else (0.0, sector) if wedge \
        else (None, None)
    return neighbours, low, high


def _bite_span(bite, angles, radius) -> float:
    """Half a bite's span as an angle (rad) on a circle of ``radius``: ``bite`` long, or shorter where the
    neighbouring sutures' ``angles`` (rad, their mirror images in a wedge among them) are closer, so
    that two bites never overlap."""
    if not (is_number(bite) and bite >= 0):
        raise SceneError(f"buckled_eye: bite must be a nonnegative number (0: a point), got {bite!r}")
    every = np.unique(np.mod(angles, 2 * np.pi).round(12))  # a suture on a cut plane is its own mirror image
    closest = np.diff(np.concatenate([every, every[:1] + 2 * np.pi])).min() if len(every) > 1 else 2 * np.pi
    return 0.5 * min(bite / radius, closest)


def _spread(middle, half, radius, low=None, high=None) -> np.ndarray:
    """The angles (rad) of the points a bite from ``middle - half`` to ``middle + half`` on a circle of
    ``radius`` is spread over, its span cut to [low, high]: the midpoints of equal pieces at most
    ``BITE_SPACING`` long."""
    start, end = middle - half, middle + half
    start, end = (start if low is None else max(start, low)), (end if high is None else min(end, high))
    pieces = max(1, math.ceil((end - start) * radius / BITE_SPACING - 1e-9))  # 3 mm: 30 pieces, not 31
    return start + (end - start) * (np.arange(pieces) + 0.5) / pieces


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
        middle = math.radians(body.azimuth_deg)
        if body.arc_deg < 360.0 and abs(_near(phi, middle) - middle) > math.radians(body.arc_deg) / 2 + 1e-9:
            raise SceneError(f"buckled_eye: no suture at azimuth {math.degrees(phi):.1f} deg, outside the tire")
        if all(abs(phi - other) > 1e-9 for other in azimuths):
            azimuths.append(phi)
    return azimuths

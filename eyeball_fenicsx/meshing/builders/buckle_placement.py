"""Where the scleral buckle of eyeball_fenicsx/meshing/builders/buckled_eye.py lies: its bodies' shapes on the sclera.

As in eyeball_fenicsx/meshing/builders/eye.py the optic axis is z, the corneal apex at +z, the origin
the centre of the sclera, whose outer surface is the sphere of radius R_o from the optic nerve to
the limbus. The buckle lies on that sphere; a point of it is given by its polar angle theta measured
from the posterior pole (z = -r cos theta, rho = r sin theta), and its azimuth phi from the x axis.

* The buckle's centre line is the circle at arc length ``band_position`` behind the limbus on the
  sclera's outer surface: theta_c = (s_l - band_position) / R_o, s_l the arc length of the limbus
  from the posterior pole.
* Each body is a spherical shell zone r_in <= r <= r_out, |theta - theta_c| <= w / (2 r_in): its
  meridional width ``w`` is measured on its inner surface, its section is bounded by radial lines.
  Its inner surface follows the outer surface of the body under it, offset by ``gap``: the
  sclera's outer surface (r_in = R_o + gap), or the tire's (r_in = R_o + gap + height + gap for a
  band on a tire). As the sclera's, its nodes are on the azimuths 2 pi k / n_circ, so its facets
  are parallel to the sclera's and the clearance is ``gap`` everywhere, give or take the sag
  h^2 / 8R < 0.007 mm of the meridional chords (h the meridional element size).
* The band: ``n_band_width`` x ``n_band_thick`` elements in the meridian. The tire: elements of
  about the band's size, at least as many. A segmental tire (``arc_deg`` < 360) spans the azimuths
  ``azimuth_deg`` +- ``arc_deg`` / 2: its nodes are the eye's azimuths inside the arc and the two
  ends (the eye's azimuths within a quarter sector of an end are dropped).
* With a segmental tire the band is not built unless asked (``band=True``); asked, it is the same
  ring all around, resting on the tire where the tire is and standing height + gap clear of the
  sclera elsewhere (tightening brings it down).
* A radial sponge (``sponge``) is a segmental element laid along the meridian instead: a shell
  zone of ``length`` along the meridian (on its inner surface), centred on the centre line, over
  the azimuths ``azimuth_deg`` +- half its ``width`` (measured on its inner surface at the centre
  line), ``height`` thick, with ``n_width`` x ``n_length`` x ``n_height`` elements. It rests on
  the sclera alone (no band, no tire), in a whole eye (a wedge would mirror it).
* A detachment given without its centre is centred under the buckle: on the centre line, and at
  the azimuth of a segmental tire or a sponge.
* The whole buckle must rest on the spherical sclera, between the optic nerve and the limbal blend
  of eye_meridian.py; behind the equator of an eye longer than 24 mm the sclera is outside the
  sphere R_o (eye_meridian.py), and the buckle must clear it there. In a wedge model a segmental
  tire must be centred on a cut plane.

Sources of the defaults (beside each constant): the band's position (J. Ophthalmol. 2016, article
3578617; an ARVO abstract, IOVS article 2745536) and its width (Read & Hahn, "Pearls for scleral
buckling with tunnels", Retina Specialist).
"""
import dataclasses
import inspect
import math

import numpy as np

from ...checks import is_number
from ...errors import SceneError
from .eye import checked_parameters, eye_geometry
from .eye_azimuths import node_azimuths
from .eye_meridian import LIMBUS_BLEND
from .hexes import check

# An encircling element is secured to the sclera 12-13 mm behind the limbus (J. Ophthalmol. 2016, article
# 3578617, a finite element study of the encircling band's width); an FE study of the band's position took
# 11.5 (anterior), 12.6 (equatorial), 13.7 and 14.8 mm (posterior) behind the limbus (ARVO abstract, IOVS,
# iovs.arvojournals.org article 2745536). In the default eye of eyeball_fenicsx/meshing/builders/eye.py the
# equator is 12.95 mm behind the limbus.
BAND_POSITION = 12.5
# A 240 band is 2.5 mm wide; a 41 band 3.5 mm, a 42 band 4 mm (Read & Hahn, "Pearls for scleral buckling
# with tunnels", Retina Specialist). 0.6 mm: the thickness of the band in eyeball_fenicsx/meshing/builders/band.py.
BAND_WIDTH, BAND_THICKNESS = 2.5, 0.6
GAP = 0.02
TIRE = {"width": 4.0, "height": 1.0, "arc_deg": 360.0, "azimuth_deg": 0.0}
_TIRE_KEYS = ("width", "height", "arc_deg", "azimuth_deg", "n_width", "n_height")
# A radial sponge: 5 mm wide, 2 mm high, 10 mm long (round figures of the size of a radial element laid
# over a single break, a few mm wider than a 4 mm tire); its elements about the band's, at least 4 x 8 x 2.
SPONGE = {"width": 5.0, "height": 2.0, "length": 10.0, "azimuth_deg": 0.0}
_SPONGE_KEYS = ("width", "height", "length", "azimuth_deg", "n_width", "n_height", "n_length")


@dataclasses.dataclass
class BuckleBody:
    """One body of the buckle: a spherical shell zone, revolved over ``azimuths``.

    Attributes:
        name: "band", "tire" or "sponge" (its volume group, and the prefix of its surfaces).
        inner_radius, outer_radius: radii of its inner and outer surfaces (mm).
        theta: polar angles (rad, from the posterior pole) of its back and front faces.
        azimuths: azimuths of its node planes (rad), increasing.
        closed: a whole ring (periodic in azimuth).
        end_names: surface names of its faces at the first and the last azimuth (open bodies).
        n_width, n_thick: elements along the meridian and through the thickness.
        radial: laid along the meridian (a radial sponge): its sutures cross it in azimuth.
        arc_deg, azimuth_deg: its azimuthal extent over the whole eye (360 for a ring) and the
            azimuth of its middle.
    """

    name: str
    inner_radius: float
    outer_radius: float
    theta: tuple
    azimuths: np.ndarray
    closed: bool
    end_names: tuple
    n_width: int
    n_thick: int
    arc_deg: float = 360.0
    azimuth_deg: float = 0.0
    radial: bool = False

    def volume(self) -> float:
        """Volume of the smooth shell zone (mm^3): (1/3)(r_out^3 - r_in^3)(cos theta_back - cos theta_front)
        times its azimuthal span (the integral of r^2 sin theta over the zone, the difference of spherical
        sectors (2 pi / 3) r^3 (1 - cos theta))."""
        span = 2 * math.pi if self.closed else self.azimuths[-1] - self.azimuths[0]
        return span / 3 * (self.outer_radius**3 - self.inner_radius**3) * (math.cos(self.theta[0])
                                                                           - math.cos(self.theta[1]))


@dataclasses.dataclass
class BuckleLayout:
    """Where the buckle is (see the module docstring).

    Attributes:
        eye: the eye's parameters (all of them, with their defaults).
        globe_radius: R_o, the radius of the sclera's outer surface (mm).
        limbus_arc: s_l, arc length of the limbus from the posterior pole on the sclera (mm).
        nerve_arc: arc length of the optic nerve's edge from the posterior pole (mm).
        centre_theta: theta_c (rad).
        bodies: "tire" and/or "band", or "sponge" -> :class:`BuckleBody`, from the sclera outward.
        sutured: the body that :func:`buckle_sutures.suture_points` ties (the sponge or the tire if there is
            one, else "band").
        detachment: the detachment passed to the eye (its polar angle filled in), or None.
    """

    eye: dict
    globe_radius: float
    limbus_arc: float
    nerve_arc: float
    centre_theta: float
    bodies: dict
    sutured: str
    detachment: dict


def _eye_parameters(eye_parameters):
    """The eye's parameters with its defaults, checked; and its meridian."""
    defaults = {name: parameter.default for name, parameter in inspect.signature(eye_geometry).parameters.items()}
    unknown = sorted(set(eye_parameters) - set(defaults))
    if unknown:
        raise SceneError(f"buckled_eye: unknown parameter(s) {', '.join(unknown)}")
    return checked_parameters({**defaults, **eye_parameters})


def _arc_azimuths(n_circ, start, stop):
    """Node azimuths of an arc [start, stop] (rad): its ends and the eye's azimuths between them, but
    those within a quarter sector of an end."""
    step = 2 * np.pi / n_circ
    k = np.arange(math.ceil(start / step - 1e-9), math.floor(stop / step + 1e-9) + 1)
    between = k * step
    between = between[(between - start > 0.25 * step) & (stop - between > 0.25 * step)]
    return np.concatenate([[start], between, [stop]])


def _checked_body(name, given, defaults, keys, sizes):
    """A buckle body's table (a tire, a sponge) over its defaults: known keys, positive sizes, a
    numeric azimuth and positive element counts (the keys starting with "n_")."""
    if not isinstance(given, dict) or set(given) - set(keys):
        raise SceneError(f"buckled_eye: {name} must be None or a table with keys among {', '.join(keys)}, "
                         f"got {given!r}")
    body = {**defaults, **given}
    for key in sizes:
        check("buckled_eye", f"{name} {key}", body[key], "positive number")
    if not is_number(body["azimuth_deg"]):
        raise SceneError(f"buckled_eye: {name} azimuth_deg must be a number, got {body['azimuth_deg']!r}")
    for key in keys:
        if key.startswith("n_") and key in body:
            check("buckled_eye", f"{name} {key}", body[key], "positive integer")
    return body


def _check_tire(tire, sector_deg):
    tire = _checked_body("tire", tire, TIRE, _TIRE_KEYS, ("width", "height", "arc_deg"))
    if tire["arc_deg"] > 360.0:
        raise SceneError(f"buckled_eye: tire arc_deg must be at most 360, got {tire['arc_deg']}")
    if tire["arc_deg"] < 360.0 and sector_deg < 360.0:
        centre = tire["azimuth_deg"] % 360.0
        on_cut = min(abs(centre), abs(centre - 360.0)) < 1e-9 or abs(centre - sector_deg) < 1e-9
        if not on_cut or tire["arc_deg"] / 2 >= sector_deg:
            raise SceneError("buckled_eye: a wedge model is mirrored across its cut planes, so a segmental tire must "
                             f"be centred on one (azimuth_deg 0 or {sector_deg:g}) with arc_deg / 2 below "
                             f"sector_deg, got azimuth_deg {tire['azimuth_deg']}, arc_deg {tire['arc_deg']}")
    return tire


def _check_sponge(sponge, sector_deg, tire, band):
    sponge = _checked_body("sponge", sponge, SPONGE, _SPONGE_KEYS, ("width", "height", "length"))
    if sector_deg < 360.0:
        raise SceneError(f"buckled_eye: a radial sponge needs the whole eye (sector_deg = 360), got sector_deg "
                         f"{sector_deg:g}: a wedge would mirror it")
    if tire is not None or band:
        raise SceneError("buckled_eye: a radial sponge rests on the sclera alone: give no tire and no band = true")
    return sponge


def _sponge(sponge, inner, theta_c, element):
    """The radial sponge, its inner surface of radius ``inner``; ``element`` the band's element size."""
    half_length = sponge["length"] / (2 * inner)
    half_width = sponge["width"] / (2 * inner * math.sin(theta_c))
    if half_width >= 0.25 * math.pi:
        raise SceneError(f"buckled_eye: the sponge's width {sponge['width']} mm spans half the eye's azimuths or more")
    n_width = int(sponge.get("n_width", max(4, round(sponge["width"] / element))))
    n_length = int(sponge.get("n_length", max(8, round(sponge["length"] / element))))
    n_height = int(sponge.get("n_height", max(2, round(sponge["height"] / element))))
    middle = math.radians(sponge["azimuth_deg"])
    azimuths = np.linspace(middle - half_width, middle + half_width, n_width + 1)
    return BuckleBody("sponge", inner, inner + sponge["height"], (theta_c - half_length, theta_c + half_length),
                      azimuths, False, ("sponge_side_0", "sponge_side_1"), n_length, n_height,
                      math.degrees(2 * half_width), float(sponge["azimuth_deg"]), radial=True)


def buckle_layout(band_width: float = BAND_WIDTH, band_thickness: float = BAND_THICKNESS,
                  band_position: float = BAND_POSITION, tire: dict | None = None, gap: float = GAP,
                  n_band_thick: int = 2, n_band_width: int = 4, band: bool | None = None,
                  sponge: dict | None = None, **eye_parameters) -> BuckleLayout:
    """Where the buckle's bodies are, without meshing (see :func:`build_buckled_eye` for the parameters).

    Returns:
        A :class:`BuckleLayout`.

    Raises:
        SceneError: if a parameter is invalid or the buckle does not fit on the sclera.
    """
    for name, value in (("band_width", band_width), ("band_thickness", band_thickness),
                        ("band_position", band_position), ("gap", gap)):
        check("buckled_eye", name, value, "positive number")
    for name, value in (("n_band_thick", n_band_thick), ("n_band_width", n_band_width)):
        check("buckled_eye", name, value, "positive integer")
    if band not in (None, True, False):
        raise SceneError(f"buckled_eye: band must be true, false or omitted, got {band!r}")
    p, m = _eye_parameters(eye_parameters)
    sector, n_circ = p["sector_deg"], p["n_circ"]
    if sponge is not None:
        sponge = _check_sponge(sponge, sector, tire, band)
    if tire is not None:
        tire = _check_tire(tire, sector)
    segmental = sponge is not None or tire is not None and tire["arc_deg"] < 360.0
    if band is None:
        band = not segmental
    if not band and tire is None and sponge is None:
        raise SceneError("buckled_eye: without the band there must be a tire or a sponge")
    if len(p["graded_azimuths"]) and (band or tire is not None):
        raise SceneError("buckled_eye: graded_azimuths grades the eye around a radial sponge; a tire or a band lies "
                         "on the eye's even azimuths")
    Ro, theta_c = m.Ro, (m.s_l - band_position) / m.Ro
    grid = node_azimuths(n_circ, sector)
    whole = sector >= 360.0
    ring_ends = () if whole else ("cut_0", "cut_1")
    bodies = {}
    radius = Ro
    if sponge is not None:
        bodies["sponge"] = _sponge(sponge, radius + gap, theta_c, band_width / n_band_width)
    if tire is not None:
        n_width = tire.get("n_width", max(n_band_width, round(tire["width"] / (band_width / n_band_width))))
        n_thick = tire.get("n_height", max(n_band_thick, round(tire["height"] / (band_thickness / n_band_thick))))
        bodies["tire"] = _tire(tire, radius + gap, theta_c, n_width, n_thick, n_circ, sector, grid, ring_ends)
        radius = bodies["tire"].outer_radius
    if band:
        inner = radius + gap
        half = band_width / (2 * inner)
        if tire is not None and half > bodies["tire"].theta[1] - theta_c + 1e-12:
            raise SceneError(f"buckled_eye: the band ({band_width} mm) must not be wider than the tire it rests on "
                             f"({tire['width']} mm)")
        bodies["band"] = BuckleBody("band", inner, inner + band_thickness, (theta_c - half, theta_c + half),
                                    grid, whole, ring_ends, n_band_width, n_band_thick)
    _check_fit(bodies, m, band_position)
    sutured = next(name for name in ("sponge", "tire", "band") if name in bodies)
    return BuckleLayout(eye=p, globe_radius=Ro, limbus_arc=m.s_l, nerve_arc=m.s_nerve, centre_theta=theta_c,
                        bodies=bodies, sutured=sutured, detachment=_under_buckle(p.pop("detachment"), bodies, theta_c))


def _under_buckle(detachment, bodies, theta_c):
    """A detachment given without its centre, centred under the buckle: on its centre line, and at the
    azimuth of a segmental body (that of a given ``azimuth_deg`` kept)."""
    if not isinstance(detachment, dict) or "polar_deg" in detachment:
        return detachment
    segmental = [body for body in bodies.values() if body.arc_deg < 360.0]
    azimuth = {"azimuth_deg": segmental[0].azimuth_deg} if segmental else {}
    return {**azimuth, **detachment, "polar_deg": math.degrees(theta_c)}


def _tire(tire, inner, theta_c, n_width, n_thick, n_circ, sector, grid, ring_ends):
    """The tire, its inner surface of radius ``inner``; a ring has the eye's node azimuths ``grid``
    and, in a wedge model, the end faces ``ring_ends``."""
    half = tire["width"] / (2 * inner)
    if not tire["arc_deg"] < 360.0:
        azimuths, closed, ends = grid, sector >= 360.0, ring_ends
    else:
        centre, arc = math.radians(tire["azimuth_deg"]), math.radians(tire["arc_deg"])
        if sector >= 360.0:
            start = centre - arc / 2
            azimuths, ends = _arc_azimuths(n_circ, start, start + arc), ("tire_end_0", "tire_end_1")
        elif abs(math.remainder(tire["azimuth_deg"], 360.0)) < 1e-9:  # centred on cut_0
            azimuths, ends = _arc_azimuths(n_circ, 0.0, arc / 2), ("cut_0", "tire_end_1")
        else:  # centred on cut_1
            top = math.radians(sector)
            azimuths, ends = _arc_azimuths(n_circ, top - arc / 2, top), ("tire_end_0", "cut_1")
        closed = False
    return BuckleBody("tire", inner, inner + tire["height"], (theta_c - half, theta_c + half), azimuths, closed, ends,
                      int(n_width), int(n_thick), float(tire["arc_deg"]), float(tire["azimuth_deg"]))


def _check_fit(bodies, m, band_position):
    """The whole buckle must rest on the spherical sclera, between the optic nerve and the limbal blend."""
    back = min(body.theta[0] for body in bodies.values()) * m.Ro
    front = max(body.theta[1] for body in bodies.values()) * m.Ro
    limit = m.s_l - LIMBUS_BLEND
    if back < m.s_nerve or front > limit:
        raise SceneError(f"buckled_eye: the buckle must rest on the sclera between {m.s_l - m.s_nerve:.1f} and "
                         f"{LIMBUS_BLEND} mm behind the limbus, but it spans {m.s_l - back:.2f} to "
                         f"{m.s_l - front:.2f} mm (band_position {band_position})")
    for body in bodies.values():  # behind the equator a long eye's sclera is outside the sphere R_o
        reach = float(np.max(m.radius(np.linspace(*body.theta, 50))))
        if reach >= body.inner_radius:
            raise SceneError(f"buckled_eye: the {body.name} would cut into the sclera behind the equator of "
                             f"this {m.p['axial_length']} mm eye (the sclera reaches radius {reach:.3f} mm under it, "
                             f"its inner surface is at {body.inner_radius:.3f} mm): move it forward "
                             f"(band_position {band_position})")

"""The eye of eyeball_fenicsx/meshing/builders/eye.py with a scleral buckle: an encircling silicone band, a silicone tire, or both.

One gmsh model holds the eye (its tissues, surfaces and optional retinal detachment, unchanged) and
the buckle's bodies, all 8-node hexahedra. The buckle does not share a single node with the eye:
each body is its own mesh, a small clearance ``gap`` away from the body under it, so that contact
(eyeball_fenicsx/contact/) closes the gap and carries the load.

**Geometry.** As in eyeball_fenicsx/meshing/builders/eye.py the optic axis is z, the corneal apex at +z, the origin the
centre of the sclera, whose outer surface is the sphere of radius R_o from the optic nerve to the
limbus. The buckle lies on that sphere; a point of it is given by its polar angle theta measured
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

Physical groups: the eye's volumes and surfaces (eyeball_fenicsx/meshing/builders/eye.py), then the volumes "tire" and
"band" and their surfaces "tire_inner", "tire_outer", "tire_front" (toward the cornea),
"tire_back" (toward the posterior pole), "tire_end_0" and "tire_end_1" (the ends of a segmental
tire, at its smaller and larger azimuth), "band_inner", "band_outer", "band_front", "band_back".
In a wedge model (``sector_deg`` 180 or 90) the buckle's faces on the cut planes join the eye's
"cut_0" and "cut_1".

**Sutures** (:func:`suture_points`). The seed's suture treatment ties the top edges of the buckle
to points of the sclera beside it. Here each suture is a string from a *sclera bite point* on the
sclera's outer surface, at arc length ``suture_width`` / 2 in front of or behind the buckle's centre
line (the seed's "suture width", wider than the buckle, so that the tightened strings press the
buckle into the eye), to a *buckle point*, a node of the top edge on the same side (front or back)
of the sutured body: the tire if there is one, else the band. At each azimuth there are two
sutures, "front" and "back", as the two arms of a mattress suture. In a wedge model a suture on a
cut plane is kept with ``share`` 1/2 (its mirror image holds the other half): dropping it can leave
the buckle with a single suture azimuth, whose two strings meet the buckle in one meridian and
leave it free to slide along the sclera before contact holds it (a singular tangent).

Usage: ``python3 -m eyeball_fenicsx.meshing.builders.buckled_eye --out buckled.msh [--tire 4 1 360 0] [--detachment 20 0.1]``
"""
import argparse
import dataclasses
import inspect
import math
import numbers
import time

import numpy as np

from eyeball_fenicsx.errors import SceneError

from . import eye as _eye
from .hexes import add_hex_model, boundary_quads, check, corner_jacobians, hex_grid, run_cli, write_msh

# An encircling element is secured to the sclera 12-13 mm behind the limbus (J. Ophthalmol. 2016, article
# 3578617, a finite element study of the encircling band's width); an FE study of the band's position took
# 11.5 (anterior), 12.6 (equatorial), 13.7 and 14.8 mm (posterior) behind the limbus (ARVO abstract, IOVS,
# iovs.arvojournals.org article 2745536). In the default eye of eyeball_fenicsx/meshing/builders/eye.py the equator is 12.95 mm behind
# the limbus.
BAND_POSITION = 12.5
# A 240 band is 2.5 mm wide; a 41 band 3.5 mm, a 42 band 4 mm (Read & Hahn, "Pearls for scleral buckling
# with tunnels", Retina Specialist). 0.6 mm: the thickness of the band in eyeball_fenicsx/meshing/builders/band.py.
BAND_WIDTH, BAND_THICKNESS = 2.5, 0.6
GAP = 0.02
# Mattress sutures are placed 1 mm beyond each edge of the element, "so that the indent occurs when the buckle
# is tightened" (Cybersight/Orbis, "Simulated surgery: placing the sutures for a scleral buckle": 9 mm apart
# for a 7 mm buckle).
SUTURE_MARGIN = 1.0
TIRE = {"width": 4.0, "height": 1.0, "arc_deg": 360.0, "azimuth_deg": 0.0}
_TIRE_KEYS = ("width", "height", "arc_deg", "azimuth_deg", "n_width", "n_height")
MIN_BUCKLE_JACOBIAN = 0.5  # the builder refuses a buckle element with a worse corner
_SUTURE_SIDES = ("back", "front")


@dataclasses.dataclass
class BuckleBody:
    """One body of the buckle: a spherical shell zone, revolved over ``azimuths``.

    Attributes:
        name: "band" or "tire" (its volume group, and the prefix of its surfaces).
        inner_radius, outer_radius: radii of its inner and outer surfaces (mm).
        theta: polar angles (rad, from the posterior pole) of its back and front faces.
        azimuths: azimuths of its node planes (rad), increasing.
        closed: a whole ring (periodic in azimuth).
        end_names: surface names of its faces at the first and the last azimuth (open bodies).
        n_width, n_thick: elements along the meridian and through the thickness.
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

    def volume(self):
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
        bodies: "tire" and/or "band" -> :class:`BuckleBody`, from the sclera outward.
        sutured: the body that :func:`suture_points` ties ("tire" if there is one, else "band").
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
    defaults = {name: parameter.default for name, parameter in inspect.signature(_eye.eye_geometry).parameters.items()}
    unknown = sorted(set(eye_parameters) - set(defaults))
    if unknown:
        raise SceneError(f"buckled_eye: unknown parameter(s) {', '.join(unknown)}")
    p = {**defaults, **eye_parameters}
    if p["n_circ"] is None and isinstance(p["refine"], numbers.Integral):
        p["n_circ"] = _eye.N_CIRC * p["refine"]
    if isinstance(p["sector_deg"], numbers.Real) and not isinstance(p["sector_deg"], bool):
        p["sector_deg"] = float(p["sector_deg"])
    _eye._check_parameters(p)
    return p, _eye._Meridian(p)


def _grid_azimuths(n_circ, sector_deg):
    """The eye's node azimuths (rad): 2 pi k / n_circ over the model's sector, as eyeball_fenicsx/meshing/builders/eye.py."""
    sectors = round(n_circ * sector_deg / 360.0)
    return 2 * np.pi * np.arange(sectors + (0 if sector_deg >= 360.0 else 1)) / n_circ


def _arc_azimuths(n_circ, start, stop):
    """Node azimuths of an arc [start, stop] (rad): its ends and the eye's azimuths between them, but
    those within a quarter sector of an end."""
    step = 2 * np.pi / n_circ
    k = np.arange(math.ceil(start / step - 1e-9), math.floor(stop / step + 1e-9) + 1)
    between = k * step
    between = between[(between - start > 0.25 * step) & (stop - between > 0.25 * step)]
    return np.concatenate([[start], between, [stop]])


def _check_tire(tire, sector_deg):
    if not isinstance(tire, dict) or set(tire) - set(_TIRE_KEYS):
        raise SceneError(f"buckled_eye: tire must be None or a table with keys among {', '.join(_TIRE_KEYS)}, "
                         f"got {tire!r}")
    tire = {**TIRE, **tire}
    for key in ("width", "height", "arc_deg"):
        check("buckled_eye", f"tire {key}", tire[key], "positive number")
    value = tire["azimuth_deg"]
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise SceneError(f"buckled_eye: tire azimuth_deg must be a number, got {value!r}")
    for key in ("n_width", "n_height"):
        if key in tire:
            check("buckled_eye", f"tire {key}", tire[key], "positive integer")
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


def buckle_layout(band_width=BAND_WIDTH, band_thickness=BAND_THICKNESS, band_position=BAND_POSITION, tire=None,
                  gap=GAP, n_band_thick=2, n_band_width=4, band=None, **eye_parameters):
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
    if tire is not None:
        tire = _check_tire(tire, sector)
    segmental = tire is not None and tire["arc_deg"] < 360.0
    if band is None:
        band = not segmental
    if not band and tire is None:
        raise SceneError("buckled_eye: without the band there must be a tire")
    Ro, theta_c = m.Ro, (m.s_l - band_position) / m.Ro
    grid = _grid_azimuths(n_circ, sector)
    whole = sector >= 360.0
    ring_ends = () if whole else ("cut_0", "cut_1")
    bodies = {}
    radius = Ro
    if tire is not None:
        inner = radius + gap
        half = tire["width"] / (2 * inner)
        n_width = tire.get("n_width", max(n_band_width, round(tire["width"] / (band_width / n_band_width))))
        n_thick = tire.get("n_height", max(n_band_thick, round(tire["height"] / (band_thickness / n_band_thick))))
        if not segmental:
            azimuths, closed, ends = grid, whole, ring_ends
        else:
            centre, arc = math.radians(tire["azimuth_deg"]), math.radians(tire["arc_deg"])
            if whole:
                start = centre - arc / 2
                azimuths, ends = _arc_azimuths(n_circ, start, start + arc), ("tire_end_0", "tire_end_1")
            elif abs(math.remainder(tire["azimuth_deg"], 360.0)) < 1e-9:  # centred on cut_0
                azimuths, ends = _arc_azimuths(n_circ, 0.0, arc / 2), ("cut_0", "tire_end_1")
            else:  # centred on cut_1
                top = math.radians(sector)
                azimuths, ends = _arc_azimuths(n_circ, top - arc / 2, top), ("tire_end_0", "cut_1")
            closed = False
        bodies["tire"] = BuckleBody("tire", inner, inner + tire["height"], (theta_c - half, theta_c + half),
                                    azimuths, closed, ends, int(n_width), int(n_thick), float(tire["arc_deg"]),
                                    float(tire["azimuth_deg"]))
        radius = inner + tire["height"]
    if band:
        inner = radius + gap
        half = band_width / (2 * inner)
        if tire is not None and half > bodies["tire"].theta[1] - theta_c + 1e-12:
            raise SceneError(f"buckled_eye: the band ({band_width} mm) must not be wider than the tire it rests on "
                             f"({tire['width']} mm)")
        bodies["band"] = BuckleBody("band", inner, inner + band_thickness, (theta_c - half, theta_c + half),
                                    grid, whole, ring_ends, n_band_width, n_band_thick)
    # The whole buckle must rest on the spherical sclera, between the optic nerve and the limbal blend.
    back = min(body.theta[0] for body in bodies.values()) * Ro
    front = max(body.theta[1] for body in bodies.values()) * Ro
    limit = m.s_l - _eye.LIMBUS_BLEND
    if back < m.s_nerve or front > limit:
        raise SceneError(f"buckled_eye: the buckle must rest on the sclera between {m.s_l - m.s_nerve:.1f} and "
                         f"{_eye.LIMBUS_BLEND} mm behind the limbus, but it spans {m.s_l - back:.2f} to "
                         f"{m.s_l - front:.2f} mm (band_position {band_position})")
    detachment = p.pop("detachment")
    if isinstance(detachment, dict) and "polar_deg" not in detachment:
        detachment = {**detachment, "polar_deg": math.degrees(theta_c)}  # under the buckle
    return BuckleLayout(eye=p, globe_radius=Ro, limbus_arc=m.s_l, nerve_arc=m.s_nerve, centre_theta=theta_c,
                        bodies=bodies, sutured="tire" if tire is not None else "band", detachment=detachment)


def _mesh_body(body):
    """Nodes, hexahedra and named surfaces of one buckle body (0-based, its own numbering)."""
    theta = np.linspace(body.theta[0], body.theta[1], body.n_width + 1)[:, None, None]
    radius = np.linspace(body.inner_radius, body.outer_radius, body.n_thick + 1)[None, :, None]
    cos, sin = np.cos(body.azimuths), np.sin(body.azimuths)
    cos[np.abs(cos) < 1e-15] = 0.0
    sin[np.abs(sin) < 1e-15] = 0.0
    rho = radius * np.sin(theta)
    z = -radius * np.cos(theta)
    # Axes (u, v, w) = (theta, r, phi): right-handed, since theta grows away from the posterior pole.
    nodes = np.stack(np.broadcast_arrays(rho * cos, rho * sin, z), axis=-1)
    ids = np.arange(nodes[..., 0].size).reshape(nodes.shape[:-1])
    if body.closed:
        ids = np.concatenate([ids, ids[..., :1]], axis=-1)
    hexes = hex_grid(ids)
    nodes = nodes.reshape(-1, 3)
    det, scaled = corner_jacobians(nodes, hexes.reshape(-1, 8))
    if det.min() <= 0:
        raise RuntimeError(f"buckled_eye: inverted {body.name} element")
    if scaled.min() < MIN_BUCKLE_JACOBIAN:
        raise SceneError(f"buckled_eye: the {body.name} has a corner with scaled Jacobian {scaled.min():.3f} < "
                         f"{MIN_BUCKLE_JACOBIAN}")
    surfaces = {f"{body.name}_inner": boundary_quads(hexes, "v-"), f"{body.name}_outer": boundary_quads(hexes, "v+"),
                f"{body.name}_front": boundary_quads(hexes, "u+"), f"{body.name}_back": boundary_quads(hexes, "u-")}
    if not body.closed:
        surfaces[body.end_names[0]] = boundary_quads(hexes, "w-")
        surfaces[body.end_names[1]] = boundary_quads(hexes, "w+")
    return nodes, hexes.reshape(-1, 8), surfaces


_GAUSS = (0.5 - 0.5 / math.sqrt(3), 0.5 + 0.5 / math.sqrt(3))


def hex_volumes(nodes, hexes):
    """Volumes of trilinear hexahedra (gmsh order), exact (2 x 2 x 2 Gauss points)."""
    x = nodes[hexes]
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    volume = np.zeros(len(hexes))
    for u in _GAUSS:
        for v in _GAUSS:
            for w in _GAUSS:
                jacobian = np.zeros((len(hexes), 3, 3))
                for k, (a, b, c) in enumerate(corners):
                    weights = ((u if a else 1 - u), (v if b else 1 - v), (w if c else 1 - w))
                    gradient = ((1 if a else -1) * weights[1] * weights[2], (1 if b else -1) * weights[0] * weights[2],
                                (1 if c else -1) * weights[0] * weights[1])
                    jacobian += x[:, k, :, None] * np.array(gradient)[None, None, :]
                volume += np.linalg.det(jacobian) / 8
    return volume


def buckled_eye_geometry(**parameters):
    """The buckled eye as numpy arrays (see :func:`build_buckled_eye` for the parameters).

    Returns:
        ``(eye_mesh, layout)``: an ``eyeball_fenicsx.meshing.builders.eye.EyeMesh`` holding the eye and the buckle (its
        ``regions`` and ``surfaces`` extended, its ``info`` with the buckle's statistics), and the
        :class:`BuckleLayout`.
    """
    start = time.perf_counter()
    layout = buckle_layout(**parameters)
    mesh = _eye.eye_geometry(**layout.eye, detachment=layout.detachment)
    nodes, regions, surfaces = [mesh.nodes], dict(mesh.regions), dict(mesh.surfaces)
    count = len(mesh.nodes)
    info = dict(mesh.info)
    buckle_scaled = []
    for body in layout.bodies.values():
        body_nodes, body_hexes, body_surfaces = _mesh_body(body)
        nodes.append(body_nodes)
        regions[body.name] = body_hexes + count
        for name, quads in body_surfaces.items():
            surfaces[name] = np.concatenate([surfaces[name], quads + count]) if name in surfaces else quads + count
        count += len(body_nodes)
        _, scaled = corner_jacobians(body_nodes, body_hexes)
        buckle_scaled.append(scaled.min())
        volumes = hex_volumes(body_nodes, body_hexes)
        info[body.name] = {
            "hexahedra": len(body_hexes), "nodes": len(body_nodes), "min_scaled_jacobian": float(scaled.min()),
            "inner_radius": body.inner_radius, "outer_radius": body.outer_radius,
            "polar_deg": tuple(math.degrees(t) for t in body.theta),
            "behind_limbus": tuple(layout.limbus_arc - t * layout.globe_radius for t in body.theta[::-1]),
            "azimuth_deg": (math.degrees(body.azimuths[0]), math.degrees(body.azimuths[-1])),
            "volume": float(volumes.sum()), "smooth_volume": body.volume(),
        }
    nodes = np.concatenate(nodes)
    order = [name for name in mesh.surfaces if not name.startswith("cut_")]
    order += [name for name in surfaces if name not in mesh.surfaces]
    order += [name for name in ("cut_0", "cut_1") if name in surfaces]
    surfaces = {name: surfaces[name] for name in order}
    hexes = np.concatenate(list(regions.values()))
    info.update({
        "hexahedra": len(hexes), "nodes": len(nodes),
        "per_region": {name: len(cells) for name, cells in regions.items()},
        "min_scaled_jacobian": min(info["min_scaled_jacobian"], *buckle_scaled),
        "buckle_min_scaled_jacobian": float(min(buckle_scaled)),
        "band_position": layout.limbus_arc - layout.centre_theta * layout.globe_radius,
        "centre_polar_deg": math.degrees(layout.centre_theta),
        "build_seconds": time.perf_counter() - start,
    })
    return _eye.EyeMesh(nodes, regions, surfaces, info), layout


def build_buckled_eye(band_width=BAND_WIDTH, band_thickness=BAND_THICKNESS, band_position=BAND_POSITION, tire=None,
                      gap=GAP, n_band_thick=2, n_band_width=4, band=None, **eye_parameters):
    """Add the gmsh model "buckled_eye": the eye of eyeball_fenicsx/meshing/builders/eye.py and a scleral buckle (module docstring).

    Call on the rank that owns gmsh, with gmsh initialized.

    Args:
        band_width: meridional width of the encircling band on its inner surface, 2.5 mm (a 240 band).
        band_thickness: 0.6 mm.
        band_position: arc length on the sclera's outer surface from the limbus back to the
            buckle's centre line, 12.5 mm (``BAND_POSITION``: at about the equator).
        tire: None, or {"width": meridional width (4.0 mm), "height": thickness (1.0 mm),
            "arc_deg": its azimuthal extent (360: a ring under the band), "azimuth_deg": the
            azimuth of its middle (0), "n_width", "n_height": its elements (default: about the
            band's element size)}; it is centred on the band's centre line.
        gap: initial clearance between the buckle and the sclera, and between band and tire, 0.02 mm.
        n_band_thick, n_band_width: the band's elements through its thickness and across its width.
        band: build the band (default: yes, but over a segmental tire).
        **eye_parameters: the eye's parameters (eyeball_fenicsx.meshing.builders.eye.build_eye), passed through; a
            ``detachment`` without "polar_deg" is centred under the buckle.

    Returns:
        The statistics (``info``): those of the eye (totals now include the buckle), and per
        buckle body its elements, worst scaled Jacobian, radii, polar angles, distances behind
        the limbus, mesh volume and the volume of the smooth shell zone.

    Raises:
        SceneError: if a parameter is invalid or the buckle does not fit on the sclera.
    """
    parameters = dict(locals())
    parameters.update(parameters.pop("eye_parameters"))
    mesh, _ = buckled_eye_geometry(**parameters)
    add_hex_model("buckled_eye", mesh.nodes, None, None, mesh.surfaces, regions=mesh.regions)
    return mesh.info


def suture_points(parameters=None, count=4, suture_width=None, azimuth_deg=None):
    """Reference points of the buckle's sutures (see the module docstring for the convention).

    Args:
        parameters: the keyword arguments of :func:`build_buckled_eye` (a dict; missing ones take
            their defaults).
        count: number of suture azimuths over the whole eye: 360 (k + 1/2) / count degrees for a
            ring (45, 135, 225, 315 for 4: one in each oblique quadrant, between the rectus
            muscles), spread the same way over the arc of a segmental tire. In a wedge model
            those on a cut plane are kept at half share, those in the mirror image dropped.
        suture_width: distance between the two bites of a suture, measured along the sclera's
            meridian (default: the widest buckle body's footprint plus ``SUTURE_MARGIN`` on each
            side); it must exceed the widest body's footprint.
        azimuth_deg: explicit azimuths (degrees) instead of ``count``.

    Each azimuth is moved to the nearest node azimuth of the sutured body (azimuths that meet there
    give one suture pair), so that the buckle point is a node of its top edge; the sclera bite point
    is on the sclera's smooth outer surface (the sphere of radius R_o; the Suture feature takes the
    nearest node of "sclera_outer").

    Returns:
        A list of dicts, two per azimuth ("back" then "front"): {"name": "suture_<azimuth>_<side>",
        "azimuth_deg", "side", "share" (1, or 1/2 on a cut plane of a wedge), "sclera": bite point
        (x, y, z), "buckle": buckle point,
        "sclera_surface": "sclera_outer", "buckle_surface": "<body>_outer"} -- ready for
        ``Suture(name, first=sclera, second=buckle, first_surface=..., second_surface=...)``.
    """
    layout = buckle_layout(**(parameters or {}))
    body = layout.bodies[layout.sutured]
    Ro, theta_c = layout.globe_radius, layout.centre_theta
    footprint = max(Ro * (b.theta[1] - b.theta[0]) for b in layout.bodies.values())
    if suture_width is None:
        suture_width = footprint + 2 * SUTURE_MARGIN
    check("buckled_eye", "suture_width", suture_width, "positive number")
    if not suture_width > footprint:
        raise SceneError(f"buckled_eye: suture_width {suture_width} must exceed the buckle's footprint "
                         f"{footprint:.3f} mm on the sclera")
    half = suture_width / 2 / Ro
    if Ro * (theta_c - half) < layout.nerve_arc or Ro * (theta_c + half) > layout.limbus_arc - _eye.LIMBUS_BLEND:
        raise SceneError(f"buckled_eye: suture_width {suture_width} puts a bite off the spherical sclera")
    if azimuth_deg is None:
        check("buckled_eye", "count", count, "positive integer")
        fractions = (np.arange(count) + 0.5) / count
        # Over the whole eye: a ring, or the whole arc of a segmental tire (mirrored in a wedge).
        azimuth_deg = body.azimuth_deg + body.arc_deg * (fractions - 0.5) if body.arc_deg < 360.0 \
            else 360.0 * fractions
    snapped = []
    sector, step = math.radians(layout.eye["sector_deg"]), 2 * np.pi / layout.eye["n_circ"]
    wedge = sector < 2 * np.pi
    for phi in np.radians(np.asarray(azimuth_deg, dtype=float)) % (2 * np.pi):
        if wedge and not phi <= sector + 1e-9:
            continue  # in the mirror image of the wedge
        distance = np.abs(np.angle(np.exp(1j * (body.azimuths - phi))))
        if distance.min() > step:
            raise SceneError(f"buckled_eye: no suture at azimuth {math.degrees(phi):.1f} deg, outside the tire")
        phi = float(body.azimuths[np.argmin(distance)]) % (2 * np.pi)
        if all(abs(phi - other) > 1e-9 for other in snapped):
            snapped.append(phi)
    sutures = []
    for phi in snapped:
        share = 0.5 if wedge and not 1e-9 < phi < sector - 1e-9 else 1.0  # on a cut plane: half in the wedge
        direction = np.array([math.cos(phi), math.sin(phi)])
        for side, sign in zip(_SUTURE_SIDES, (-1, 1)):
            bite, edge = theta_c + sign * half, body.theta[1 if sign > 0 else 0]
            sclera = Ro * np.array([*(math.sin(bite) * direction), -math.cos(bite)])
            buckle = body.outer_radius * np.array([*(math.sin(edge) * direction), -math.cos(edge)])
            degrees = math.degrees(phi)
            sutures.append({"name": f"suture_{degrees:g}_{side}", "azimuth_deg": degrees, "side": side,
                            "share": share, "sclera": tuple(sclera.tolist()), "buckle": tuple(buckle.tolist()),
                            "sclera_surface": "sclera_outer", "buckle_surface": f"{body.name}_outer"})
    return sutures


def write(path, **parameters):
    """Write the buckled eye as an MSH 4.1 file in a private gmsh session (serial)."""
    write_msh(path, build_buckled_eye, **parameters)


def _build_from_cli(tire=None, detachment=None, **parameters):
    if tire is not None:
        tire = dict(zip(("width", "height", "arc_deg", "azimuth_deg"), tire))
    if detachment is not None:
        if len(detachment) not in (2, 4):
            raise SceneError("buckled_eye: --detachment takes EXTENT_DEG GAP (under the buckle) or "
                             "POLAR_DEG AZIMUTH_DEG EXTENT_DEG GAP")
        keys = ("extent_deg", "gap") if len(detachment) == 2 else ("polar_deg", "azimuth_deg", "extent_deg", "gap")
        detachment = dict(zip(keys, detachment))
    info = build_buckled_eye(tire=tire, detachment=detachment, **parameters)
    bodies = ", ".join(f"{name} {info[name]['hexahedra']} hexahedra (worst scaled Jacobian "
                       f"{info[name]['min_scaled_jacobian']:.3f}, {info[name]['behind_limbus'][0]:.2f}-"
                       f"{info[name]['behind_limbus'][1]:.2f} mm behind the limbus)"
                       for name in ("tire", "band") if name in info)
    print(f"buckled eye: {info['hexahedra']} hexahedra, {info['nodes']} nodes, worst scaled Jacobian "
          f"{info['min_scaled_jacobian']:.3f}; {bodies}; built in {info['build_seconds']:.2f} s")


def main(argv=None):
    """Command-line entry point: write a buckled eye mesh (on rank 0 when run under MPI)."""
    parser = argparse.ArgumentParser(prog="python3 -m eyeball_fenicsx.meshing.builders.buckled_eye", description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="the .msh file to write")
    parser.add_argument("--band-width", dest="band_width", type=float, default=BAND_WIDTH)
    parser.add_argument("--band-thickness", dest="band_thickness", type=float, default=BAND_THICKNESS)
    parser.add_argument("--band-position", dest="band_position", type=float, default=BAND_POSITION,
                        help="arc length from the limbus back to the buckle's centre line (mm)")
    parser.add_argument("--gap", type=float, default=GAP, help="initial clearance (mm)")
    parser.add_argument("--n-band-thick", dest="n_band_thick", type=int, default=2)
    parser.add_argument("--n-band-width", dest="n_band_width", type=int, default=4)
    parser.add_argument("--tire", type=float, nargs=4, metavar=("WIDTH", "HEIGHT", "ARC_DEG", "AZIMUTH_DEG"),
                        help="a silicone tire under the band (arc_deg < 360: segmental, no band unless --band)")
    parser.add_argument("--band", action=argparse.BooleanOptionalAction, default=None,
                        help="build the band (default: yes, but over a segmental tire)")
    _eye.add_eye_arguments(parser)
    parser.add_argument("--detachment", type=float, nargs="+", metavar="VALUE",
                        help="EXTENT_DEG GAP (a detached cap under the buckle, azimuth 0) or "
                             "POLAR_DEG AZIMUTH_DEG EXTENT_DEG GAP")
    run_cli(parser, _build_from_cli, argv)


if __name__ == "__main__":
    main()

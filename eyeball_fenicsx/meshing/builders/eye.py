"""Hexahedral mesh of a human eye, axisymmetric about the optic axis, for scleral-buckling simulations.

The optic axis is the z axis: the corneal apex is at +z, the posterior pole at -z, and the origin
is the centre of the sclera's anterior sphere, so the equator is the plane z = 0. The eye is built
from its biometry: axial length, anterior corneal radius, anterior chamber depth and the wall's
thicknesses; an eye longer or shorter than 24 mm is elongated or shortened behind the equator as
myopic eyes are (eye_meridian.py, after Atchison et al., IOVS 45:3380, 2004). Only the solid tissues
are meshed, with 8-node hexahedra; the vitreous and the aqueous are liquid cavities, and an
optional retinal detachment is an empty subretinal gap.

The mesh is built in four steps, one module each:

* eye_meridian.py, the meridional section: the anatomy (Le Grand's schematic eye and histology,
  cited there) and the structured quadrilateral blocks of the corneoscleral shell, the choroid,
  retina and ciliary body, the zonule, the lens and the optic nerve;
* eye_azimuths.py, the node azimuths (even, or graded around given meridians) and the discs of
  the butterfly cores where a part crosses the axis;
* eye_revolution.py, the blocks revolved about the axis over those azimuths, and the cores;
  bonded tissues share nodes;
* eye_detachment.py, the optional detachment: a cap of the retina moved off the choroid by a
  constant gap;
* eye_surfaces.py, the named boundary surfaces, and the check that the cavities are closed.

Physical groups: the volumes "cornea", "sclera", "ciliary_body", "choroid", "retina",
"optic_nerve", "lens", "zonule"; the surfaces "sclera_outer", "cornea_outer", "optic_nerve_side",
"optic_nerve_end", "vitreous_wall", "anterior_chamber_wall" (the aqueous cavity: anterior and
posterior chamber, there is no iris), with a detachment "retina_outer" and "choroid_inner", and in
a wedge model "cut_0" (plane azimuth 0) and "cut_1" (plane azimuth ``sector_deg``).

Usage: ``/usr/bin/python3 -m eyeball_fenicsx.meshing.builders.eye --out eye.msh [--sector-deg 180]
[--detachment 60 0 30 0.1]``
"""
import dataclasses
import inspect
import math
import numbers
import time
from collections.abc import Sequence

import numpy as np

from ...checks import is_number
from ...errors import SceneError
from .eye_detachment import DETACHMENT_KEYS, check_detachment, detach
from .eye_meridian import ANTERIOR_CHAMBER_DEPTH, CILIARY_THICKNESS, CORNEA_RADIUS, N_CIRC, Meridian
from .eye_revolution import assemble_eye
from .eye_surfaces import TOLERANCE, check_closed, name_surfaces
from .hexes import add_hex_model, builder_main, check, corner_jacobians, enclosed_volume, msh_writer

MIN_SCALED_JACOBIAN = 0.2  # the builder refuses a mesh with a worse corner
_SECTORS = (90.0, 180.0, 360.0)
# The biometry the builder accepts (mm): adult axial lengths, anterior corneal radii of 35.5 to 52 D
# keratometry (normal 7.0-8.6 mm), aqueous depths (posterior cornea to lens) of shallow to deep chambers.
BIOMETRY_RANGES = {"axial_length": (21.0, 30.0), "corneal_radius": (6.5, 9.5), "anterior_chamber_depth": (1.5, 4.5)}


@dataclasses.dataclass
class EyeMesh:
    """The eye mesh as arrays (0-based node indices, gmsh order).

    Attributes:
        nodes: coordinates, shape ``(num_nodes, 3)``.
        regions: tissue name -> hexahedra, shape ``(count, 8)``.
        surfaces: surface name -> outward quadrilaterals, shape ``(count, 4)``.
        info: statistics: counts, worst scaled Jacobian, cavity volumes (mm^3, whole eye),
            measured axial length, globe radius, build time (s).
    """

    nodes: np.ndarray
    regions: dict
    surfaces: dict
    info: dict


def _check_parameters(p):
    """Raise SceneError unless the eye's parameters are valid (the detachment aside)."""
    for name in ("sclera_thickness_limbus", "sclera_thickness_equator", "sclera_thickness_pole",
                 "cornea_thickness", "choroid_thickness", "retina_thickness", "optic_nerve_diameter",
                 "optic_nerve_length"):
        check("eye", name, p[name], "positive number")
    for name, (low, high) in BIOMETRY_RANGES.items():
        check("eye", name, p[name], "positive number")
        if not low <= p[name] <= high:
            raise SceneError(f"eye: {name} must be between {low:g} and {high:g} mm, got {p[name]!r}")
    check("eye", "refine", p["refine"], "positive integer")
    check("eye", "wall_layers", p["wall_layers"], "positive integer")
    check("eye", "n_circ", p["n_circ"], "positive integer")
    if p["sector_deg"] not in _SECTORS:
        raise SceneError(f"eye: sector_deg must be one of {_SECTORS}, got {p['sector_deg']!r}")
    # The butterfly core's square has n_circ / 4 quadrilaterals a side, and its boundary must have a node
    # at azimuth 0 (and, in a wedge, on the cut planes): an even number of them.
    if p["n_circ"] % 8:
        raise SceneError(f"eye: n_circ must be a multiple of 8 (the butterfly cores have n_circ / 4 quadrilaterals "
                         f"a side, an even number), got {p['n_circ']}")
    graded = p["graded_azimuths"]
    if not (isinstance(graded, (list, tuple, np.ndarray)) and all(is_number(x) for x in graded)):
        raise SceneError(f"eye: graded_azimuths must be a list of azimuths (degrees), got {graded!r}")
    if len(graded) and p["sector_deg"] < 360.0:
        raise SceneError(f"eye: graded_azimuths needs the whole eye (sector_deg = 360), got sector_deg "
                         f"{p['sector_deg']:g}")
    between = p["graded_between"]
    if not (isinstance(between, (list, tuple, np.ndarray)) and len(between) in (0, 2)
            and all(is_number(x) for x in between) and (not len(between) or between[0] < between[1])):
        raise SceneError(f"eye: graded_between must be two distances behind the limbus (mm), the front one first, "
                         f"got {between!r}")
    if len(between) and not len(graded):
        raise SceneError("eye: graded_between says where graded_azimuths holds along the meridian: "
                         "give graded_azimuths")
    inner = p["choroid_thickness"] + p["retina_thickness"]
    if not inner < CILIARY_THICKNESS:
        raise SceneError(f"eye: choroid_thickness + retina_thickness ({inner}) must be below the ciliary body "
                         f"thickness {CILIARY_THICKNESS} mm")
    if max(p["sclera_thickness_limbus"], p["sclera_thickness_equator"], p["sclera_thickness_pole"],
           p["cornea_thickness"]) > 2.0:
        raise SceneError("eye: the sclera and the cornea must be thinner than 2 mm")


def checked_parameters(p: dict) -> tuple[dict, Meridian]:
    """The eye's parameters (all of them) completed -- ``n_circ`` by default ``N_CIRC * refine``,
    ``sector_deg`` a float -- and checked, and their meridian.

    Raises:
        SceneError: if a parameter is invalid.
    """
    p = dict(p)
    if p["n_circ"] is None and isinstance(p["refine"], numbers.Integral):
        p["n_circ"] = N_CIRC * p["refine"]
    if isinstance(p["sector_deg"], numbers.Real) and not isinstance(p["sector_deg"], bool):
        p["sector_deg"] = float(p["sector_deg"])
    _check_parameters(p)
    return p, Meridian(p)


def eye_geometry(axial_length: float = 24.0, corneal_radius: float = CORNEA_RADIUS,
                 anterior_chamber_depth: float = ANTERIOR_CHAMBER_DEPTH, sclera_thickness_limbus: float = 0.5,
                 sclera_thickness_equator: float = 0.4, sclera_thickness_pole: float = 1.0,
                 cornea_thickness: float = 0.53, choroid_thickness: float = 0.25, retina_thickness: float = 0.25,
                 optic_nerve_diameter: float = 3.5, optic_nerve_length: float = 3.0, detachment: dict | None = None,
                 refine: int = 1, n_circ: int | None = None, sector_deg: float = 360.0,
                 wall_layers: int = 1, graded_at: Sequence[float] = (),
                 graded_azimuths: Sequence[float] = (), graded_between: Sequence[float] = ()) -> EyeMesh:
    """The eye mesh as numpy arrays (see :func:`build_eye` for the parameters).

    Returns:
        An :class:`EyeMesh`.

    Raises:
        SceneError: if a parameter is invalid or the mesh would have a corner with a scaled
            Jacobian below ``MIN_SCALED_JACOBIAN``.
    """
    start = time.perf_counter()
    p = dict(locals())
    del p["start"]
    p, m = checked_parameters(p)
    if detachment is not None:
        detachment = check_detachment(detachment, m, p["sector_deg"])
    nodes, hexes, regions, azimuths = assemble_eye(m, p["n_circ"], p["sector_deg"], np.radians(p["graded_azimuths"]),
                                                   p["graded_between"])
    if detachment is not None:
        nodes, hexes = detach(nodes, hexes, regions, m, detachment, p["sector_deg"])
    _, scaled = corner_jacobians(nodes, hexes)
    if not scaled.min() >= MIN_SCALED_JACOBIAN:  # a collapsed edge gives NaN
        raise SceneError(f"eye: the mesh has a corner with scaled Jacobian {scaled.min():.3f} < {MIN_SCALED_JACOBIAN} "
                         f"({_distortion_cause(p, detachment)})")
    surfaces = name_surfaces(nodes, hexes, regions, m, p["sector_deg"])
    check_closed(nodes, surfaces, p["sector_deg"], detachment is not None)
    info = {**_statistics(nodes, hexes, regions, surfaces, scaled, m, p), "azimuths": len(azimuths)}
    if detachment is not None:
        info["detachment"] = detachment
    order = ["cornea", "sclera", "ciliary_body", "choroid", "retina", "optic_nerve", "lens", "zonule"]
    info["build_seconds"] = time.perf_counter() - start
    return EyeMesh(nodes, {name: hexes[regions == name] for name in order}, surfaces, info)


def _distortion_cause(p, detachment):
    """What a distorted element suggests is wrong, for the builder's error message."""
    if detachment is not None:
        return "a detachment gap too large for the elements?"
    return (f"axial_length {p['axial_length']} mm, corneal_radius {p['corneal_radius']} mm, anterior_chamber_depth "
            f"{p['anterior_chamber_depth']} mm and the thicknesses out of proportion?")


def _statistics(nodes, hexes, regions, surfaces, scaled, m, p):
    """The statistics of :attr:`EyeMesh.info` but the detachment and the build time."""
    whole = 360.0 / p["sector_deg"]
    wall = np.unique(surfaces["vitreous_wall"])
    on_axis = wall[np.linalg.norm(nodes[wall, :2], axis=1) < TOLERANCE]
    return {
        "hexahedra": len(hexes), "nodes": len(nodes),
        "per_region": {name: int(np.sum(regions == name)) for name in np.unique(regions)},
        "min_scaled_jacobian": float(scaled.min()),
        "vitreous_volume": whole * enclosed_volume(nodes, surfaces["vitreous_wall"]),
        "anterior_chamber_volume": whole * enclosed_volume(nodes, surfaces["anterior_chamber_wall"]),
        "axial_length": m.z_apex - nodes[on_axis, 2].min(),
        "globe_radius": m.Ro, "posterior_semi_axis": m.Ro + m.elongation, "corneal_apex_z": m.z_apex,
        "limbus": (m.rho_l, float(m.outer(m.s_l)[0][1])),
        "ora_serrata_deg": math.degrees(m.s_ora / m.Ro),
        "optic_nerve_end_z": m.z_nerve_end, "n_circ": p["n_circ"],
    }


def scleral_wall(samples: int = 60, **parameters) -> tuple[np.ndarray, list[list[tuple[float, float, str]]]]:
    """The wall around the vitreous as the mesh builds it, direction by direction from the centre
    of the sclera, for estimates that treat each direction as a piece of a layered sphere.

    On the sclera the shell's lines are radial (but within ``LIMBUS_BLEND`` of the limbus), so at
    polar angle theta (from the posterior pole) the wall is concentric spherical layers: retina,
    choroid and sclera up to the ora serrata, the ciliary body and the sclera from there to the
    scleral spur, where the ciliary body ends. The sclera in front of the spur and the cornea are
    left out (they bound the aqueous, a cavity of its own). Behind the equator of an eye longer or
    shorter than 24 mm the layers' radii are those of the mesh's line at theta (the wall is not
    spherical there: each direction is then a piece of a sphere of its own radius).

    Args:
        samples: number of polar angles, equally spaced from the pole to the scleral spur.
        parameters: as :func:`eye_geometry` (defaults the same).

    Returns:
        (theta, layers): the polar angles (radians), and for each the layers inside out,
        ``[(inner radius, outer radius, tissue), ...]`` in mm.
    """
    p = {name: value.default for name, value in inspect.signature(eye_geometry).parameters.items()}
    p.update(parameters)
    m = Meridian(p)
    inner = p["choroid_thickness"] + p["retina_thickness"]
    theta, layers = np.linspace(0.0, m.s_spur / m.Ro, samples), []
    for s in m.Ro * theta:
        outer, depth = float(m.radius(s / m.Ro)), float(np.linalg.norm(m.outer(s)[1]))  # depth: along the line
        scleral = outer - depth * float(m.shell_thickness(s))
        below = scleral - depth * float(m.inner_thickness(s))
        if s < m.s_ora:
            choroid = scleral - p["choroid_thickness"] / inner * (scleral - below)
            layers.append([(below, choroid, "retina"), (choroid, scleral, "choroid"), (scleral, outer, "sclera")])
        else:
            layers.append([(below, scleral, "ciliary_body"), (scleral, outer, "sclera")])
    return theta, layers


def build_eye(**parameters) -> dict:
    """Add the gmsh model "eye": a human eye in 8-node hexahedra (see the module docstring).

    Call on the rank that owns gmsh, with gmsh initialized.

    Args:
        axial_length: corneal apex to the vitreoretinal interface on the axis (mm), 21 to 30, 24
            (Atchison & Smith's schematic eyes). At 24 the sclera is a sphere whose radius follows
            from it; a longer eye is wider at the equator by ``EQUATOR_PER_AXIAL`` = 0.41 mm per mm
            of length and prolate behind it, a shorter one narrower and oblate (eye_meridian.py).
        corneal_radius: anterior corneal radius of curvature, 7.8 mm (Le Grand's eye; 6.5 to 9.5).
        anterior_chamber_depth: posterior corneal surface to the anterior lens on the axis, 3.05 mm
            (Le Grand's aqueous depth; 1.5 to 4.5). A biometer's ACD, from the corneal epithelium,
            is this plus ``cornea_thickness``.
        sclera_thickness_limbus, sclera_thickness_equator, sclera_thickness_pole: 0.5, 0.4 and 1.0 mm
            (Olsen et al., Am. J. Ophthalmol. 125:237, 1998: 0.53, 0.39, 0.9-1.0; Norman et al.,
            Exp. Eye Res. 90:277, 2010).
        cornea_thickness: central, 0.53 mm (Doughty & Zaman, Surv. Ophthalmol. 44:367, 2000); it
            blends into the limbal sclera.
        choroid_thickness: 0.25 mm (subfoveal 0.29 mm: Margolis & Spaide, Am. J. Ophthalmol.
            147:811, 2009).
        retina_thickness: 0.25 mm (~0.25 mm posteriorly, thinner toward the ora: Hogan et al. 1971).
        optic_nerve_diameter: with its sheaths, 3.5 mm (3-4 mm); optic_nerve_length: 3 mm of it.
        detachment: None, or {"polar_deg": angle of the centre from the posterior pole,
            "azimuth_deg": its azimuth from the x axis (default 0), "extent_deg": angular radius of
            the detached cap, "gap": subretinal gap in mm (0.05-0.2)}; angles seen from the centre
            of the eye.
        refine: 1 gives 9,820 hexahedra (the seed's eye had 9,862); 2 doubles the elements in every
            direction (78,560).
        n_circ: sectors of the full circle (default 40 * refine), a multiple of 8.
        wall_layers: multiplies the elements through the wall (sclera and cornea 2, choroid 1,
            retina 1, times ``refine``), the rest of the mesh as it is: 2 or 3 with a larger
            ``n_circ`` gives a fine eye whose wall elements keep their shape.
        sector_deg: 360 (whole eye), 180 or 90 (a wedge with the cut planes "cut_0" at azimuth 0
            and "cut_1" at ``sector_deg``, for models symmetric about them).
        graded_at: circles of latitude (mm behind the limbus along the sclera, as a buckle's
            ``band_position``; more than 3 mm behind it, in front of the optic nerve's edge) around
            which the elements along the meridian are finer: 0.1 mm at a circle, 0.5 mm longer per
            mm away, up to the usual 0.8 (over ``refine``; eye_meridian.py). A scene's
            ``[buckle_sutures]`` grades at a tire's edges and its sutures' bites.
        graded_azimuths: meridians (azimuths, degrees; whole eye) around which the elements are
            finer across the meridian, spaced as ``graded_at``'s along the equator (eye_azimuths.py;
            a scene's ``[buckle_sutures]`` grades at a radial sponge's sides and its sutures' bites),
            between the circles ``graded_between`` (mm behind the limbus, front, back; by default
            everywhere), coarser one column at a time away from them (eye_revolution.py).

    Returns:
        The mesh statistics (:attr:`EyeMesh.info`).

    Raises:
        SceneError: if a parameter is invalid, or the mesh would have a corner with a scaled
            Jacobian below ``MIN_SCALED_JACOBIAN`` (a detachment gap too large for its elements).
    """
    known = inspect.signature(eye_geometry).parameters
    unknown = sorted(set(parameters) - set(known))
    if unknown:
        raise SceneError(f"eye: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(known)}")
    eye = eye_geometry(**parameters)
    add_hex_model("eye", eye.nodes, None, None, eye.surfaces, regions=eye.regions)
    return eye.info


write = msh_writer(build_eye)


def _build_from_cli(detachment=None, **parameters):
    if detachment is not None:
        detachment = dict(zip(DETACHMENT_KEYS, detachment))
    info = build_eye(detachment=detachment, **parameters)
    print(f"eye: {info['hexahedra']} hexahedra, {info['nodes']} nodes, worst scaled Jacobian "
          f"{info['min_scaled_jacobian']:.3f}, vitreous {info['vitreous_volume'] / 1000:.2f} mL, anterior chamber "
          f"{info['anterior_chamber_volume'] / 1000:.3f} mL, axial length {info['axial_length']:.2f} mm, "
          f"built in {info['build_seconds']:.2f} s")


# The eye's dimensions and resolution as command-line options (all but the detachment), for builder_main.
EYE_OPTIONS = {
    "axial_length": 24.0, "corneal_radius": CORNEA_RADIUS, "anterior_chamber_depth": ANTERIOR_CHAMBER_DEPTH,
    "sclera_thickness_limbus": 0.5, "sclera_thickness_equator": 0.4,
    "sclera_thickness_pole": 1.0, "cornea_thickness": 0.53, "choroid_thickness": 0.25, "retina_thickness": 0.25,
    "optic_nerve_diameter": 3.5, "optic_nerve_length": 3.0,
    "refine": dict(type=int, default=1, help="2 doubles the elements in every direction"),
    "n_circ": dict(type=int, default=None, help="sectors of the full circle"),
    "wall_layers": dict(type=int, default=1, help="multiplies the elements through the wall"),
    "sector_deg": dict(type=float, default=360.0, choices=_SECTORS),
    "graded_at": dict(type=float, nargs="+", default=(), metavar="MM",
                      help="circles of latitude to grade the eye at, mm behind the limbus"),
    "graded_azimuths": dict(type=float, nargs="+", default=(), metavar="DEG",
                            help="meridians to grade the eye at, degrees of azimuth (whole eye)"),
    "graded_between": dict(type=float, nargs=2, default=(), metavar=("FRONT", "BACK"),
                           help="the circles between which the meridians are graded, mm behind the limbus"),
}
main = builder_main(_build_from_cli, "eyeball_fenicsx.meshing.builders.eye", __doc__, **EYE_OPTIONS,
                    detachment=dict(type=float, nargs=4, metavar=("POLAR_DEG", "AZIMUTH_DEG", "EXTENT_DEG", "GAP"),
                                    help="detached cap: centre (degrees from the posterior pole, azimuth), angular "
                                         "radius, gap (mm)"))


if __name__ == "__main__":
    main()

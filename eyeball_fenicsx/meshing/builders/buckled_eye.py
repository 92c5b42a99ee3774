"""The eye of eye.py with a scleral buckle: an encircling silicone band, a silicone tire, or both.

One gmsh model holds the eye (its tissues, surfaces and optional retinal detachment, unchanged) and
the buckle's bodies, all 8-node hexahedra. The buckle does not share a single node with the eye:
each body is its own mesh, a small clearance ``gap`` away from the body under it, so that contact
(eyeball_fenicsx/contact/) closes the gap and carries the load.

Where the bodies lie -- spherical shell zones about the centre of the sclera, at ``band_position``
behind the limbus -- is buckle_placement.py; where the sutures that hold them are, buckle_sutures.py
(:func:`suture_points`). Here each body is meshed as a structured block in (theta, r, phi), polar
angle, radius and azimuth, and added to the eye's mesh; a detachment given without its centre is
centred under the buckle.

Physical groups: the eye's volumes and surfaces (eyeball_fenicsx/meshing/builders/eye.py), then the volumes "tire"
and "band" and their surfaces "tire_inner", "tire_outer", "tire_front" (toward the cornea),
"tire_back" (toward the posterior pole), "tire_end_0" and "tire_end_1" (the ends of a segmental
tire, at its smaller and larger azimuth), "band_inner", "band_outer", "band_front", "band_back"; a
radial sponge: "sponge", with "sponge_inner", "sponge_outer", "sponge_front" and "sponge_back" (its
ends along the meridian), "sponge_side_0" and "sponge_side_1" (its long sides, at its smaller and
larger azimuth).
In a wedge model (``sector_deg`` 180 or 90) the buckle's faces on the cut planes join the eye's
"cut_0" and "cut_1".

Usage: ``python3 -m eyeball_fenicsx.meshing.builders.buckled_eye --out buckled.msh [--tire 4 1 360 0]
[--detachment 20 0.1]``
"""
import argparse
import math
import time

import numpy as np

from ...errors import SceneError
from .buckle_placement import (
    BAND_POSITION,
    BAND_THICKNESS,
    BAND_WIDTH,
    GAP,
    TIRE,
    BuckleBody,
    BuckleLayout,
    buckle_layout,
)
from .buckle_sutures import GRADED_MARGIN, SUTURE_MARGIN, suture_grading, suture_points
from .eye import EYE_OPTIONS, EyeMesh, eye_geometry
from .eye_azimuths import cos_sin
from .eye_detachment import DETACHMENT_KEYS
from .hexes import add_hex_model, boundary_quads, builder_main, corner_jacobians, hex_grid, hex_volumes, msh_writer

__all__ = ["BAND_POSITION", "BAND_THICKNESS", "BAND_WIDTH", "GAP", "GRADED_MARGIN", "MIN_BUCKLE_JACOBIAN",
           "SUTURE_MARGIN", "TIRE", "BuckleBody", "BuckleLayout", "buckle_layout", "buckled_eye_geometry",
           "build_buckled_eye", "hex_volumes", "main", "suture_grading", "suture_points", "write"]

MIN_BUCKLE_JACOBIAN = 0.5  # the builder refuses a buckle element with a worse corner


def _mesh_body(body: BuckleBody) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Nodes, hexahedra and named surfaces of one buckle body (0-based, its own numbering)."""
    theta = np.linspace(body.theta[0], body.theta[1], body.n_width + 1)[:, None, None]
    radius = np.linspace(body.inner_radius, body.outer_radius, body.n_thick + 1)[None, :, None]
    cos, sin = cos_sin(body.azimuths)
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


def buckled_eye_geometry(**parameters) -> tuple[EyeMesh, BuckleLayout]:
    """The buckled eye as numpy arrays (see :func:`build_buckled_eye` for the parameters).

    Returns:
        ``(eye_mesh, layout)``: an :class:`eye.EyeMesh` holding the eye and the buckle (its
        ``regions`` and ``surfaces`` extended, its ``info`` with the buckle's statistics), and the
        :class:`BuckleLayout`.
    """
    start = time.perf_counter()
    layout = buckle_layout(**parameters)
    mesh = eye_geometry(**layout.eye, detachment=layout.detachment)
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
    return EyeMesh(nodes, regions, surfaces, info), layout


def build_buckled_eye(band_width: float = BAND_WIDTH, band_thickness: float = BAND_THICKNESS,
                      band_position: float = BAND_POSITION, tire: dict | None = None, gap: float = GAP,
                      n_band_thick: int = 2, n_band_width: int = 4, band: bool | None = None,
                      sponge: dict | None = None, **eye_parameters) -> dict:
    """Add the gmsh model "buckled_eye": the eye of eye.py and a scleral buckle (module docstring).

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
        band: build the band (default: yes, but over a segmental tire or with a sponge).
        sponge: None, or a radial sponge laid along the meridian, alone on the sclera of a whole eye:
            {"width": its azimuthal width at the centre line (5.0 mm), "height" (2.0 mm), "length":
            along the meridian, centred on the centre line (10.0 mm), "azimuth_deg" of its middle (0),
            "n_width", "n_height", "n_length": its elements}.
        **eye_parameters: the eye's parameters (:func:`eye.build_eye`), passed through; a
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


write = msh_writer(build_buckled_eye)


def _build_from_cli(tire=None, detachment=None, **parameters):
    if tire is not None:
        tire = dict(zip(("width", "height", "arc_deg", "azimuth_deg"), tire))
    if detachment is not None:
        if len(detachment) not in (2, 4):
            raise SceneError("buckled_eye: --detachment takes EXTENT_DEG GAP (under the buckle) or "
                             "POLAR_DEG AZIMUTH_DEG EXTENT_DEG GAP")
        keys = ("extent_deg", "gap") if len(detachment) == 2 else DETACHMENT_KEYS
        detachment = dict(zip(keys, detachment))
    info = build_buckled_eye(tire=tire, detachment=detachment, **parameters)
    bodies = ", ".join(f"{name} {info[name]['hexahedra']} hexahedra (worst scaled Jacobian "
                       f"{info[name]['min_scaled_jacobian']:.3f}, {info[name]['behind_limbus'][0]:.2f}-"
                       f"{info[name]['behind_limbus'][1]:.2f} mm behind the limbus)"
                       for name in ("tire", "band") if name in info)
    print(f"buckled eye: {info['hexahedra']} hexahedra, {info['nodes']} nodes, worst scaled Jacobian "
          f"{info['min_scaled_jacobian']:.3f}; {bodies}; built in {info['build_seconds']:.2f} s")


main = builder_main(
    _build_from_cli, "eyeball_fenicsx.meshing.builders.buckled_eye", __doc__,
    band_width=BAND_WIDTH, band_thickness=BAND_THICKNESS,
    band_position=dict(type=float, default=BAND_POSITION,
                       help="arc length from the limbus back to the buckle's centre line (mm)"),
    gap=dict(type=float, default=GAP, help="initial clearance (mm)"), n_band_thick=2, n_band_width=4,
    tire=dict(type=float, nargs=4, metavar=("WIDTH", "HEIGHT", "ARC_DEG", "AZIMUTH_DEG"),
              help="a silicone tire under the band (arc_deg < 360: segmental, no band unless --band)"),
    band=dict(action=argparse.BooleanOptionalAction, default=None,
              help="build the band (default: yes, but over a segmental tire)"),
    **EYE_OPTIONS,
    detachment=dict(type=float, nargs="+", metavar="VALUE",
                    help="EXTENT_DEG GAP (a detached cap under the buckle, azimuth 0) or "
                         "POLAR_DEG AZIMUTH_DEG EXTENT_DEG GAP"))


if __name__ == "__main__":
    main()

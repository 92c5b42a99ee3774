"""Structured hexahedral mesh of a ring (band) around a faceted thick tube, both about the z axis.

The test case of contact on a faceted master surface: the tube bore <= r <= radius and the ring
radius + gap <= r <= radius + gap + ring_thickness, both over 0 <= z <= length (half the ring's
width, z = 0 its mid-plane), with their nodes on the same azimuths 2 pi k / n_circ. The tube's
outer surface is a polygon of n_circ flat facets, and every node of the ring's inner surface
lies over a fold of it (exactly on it when ``gap`` is 0): the tie case of node-to-segment
contact. A sector 0 <= theta <= ``sector`` (a multiple of 360 / n_circ) has cut faces on the
planes theta = 0 and theta = sector; ``sector = 360`` is the full ring.

The bodies share no node. Physical groups: volumes "cylinder" and "ring"; surfaces
"<body>_inner", "_outer", "_back" (z = 0), "_front" (z = length) and, for a sector, "_cut_0"
(theta = 0) and "_cut_1" (theta = sector), body "cylinder" or "ring".

Usage: ``/usr/bin/python3 -m eyeball_fenicsx.meshing.builders.ring_on_cylinder --out ring.msh --n-circ 24 --sector 90``
"""

import numpy as np

from ...checks import is_number
from ...errors import SceneError
from .hexes import add_hex_model, boundary_quads, builder_main, check, hex_grid


def _annulus(inner, outer, length, angles, closed, n_radial, n_length):
    """Nodes (N, 3), hexahedra (M, 8) and named boundary quads of one body (see module docstring)."""
    radii = np.linspace(inner, outer, n_radial + 1)
    heights = np.linspace(0.0, length, n_length + 1)
    r, theta, z = np.meshgrid(radii, angles, heights, indexing="ij")
    nodes = np.column_stack([(r * np.cos(theta)).ravel(), (r * np.sin(theta)).ravel(), z.ravel()])
    ids = np.arange(len(nodes)).reshape(r.shape)
    if closed:  # the last layer of hexahedra wraps around to theta = 0
        ids = np.concatenate([ids, ids[:, :1, :]], axis=1)
    hexes = hex_grid(ids)  # (u, v, w) = (r, theta, z) is right-handed: positive Jacobians
    sides = {"inner": "u-", "outer": "u+", "back": "w-", "front": "w+"}
    if not closed:
        sides.update(cut_0="v-", cut_1="v+")
    return nodes, hexes.reshape(-1, 8), {name: boundary_quads(hexes, side) for name, side in sides.items()}


def ring_on_cylinder_geometry(radius: float = 10.0, bore: float = 5.0, length: float = 1.0,
                              ring_thickness: float = 0.25, gap: float = 0.0, n_circ: int = 24, sector: float = 90.0,
                              n_radial: int = 3, n_length: int = 2,
                              n_thick: int = 1) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Nodes, hexahedra by region and named boundary quadrilaterals (see module docstring).

    Args:
        radius: vertex radius of the tube's faceted outer surface.
        bore: inner radius of the tube, 0 < bore < radius.
        length: axial length of both bodies (half the ring's width).
        ring_thickness: radial thickness of the ring.
        gap: radial clearance between the tube's outer vertices and the ring's inner ones (>= 0).
        n_circ: facets around the full circle.
        sector: angle (degrees) of the model, a multiple of 360 / n_circ, at most 360.
        n_radial, n_length, n_thick: hexahedra through the tube's wall, along z, through the ring.

    Returns:
        ``(nodes, regions, surfaces)``: coordinates ``(N, 3)``, {"cylinder", "ring": hexahedra
        ``(M, 8)`` in gmsh order} and {"cylinder_outer", ...: quads ``(K, 4)``}, 0-based.

    Raises:
        SceneError: if a parameter is invalid.
    """
    for name, value in (("radius", radius), ("bore", bore), ("length", length), ("ring_thickness", ring_thickness),
                        ("sector", sector)):
        check("ring_on_cylinder", name, value, "positive number")
    for name, value in (("n_circ", n_circ), ("n_radial", n_radial), ("n_length", n_length), ("n_thick", n_thick)):
        check("ring_on_cylinder", name, value, "positive integer")
    if not bore < radius:
        raise SceneError(f"ring_on_cylinder: bore {bore!r} must be less than radius {radius!r}")
    if not is_number(gap) or gap < 0:
        raise SceneError(f"ring_on_cylinder: gap must be a finite number >= 0, got {gap!r}")
    facets = sector / (360.0 / n_circ)
    if not (abs(facets - round(facets)) < 1e-9 and 1 <= round(facets) <= n_circ):
        raise SceneError(f"ring_on_cylinder: sector {sector!r} must be a multiple of 360 / n_circ = "
                         f"{360.0 / n_circ:.6g} degrees, at most 360")
    facets = int(round(facets))
    closed = facets == n_circ
    angles = 2 * np.pi / n_circ * np.arange(facets + (0 if closed else 1))
    nodes, regions, surfaces, offset = [], {}, {}, 0
    for body, inner, outer, n_across in (("cylinder", bore, radius, n_radial),
                                         ("ring", radius + gap, radius + gap + ring_thickness, n_thick)):
        x, hexes, quads = _annulus(inner, outer, length, angles, closed, n_across, n_length)
        nodes.append(x)
        regions[body] = hexes + offset
        surfaces.update({f"{body}_{name}": q + offset for name, q in quads.items()})
        offset += len(x)
    return np.concatenate(nodes), regions, surfaces


def build_ring_on_cylinder(**parameters) -> None:
    """Add the gmsh model "ring_on_cylinder" (keywords of :func:`ring_on_cylinder_geometry`)."""
    nodes, regions, surfaces = ring_on_cylinder_geometry(**parameters)
    add_hex_model("ring_on_cylinder", nodes, None, None, surfaces, regions=regions)


main = builder_main(build_ring_on_cylinder, "eyeball_fenicsx.meshing.builders.ring_on_cylinder", __doc__, radius=10.0,
                    bore=5.0, length=1.0, ring_thickness=0.25, gap=0.0, n_circ=24, sector=90.0, n_radial=3,
                    n_length=2, n_thick=1)


if __name__ == "__main__":
    main()

"""Structured hexahedral mesh of a band: the ring R <= r <= R + t, |z - z_c| <= w/2 about the z axis.

The encircling silicone band of scleral buckling in its simplest form, and the ring used to
test band tightening. Nodes are placed in cylindrical coordinates; a full ring (``sector =
360``) is periodic, a sector 0 <= theta <= sector has the cut faces "cut_0" (theta = 0) and
"cut_1" (theta = sector).

Usage: ``/usr/bin/python3 -m eyeball_fenicsx.meshing.builders.band --out band.msh --inner-radius 12 --thickness 0.6
--width 2.5``
"""
import numpy as np

from .hexes import add_hex_model, boundary_quads, builder_main, check, hex_grid


def band_geometry(inner_radius: float, thickness: float, width: float, z_center: float = 0.0, n_circ: int = 64,
                  n_thick: int = 2, n_width: int = 4,
                  sector: float = 360.0) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Nodes, hexahedra and named boundary quadrilaterals of the band (see module docstring).

    Returns:
        ``(nodes, hexes, surfaces)``: coordinates ``(N, 3)``, hexahedra ``(M, 8)`` in gmsh
        order, and {"inner", "outer", "back" (z min), "front" (z max)[, "cut_0", "cut_1"]: quads}.
    """
    for name, value in (("inner_radius", inner_radius), ("thickness", thickness), ("width", width),
                        ("sector", sector)):
        check("band", name, value, "positive number")
    for name, value in (("n_circ", n_circ), ("n_thick", n_thick), ("n_width", n_width)):
        check("band", name, value, "positive integer")
    closed = sector >= 360.0
    angles = np.linspace(0.0, np.radians(min(sector, 360.0)), n_circ + 1)[: n_circ if closed else n_circ + 1]
    radii = np.linspace(inner_radius, inner_radius + thickness, n_thick + 1)
    heights = np.linspace(z_center - width / 2, z_center + width / 2, n_width + 1)
    r, theta, z = np.meshgrid(radii, angles, heights, indexing="ij")
    nodes = np.column_stack([(r * np.cos(theta)).ravel(), (r * np.sin(theta)).ravel(), z.ravel()])
    ids = np.arange(len(nodes)).reshape(r.shape)
    if closed:  # the last layer of hexahedra wraps around to theta = 0
        ids = np.concatenate([ids, ids[:, :1, :]], axis=1)
    # (u, v, w) = (r, theta, z) is right-handed, so the hexahedra have positive Jacobians
    hexes = hex_grid(ids)
    surfaces = {"inner": boundary_quads(hexes, "u-"), "outer": boundary_quads(hexes, "u+"),
                "back": boundary_quads(hexes, "w-"), "front": boundary_quads(hexes, "w+")}
    if not closed:
        surfaces["cut_0"] = boundary_quads(hexes, "v-")
        surfaces["cut_1"] = boundary_quads(hexes, "v+")
    return nodes, hexes.reshape(-1, 8), surfaces


def build_band(inner_radius: float = 12.0, thickness: float = 0.6, width: float = 2.5, z_center: float = 0.0,
               n_circ: int = 64, n_thick: int = 2, n_width: int = 4, sector: float = 360.0,
               region: str = "band") -> None:
    """Add the gmsh model "band" (volume group ``region``; surfaces ``<region>_inner``,
    ``_outer``, ``_back``, ``_front`` and, for a sector, ``_cut_0``, ``_cut_1``)."""
    nodes, hexes, surfaces = band_geometry(inner_radius, thickness, width, z_center, n_circ, n_thick, n_width, sector)
    add_hex_model("band", nodes, hexes, region, {f"{region}_{name}": quads for name, quads in surfaces.items()})


main = builder_main(build_band, "eyeball_fenicsx.meshing.builders.band", __doc__, region="band", inner_radius=12.0,
                    thickness=0.6, width=2.5, z_center=0.0, n_circ=64, n_thick=2, n_width=4, sector=360.0)


if __name__ == "__main__":
    main()

"""Structured hexahedral mesh of the octant x, y, z >= 0 of a thick spherical shell a <= r <= b.

The octant of the unit sphere is covered by three cube-sphere patches, one around each axis, each
n x n quadrilaterals of the equi-angular gnomonic map: on the patch around axis p the direction is
e_p + tan(s) e_q + tan(t) e_r, (p, q, r) cyclic, with s, t in [0, pi/4] in n equal steps. The
patches meet along the arcs x = y, y = z, z = x and at the point (1, 1, 1)/sqrt(3). The surface mesh is
extruded radially: every node lies on a sphere r = r_k, k = 0 .. layers.

Usage: ``/usr/bin/python3 -m eyeball_fenicsx.meshing.builders.sphere_octant --out octant.msh --n 16 --layers 8``
"""

import numpy as np

from ...errors import SceneError
from .hexes import add_hex_model, boundary_quads, builder_main, check, hex_grid, msh_writer

_SYMMETRY_PLANES = ("sym_x", "sym_y", "sym_z")


def octant_directions(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions of the cube-sphere nodes on the octant, shared nodes merged.

    A node is identified by its integer cube coordinates K (0 <= K_i <= n, max K_i = n): on the
    patch around axis p, K_p = n and the other two are the angle steps. Nodes on the arcs between
    patches have the same K on both patches, hence a single index.

    Args:
        n: number of quadrilaterals along each edge of a patch.

    Returns:
        ``(directions, patches)``: unit vectors, shape ``(3 (n + 1)^2 - 3 (n + 1) + 1, 3)``, and the
        node index of step (i, j) of the patch around axis p, ``patches[p, i, j]``, shape
        ``(3, n + 1, n + 1)``, with i along axis (p + 1) % 3 and j along axis (p + 2) % 3.
    """
    steps = np.arange(n + 1)
    cube = np.empty((3, n + 1, n + 1, 3), dtype=np.int64)
    for p in range(3):
        cube[p, :, :, p] = n
        cube[p, :, :, (p + 1) % 3] = steps[:, None]
        cube[p, :, :, (p + 2) % 3] = steps[None, :]
    keys = np.ravel_multi_index(np.moveaxis(cube, -1, 0), (n + 1,) * 3)
    unique_keys, patches = np.unique(keys, return_inverse=True)
    cube_nodes = np.stack(np.unravel_index(unique_keys, (n + 1,) * 3), axis=-1)
    tangents = np.where(cube_nodes == n, 1.0, np.tan(np.pi / 4 * cube_nodes / n))
    return tangents / np.linalg.norm(tangents, axis=1, keepdims=True), patches.reshape(3, n + 1, n + 1)


def layer_radii(inner_radius: float, outer_radius: float, layers: int, grading: float) -> np.ndarray:
    """Radii of the node spheres: each layer ``grading`` times as thick as the one inside it.

    Args:
        inner_radius: a.
        outer_radius: b > a.
        layers: number of layers.
        grading: thickness ratio of consecutive layers (outer / inner); 1 is uniform and
            ``grading > 1`` refines toward the inner surface.

    Returns:
        Radii r_0 = a < r_1 < ... < r_layers = b, shape ``(layers + 1,)``.
    """
    if grading == 1.0:
        fractions = np.linspace(0.0, 1.0, layers + 1)
    else:
        fractions = (grading ** np.arange(layers + 1) - 1.0) / (grading ** layers - 1.0)
        fractions[-1] = 1.0
    return inner_radius + (outer_radius - inner_radius) * fractions


def build_sphere_octant(inner_radius: float = 1.0, outer_radius: float = 2.0, n: int = 16, layers: int = 8,
                        region: str = "wall", grading: float = 1.0) -> None:
    """Add the gmsh model "sphere_octant": the shell octant in 3 n^2 layers 8-node hexahedra.

    Call on the rank that owns gmsh, with gmsh initialized. Physical groups: the volume ``region``
    and the surfaces "inner" (r = a), "outer" (r = b), "sym_x" (x = 0), "sym_y" (y = 0) and
    "sym_z" (z = 0).

    Args:
        inner_radius: a, positive.
        outer_radius: b > a.
        n: quadrilaterals along each edge of each of the three patches, positive integer.
        layers: hexahedra through the thickness, positive integer.
        region: name of the volume physical group.
        grading: thickness ratio of consecutive layers, outer over inner, positive; 1 gives
            uniform layers, > 1 refines toward the inner surface.

    Raises:
        SceneError: if a parameter is invalid.
    """
    check("sphere_octant", "inner_radius", inner_radius, "positive number")
    check("sphere_octant", "outer_radius", outer_radius, "positive number")
    if outer_radius <= inner_radius:
        raise SceneError(f"sphere_octant: outer_radius ({outer_radius}) must exceed inner_radius ({inner_radius})")
    check("sphere_octant", "n", n, "positive integer")
    check("sphere_octant", "layers", layers, "positive integer")
    check("sphere_octant", "grading", grading, "positive number")
    directions, patches = octant_directions(n)
    radii = layer_radii(inner_radius, outer_radius, layers, grading)
    nodes = (radii[:, None, None] * directions[None, :, :]).reshape(-1, 3)
    # Node (patch p, step i, step j, layer k) is number k * len(directions) + patches[p, i, j].
    layer_offsets = len(directions) * np.arange(layers + 1)
    hexes = [hex_grid(patches[p][:, :, None] + layer_offsets) for p in range(3)]
    surfaces = {
        "inner": np.concatenate([boundary_quads(h, "w-") for h in hexes]),
        "outer": np.concatenate([boundary_quads(h, "w+") for h in hexes]),
    }
    for axis, name in enumerate(_SYMMETRY_PLANES):
        # The plane x_axis = 0 is side i = 0 of patch axis - 1 and side j = 0 of patch axis - 2.
        surfaces[name] = np.concatenate([boundary_quads(hexes[(axis - 1) % 3], "u-"),
                                         boundary_quads(hexes[(axis - 2) % 3], "v-")])
    add_hex_model("sphere_octant", nodes, np.concatenate([h.reshape(-1, 8) for h in hexes]), region, surfaces)


write = msh_writer(build_sphere_octant)
main = builder_main(build_sphere_octant, "eyeball_fenicsx.meshing.builders.sphere_octant", __doc__, region="wall",
                    inner_radius=1.0, outer_radius=2.0,
                    n=dict(type=int, default=16, help="quadrilaterals along each patch edge"),
                    layers=dict(type=int, default=8, help="hexahedra through the thickness"),
                    grading=dict(type=float, default=1.0, help="thickness ratio of consecutive layers, outer over "
                                 "inner (> 1 refines the inside)"))


if __name__ == "__main__":
    main()

"""Structured hexahedral mesh of Cook's membrane: the tapered panel with corners (0, 0), (48, 44),
(48, 60), (0, 44) (Cook 1974), extruded to a slab of the given thickness along z.

The node columns are equally spaced in x; each column is divided equally between the lower
edge y = 44 x / 48 and the upper edge y = 44 + 16 x / 48, so every element is a trapezoid in the
(x, y) plane and the mesh represents the straight-sided panel exactly at every refinement.

Usage: ``/usr/bin/python3 -m eyeball_fenicsx.meshing.builders.cook --out cook.msh --divisions 16 16 1``
"""
from collections.abc import Sequence

import numpy as np

from ...errors import SceneError
from .hexes import add_block_model, builder_main, check, hex_grid, msh_writer

# Surface physical groups by the side of the panel they cover.
_SIDES = {"clamped": "u-", "loaded": "u+", "bottom": "v-", "top": "v+", "z0": "w-", "z1": "w+"}
LENGTH, LEFT_HEIGHT, RIGHT_BOTTOM, RIGHT_TOP = 48.0, 44.0, 44.0, 60.0
TIP = (LENGTH, RIGHT_TOP)  # the upper corner of the loaded edge, where the deflection is measured


def build_cook(divisions: Sequence[int] = (16, 16, 1), thickness: float = 1.0, region: str = "solid") -> None:
    """Add the gmsh model "cook": Cook's panel in nx x ny x nz 8-node hexahedra.

    Call on the rank that owns gmsh, with gmsh initialized. Physical groups: the volume
    ``region`` and the surfaces "clamped" (x = 0), "loaded" (x = 48), "bottom" (the lower
    edge, from (0, 0) to (48, 44)), "top" (the upper edge, from (0, 44) to (48, 60)), "z0"
    (z = 0) and "z1" (z = thickness).

    Args:
        divisions: hexahedra (nx, ny, nz) along x, across the panel, and through the thickness.
        thickness: the extrusion length along z, positive.
        region: name of the volume physical group.

    Raises:
        SceneError: if a division count or the thickness is invalid.
    """
    if len(divisions) != 3:
        raise SceneError(f"cook: divisions needs three entries, got {divisions!r}")
    for name, count in zip(("nx", "ny", "nz"), divisions):
        check("cook", f"the division count {name}", count, "positive integer")
    check("cook", "the thickness", thickness, "positive number")
    nx, ny, nz = divisions
    s, t, w = np.meshgrid(np.linspace(0, 1, nx + 1), np.linspace(0, 1, ny + 1), np.linspace(0, 1, nz + 1),
                          indexing="ij")
    lower = RIGHT_BOTTOM * s
    upper = LEFT_HEIGHT + (RIGHT_TOP - LEFT_HEIGHT) * s
    nodes = np.stack([LENGTH * s, lower + (upper - lower) * t, thickness * w], axis=-1).reshape(-1, 3)
    hexes = hex_grid(np.arange(len(nodes)).reshape(nx + 1, ny + 1, nz + 1))
    add_block_model("cook", nodes, hexes, region, _SIDES)


write = msh_writer(build_cook)
main = builder_main(build_cook, "eyeball_fenicsx.meshing.builders.cook", __doc__, region="solid",
                    divisions=dict(type=int, nargs=3, default=(16, 16, 1), metavar=("NX", "NY", "NZ")),
                    thickness=1.0)


if __name__ == "__main__":
    main()

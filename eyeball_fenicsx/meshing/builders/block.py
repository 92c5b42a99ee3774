"""Structured hexahedral mesh of the box [0, Lx] x [0, Ly] x [0, Lz].

Usage: ``/usr/bin/python3 -m eyeball_fenicsx.meshing.builders.block --out block.msh --lengths 1 1 1 --divisions 4 4 4``
"""
from collections.abc import Sequence

import numpy as np

from ...errors import SceneError
from .hexes import add_block_model, builder_main, check, hex_grid, msh_writer

# Surface physical groups by the side of the box they cover: "x0" is the face x = 0, etc.
_SIDES = {"x0": "u-", "x1": "u+", "y0": "v-", "y1": "v+", "z0": "w-", "z1": "w+"}


def build_block(lengths: Sequence[float] = (1.0, 1.0, 1.0), divisions: Sequence[int] = (4, 4, 4),
                region: str = "solid") -> None:
    """Add the gmsh model "block": the box meshed with uniform 8-node hexahedra.

    Call on the rank that owns gmsh, with gmsh initialized. Physical groups: the volume
    ``region`` and the surfaces "x0", "x1", "y0", "y1", "z0", "z1" (``"x0"`` is the face x = 0).

    Args:
        lengths: edge lengths (Lx, Ly, Lz) of the box, positive.
        divisions: number of hexahedra (nx, ny, nz) along each edge, positive integers.
        region: name of the volume physical group.

    Raises:
        SceneError: if a length or a division count is invalid.
    """
    if len(lengths) != 3 or len(divisions) != 3:
        raise SceneError(f"block: lengths and divisions need three entries each, got {lengths!r} and {divisions!r}")
    for axis, length, count in zip("xyz", lengths, divisions):
        check("block", f"the {axis} length", length, "positive number")
        check("block", f"the {axis} division count", count, "positive integer")
    axes = [np.linspace(0.0, length, n + 1) for length, n in zip(lengths, divisions)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    hexes = hex_grid(np.arange(len(nodes)).reshape([n + 1 for n in divisions]))
    add_block_model("block", nodes, hexes, region, _SIDES)


write = msh_writer(build_block)
main = builder_main(build_block, "eyeball_fenicsx.meshing.builders.block", __doc__, region="solid",
                    lengths=dict(type=float, nargs=3, default=(1.0, 1.0, 1.0), metavar=("LX", "LY", "LZ")),
                    divisions=dict(type=int, nargs=3, default=(4, 4, 4), metavar=("NX", "NY", "NZ")))


if __name__ == "__main__":
    main()

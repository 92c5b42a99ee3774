"""Shared plumbing of the builders: structured hexahedra from numpy arrays into gmsh discrete entities.

Node and element numbering follow gmsh: an 8-node hexahedron (element type 5) lists its bottom face
(w = -1) counter-clockwise seen from +w, then the top face (w = +1) in the same order, so a hexahedron
whose (u, v, w) directions form a right-handed frame has a positive Jacobian. Boundary faces are
4-node quadrilaterals (element type 3) ordered counter-clockwise seen from outside the hexahedron.
"""
import argparse
import math
import numbers

import gmsh
import numpy as np
from mpi4py import MPI

from eyeball_fenicsx.errors import SceneError

HEXAHEDRON = 5
QUADRANGLE = 3

# Local nodes of each hexahedron face, counter-clockwise seen from outside, by outward direction.
HEX_FACES = {
    "u-": (0, 4, 7, 3), "u+": (1, 2, 6, 5),
    "v-": (0, 1, 5, 4), "v+": (2, 3, 7, 6),
    "w-": (0, 3, 2, 1), "w+": (4, 5, 6, 7),
}


def check(builder, name, value, kind):
    """Raise SceneError unless a builder parameter is a positive integer or a positive finite number.

    Args:
        builder: builder name, for the message.
        name: parameter name, for the message.
        value: the parameter.
        kind: ``"positive integer"`` or ``"positive number"``.
    """
    valid = isinstance(value, numbers.Integral if kind == "positive integer" else numbers.Real)
    if isinstance(value, bool) or not valid or not math.isfinite(value) or value <= 0:
        raise SceneError(f"{builder}: {name} must be a {kind}, got {value!r}")


def hex_grid(ids):
    """Hexahedra of a structured block of nodes.

    Args:
        ids: node indices, shape ``(nu + 1, nv + 1, nw + 1)``, axes along u, v, w.

    Returns:
        Node indices of the hexahedra in gmsh order, shape ``(nu, nv, nw, 8)``.
    """
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    nu, nv, nw = (size - 1 for size in ids.shape)
    return np.stack([ids[a:a + nu, b:b + nv, c:c + nw] for a, b, c in corners], axis=-1)


def boundary_quads(hexes, side):
    """Outward-oriented quadrilaterals on one side of a structured block of hexahedra.

    Args:
        hexes: hexahedra from :func:`hex_grid`, shape ``(nu, nv, nw, 8)``.
        side: which side of the block, a key of :data:`HEX_FACES` (``"u-"`` is the layer u = 0).

    Returns:
        Node indices of the quadrilaterals, shape ``(count, 4)``.
    """
    axis = "uvw".index(side[0])
    layer = np.take(hexes, 0 if side[1] == "-" else -1, axis=axis)
    return layer[..., HEX_FACES[side]].reshape(-1, 4)


def add_hex_model(name, nodes, hexes, region, surfaces):
    """Add a gmsh model made of one discrete volume of hexahedra and named discrete boundary surfaces.

    The volume physical group gets tag 1 and the surface physical groups tags 2, 3, ... in the
    order of ``surfaces``. Must be called with gmsh initialized; the new model becomes current.

    Args:
        name: name of the gmsh model.
        nodes: node coordinates, shape ``(num_nodes, 3)``.
        hexes: 0-based node indices of the hexahedra in gmsh order, shape ``(num_hexes, 8)``.
        region: name of the volume physical group.
        surfaces: surface physical-group name -> 0-based node indices of its quadrilaterals,
            shape ``(count, 4)``.
    """
    gmsh.model.add(name)
    volume = 1
    surface_tags = list(range(2, len(surfaces) + 2))
    for tag in surface_tags:
        gmsh.model.addDiscreteEntity(2, tag)
    gmsh.model.addDiscreteEntity(3, volume, surface_tags)
    gmsh.model.mesh.addNodes(3, volume, np.arange(1, len(nodes) + 1), np.ravel(nodes))
    gmsh.model.mesh.addElementsByType(volume, HEXAHEDRON, np.arange(1, len(hexes) + 1), np.ravel(hexes) + 1)
    gmsh.model.addPhysicalGroup(3, [volume], volume)
    gmsh.model.setPhysicalName(3, volume, region)
    first = len(hexes) + 1
    for tag, (surface, quads) in zip(surface_tags, surfaces.items()):
        gmsh.model.mesh.addElementsByType(tag, QUADRANGLE, np.arange(first, first + len(quads)), np.ravel(quads) + 1)
        first += len(quads)
        gmsh.model.addPhysicalGroup(2, [tag], tag)
        gmsh.model.setPhysicalName(2, tag, surface)
    gmsh.model.mesh.reclassifyNodes()


def write_msh(path, build, **options):
    """Build a model in a private gmsh session and write it as an MSH 4.1 file (serial).

    Args:
        path: the .msh file to write.
        build: builder function that adds the model to gmsh.
        **options: keyword arguments of ``build``.
    """
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        build(**options)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def run_cli(parser: argparse.ArgumentParser, build, argv=None):
    """Parse a builder's command line, then write the .msh file and report on rank 0.

    An invalid parameter exits with status 2 and the usage message, like any argparse error.

    Args:
        parser: parser with an ``--out`` option and one option per keyword of ``build``.
        build: builder function that adds the model to gmsh.
        argv: command-line arguments (default ``sys.argv[1:]``).
    """
    options = vars(parser.parse_args(argv))
    out = options.pop("out")
    if MPI.COMM_WORLD.rank == 0:
        try:
            write_msh(out, build, **options)
        except SceneError as error:
            parser.error(str(error))
        print(f"wrote {out}")

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


def add_hex_model(name, nodes, hexes, region, surfaces, regions=None):
    """Add a gmsh model made of discrete volumes of hexahedra and named discrete boundary surfaces.

    One region: the volume physical group gets tag 1 and the surface physical groups tags 2, 3, ...
    in the order of ``surfaces``. Several regions (``regions``): the volume groups get tags
    1 .. len(regions) in the order of ``regions``, and the surface groups the next tags. Must be
    called with gmsh initialized; the new model becomes current.

    Args:
        name: name of the gmsh model.
        nodes: node coordinates, shape ``(num_nodes, 3)``.
        hexes: 0-based node indices of the hexahedra in gmsh order, shape ``(num_hexes, 8)``;
            None with ``regions``.
        region: name of the volume physical group; None with ``regions``.
        surfaces: surface physical-group name -> 0-based node indices of its quadrilaterals,
            shape ``(count, 4)``.
        regions: volume physical-group name -> 0-based node indices of its hexahedra, shape
            ``(count, 8)``, instead of ``hexes`` and ``region``. Regions share the nodes they
            have in common (bonded tissues).
    """
    if regions is None:
        regions = {region: hexes}
    elif hexes is not None or region is not None:
        raise ValueError("add_hex_model: give either hexes and region, or regions")
    gmsh.model.add(name)
    volume_tags = list(range(1, len(regions) + 1))
    surface_tags = list(range(len(regions) + 1, len(regions) + len(surfaces) + 1))
    for tag in surface_tags:
        gmsh.model.addDiscreteEntity(2, tag)
    for tag in volume_tags:
        gmsh.model.addDiscreteEntity(3, tag, surface_tags if tag == 1 else [])
    # All nodes go to the first volume; reclassifyNodes() puts each on the entity it belongs to.
    gmsh.model.mesh.addNodes(3, 1, np.arange(1, len(nodes) + 1), np.ravel(nodes))
    first = 1
    for tag, (region_name, cells) in zip(volume_tags, regions.items()):
        gmsh.model.mesh.addElementsByType(tag, HEXAHEDRON, np.arange(first, first + len(cells)), np.ravel(cells) + 1)
        first += len(cells)
        gmsh.model.addPhysicalGroup(3, [tag], tag)
        gmsh.model.setPhysicalName(3, tag, region_name)
    for tag, (surface, quads) in zip(surface_tags, surfaces.items()):
        gmsh.model.mesh.addElementsByType(tag, QUADRANGLE, np.arange(first, first + len(quads)), np.ravel(quads) + 1)
        first += len(quads)
        gmsh.model.addPhysicalGroup(2, [tag], tag)
        gmsh.model.setPhysicalName(2, tag, surface)
    gmsh.model.mesh.reclassifyNodes()


# Corners of the gmsh hexahedron by reference position (a, b, c) in {0, 1}^3 along (u, v, w).
_CORNER = {(0, 0, 0): 0, (1, 0, 0): 1, (1, 1, 0): 2, (0, 1, 0): 3,
           (0, 0, 1): 4, (1, 0, 1): 5, (1, 1, 1): 6, (0, 1, 1): 7}


def corner_jacobians(nodes, hexes):
    """Corner Jacobians of trilinear hexahedra: det(J) and the scaled Jacobian at each of the 8 corners.

    At a corner the columns of J are the three edges along u, v and w, so the scaled Jacobian
    det(J) / (|J_1| |J_2| |J_3|) is 1 for a right-angled corner, sin(alpha) for a corner where two
    edges meet at an angle alpha and the third is perpendicular to both, and <= 0 for an inverted one.

    Args:
        nodes: node coordinates, shape ``(num_nodes, 3)``.
        hexes: node indices in gmsh order, shape ``(num_hexes, 8)``.

    Returns:
        ``(det, scaled)``, each of shape ``(num_hexes, 8)``.
    """
    x = nodes[hexes]
    det, scaled = np.empty(hexes.shape), np.empty(hexes.shape)
    for (a, b, c), corner in _CORNER.items():
        columns = np.stack([x[:, _CORNER[1, b, c]] - x[:, _CORNER[0, b, c]],
                            x[:, _CORNER[a, 1, c]] - x[:, _CORNER[a, 0, c]],
                            x[:, _CORNER[a, b, 1]] - x[:, _CORNER[a, b, 0]]], axis=-1)
        det[:, corner] = np.linalg.det(columns)
        scaled[:, corner] = det[:, corner] / np.prod(np.linalg.norm(columns, axis=-2), axis=-1)
    return det, scaled


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

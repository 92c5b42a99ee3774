"""Shared plumbing of the builders: structured hexahedra from numpy arrays into gmsh discrete entities.

Node and element numbering follow gmsh: an 8-node hexahedron (element type 5) lists its bottom face
(w = -1) counter-clockwise seen from +w, then the top face (w = +1) in the same order, so a hexahedron
whose (u, v, w) directions form a right-handed frame has a positive Jacobian. Boundary faces are
4-node quadrilaterals (element type 3) ordered counter-clockwise seen from outside the hexahedron.

Measures of the elements: corner Jacobians (the mesh quality), and by Gauss-Legendre quadrature with
2 points per direction the areas of bilinear quadrilaterals, the volume that a closed surface of
element faces encloses (the divergence theorem: -(1/3) of the integral of x . n, n the faces' normal,
out of their hexahedra and so into the enclosed cavity; negative for the outer boundary of a mesh)
and the volumes of trilinear hexahedra. The two volumes are exact, their integrands being
polynomials of degree at most 2 in each reference coordinate.

Each builder is also a command, ``python3 -m eyeball_fenicsx.meshing.builders.<name> --out <file>.msh
[options]`` (:func:`builder_main`), and has a ``write(path, **options)`` (:func:`msh_writer`).
"""
import argparse
import math
import numbers
import os
from collections.abc import Callable, Sequence

import gmsh
import numpy as np
from mpi4py import MPI

from ...checks import is_number
from ...errors import SceneError

HEXAHEDRON = 5
QUADRANGLE = 3

# Reference positions (a, b, c) in {0, 1}^3 along (u, v, w) of the corners of the gmsh hexahedron, in its order.
_CORNERS = ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))
_CORNER = {position: corner for corner, position in enumerate(_CORNERS)}

# Local nodes of each hexahedron face, counter-clockwise seen from outside, by outward direction.
HEX_FACES = {
    "u-": (0, 4, 7, 3), "u+": (1, 2, 6, 5),
    "v-": (0, 1, 5, 4), "v+": (2, 3, 7, 6),
    "w-": (0, 3, 2, 1), "w+": (4, 5, 6, 7),
}


def check(builder: str, name: str, value, kind: str) -> None:
    """Raise SceneError unless a builder parameter is a positive integer or a positive finite number.

    Args:
        builder: builder name, for the message.
        name: parameter name, for the message.
        value: the parameter.
        kind: ``"positive integer"`` or ``"positive number"``.
    """
    valid = is_number(value) and (kind != "positive integer" or isinstance(value, numbers.Integral))
    if not valid or value <= 0:
        raise SceneError(f"{builder}: {name} must be a {kind}, got {value!r}")


def hex_grid(ids: np.ndarray) -> np.ndarray:
    """Hexahedra of a structured block of nodes.

    Args:
        ids: node indices, shape ``(nu + 1, nv + 1, nw + 1)``, axes along u, v, w.

    Returns:
        Node indices of the hexahedra in gmsh order, shape ``(nu, nv, nw, 8)``.
    """
    nu, nv, nw = (size - 1 for size in ids.shape)
    return np.stack([ids[a:a + nu, b:b + nv, c:c + nw] for a, b, c in _CORNERS], axis=-1)


def boundary_quads(hexes: np.ndarray, side: str) -> np.ndarray:
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


def faces(hexes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All hexahedron faces, outward and counter-clockwise: ``(quads, face_id)`` with
    quads shape ``(6 num_hexes, 4)``, row 6 h + f the face f of hexahedron h, and face_id the
    same number for the two sides of an interior face."""
    quads = hexes[:, list(HEX_FACES.values())].reshape(-1, 4)
    _, face_id = np.unique(np.sort(quads, axis=1), axis=0, return_inverse=True)
    return quads, face_id.ravel()


def open_edges(quads: np.ndarray) -> np.ndarray:
    """Edges (node pairs) used by one quadrilateral of ``quads`` only."""
    edges = np.sort(np.concatenate([quads[:, [k, (k + 1) % 4]] for k in range(4)]), axis=1)
    unique_edges, counts = np.unique(edges, axis=0, return_counts=True)
    return unique_edges[counts == 1]


def add_hex_model(name: str, nodes: np.ndarray, hexes: np.ndarray | None, region: str | None,
                  surfaces: dict[str, np.ndarray], regions: dict[str, np.ndarray] | None = None) -> None:
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


def add_block_model(name: str, nodes: np.ndarray, hexes: np.ndarray, region: str, sides: dict[str, str]) -> None:
    """Add a gmsh model of one structured block (:func:`add_hex_model`), its surfaces named by side.

    Args:
        name: name of the gmsh model.
        nodes: node coordinates, shape ``(num_nodes, 3)``.
        hexes: hexahedra from :func:`hex_grid`, shape ``(nu, nv, nw, 8)``.
        region: name of the volume physical group.
        sides: surface physical-group name -> the side of the block it covers (:func:`boundary_quads`).
    """
    surfaces = {surface: boundary_quads(hexes, side) for surface, side in sides.items()}
    add_hex_model(name, nodes, hexes.reshape(-1, 8), region, surfaces)


def corner_jacobians(nodes: np.ndarray, hexes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


_GAUSS = (0.5 - 0.5 / math.sqrt(3), 0.5 + 0.5 / math.sqrt(3))


def _bilinear(nodes, quads):
    """Yield (weight, point, x_u x x_v) at the 2 x 2 Gauss points of bilinear quadrilaterals."""
    x = nodes[quads]  # corners 0, 1, 2, 3 at (u, v) = (0, 0), (1, 0), (1, 1), (0, 1)
    for u in _GAUSS:
        for v in _GAUSS:
            point = x[:, 0] * (1 - u) * (1 - v) + x[:, 1] * u * (1 - v) + x[:, 2] * u * v + x[:, 3] * (1 - u) * v
            du = (x[:, 1] - x[:, 0]) * (1 - v) + (x[:, 2] - x[:, 3]) * v
            dv = (x[:, 3] - x[:, 0]) * (1 - u) + (x[:, 2] - x[:, 1]) * u
            yield 0.25, point, np.cross(du, dv)


def quad_areas(nodes: np.ndarray, quads: np.ndarray) -> np.ndarray:
    """Areas of bilinear quadrilaterals."""
    return sum(w * np.linalg.norm(normal, axis=1) for w, _, normal in _bilinear(nodes, quads))


def enclosed_volume(nodes: np.ndarray, quads: np.ndarray) -> float:
    """-(1/3) integral of x . n over bilinear quadrilaterals, n their outward normal (2 x 2 Gauss: exact)."""
    return -sum(w * np.sum(point * normal) for w, point, normal in _bilinear(nodes, quads)) / 3


def hex_volumes(nodes: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """Volumes of trilinear hexahedra (gmsh order), exact (2 x 2 x 2 Gauss points)."""
    x = nodes[hexes]
    volume = np.zeros(len(hexes))
    for u in _GAUSS:
        for v in _GAUSS:
            for w in _GAUSS:
                jacobian = np.zeros((len(hexes), 3, 3))
                for k, (a, b, c) in enumerate(_CORNERS):
                    weights = ((u if a else 1 - u), (v if b else 1 - v), (w if c else 1 - w))
                    gradient = ((1 if a else -1) * weights[1] * weights[2], (1 if b else -1) * weights[0] * weights[2],
                                (1 if c else -1) * weights[0] * weights[1])
                    jacobian += x[:, k, :, None] * np.array(gradient)[None, None, :]
                volume += np.linalg.det(jacobian) / 8
    return volume


def write_msh(path: str | os.PathLike, build: Callable, **options) -> None:
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


def msh_writer(build: Callable) -> Callable[..., None]:
    """The ``write(path, **options)`` function of a builder: :func:`write_msh` of ``build``."""
    def write(path: str | os.PathLike, **options) -> None:
        write_msh(path, build, **options)

    write.__doc__ = (f"Write the model of ``{build.__name__}`` (its keyword arguments ``options``) to the MSH 4.1 "
                     "file ``path``, in a private gmsh session (serial).")
    return write


def builder_main(build: Callable, module: str, doc: str, region: str | None = None,
                 **options: dict | float) -> Callable[[Sequence[str] | None], None]:
    """The command-line entry point of a builder: ``python3 -m <module> --out <file>.msh [options]``.

    Args:
        build: the function that adds the model to gmsh, called with the options.
        module: the builder's module, for the usage message.
        doc: its module docstring, whose first line describes the command.
        region: if given, the default of ``--region``, the name of the volume physical group.
        **options: option name (a keyword of ``build``; on the command line with ``--`` and dashes
            for underscores) -> the keyword arguments of ``argparse.ArgumentParser.add_argument``,
            or just a default (an int or a float: the option takes one number of its type).

    Returns:
        ``main(argv=None)``, which parses ``argv`` (default ``sys.argv[1:]``) and runs :func:`run_cli`.
    """
    def main(argv: Sequence[str] | None = None) -> None:
        parser = argparse.ArgumentParser(prog=f"python3 -m {module}", description=doc.splitlines()[0])
        parser.add_argument("--out", required=True, help="the .msh file to write")
        for name, keywords in options.items():
            if not isinstance(keywords, dict):
                keywords = {"type": type(keywords), "default": keywords}
            parser.add_argument(f"--{name.replace('_', '-')}", dest=name, **keywords)
        if region is not None:
            parser.add_argument("--region", default=region, help="name of the volume physical group")
        run_cli(parser, build, argv)

    main.__doc__ = f"Command-line entry point: {doc.splitlines()[0]} (written on rank 0 under MPI)."
    return main


def run_cli(parser: argparse.ArgumentParser, build: Callable, argv: Sequence[str] | None = None) -> None:
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

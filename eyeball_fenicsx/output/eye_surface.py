"""A 3D picture of the eye as the surgeon sees it: the deformed outer surface of the globe and its
buckle, coloured by the von Mises stress of the element under each face, as the seed's program
shows its results (Sun and Makinouchi, "Mises stress (MPa)" after each step of the operation).

Method: the faces drawn are the owned facets of the named outer surfaces (``OUTER_SURFACES``: the
cornea, the sclera, the optic nerve, the band's and the tire's faces but their inner ones, which
lie on the sclera), moved by the current displacement and gathered on rank 0 with their cells'
stress (``gather_faces``, with which the section of output/eye_pictures.py gathers its faces
too): a surface, never the mesh. A wedge model is mirrored across the planes of its cut surfaces
("cut_0", "cut_1") to show the whole eye. The faces are projected orthographically along the
line of sight (``VIEW``, the optic axis to the right, ``screen_axes``) and drawn as one 2D
PolyCollection, farthest first (the painter's algorithm, faces sorted by mean depth). Of the
globe only the faces that face the viewer are drawn (centroids in front of the plane through the
eye's centre normal to the line of sight, which in an orthographic projection is exactly the
visible half of a sphere), so that the painter's algorithm has no hidden face to misplace; the
buckle's faces are all drawn, since its far side shows beyond the globe's outline. Each face is
shaded by its angle to a light along the line of sight (a Lambert term, 0.55 + 0.45 |cos|).
The figure (``SurfacePicture``) is built for the first picture and drawn again after each step with the
new faces, colour scales and title.

Colour scales: the band's stress is not the tissues' (default eye: the largest 0.004 MPa against
the sclera's 0.027 at 15 mmHg, 0.23 against 0.11 once tightened), so on one scale one of the two
would sit in its lowest colours. The eye's tissues take the seed's rainbow (``jet``) from 0 to
the 99th percentile of their drawn faces (a robust top: a few faces do not squeeze the others
into the lowest colours; those above it take the top colour, and the colour bar says so);
the buckle's bodies (``BUCKLE_REGIONS``) have a scale and a colour bar of their own (``copper``,
from 0 to their largest face).
"""
from __future__ import annotations

import itertools
from typing import TYPE_CHECKING

import numpy as np
from dolfinx import cpp
from mpi4py import MPI

from .files import new_figure, save_figure_atomic

if TYPE_CHECKING:
    from dolfinx import fem

    from ..mechanics.solid import MixedSolid
    from ..meshing.load import MeshData

# The surfaces of eye.py and buckled_eye.py seen from outside (those a mesh lacks are skipped).
OUTER_SURFACES = ("cornea_outer", "sclera_outer", "optic_nerve_side", "optic_nerve_end", "band_outer", "band_front",
                  "band_back", "tire_outer", "tire_front", "tire_back", "tire_end_0", "tire_end_1")
BUCKLE_REGIONS = ("band", "tire")
EYE_PERCENTILE = 99.0
# The picture's axes: its horizontal x the optic axis (model z, the cornea at +), its y the
# model's x, its vertical the model's y (the half model's cut plane is horizontal).
PLOT_AXES = (2, 0, 1)
# The line of sight, in the picture's axes, from the eye towards the viewer: in front of the eye
# and to its side, a little from above, so that the cornea, the band and the globe behind show.
VIEW = np.array([0.55, -0.75, 0.35])
SMALLEST_TOP = 1e-6  # MPa: the top of a colour scale over a body without stress
EYE_MAP, BUCKLE_MAP = "jet", "copper"
# The picture (inches), and where the eye sits in it: the centre of its bounding box at FRAME_CENTRE
# (fractions of the figure), the figure's height FRAME_HEIGHT times the box's largest side.
FIGURE_SIZE, FRAME_CENTRE, FRAME_HEIGHT = (8.0, 6.0), (0.36, 0.47), 1.26


def quad_nodes(msh, facets: np.ndarray) -> np.ndarray:
    """The geometry nodes of quadrilateral facets, in cyclic order (count, 4)."""
    # DOLFINx numbers a quadrilateral's vertices as a tensor product: 0, 1, 3, 2 goes round it.
    return cpp.mesh.entities_to_geometry(msh._mesh, msh.topology.dim - 1, facets, False)[:, [0, 1, 3, 2]]


def gather_faces(mesh_data: MeshData, facets: np.ndarray, solid: MixedSolid | None = None,
                 field: fem.Function | None = None, root: int = 0) -> tuple:
    """Corners, region names and field values of owned quadrilateral facets, gathered on rank ``root``.

    Collective.

    Args:
        facets: local indices of owned facets (each facet on one rank only).
        solid: if given, the corners are moved by its current displacement (evaluated in the
            facet's cell).
        field: a cell-wise (DG0) function whose value each face takes (that of its cell).

    Returns:
        On rank ``root``, ``(corners, regions, values)``: shape ``(count, 4, 3)`` in cyclic order,
        the region name of each face's cell, and the field's values (NaN without a field);
        ``(None, None, None)`` elsewhere.
    """
    msh = mesh_data.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    facet_cells = msh.topology.connectivity(tdim - 1, tdim)
    cells = np.array([facet_cells.links(f)[0] for f in facets], dtype=np.int32)
    names = {tag: name for name, tag in mesh_data.regions.items()}
    cell_map = msh.topology.index_map(tdim)
    tag_of_cell = np.zeros(cell_map.size_local + cell_map.num_ghosts, dtype=np.int32)
    tag_of_cell[mesh_data.cell_tags.indices] = mesh_data.cell_tags.values
    regions = [names.get(tag, "") for tag in tag_of_cell[cells]]
    corners = msh.geometry.x[quad_nodes(msh, facets)].reshape(-1, 4, 3)
    if solid is not None and len(cells):  # each corner moved by u evaluated in the face's cell
        u = solid.w.sub(0)
        corners = corners + u.eval(corners.reshape(-1, 3), np.repeat(cells, 4))[:, :3].reshape(corners.shape)
    values = field.x.array[cells] if field is not None else np.full(len(cells), np.nan)
    gathered = msh.comm.gather((corners, regions, values), root=root)
    if msh.comm.rank != root:
        return None, None, None
    return (np.concatenate([g[0] for g in gathered]).reshape(-1, 4, 3), [name for g in gathered for name in g[1]],
            np.concatenate([g[2] for g in gathered]))


def outer_facets(solid: MixedSolid) -> np.ndarray:
    """Local indices of the owned facets of the mesh's ``OUTER_SURFACES``, each once."""
    md = solid.mesh_data
    owned = md.mesh.topology.index_map(md.mesh.topology.dim - 1).size_local
    facets = [md.facets(name) for name in OUTER_SURFACES if name in md.surfaces]
    facets = np.unique(np.concatenate(facets)) if facets else np.zeros(0, dtype=np.int32)
    return facets[facets < owned].astype(np.int32)


def mirror_axes(solid: MixedSolid, tolerance: float = 1e-9) -> list[int]:
    """The coordinate axes (x 0, y 1) whose planes through the optic axis hold a cut surface of a
    wedge model: [1] for a half model (both cuts in y = 0), [0, 1] for a quarter, [] for a whole
    eye. Collective."""
    md = solid.mesh_data
    msh = md.mesh
    axes = set()
    for name in ("cut_0", "cut_1"):
        facets = md.facets(name) if name in md.surfaces else np.zeros(0, dtype=np.int32)
        x = msh.geometry.x[quad_nodes(msh, facets).ravel()] if len(facets) else np.zeros((0, 3))
        extent = _largest(msh.comm, x)
        axes |= {axis for axis in (0, 1) if 0.0 <= extent[axis] < tolerance}
    return sorted(axes)


def _largest(comm: MPI.Comm, x: np.ndarray) -> np.ndarray:
    """The largest |x| and |y| of points over the ranks (-1 where no rank has a point)."""
    local = np.abs(x[:, :2]).max(axis=0) if len(x) else np.full(2, -1.0)
    result = np.empty(2)
    comm.Allreduce(local, result, op=MPI.MAX)
    return result


def mirrored(corners: np.ndarray, values: np.ndarray, buckle: np.ndarray, axes: list[int]) -> tuple:
    """The faces and their copies reflected across every combination of the planes ``axes``."""
    copies = []
    for flips in itertools.chain.from_iterable(itertools.combinations(axes, k) for k in range(len(axes) + 1)):
        sign = np.ones(3)
        sign[list(flips)] = -1.0
        copies.append(corners * sign)
    count = len(copies)
    return np.concatenate(copies), np.tile(values, count), np.tile(buckle, count)


def screen_axes(view: np.ndarray) -> np.ndarray:
    """The orthographic projection along the unit vector ``view`` (from the scene towards the
    viewer), as a (3, 2) matrix: a point's coordinates on the screen, to the right and upwards
    (the third axis upright)."""
    right = np.cross((0.0, 0.0, 1.0), view)
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(view, right)], axis=1)


def shaded_faces(corners: np.ndarray, regions: list[str], values: np.ndarray, axes: list[int]) -> tuple:
    """The faces of the picture (module docstring): the outer surface mirrored across ``axes``,
    the globe's faces that face the viewer and all the buckle's, projected, farthest first.

    Returns:
        ``(polygons, colours, tops, limits)``: the faces on the screen (count, 4, 2), their
        shaded RGBA colours, the tops of the eye's and the buckle's colour scales (MPa; the
        buckle's None without one) and the picture's (x, y) limits.
    """
    from matplotlib import colormaps

    buckle = np.array([region in BUCKLE_REGIONS for region in regions], dtype=bool)
    corners, values, buckle = mirrored(corners, values, buckle, axes)
    corners = corners[..., list(PLOT_AXES)]
    view = VIEW / np.linalg.norm(VIEW)
    front = (corners.mean(axis=1) @ view >= 0.0) | buckle
    corners, values, buckle = corners[front], values[front], buckle[front]
    normals = np.cross(corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 1])
    light = 0.55 + 0.45 * np.abs(normals @ view) / np.maximum(np.linalg.norm(normals, axis=1), 1e-300)
    eye_values = values[~buckle]
    eye_top = max(float(np.percentile(eye_values, EYE_PERCENTILE)) if len(eye_values) else 0.0, SMALLEST_TOP)
    buckle_top = max(float(values[buckle].max()), SMALLEST_TOP) if buckle.any() else None
    rgba = np.where(buckle[:, None], colormaps[BUCKLE_MAP](values / (buckle_top or 1.0)),
                    colormaps[EYE_MAP](values / eye_top))
    rgba[:, :3] *= light[:, None]
    projection = screen_axes(view)
    order = np.argsort(corners.mean(axis=1) @ view)  # the painter's algorithm: the farthest face first
    low, high = corners.reshape(-1, 3).min(axis=0), corners.reshape(-1, 3).max(axis=0)
    centre = 0.5 * (low + high) @ projection
    (x, y), (width, height) = FRAME_CENTRE, FIGURE_SIZE
    height_mm = FRAME_HEIGHT * (high - low).max()
    width_mm = height_mm * width / height
    limits = ((centre[0] - x * width_mm, centre[0] + (1 - x) * width_mm),
              (centre[1] - y * height_mm, centre[1] + (1 - y) * height_mm))
    return corners[order] @ projection, rgba[order], (eye_top, buckle_top), limits


class SurfacePicture:
    """The figure of the outer surface coloured by the von Mises stress, built at its first draw
    and drawn again with the new faces, colour scales and title after (its axes, colour bars and
    their ticks are kept)."""

    def __init__(self) -> None:
        self._figure = None

    def _build(self, buckle: bool, whole: bool) -> None:
        from matplotlib import cm, colors
        from matplotlib.collections import PolyCollection

        self._figure = figure = new_figure(FIGURE_SIZE)
        self._axes = figure.add_axes((0.0, 0.0, 1.0, 1.0))
        self._axes.set_axis_off()
        self._faces = PolyCollection([], edgecolors=(0, 0, 0, 0.15), linewidths=0.1)
        self._axes.add_collection(self._faces, autolim=False)
        bars = [(EYE_MAP, f"eye (MPa; top: {EYE_PERCENTILE:g}th percentile)", "max")]
        if buckle:
            bars.append((BUCKLE_MAP, "buckle (MPa)", "neither"))
        self._scales = [cm.ScalarMappable(colors.Normalize(0.0, 1.0), colour_map) for colour_map, _, _ in bars]
        for k, (scale, (_, text, extend)) in enumerate(zip(self._scales, bars)):
            figure.colorbar(scale, cax=figure.add_axes((0.74 + 0.13 * k, 0.12, 0.025, 0.7)), extend=extend,
                            label=f"von Mises stress, {text}")
        self._title = figure.suptitle("", fontsize=11)
        figure.text(0.02, 0.02, ("the model mirrored to the whole eye; " if whole else "") + "the cornea to the right",
                    fontsize=8)

    def draw(self, corners: np.ndarray, regions: list[str], values: np.ndarray, path: str, axes: list[int],
             title: str | None = None) -> None:
        """Write the picture of the outer surface, mirrored across ``axes``. Call on one rank, with
        what ``gather_faces`` gathered."""
        polygons, colours, tops, (xlim, ylim) = shaded_faces(corners, regions, values, axes)
        if self._figure is None:
            self._build(tops[1] is not None, bool(axes))
        self._faces.set_verts(polygons)
        self._faces.set_facecolor(colours)
        self._axes.set(xlim=xlim, ylim=ylim)
        for scale, top in zip(self._scales, tops):
            scale.set_clim(0.0, top)
        self._title.set_text(title or "")
        save_figure_atomic(self._figure, path, dpi=110)


class OuterSurface:
    """The outer surface of one solid's eye, found once (collective): its facets and mirror planes."""

    def __init__(self, solid: MixedSolid) -> None:
        self.solid = solid
        self.facets = outer_facets(solid)
        self.axes = mirror_axes(solid)
        self.picture = SurfacePicture()

    def faces(self, mises: fem.Function) -> tuple:
        """The faces of the current state and their ``mises`` (DG0), as ``gather_faces`` gathers
        them on rank 0. Collective."""
        return gather_faces(self.solid.mesh_data, self.facets, self.solid, mises)

    def draw(self, faces: tuple, path: str, title: str | None = None) -> None:
        """The picture of ``faces`` (from ``faces``); nothing on the ranks that did not gather them."""
        corners, regions, values = faces
        if corners is not None and len(corners):
            self.picture.draw(corners, regions, values, path, self.axes, title)

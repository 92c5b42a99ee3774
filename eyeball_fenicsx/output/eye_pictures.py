"""Pictures of the eye model: its meridional section with the tissues coloured or its stress,
the retina's gap from the choroid over a detachment, and the eye measures over the steps of a
run. Files appear atomically (output/files.py). The functions only draw what they are given.

Data path: ``EyePictures`` observes the runs of a scene with an output folder (output/observer.py),
after the ``EyeMeasures`` (output/measures.py) whose results it draws: after each converged step
``section_<step>.png`` (the deformed meridional section coloured by the von Mises stress the
measures just interpolated) and, with a detachment, ``retina_gap_<step>.png`` (the gap they just
measured, flattened), and at the end of a run ``eye_measures.png`` (the scalar measures of that
run's steps, from its summary). After a step the ranks draw at the same time: the last rank the
gap map, rank 0 the outer surface and, on two ranks, the section (on three or more, rank 1
draws it); at the end each rank draws its share of the measures' rows (output/files.py's
``plot_curves``). Each figure has fixed margins (no layout
pass) and is rendered once, on its own Agg canvas (output/files.py); the section's
(``SectionPicture``), like the outer surface's (output/eye_surface.py), is built for the first
step and drawn again after the others.
"""
from __future__ import annotations

import os
import re
from typing import TYPE_CHECKING

import numpy as np
from dolfinx import fem

from .eye_surface import OuterSurface, gather_faces, quad_nodes
from .files import could_not_draw, flatten, new_figure, plot_curves, raise_any_rank_failure, save_figure_atomic
from .labels import label
from .measures import DETACHED_GAP, EyeMeasures, polar_angle
from .observer import Observer

if TYPE_CHECKING:
    from mpi4py import MPI

    from ..mechanics.solid import MixedSolid
    from ..meshing.load import MeshData
    from ..system.problem import Problem

# Tissue colours of the section (matplotlib names); regions not listed are grey.
TISSUE_COLOURS = {"cornea": "lightskyblue", "sclera": "gainsboro", "ciliary_body": "sienna", "choroid": "firebrick",
                  "retina": "hotpink", "optic_nerve": "gold", "lens": "steelblue", "zonule": "seagreen"}


def meridional_section(mesh_data: MeshData, tolerance: float = 1e-9, solid: MixedSolid | None = None,
                       field: fem.Function | None = None, root: int = 0) -> tuple:
    """Faces of the mesh in the plane y = 0 (the section through the optic axis at azimuth 0 and 180).

    Collective.

    Args:
        mesh_data: a :class:`~eyeball_fenicsx.meshing.load.MeshData` of hexahedra whose nodes lie exactly on
            y = 0 where the section cuts them (true of ``eyeball_fenicsx.meshing.builders.eye``).
        tolerance: distance (mesh units) under which a node is on the plane.
        solid: if given, the faces are drawn in its current (deformed) configuration.
        field: a cell-wise (DG0) function whose value each face takes (von Mises stress).
        root: the rank that receives the faces.

    Returns:
        On rank ``root``, ``(polygons, regions, values)``: the faces' corners in the (x, z) plane in
        cyclic order, shape ``(count, 4, 2)``, the region name of each face and the field's
        value on it (None without a field); ``(None, None, None)`` elsewhere.
    """
    msh = mesh_data.mesh
    tdim = msh.topology.dim
    facets = np.arange(msh.topology.index_map(tdim - 1).size_local, dtype=np.int32)
    x = msh.geometry.x[quad_nodes(msh, facets)]
    corners, regions, values = gather_faces(mesh_data, facets[np.all(np.abs(x[..., 1]) < tolerance, axis=1)],
                                            solid, field, root)
    if corners is None:
        return None, None, None
    return corners[..., [0, 2]], regions, values if field is not None else None


def eye_section_png(mesh_data: MeshData, path: str, title: str | None = None) -> None:
    """Draw the meridional section of an eye mesh with its tissues coloured, as a PNG (matplotlib Agg).

    Collective; rank 0 writes the file.

    Args:
        mesh_data: the eye mesh (:func:`eyeball_fenicsx.meshing.builders.eye.build_eye` through ``built_mesh``).
        path: the .png file to write.
        title: optional title of the figure.
    """
    polygons, regions, _ = meridional_section(mesh_data)
    if polygons is None:  # not rank 0
        return
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Patch

    figure = new_figure((7, 8))
    axes = figure.add_axes((0.12, 0.07, 0.85, 0.87))
    colours = [TISSUE_COLOURS.get(name, "grey") for name in regions]
    axes.add_collection(PolyCollection(polygons, facecolors=colours, edgecolors="black", linewidths=0.15))
    axes.autoscale_view()
    axes.set_aspect("equal")
    axes.set_xlabel("x (mm)")
    axes.set_ylabel("z: optic axis (mm)")
    present = [name for name in TISSUE_COLOURS if name in set(regions)]
    axes.legend(handles=[Patch(facecolor=TISSUE_COLOURS[name], edgecolor="black", label=name.replace("_", " "))
                         for name in present], loc="center", fontsize=8, frameon=False)
    if title:
        axes.set_title(title)
    save_figure_atomic(figure, path)


class SectionPicture:
    """The figure of the deformed section coloured by the von Mises stress, built at its first
    draw and drawn again with the new faces, colour scale and title after (its axes, colour
    bar and ticks are kept)."""

    def __init__(self) -> None:
        self._figure = None

    def draw(self, polygons: np.ndarray, values: np.ndarray, path: str, title: str | None = None) -> None:
        """Write the picture of faces ``polygons`` (count, 4, 2) coloured by ``values`` (MPa). Call on one rank."""
        from matplotlib.collections import PolyCollection

        if self._figure is None:
            self._figure = figure = new_figure((7, 8))
            self._axes = axes = figure.add_axes((0.12, 0.07, 0.7, 0.87))
            self._faces = PolyCollection([], cmap="jet", edgecolors="none")
            axes.add_collection(self._faces, autolim=False)
            figure.colorbar(self._faces, cax=figure.add_axes((0.85, 0.2, 0.035, 0.6)), label="von Mises stress (MPa)")
            axes.set_aspect("equal")
            axes.set_xlabel("x (mm)")
            axes.set_ylabel("z: optic axis (mm)")
        self._faces.set_verts(polygons)
        self._faces.set_array(values)
        self._faces.set_clim(values.min(), values.max())
        low, high = polygons.reshape(-1, 2).min(axis=0), polygons.reshape(-1, 2).max(axis=0)
        margin = 0.05 * (high - low)  # matplotlib's default margins
        self._axes.set(xlim=(low[0] - margin[0], high[0] + margin[0]), ylim=(low[1] - margin[1], high[1] + margin[1]))
        self._axes.set_title(title or "", y=1.0)  # fixed above the axes: nothing of theirs goes there
        save_figure_atomic(self._figure, path, dpi=110)


def stress_section_png(solid: MixedSolid, mises: fem.Function, path: str, title: str | None = None) -> None:
    """Draw the deformed meridional section coloured by the von Mises stress (MPa), as the
    seed shows its results. Collective; rank 0 writes the file.

    Args:
        solid: the solved ``MixedSolid`` (its current displacement deforms the section).
        mises: a cell-wise (DG0) function of the von Mises stress.
        path: the .png file to write.
    """
    polygons, _, values = meridional_section(solid.mesh_data, solid=solid, field=mises)
    if polygons is None or not len(polygons):  # not rank 0, or no face in the plane y = 0
        return
    SectionPicture().draw(polygons, values, path, title)


def retina_gap_png(azimuth: np.ndarray, polar: np.ndarray, gap: np.ndarray, path: str, detached: float,
                   title: str | None = None) -> None:
    """Map the retina-choroid gap (mm) over the detached retina, flattened: each node of
    "retina_outer" at its reference azimuth and polar angle from the posterior pole (degrees),
    with the contour of ``detached``, the gap beyond which the retina counts as detached. Call
    on one rank.
    """
    figure = new_figure((8, 4.5))
    axes = figure.add_axes((0.09, 0.11, 0.72, 0.81))
    levels = np.linspace(min(gap.min(), 0.0), max(gap.max(), 1e-3), 21)
    filled = axes.tricontourf(azimuth, polar, gap, levels=levels, cmap="viridis")
    if gap.min() < detached < gap.max():
        axes.tricontour(azimuth, polar, gap, levels=[detached], colors="white", linewidths=1.0)
    figure.colorbar(filled, cax=figure.add_axes((0.84, 0.11, 0.03, 0.81)),
                    label=f"retina-choroid gap (mm); white: {detached} mm, detached beyond")
    axes.set_xlabel("azimuth (deg)")
    axes.set_ylabel("polar angle from the posterior pole (deg)")
    if title:
        axes.set_title(title, y=1.0)
    save_figure_atomic(figure, path, dpi=110)


def eye_measures_png(steps: list[dict], path: str, comm: MPI.Comm | None = None) -> None:
    """Curves of the scalar eye measures over the steps of a run (one plot a measure, one
    point a step, in the order of ``steps``). Call on one rank, or on every rank of ``comm``
    (they draw it together: ``plot_curves``).

    Args:
        steps: summary.json's "steps"; those without an "eye" entry are left out.
        path: the .png file to write.
    """
    steps = [step for step in steps if "eye" in step]
    if not steps:
        return
    rows = [flatten(step["eye"]) for step in steps]
    names = [name for name in rows[0] if all(isinstance(row.get(name), float) for row in rows)]
    curves = {label(f"eye.{name}"): [row[name] for row in rows] for name in names}
    plot_curves(path, list(range(1, len(rows) + 1)), curves, "step", [step["name"] for step in steps], comm=comm)


def step_pictures(step: str) -> dict[str, str]:
    """The file names of the pictures ``EyePictures`` draws after step ``step``, by kind."""
    name = re.sub(r"[^\w.-]+", "_", step)
    return {"surface": f"surface_{name}.png", "section": f"section_{name}.png", "retina_gap": f"retina_gap_{name}.png"}


class EyePictures(Observer):
    """The pictures of the eye's runs (see the module docstring), drawn from ``measures``, an
    observer of the same scene that comes before this one."""

    def __init__(self, measures: EyeMeasures) -> None:
        self.measures = measures

    def setup(self, solid: MixedSolid, problem: Problem) -> None:
        self.solid = solid
        self._surface, self._section = OuterSurface(solid), SectionPicture()

    def start(self, scene: str, out_dir: str | None) -> None:
        self.scene, self.out_dir = scene, out_dir

    def after_step(self, step: str, index: int, entry: dict, converged: bool) -> None:
        """Collective: the outer surface and the section coloured by the stress, and the retina's
        gap map, of a converged step, as the measures just measured them. Each is gathered
        first, then drawn at once: the surface on rank 0, the gap map (the slowest) on the last
        rank, the section on rank 1 if there are three ranks or more, else on rank 0 (one rank
        draws all three); every file is written when this returns, on every rank, and a failure
        on any rank is an ``OutputError`` on every rank."""
        if not self.out_dir or not converged:
            return
        files = {kind: os.path.join(self.out_dir, name) for kind, name in step_pictures(step).items()}
        title = f"{self.scene}, step {step}: von Mises stress (MPa)"
        size = self.solid.comm.size
        surface = self._surface.faces(self.measures.mises)
        section, _, mises = meridional_section(self.solid.mesh_data, solid=self.solid, field=self.measures.mises,
                                               root=1 if size > 2 else 0)
        X, gap = self.measures.retina_gap_map(root=size - 1)
        drawings = {"surface": lambda: self._surface.draw(surface, files["surface"], title)}
        if section is not None and len(section):
            drawings["section"] = lambda: self._section.draw(section, mises, files["section"], title)
        if X is not None:
            drawings["retina_gap"] = lambda: retina_gap_png(
                np.degrees(np.arctan2(X[:, 1], X[:, 0])), np.degrees(polar_angle(X)), gap, files["retina_gap"],
                DETACHED_GAP, title=f"{self.scene}, step {step}: the detached retina")
        failure = None
        for kind, draw in drawings.items():
            try:
                draw()
            except Exception as error:  # said on every rank, none left waiting for the others
                failure = failure or could_not_draw(files[kind], error)
        raise_any_rank_failure(failure, self.solid.comm)  # the run's page (output/report.py, rank 0) shows them next

    def finish(self, summary: dict) -> None:
        """Collective: the eye measures' picture, drawn by every rank (``eye_measures_png``)."""
        if self.out_dir:
            eye_measures_png(summary["steps"], os.path.join(self.out_dir, "eye_measures.png"), self.solid.comm)

"""What a run writes: field output (XDMF for ParaView), summary.json and pictures (small plots
of curves drawn by one rank, or by the ranks together, each its rows: ``plot_curves``).

Every file appears atomically: summary.json and the PNG pictures are written to a temporary
name and renamed; the XDMF/HDF5 pair is written in a hidden folder and moved into place when
closed.
"""
from __future__ import annotations

import json
import os
import shutil
from typing import TYPE_CHECKING

import numpy as np
from dolfinx import fem, io
from mpi4py import MPI

from ..errors import OutputError
from .observer import Observer

if TYPE_CHECKING:
    from ..mechanics.solid import MixedSolid
    from ..system.problem import Problem


class FieldOutput(Observer):
    """Displacement, pressure, von Mises stress and region tags after each step, in XDMF
    (``<name>.xdmf`` and ``.h5`` in the run's folder; time k is the end of step k)."""

    def __init__(self, name: str = "fields") -> None:
        self.name = name

    def setup(self, solid: MixedSolid, problem: Problem) -> None:
        """The written functions and the expressions interpolated into them (collective)."""
        self.solid, self.comm = solid, solid.comm
        msh = solid.mesh_data.mesh
        self.displacement = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 1)), name="displacement")
        self.pressure = fem.Function(fem.FunctionSpace(msh, ("DG", 0)), name="pressure")
        self.mises = fem.Function(self.pressure.function_space, name="von_mises")
        points = self.pressure.function_space.element.interpolation_points()
        self._mises_expr = fem.Expression(solid.mises_expression(), points)
        self._u_expr = fem.Expression(solid.u, self.displacement.function_space.element.interpolation_points())
        self._p_expr = fem.Expression(solid.p, points)

    def start(self, scene: str, out_dir: str) -> None:
        """Open the files in a hidden folder of ``out_dir`` and write the mesh and its regions."""
        self.final = [os.path.join(out_dir, self.name + ext) for ext in (".xdmf", ".h5")]
        self.hidden = os.path.join(out_dir, f".{self.name}.partial")
        make_folder(self.hidden, self.comm)
        self.file = io.XDMFFile(self.comm, os.path.join(self.hidden, self.name + ".xdmf"), "w")
        self.file.write_mesh(self.solid.mesh_data.mesh)
        self.solid.mesh_data.cell_tags.name = "region"
        self.file.write_meshtags(self.solid.mesh_data.cell_tags)

    def after_step(self, step: str, index: int, entry: dict, converged: bool) -> None:
        self.displacement.interpolate(self._u_expr)
        self.pressure.interpolate(self._p_expr)
        self.mises.interpolate(self._mises_expr)
        for f in (self.displacement, self.pressure, self.mises):
            self.file.write_function(f, float(index + 1))

    def finish(self, summary: dict) -> None:
        """Close the files and move them into place."""
        self.file.close()
        self.comm.barrier()
        if self.comm.rank == 0:
            for final in self.final:
                os.replace(os.path.join(self.hidden, os.path.basename(final)), final)
            shutil.rmtree(self.hidden, ignore_errors=True)
        self.comm.barrier()


def _could_not_write(path: str, error: OSError) -> str:
    return f"could not write {path} ({type(error).__name__}: {error.strerror or error})"


def raise_on_every_rank(failure: str | None, comm: MPI.Comm) -> None:
    """Rank 0's ``failure`` (None: none) as an ``OutputError`` on every rank (collective)."""
    failure = comm.bcast(failure, root=0)
    if failure:
        raise OutputError(failure)


def raise_any_rank_failure(failure: str | None, comm: MPI.Comm) -> None:
    """The first rank's ``failure`` of those that had one (None: none) as an ``OutputError`` on
    every rank (collective: it returns, or raises, on every rank once all have called it)."""
    failures = comm.gather(failure, root=0)
    raise_on_every_rank(next((f for f in failures if f), None) if comm.rank == 0 else None, comm)


def make_folder(path: str, comm: MPI.Comm) -> None:
    """Make a folder on rank 0; an ``OutputError`` on every rank if it could not."""
    failure = None
    if comm.rank == 0:
        try:
            os.makedirs(path, exist_ok=True)
        except OSError as error:
            failure = _could_not_write(path, error)
    raise_on_every_rank(failure, comm)


def write_text_atomic(path: str, text: str, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Write a text file on rank 0 to a temporary name, then rename it into place; an
    ``OutputError`` on every rank if rank 0 could not (the file as it was is kept)."""
    failure = None
    if comm.rank == 0:
        tmp = f"{path}.tmp{os.getpid()}"
        try:
            os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
            with open(tmp, "w") as f:
                f.write(text)
            os.replace(tmp, path)
        except OSError as error:
            failure = _could_not_write(path, error)
            if os.path.exists(tmp):
                os.remove(tmp)
    raise_on_every_rank(failure, comm)


def write_json_atomic(path: str, data: dict, comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Write JSON atomically (see ``write_text_atomic``); NaN is refused, never written."""
    write_text_atomic(path, json.dumps(data, indent=1, allow_nan=False) if comm.rank == 0 else "", comm)


def new_figure(figsize: tuple[float, float]):
    """A matplotlib Figure on its own Agg canvas, outside pyplot's state (nothing to close)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    figure = Figure(figsize=figsize)
    FigureCanvasAgg(figure)
    return figure


def save_figure_atomic(figure, path: str, dpi: int = 150) -> None:
    """Render a matplotlib figure once on an Agg canvas at ``dpi`` and write it as a PNG
    (``save_pixels_atomic``; call on the one rank that draws)."""
    save_pixels_atomic(render(figure, dpi), path)


def render(figure, dpi: int) -> np.ndarray:
    """The figure's RGB pixels (rows, columns, 3), rendered once on an Agg canvas at ``dpi`` (its
    background is opaque)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    figure.dpi = dpi
    canvas = figure.canvas if isinstance(figure.canvas, FigureCanvasAgg) else FigureCanvasAgg(figure)
    canvas.draw()
    return np.ascontiguousarray(np.asarray(canvas.buffer_rgba())[..., :3])


def save_pixels_atomic(pixels: np.ndarray, path: str) -> None:
    """Write RGB pixels as a PNG (zlib level 3) under a temporary name, then rename it into place."""
    from PIL import Image
    tmp = f"{path}.tmp{os.getpid()}.png"
    Image.fromarray(pixels).save(tmp, format="png", compress_level=3)
    os.replace(tmp, path)


# The margins (inches) of each small plot of ``plot_curves`` in its 4 x 3 in cell: room for
# the y tick labels on the left, the title above, the slanted x tick labels and the x label below.
# At DPI, the cells and the margins are whole pixels, so that rows drawn apart stack into the
# same picture (an edge half a pixel off would be snapped either way by round-off).
DPI = 110
CELL, MARGINS = (4.0, 3.0), {"left": 88 / DPI, "right": 16 / DPI, "top": 38 / DPI, "bottom": 88 / DPI}


def plot_curves(path: str, x: list, curves: dict[str, list], xlabel: str, xticklabels: list[str] | None = None,
                bands: dict[str, tuple[list, list]] | None = None, band_label: str = "",
                comm: MPI.Comm | None = None) -> None:
    """A PNG of small plots, one curve each, against the same x (matplotlib Agg), three in a
    row, each in a cell of fixed margins (``MARGINS``). Call on one rank, or on every rank of
    ``comm``: then each draws only its share of the rows, and rank 0 stacks their pixels and
    writes the picture; a failure on any rank, drawing or writing, is an ``OutputError`` on every
    rank (none is left waiting for the others).

    Args:
        curves: {title: y values}.
        xticklabels: labels of the x values (step names), or None for numbers.
        bands: {title: (lower values, upper values)}: a shaded band about the curve of that
            title, named ``band_label`` in its legend.
    """
    columns = min(3, len(curves))
    lines = -(-len(curves) // columns)
    if comm is None:
        save_pixels_atomic(_rows(x, curves, xlabel, xticklabels, bands, band_label, columns, 0, lines), path)
        return
    first, last = lines * comm.rank // comm.size, lines * (comm.rank + 1) // comm.size  # this rank's rows
    try:
        drawn = None, _rows(x, curves, xlabel, xticklabels, bands, band_label, columns, first, last)
    except Exception as error:  # sent to rank 0, which says it on every rank
        drawn = f"could not draw {path} ({type(error).__name__}: {error})", None
    drawn = comm.gather(drawn, root=0)
    failure = None
    if comm.rank == 0:
        failure = next((message for message, _ in drawn if message), None)
        try:
            if failure is None:
                save_pixels_atomic(np.concatenate([pixels for _, pixels in drawn]), path)
        except OSError as error:
            failure = _could_not_write(path, error)
    raise_on_every_rank(failure, comm)


def _rows(x, curves, xlabel, xticklabels, bands, band_label, columns, first, last) -> np.ndarray:
    """The pixels of rows ``first`` to ``last`` (excluded) of ``plot_curves``' picture (none: an
    empty array as wide as the picture)."""
    if last == first:
        return np.zeros((0, round(CELL[0] * columns * DPI), 3), dtype=np.uint8)
    width, height = CELL[0] * columns, CELL[1] * (last - first)
    figure = new_figure((width, height))
    for k, (name, y) in enumerate(list(curves.items())[first * columns: last * columns]):
        line, column = divmod(k, columns)
        ax = figure.add_axes(((column * CELL[0] + MARGINS["left"]) / width,
                              ((last - first - 1 - line) * CELL[1] + MARGINS["bottom"]) / height,
                              (CELL[0] - MARGINS["left"] - MARGINS["right"]) / width,
                              (CELL[1] - MARGINS["top"] - MARGINS["bottom"]) / height))
        ax.plot(x, y, "o-")
        if bands and name in bands:
            ax.fill_between(x, *bands[name], alpha=0.3, label=band_label)
            ax.legend(fontsize=7)
        ax.set_xlabel(xlabel)
        _title(ax, name)
        if xticklabels is not None:
            ax.set_xticks(x, xticklabels, rotation=30, fontsize=8)
    return render(figure, DPI)


def _title(ax, name: str) -> None:
    """The title of a small plot: at a fixed place above the axes (no positioning pass at drawing),
    unless its y axis shows an offset or a multiplier there, which the title is then placed above."""
    formatter = ax.yaxis.get_major_formatter()
    formatter.set_locs(ax.yaxis.get_majorticklocs())
    ax.set_title(name, fontsize=9, **({} if formatter.get_offset() else {"y": 1.0}))


def flatten(entries: dict, prefix: str = "") -> dict:
    """{"a": 1, "b": {"c": 2}, "d": [3, 4]} -> {"a": 1, "b.c": 2, "d.0": 3, "d.1": 4}."""
    flat = {}
    for key, value in entries.items():
        if isinstance(value, list):
            value = dict(enumerate(value))
        if isinstance(value, dict):
            flat.update(flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat

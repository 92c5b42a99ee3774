"""What a run writes: field output (XDMF for ParaView), summary.json and pictures (small plots
of curves drawn by one rank, or by the ranks together, each its cells: ``plot_curves``).

Every file appears atomically: summary.json and the PNG pictures are written to a temporary
name and renamed; the XDMF/HDF5 pair is written in a hidden folder and moved into place when
closed.
"""
from __future__ import annotations

import json
import os
import shutil
import struct
import zlib
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


def could_not_draw(what: str, error: Exception) -> str:
    """The message of a picture (or pictures) ``what`` that could not be drawn."""
    return f"could not draw {what} ({type(error).__name__}: {error})"


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
    """Write RGB pixels as a PNG (``png_bytes``) under a temporary name, then rename it into place."""
    data, tmp = png_bytes(pixels), f"{path}.tmp{os.getpid()}.png"
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


def png_bytes(pixels: np.ndarray, level: int = 3) -> bytes:
    """RGB pixels (rows, columns, 3; uint8) as a PNG file (ISO/IEC 15948:2004): 8-bit truecolour,
    every row unfiltered (filter type 0), the rows one zlib stream at ``level``. Pillow's encoder
    tries a filter for each row, which on these pictures of flat colours took 3-4 times as long
    and gave larger files (the eye measures' 2640 x 1320 pixels: 0.13 s and 310 kB, against
    0.04 s and 296 kB)."""
    if pixels.dtype != np.uint8 or pixels.ndim != 3 or pixels.shape[2] != 3 or min(pixels.shape[:2]) < 1:
        raise ValueError(f"a PNG takes RGB bytes (rows, columns, 3), one pixel at least, not {pixels.dtype} "
                         f"{pixels.shape}")
    rows, columns, _ = pixels.shape
    scanlines = np.zeros((rows, 1 + 3 * columns), dtype=np.uint8)  # each row: its filter type 0, its bytes
    scanlines[:, 1:] = pixels.reshape(rows, -1)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    header = struct.pack(">IIBBBBB", columns, rows, 8, 2, 0, 0, 0)  # 8 bits, truecolour, deflate, no interlace
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(scanlines.tobytes(), level))
            + chunk(b"IEND", b""))


# The margins (inches) of each small plot of ``plot_curves`` in its 4 x 3 in cell: room for
# the y tick labels on the left, the title above, the slanted x tick labels and the x label below.
# At DPI, the cells are whole pixels, so that cells drawn apart stack into one picture.
DPI = 110
CELL, MARGINS = (4.0, 3.0), {"left": 88 / DPI, "right": 16 / DPI, "top": 38 / DPI, "bottom": 88 / DPI}


def plot_curves(path: str, x: list, curves: dict[str, list], xlabel: str, xticklabels: list[str] | None = None,
                bands: dict[str, tuple[list, list]] | None = None, band_label: str = "",
                comm: MPI.Comm | None = None) -> None:
    """A PNG of small plots, one curve each, against the same x (matplotlib Agg), three in a
    row, each in a cell of fixed margins (``MARGINS``). Call on one rank, or on every rank of
    ``comm``: then each draws only its share of the cells, and rank 0 stacks their pixels and
    writes the picture; a failure on any rank, drawing or writing, is an ``OutputError`` on every
    rank (none is left waiting for the others).

    Args:
        curves: {title: y values}.
        xticklabels: labels of the x values (step names), or None for numbers.
        bands: {title: (lower values, upper values)}: a shaded band about the curve of that
            title, named ``band_label`` in its legend.
    """
    if not curves:
        return

    def draw(names):
        return _cells(x, {name: curves[name] for name in names}, xlabel, xticklabels, bands or {}, band_label)
    if comm is None:
        save_pixels_atomic(_stacked(draw(list(curves))), path)
        return
    names = list(curves)
    mine = names[len(names) * comm.rank // comm.size: len(names) * (comm.rank + 1) // comm.size]
    try:
        drawn = None, draw(mine)
    except Exception as error:  # sent to rank 0, which says it on every rank
        drawn = could_not_draw(path, error), None
    drawn = comm.gather(drawn, root=0)
    failure = None
    if comm.rank == 0:
        failure = next((message for message, _ in drawn if message), None)
        try:
            if failure is None:
                save_pixels_atomic(_stacked([cell for _, cells in drawn for cell in cells]), path)
        except OSError as error:
            failure = _could_not_write(path, error)
        except Exception as error:  # said on every rank: none is left waiting for rank 0
            failure = could_not_draw(path, error)
    raise_on_every_rank(failure, comm)


def _cells(x, curves, xlabel, xticklabels, bands, band_label) -> list[np.ndarray]:
    """The pixels of ``plot_curves``' small plots, one cell each, drawn in turn on one axes (an
    axes made anew for each, with its ticks and their labels, costs more than drawing it)."""
    if not curves:
        return []
    width, height = CELL
    figure = new_figure(CELL)
    ax = figure.add_axes((MARGINS["left"] / width, MARGINS["bottom"] / height,
                          (width - MARGINS["left"] - MARGINS["right"]) / width,
                          (height - MARGINS["top"] - MARGINS["bottom"]) / height))
    (line,) = ax.plot([], [], "o-")
    ax.set_xlabel(xlabel)
    if xticklabels is not None:
        ax.set_xticks(x, xticklabels, rotation=30, fontsize=8)
    pixels = []
    for name, y in curves.items():
        if len(y) != len(x):  # set_data would broadcast them
            raise ValueError(f"{len(y)} values of {name!r} for {len(x)} x values")
        line.set_data(x, y)
        ax.set(xlim=(0.0, 1.0), ylim=(0.0, 1.0))  # a new axes' limits: what autoscaling keeps where no value is finite
        ax.set_autoscale_on(True)
        ax.relim()
        shown = []
        if name in bands:
            lower, upper = bands[name]
            shown = [ax.fill_between(x, lower, upper, facecolor=line.get_color(), alpha=0.3, label=band_label)]
            shown.append(ax.legend(fontsize=7))
        ax.autoscale_view()
        _title(ax, name)
        pixels.append(render(figure, DPI))
        for artist in shown:
            artist.remove()
    return pixels


def _stacked(cells: list[np.ndarray]) -> np.ndarray:
    """The cells of ``plot_curves``, three to a row (the last row's free places white)."""
    columns = min(3, len(cells))
    blank = np.full_like(cells[0], 255)
    cells = cells + [blank] * (-len(cells) % columns)
    return np.vstack([np.hstack(cells[k: k + columns]) for k in range(0, len(cells), columns)])


def _title(ax, name: str) -> None:
    """The title of a small plot: at a fixed place above the axes (no positioning pass at drawing),
    unless its y axis shows an offset or a multiplier there, which the title is then placed above."""
    formatter = ax.yaxis.get_major_formatter()
    formatter.set_locs(ax.yaxis.get_majorticklocs())
    if formatter.get_offset():
        ax._autotitlepos = None  # placed at drawing again (matplotlib 3.6 keeps the last title's y=1.0 fixed)
        ax.set_title(name, fontsize=9)
    else:
        ax.set_title(name, fontsize=9, y=1.0)


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

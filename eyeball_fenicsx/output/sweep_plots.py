"""The planning sweep's pictures (matplotlib Agg; drawn on rank 0).

The predictions drawn are the numeric columns of sweep.csv that vary over the grid, the eye
measures only if there are any (output/measures.py), each titled by its readable name (labels.py). Over one varied
parameter (one with two values or more): sweep.png, a curve per prediction, with the band of
bands.csv shaded about it. Over two: sweep.png, a filled contour plot per prediction over the
plane of the two parameters (``tricontourf``: linear interpolation on the Delaunay triangles of
the converged grid points, which are marked with dots; the points that did not converge are
marked with red crosses and left out), and with ranges sweep_bands.png, the same plots of each
band's width (largest minus smallest over the corners). Over three or more: no picture (the
tables hold the grid).
"""
from __future__ import annotations

import math
import os
from typing import Any

from .files import plot_curves, save_figure_atomic
from .labels import label


def plot_sweep(out_dir: str, rows: list[dict[str, Any]], grid: list[tuple[str, list[float]]],
               bands: list[dict[str, Any]] | None, ranges: list[tuple[str, float, float]]) -> None:
    """sweep.png (and sweep_bands.png) in ``out_dir`` from sweep.csv's rows and bands.csv's."""
    varied = [parameter for parameter, values in grid if len(values) > 1]
    columns = predictions(rows, exclude=[parameter for parameter, _ in grid])
    if not columns or len(varied) not in (1, 2):
        return
    if len(varied) == 1:  # in the order of the parameter's values
        order = sorted(range(len(rows)), key=lambda k: rows[k][varied[0]])
        rows, bands = [rows[k] for k in order], None if bands is None else [bands[k] for k in order]
        x, shaded = [row[varied[0]] for row in rows], None
        if bands is not None:
            shaded = {label(c): ([_value(b.get(f"{c}.min")) for b in bands], [_value(b.get(f"{c}.max")) for b in bands])
                      for c in columns}
        span = ", ".join(f"{label(p)} {low:g} to {high:g}" for p, low, high in ranges)
        curves = {label(c): [_value(row.get(c)) if row["ok"] else math.nan for row in rows] for c in columns}
        plot_curves(os.path.join(out_dir, "sweep.png"), x, curves, label(varied[0]), bands=shaded,
                    band_label=f"over {span}")
        return
    points = [(row[varied[0]], row[varied[1]]) for row in rows]
    ok = [row["ok"] for row in rows]
    fields = {label(c): [_value(row.get(c)) for row in rows] for c in columns}
    plot_contours(os.path.join(out_dir, "sweep.png"), points, ok, fields, (label(varied[0]), label(varied[1])))
    if bands is not None:
        widths = {f"spread of {label(c)}": [_value(b.get(f"{c}.max")) - _value(b.get(f"{c}.min")) for b in bands]
                  for c in columns}
        whole = [b["corners_ok"] == b["corners"] for b in bands]
        plot_contours(os.path.join(out_dir, "sweep_bands.png"), points, whole, widths,
                      (label(varied[0]), label(varied[1])))


def predictions(rows: list[dict[str, Any]], exclude: list[str]) -> list[str]:
    """The columns to draw: but the parameters (``exclude``), numbers in every converged row that
    vary over them (beyond round-off: a reaction that is zero by symmetry has no contours), the
    eye measures only if any."""
    converged = [row for row in rows if row["ok"]] or rows
    numeric = numeric_columns(converged, exclude=("ok", "wall_s", *exclude))
    varying = [c for c in numeric if _varies([row[c] for row in converged])]
    eye = [c for c in varying if c.startswith("eye.")]
    return eye or varying


def numeric_columns(rows: list[dict[str, Any]], exclude: tuple[str, ...] = ()) -> list[str]:
    """The columns, but ``exclude``, that are numbers in every row."""
    return [c for c in dict.fromkeys(key for row in rows for key in row) if c not in exclude
            and all(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool) for r in rows)]


def _varies(values: list[float]) -> bool:
    return max(values) - min(values) > 1e-9 * max(abs(v) for v in values) + 1e-12


def _value(value: Any) -> float:
    return math.nan if value is None else float(value)


def plot_contours(path: str, points: list[tuple[float, float]], ok: list[bool], fields: dict[str, list[float]],
                  axes_labels: tuple[str, str]) -> None:
    """A PNG of filled contour plots, one per field, over the same points of a plane."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    columns = min(3, len(fields))
    lines = -(-len(fields) // columns)
    figure, axes = plt.subplots(lines, columns, figsize=(4.4 * columns, 3.4 * lines), squeeze=False)
    for ax, (title, z) in zip(axes.ravel(), fields.items()):
        good = [k for k, (flag, v) in enumerate(zip(ok, z)) if flag and math.isfinite(v)]
        x, y = [points[k][0] for k in good], [points[k][1] for k in good]
        values = [z[k] for k in good]
        if len(good) >= 3 and len(set(x)) > 1 and len(set(y)) > 1:
            filled = ax.tricontourf(x, y, values, levels=12, cmap="viridis")
            figure.colorbar(filled, ax=ax)
        ax.plot(x, y, "ko", markersize=3, clip_on=False)
        bad = [k for k in range(len(points)) if k not in good]
        if bad:
            ax.plot([points[k][0] for k in bad], [points[k][1] for k in bad], "rx", markersize=8, clip_on=False,
                    label="did not converge")
            ax.legend(fontsize=7)
        ax.set_xlabel(axes_labels[0], fontsize=8)
        ax.set_ylabel(axes_labels[1], fontsize=8)
        ax.set_title(title, fontsize=9)
    for ax in axes.ravel()[len(fields):]:
        ax.axis("off")
    figure.tight_layout()
    save_figure_atomic(figure, path, dpi=110)
    plt.close(figure)

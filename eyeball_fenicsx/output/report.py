"""One page per run: ``report.html`` in the run's folder, what a surgeon opens after the run.

The page is a single HTML file with its pictures inside it (PNG as base64 ``data:`` URIs), so it
can be mailed or archived alone; it needs no script, no style sheet and no network, and reads in
any browser. It holds the scene's name, the run's state (running, done, failed, interrupted, with
the error of a run that stopped), the predictions per step (the eye measures of
output/measures.py with their readable names and units, output/labels.py), what the solver did
per step (load increments, Newton iterations, factorizations, time) and the liquids', contacts'
and bands' figures of each step, then the pictures of each converged step (the eye's outer
surface and its section coloured by the von Mises stress, the retina's gap map: output/eye_pictures.py
and output/eye_surface.py) and the measures over the steps. A scene without an ``[eye]`` table
gets the same page without the eye's rows and pictures. Every number shown carries its full
value in the cell's ``data-value`` attribute (Python's repr: what summary.json holds).

Data path: ``RunReport`` observes the runs of a scene with an output folder (output/observer.py)
after every other observer that writes into the step's entry or draws its pictures (the loader,
scene/loader.py, puts it last): after each step (while the run goes on, so that a run killed
outright still has its page, of the steps done) and at the end from the final summary.json.
Rank 0 writes, atomically (output/files.py), alone: a page that cannot be written is a
warning in the log, never a failed run. A resumed run's page takes back the steps the
checkpoint holds (output/checkpoint.py) and shows all of them.
"""
from __future__ import annotations

import base64
import html
import logging
import math
import os
from typing import TYPE_CHECKING

from mpi4py import MPI

from .eye_pictures import step_pictures
from .files import flatten, write_text_atomic
from .labels import FEATURE_FIGURES, MEASURES, label
from .observer import Observer

if TYPE_CHECKING:
    from ..mechanics.solid import MixedSolid
    from ..system.problem import Problem

log = logging.getLogger(__name__)

# The predictions first, in the order a surgeon asks for them; the other eye measures follow.
FIRST = ("axial_length_change_mm", "refraction_change_D", "iop_mmHg", "buckle_height_mm", "reattached_fraction",
         "detached_area_mm2", "subretinal_volume_mm3")
# What the solver did in a step: the key shown and how it is summed over the step's increments.
SOLVER = {"converged load increments": len, "their Newton iterations": lambda i: sum(x["newton_iterations"] for x in i),
          "their factorizations": lambda i: sum(x.get("factorizations", 0) for x in i),
          "their time (s)": lambda i: sum(x["wall_s"] for x in i)}
PREDICTIONS_NOTE = ("Changes \"from pre-op\" are from the eye after the step that fills the vitreous to its "
                    "pressure; areas and volumes are those of the model (half the eye's in a half model); the "
                    "definitions are in eyeball_fenicsx/output/measures.py.")
STATE_COLOURS = {"done": "#1a7f37", "running": "#666666", "failed": "#cf222e", "interrupted": "#bc4c00"}
STYLE = ("body{font-family:sans-serif;max-width:1400px;margin:1em auto;padding:0 1em;color:#222}"
         "table{border-collapse:collapse;margin:0.5em 0 1.5em}td,th{border:1px solid #ccc;padding:3px 8px}"
         "td{text-align:right}th{background:#f0f0f0}th.row{text-align:left;font-weight:normal}"
         "figure{display:inline-block;margin:0 0.5em 1em 0;vertical-align:top}"
         "figure img{width:440px;border:1px solid #ddd}figure.wide img{width:900px}"
         ".state{color:#fff;padding:2px 8px;border-radius:4px}")


def _number(value) -> str:
    """A figure as shown: four significant digits (its full value is in data-value)."""
    return f"{value + 0.0:.4g}" if math.isfinite(value) else str(value)  # + 0.0: no "-0"


def _table(title: str, steps: list[dict], rows: dict[str, list]) -> str:
    """An HTML table: one row per figure (its readable name), one column per step."""
    if not rows:
        return ""
    head = "".join(f"<th>{html.escape(s['name'])}{'' if s['converged'] else ' (not converged)'}</th>" for s in steps)
    lines = [f"<h2>{html.escape(title)}</h2>", f"<table><tr><th>step</th>{head}</tr>"]
    for (key, name), values in rows.items():
        cells = "".join("<td>-</td>" if v is None else
                        f'<td data-key="{html.escape(key)}" data-value="{v!r}">{_number(v)}</td>' for v in values)
        lines.append(f'<tr><th class="row">{html.escape(name)}</th>{cells}</tr>')
    return "\n".join(lines) + "</table>"


def _numbers(entries: list[dict], keys: list[str]) -> dict[str, list]:
    """{key: [value per entry, or None]} of the keys with a number in some entry."""
    rows = {}
    for key in keys:
        values = [e.get(key) if isinstance(e.get(key), (int, float)) and not isinstance(e.get(key), bool) else None
                  for e in entries]
        if any(v is not None for v in values):
            rows[key] = values
    return rows


def prediction_rows(steps: list[dict]) -> dict[tuple, list]:
    """The eye measures of each step: {(summary key, readable name): values}."""
    eyes = [flatten(step.get("eye", {})) for step in steps]
    keys = list(dict.fromkeys(k for e in eyes for k in e))
    ordered = [k for k in FIRST if k in keys] + [k for k in keys if k.startswith("max_mises")]
    ordered += [k for k in MEASURES if k in keys and k not in ordered]
    ordered += [k for k in keys if k not in ordered]
    return {(f"eye.{k}", label(f"eye.{k}")): v for k, v in _numbers(eyes, ordered).items()}


def feature_rows(steps: list[dict]) -> dict[tuple, list]:
    """Per step: the solver's work, then the liquids', contacts' and bands' figures (those
    output/labels.py names; a contact force as its magnitude)."""
    rows = {(name, name): [how(step["increments"]) if step["increments"] else None for step in steps]
            for name, how in SOLVER.items()}
    flat = []
    for step in steps:
        entry = {}
        for key, value in flatten({k: step[k] for k in ("cavities", "contact", "bands") if k in step}).items():
            if ".force." in key:  # a force as its magnitude
                entry[key[:key.rindex(".")]] = math.hypot(entry.get(key[:key.rindex(".")], 0.0), value)
            else:
                entry[key] = value
        flat.append(entry)
    keys = list(dict.fromkeys(k for e in flat for k in e if k.split(".")[-1] in FEATURE_FIGURES))
    rows.update({(k, label(k)): v for k, v in _numbers(flat, keys).items()})
    return rows


def _image(path: str, caption: str, wide: bool = False) -> str:
    with open(path, "rb") as f:
        data = base64.b64encode(f.read()).decode("ascii")
    return (f'<figure{" class=wide" if wide else ""}><img alt="{html.escape(caption)}" '
            f'src="data:image/png;base64,{data}"><figcaption>{html.escape(caption)}</figcaption></figure>')


PICTURE_CAPTIONS = {"surface": "the eye, coloured by the von Mises stress", "section": "meridional section, von Mises "
                    "stress", "retina_gap": "the detached retina: its gap from the choroid"}


def pictures(out_dir: str, steps: list[dict], final: bool) -> list[str]:
    """The figures of the pictures of the converged steps that exist in ``out_dir``, and (``final``:
    drawn at the end of the run) the measures over the steps."""
    parts = []
    for step in steps:
        found = [(kind, os.path.join(out_dir, name)) for kind, name in step_pictures(step["name"]).items()]
        found = [(kind, path) for kind, path in found if step["converged"] and os.path.isfile(path)]
        if found:
            parts.append(f"<h3>after step {html.escape(step['name'])}</h3>")
            parts += [_image(path, f"{step['name']}: {PICTURE_CAPTIONS[kind]}") for kind, path in found]
    measures = os.path.join(out_dir, "eye_measures.png")
    if final and os.path.isfile(measures):
        parts += ["<h3>the eye measures over the steps</h3>", _image(measures, "the eye measures", wide=True)]
    return parts


def report_html(summary: dict, converged: list[bool], out_dir: str) -> str:
    """The page of a run (module docstring) from its summary, with the pictures in ``out_dir``.

    Args:
        summary: summary.json's content (while running, at least "scene", "state" and "steps").
        converged: per step of the summary, whether it converged (only those have pictures).
    """
    steps = [{**step, "converged": ok} for step, ok in zip(summary["steps"], converged)]
    state = summary.get("state", "running")
    facts = [f"{len(steps)} step(s)"] + [f"{what} {summary[key]:{form}}" for key, what, form in
                                         (("ranks", "ranks", "d"), ("cells", "cells", "d"), ("wall_s", "wall time (s)",
                                                                                             ".1f")) if key in summary]
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>{html.escape(summary['scene'])}: run report</title><style>{STYLE}</style></head><body>",
             f"<h1>{html.escape(summary['scene'])}</h1>",
             f'<p>state: <span class="state" id="state" style="background:{STATE_COLOURS.get(state, "#666")}">'
             f"{html.escape(state)}</span> &middot; {html.escape(', '.join(facts))}</p>"]
    if summary.get("error"):
        parts.append(f'<p id="error"><b>error:</b> {html.escape(summary["error"])}</p>')
    predictions = prediction_rows(steps)
    parts.append(_table("Predictions per step", steps, predictions))
    if predictions:
        parts.append(f"<p>{html.escape(PREDICTIONS_NOTE)}</p>")
    parts.append(_table("The solver, the liquids, contacts and bands per step", steps, feature_rows(steps)))
    figures = pictures(out_dir, steps, final=state != "running")
    if figures:
        parts += ["<h2>Pictures</h2>", *figures]
    parts.append("</body></html>")
    return "\n".join(parts)


class RunReport(Observer):
    """Writes ``report.html`` into the output folder of every run (module docstring)."""

    def __init__(self) -> None:
        self._restored: list[dict] = []

    def setup(self, solid: MixedSolid, problem: Problem) -> None:
        self._comm = solid.comm

    def start(self, scene: str, out_dir: str | None) -> None:
        self._scene, self._out_dir = scene, out_dir
        self._steps, self._restored = self._restored, []
        self._converged = [True] * len(self._steps)  # a checkpoint holds converged steps only

    def after_step(self, step: str, index: int, entry: dict, converged: bool) -> None:
        self._steps.append(entry)
        self._converged.append(converged)
        self._write({"scene": self._scene, "state": "running", "steps": self._steps})

    def finish(self, summary: dict) -> None:
        """The final page, if the run has a step to show: a run refused before its first step
        (a scene found invalid) leaves its folder as the contract says, with summary.json only."""
        if self._steps:
            self._write(summary)

    def _write(self, summary: dict) -> None:
        """Rank 0 writes the page, alone (no collective: a page that cannot be written is a
        warning, never a run stopped or ranks left waiting)."""
        if not self._out_dir or self._comm.rank != 0:
            return
        try:
            text = report_html(summary, self._converged, self._out_dir)
            write_text_atomic(os.path.join(self._out_dir, "report.html"), text, MPI.COMM_SELF)
        except (OSError, ValueError, KeyError, TypeError) as error:
            log.warning("report.html not written in %s: %s: %s", self._out_dir, type(error).__name__, error)

    # -- a checkpoint (output/checkpoint.py) ---------------------------------------------------
    def checkpoint_state(self) -> dict:
        """The entries of the steps done, for a resumed run's page."""
        return {"steps": self._steps}

    def restore_state(self, state: dict) -> None:
        self._restored = list(state["steps"])

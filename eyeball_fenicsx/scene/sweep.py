"""Planning sweeps: run one scene over values of one parameter and tabulate what it predicts.

    eyeball-fenicsx sweep SCENE.toml --parameter band.0.reduction --values 2 4 6 8 --out DIR

The parameter is a dotted path into the scene file (table keys, and array indices for
``[[...]]`` tables), replaced in each variant by ``load_scene``'s overrides (overrides.py).
Each variant runs in the same MPI job (``DIR/<k>/summary.json``); a variant that does not
converge is a row with ``ok = false``. DIR/sweep.csv holds the final "eye" predictions of
every variant and DIR/sweep.png plots them against the parameter.
"""
import json
import os
from collections.abc import Sequence
from typing import Any

from mpi4py import MPI

from ..errors import ConvergenceError
from ..output.files import flatten, plot_curves, write_text_atomic
from .loader import load_scene


def run_sweep(scene_path: str, parameter: str, values: Sequence[Any], out_dir: str,
              comm: MPI.Comm = MPI.COMM_WORLD) -> list[dict[str, Any]]:
    """Run the variants; write sweep.csv and sweep.png; return the rows."""
    rows = []
    for k, value in enumerate(values):
        scene = load_scene(scene_path, comm, overrides={parameter: value})
        out = os.path.join(out_dir, f"{k:02d}")
        try:
            summary, ok = scene.run(out), True
        except ConvergenceError:
            ok = False
            with open(os.path.join(out, "summary.json")) as f:
                summary = json.load(f)
        final = summary["steps"][-1] if summary["steps"] else {}
        measured = {key: v for key, v in final.items() if key not in ("name", "increments")}
        rows.append({parameter: value, "ok": ok, "wall_s": summary["wall_s"], **flatten(measured)})
    columns = list(dict.fromkeys(key for row in rows for key in row))
    lines = [",".join(columns)] + [",".join(str(row.get(c, "")) for c in columns) for row in rows]
    write_text_atomic(os.path.join(out_dir, "sweep.csv"), "\n".join(lines) + "\n", comm)
    if comm.rank == 0:
        _plot(rows, parameter, os.path.join(out_dir, "sweep.png"))
    comm.barrier()
    return rows


def _plot(rows: list[dict[str, Any]], parameter: str, path: str) -> None:
    """The numeric columns against the parameter (the "eye" ones only, if any)."""
    numeric = [c for c in rows[0] if c not in (parameter, "ok", "wall_s")
               and all(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool) for r in rows)]
    if any(c.startswith("eye.") for c in numeric):
        numeric = [c for c in numeric if c.startswith("eye.")]
    if numeric:
        plot_curves(path, [r[parameter] for r in rows], {c: [r[c] for r in rows] for c in numeric}, parameter)

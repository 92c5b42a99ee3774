"""Planning sweeps: run one scene over values of one parameter and tabulate what it predicts.

    eyeball-fenicsx sweep SCENE.toml --parameter band.0.reduction --values 2 4 6 8 --out DIR

The parameter is a dotted path into the scene file (table keys, and array indices for
``[[...]]`` tables). Each variant runs in the same MPI job (``DIR/<k>/summary.json``); a
variant that does not converge is a row with ``ok = false``. DIR/sweep.csv holds the final
"eye" predictions of every variant and DIR/sweep.png plots them against the parameter.
"""
import copy
import os
import tomllib

import tomli_w
from mpi4py import MPI

from ..errors import ConvergenceError, SceneError
from ..output.files import flatten


def set_parameter(data, path, value):
    """Set the entry at a dotted path (``"band.0.reduction"``) of a parsed scene."""
    *parents, last = path.split(".")
    node = data
    for key in parents:
        try:
            node = node[int(key)] if isinstance(node, list) else node[key]
        except (KeyError, IndexError, ValueError):
            raise SceneError(f"sweep: parameter {path!r} is not in the scene (no {key!r})") from None
    if isinstance(node, list):
        raise SceneError(f"sweep: parameter {path!r} names a whole array, not a value")
    if last not in node:
        raise SceneError(f"sweep: parameter {path!r} is not in the scene (no {last!r}); "
                         f"that table has {sorted(node)}")
    node[last] = value


def run_sweep(scene_path, parameter, values, out_dir, comm=MPI.COMM_WORLD):
    """Run the variants; write sweep.csv and sweep.png; return the rows."""
    from ..output.files import write_text_atomic
    from .loader import load_scene
    if not os.path.isfile(scene_path):
        raise SceneError(f"scene file {scene_path} does not exist")
    with open(scene_path, "rb") as f:
        data = tomllib.load(f)
    tag = comm.bcast(os.getpid(), root=0)
    rows = []
    for k, value in enumerate(values):
        variant = copy.deepcopy(data)
        set_parameter(variant, parameter, value)
        # beside the original, so that relative mesh paths still resolve
        path = os.path.join(os.path.dirname(os.path.abspath(scene_path)), f".sweep-{tag}-{k}.toml")
        if comm.rank == 0:
            with open(path, "wb") as f:
                tomli_w.dump(variant, f)
        comm.barrier()
        try:
            scene = load_scene(path, comm)
        finally:
            comm.barrier()
            if comm.rank == 0:
                os.remove(path)
        try:
            summary = scene.run(os.path.join(out_dir, f"{k:02d}"))
            ok = True
        except ConvergenceError:
            ok = False
            with open(os.path.join(out_dir, f"{k:02d}", "summary.json")) as f:
                import json
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


def _plot(rows, parameter, path):
    from ..output.files import plot_curves
    numeric = [c for c in rows[0] if c not in (parameter, "ok", "wall_s")
               and all(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool) for r in rows)]
    if any(c.startswith("eye.") for c in numeric):
        numeric = [c for c in numeric if c.startswith("eye.")]
    if numeric:
        plot_curves(path, [r[parameter] for r in rows], {c: [r[c] for r in rows] for c in numeric}, parameter)

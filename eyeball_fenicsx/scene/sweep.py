"""Planning sweeps: run one scene over values of one parameter and tabulate what it predicts.

    eyeball-fenicsx sweep SCENE.toml --parameter band.0.reduction --values 2 4 6 8 --out DIR

The parameter is a dotted path to a number of the scene file (table keys, and array indices for
``[[...]]`` tables), replaced in each variant by ``load_scene``'s overrides (overrides.py). The
inputs are checked before anything runs: the values must be finite numbers, the parameter a
number of the file, and every variant a valid scene (each is read, its mesh built, first).
Each variant runs in the same MPI job (``DIR/<k>/summary.json``); a variant that does not
converge is a row with ``ok = false``. DIR/sweep.csv holds the final "eye" predictions of
every variant and DIR/sweep.png plots them against the parameter. DIR/sweep.json records what
was swept (the scene file's SHA-256, the parameter, the values).

With ``resume``, a variant whose summary.json says ``"state": "done"`` is not run again (its
row is read from that summary) and every other one resumes from its checkpoint
(``Scene.run(out, resume=True)``); the scene file and the parameter must be those of
sweep.json, and a variant done with another value is an error, not a row.
"""
import hashlib
import json
import os
from collections.abc import Sequence
from typing import Any

from mpi4py import MPI

from ..checks import is_number
from ..errors import ConvergenceError, SceneError
from ..output.files import flatten, plot_curves, write_json_atomic, write_text_atomic
from ..output.labels import label
from .loader import _parsed, load_scene
from .overrides import entry
from .scene import Scene


def run_sweep(scene_path: str, parameter: str, values: Sequence[Any], out_dir: str,
              comm: MPI.Comm = MPI.COMM_WORLD, resume: bool = False) -> list[dict[str, Any]]:
    """Run the variants; write sweep.csv and sweep.png; return the rows.

    Raises:
        SceneError: before any variant runs, if the values are not finite numbers, the parameter
            is not a number of the scene file, a variant's scene is invalid or, with ``resume``,
            DIR holds another sweep.
    """
    record = _checked(scene_path, parameter, values)
    done = _done(out_dir, record, comm) if resume else set()
    scenes = {}
    for k, value in enumerate(values):
        if k not in done:
            try:
                scenes[k] = load_scene(scene_path, comm, overrides={parameter: value})
            except SceneError as error:
                raise SceneError(f"{error} (the sweep's variant {k:02d}, {parameter} = {value!r})") from None
    write_json_atomic(os.path.join(out_dir, "sweep.json"), record, comm)
    rows = []
    for k, value in enumerate(values):
        out = _folder(out_dir, k)
        try:
            summary, ok = (_summary(out), True) if k in done else _run(scenes.pop(k), out, resume)
        except SceneError as error:  # found while building (probes, cavities) or resuming: say which file
            raise SceneError(f"{scene_path}: {error} (the sweep's variant {k:02d}, {parameter} = {value!r})") from None
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


def _checked(scene_path: str, parameter: str, values: Sequence[Any]) -> dict[str, Any]:
    """What the sweep is (sweep.json), once its inputs are checked."""
    data = _parsed(scene_path)
    where = f"{scene_path}: sweep of {parameter!r}"
    try:
        parent, key = entry(data, parameter)
    except SceneError as error:
        raise SceneError(f"{scene_path}: sweep: {error}") from None
    current = parent[key]  # type: ignore[index]
    if not is_number(current):
        raise SceneError(f"{where}: the scene has {parameter} = {current!r}, not a number: a sweep varies a number")
    if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or not values:
        raise SceneError(f"{where}: give one or more values, got {values!r}")
    wrong = [value for value in values if not is_number(value)]
    if wrong:
        raise SceneError(f"{where}: the values must be finite numbers, got {wrong[0]!r}")
    with open(scene_path, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    return {"scene": digest, "parameter": parameter, "values": [float(value) for value in values]}


def _folder(out_dir: str, k: int) -> str:
    return os.path.join(out_dir, f"{k:02d}")


def _summary(out: str) -> dict:
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def _done(out_dir: str, record: dict[str, Any], comm: MPI.Comm) -> set[int]:
    """The variants that a sweep of the same scene and parameter left done in ``out_dir``
    (rank 0 reads; every rank gets the answer, or the error)."""
    done, error = set(), None
    if comm.rank == 0:
        try:
            done = _done_on_disk(out_dir, record)
        except SceneError as failure:
            error = str(failure)
    done, error = comm.bcast((done, error), root=0)
    if error:
        raise SceneError(error)
    return done


def _done_on_disk(out_dir: str, record: dict[str, Any]) -> set[int]:
    path = os.path.join(out_dir, "sweep.json")
    if not os.path.isfile(path):
        return set()  # nothing was swept here: every variant runs
    try:
        with open(path) as f:
            before = json.load(f)
        swept = before["scene"], before["parameter"], [float(v) for v in before["values"]]
    except (OSError, ValueError, KeyError, TypeError):
        raise SceneError(f"{path} is not a sweep's record: resume a sweep in its own folder") from None
    if swept[0] != record["scene"]:
        raise SceneError(f"{out_dir}: cannot resume: the scene file has changed since the sweep in it; give a new "
                         "--out")
    if swept[1] != record["parameter"]:
        raise SceneError(f"{out_dir}: cannot resume: the sweep in it varied {swept[1]!r}, not "
                         f"{record['parameter']!r}; give a new --out")
    done, before = set(), dict(enumerate(swept[2]))
    for k, value in enumerate(record["values"]):
        try:
            state = _summary(_folder(out_dir, k)).get("state")
        except (OSError, ValueError, AttributeError):
            continue  # not started: it runs
        if state == "done" and before.get(k) != value:
            raise SceneError(f"{out_dir}: cannot resume: variant {k:02d} was done with {record['parameter']} = "
                             f"{before.get(k)}, not {value!r}; give a new --out")
        if state == "done":
            done.add(k)
    return done


def _run(scene: Scene, out: str, resume: bool) -> tuple[dict, bool]:
    """Run one variant (with ``resume``, from its checkpoint if it has one): its summary, and
    whether it converged."""
    try:
        return scene.run(out, resume=resume), True
    except ConvergenceError:
        return _summary(out), False


def _plot(rows: list[dict[str, Any]], parameter: str, path: str) -> None:
    """The numeric columns against the parameter (the "eye" ones only, if any)."""
    numeric = [c for c in rows[0] if c not in (parameter, "ok", "wall_s")
               and all(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool) for r in rows)]
    if any(c.startswith("eye.") for c in numeric):
        numeric = [c for c in numeric if c.startswith("eye.")]
    if numeric:
        curves = {label(c): [r[c] for r in rows] for c in numeric}
        plot_curves(path, [r[parameter] for r in rows], curves, label(parameter))

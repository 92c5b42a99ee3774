"""Planning sweeps: run one scene over a grid of parameter values and tabulate what it predicts,
with bands over ranges of uncertain constants.

    eyeball-fenicsx sweep SCENE.toml --parameter band.0.reduction --values 4 6 8 \\
        [--parameter mesh.band_width --values 2 2.5 3] [--range materials.sclera.c.10 0.5 0.8] --out DIR

What is run (the grid, the corners of the ranges' box) is sweep_plan.py's. Every input is checked
before anything runs: the parameters and values (sweep_plan.plan_sweep), then every variant, read
as a scene and its mesh built, one at a time and released (a variant's Scene is built again when
it runs: the check then costs a fraction of a second a variant, and the memory does not grow with
the grid). The variants run in the same MPI job, each in its folder ``DIR/<k>`` (grid point k)
or ``DIR/<k>-<corner>``; a variant that does not converge is a row with ``ok = false``.

DIR/sweep.csv holds the final predictions of each grid point's own variant, one row a point;
with ranges, DIR/bands.csv holds each point's smallest and largest value of every prediction over
the corners (``<column>.min``, ``<column>.max``; empty where a corner did not converge);
DIR/sweep.png draws them (output/sweep_plots.py); DIR/sweep.json records the scene file's SHA-256, the
grid, the ranges and each folder's overrides.

With ``resume``, a variant whose summary.json says ``"state": "done"`` is not run again (its
row is read from that summary) and every other one resumes from its checkpoint
(``Scene.run(out, resume=True)``); the scene file and the swept parameters must be those of
sweep.json, and a variant done with other values is an error, not a row. A variant stopped with
other values (the grid changed) starts again from its first step.
"""
import gc
import json
import os
from collections.abc import Mapping, Sequence
from typing import Any

from mpi4py import MPI

from ..errors import ConvergenceError, SceneError
from ..output.files import could_not_draw, flatten, raise_on_every_rank, write_json_atomic, write_text_atomic
from ..output.sweep_plots import numeric_columns, plot_sweep
from .loader import load_scene
from .sweep_plan import Plan, Variant, plan_sweep


def run_sweep(scene_path: str, grid: Sequence[tuple[str, Sequence[Any]]] | Mapping[str, Sequence[Any]],
              out_dir: str, comm: MPI.Comm = MPI.COMM_WORLD, resume: bool = False,
              ranges: Sequence[tuple[str, Any, Any]] = (), linear: str | None = None) -> list[dict[str, Any]]:
    """Run the variants; write sweep.csv, sweep.png (and bands.csv); return sweep.csv's rows.

    Args:
        grid: [(parameter, values)] or {parameter: values}: the grid is every combination.
        ranges: [(parameter, low, high)]: each grid point also runs at the box's corners.
        linear: the linear solver of every run instead of the scene's (``load_scene``).

    Raises:
        SceneError: before any variant runs, if an input is invalid (sweep_plan.plan_sweep), a
            variant's scene is invalid or, with ``resume``, DIR holds another sweep.
        OutputError: on every rank, if a file could not be written or the pictures drawn.
    """
    plan = plan_sweep(scene_path, grid, ranges)
    variants = plan.variants()
    done, stale = _done(out_dir, plan, comm) if resume else (set(), set())
    for variant in variants:
        if variant.folder not in done:
            _load(plan, variant, comm, linear)  # checked, then released
            gc.collect()
    write_json_atomic(os.path.join(out_dir, "sweep.json"), plan.record(), comm)
    rows: dict[str, dict[str, Any]] = {}
    points = plan.points()
    for variant in variants:
        out = os.path.join(out_dir, variant.folder)
        again = resume and variant.folder not in stale
        summary, ok = (_summary(out), True) if variant.folder in done else _run(plan, variant, out, again, comm,
                                                                                       linear)
        final = summary["steps"][-1] if summary["steps"] else {}
        measured = {key: v for key, v in final.items() if key not in ("name", "increments")}
        rows[variant.folder] = {**points[variant.point], "ok": ok, "wall_s": summary["wall_s"],
                                **flatten(measured)}
    table = [rows[v.folder] for v in variants if not v.corner]
    write_text_atomic(os.path.join(out_dir, "sweep.csv"), _csv(table), comm)
    bands = _bands(plan, variants, rows) if plan.ranges else None
    if bands is not None:
        write_text_atomic(os.path.join(out_dir, "bands.csv"), _csv(bands), comm)
    failure = None
    if comm.rank == 0:
        try:
            plot_sweep(out_dir, table, plan.grid, bands, plan.ranges)
        except Exception as error:  # said on every rank, none left waiting for rank 0
            failure = could_not_draw(f"the sweep's pictures in {out_dir}", error)
    raise_on_every_rank(failure, comm)
    return table


def _located(variant: Variant, error: SceneError) -> SceneError:
    values = ", ".join(f"{p} = {v!r}" for p, v in variant.overrides.items())
    return SceneError(f"{error} (the sweep's variant {variant.folder}, {values})")


def _load(plan: Plan, variant: Variant, comm: MPI.Comm, linear: str | None):
    try:
        return load_scene(plan.scene, comm, overrides=variant.overrides, linear=linear)
    except SceneError as error:
        raise _located(variant, error) from None


def _run(plan: Plan, variant: Variant, out: str, resume: bool, comm: MPI.Comm,
         linear: str | None) -> tuple[dict, bool]:
    """Run one variant (with ``resume``, from its checkpoint if it has one): its summary, and
    whether it converged."""
    scene = _load(plan, variant, comm, linear)
    try:
        return scene.run(out, resume=resume), True
    except ConvergenceError:
        return _summary(out), False
    except SceneError as error:  # found while building (probes, cavities) or resuming: say which file
        raise _located(variant, SceneError(f"{plan.scene}: {error}")) from None


def _csv(rows: list[dict[str, Any]]) -> str:
    columns = list(dict.fromkeys(key for row in rows for key in row))
    lines = [",".join(columns)] + [",".join(_cell(row.get(c)) for c in columns) for row in rows]
    return "\n".join(lines) + "\n"


def _cell(value: Any) -> str:
    return "" if value is None else str(value)


def _bands(plan: Plan, variants: list[Variant], rows: dict[str, dict[str, Any]]) -> list[dict[str, Any]]:
    """Per grid point: its parameters, how many corners converged, and the smallest and largest
    value of each numeric prediction over the corners (None unless every corner converged)."""
    bands = []
    for k, point in enumerate(plan.points()):
        corners = [rows[v.folder] for v in variants if v.point == k and v.corner]
        whole = all(row["ok"] for row in corners)
        band: dict[str, Any] = {**point, "corners": len(corners), "corners_ok": sum(row["ok"] for row in corners)}
        for column in numeric_columns(corners, exclude=(*point, "ok", "wall_s")):
            values = [row[column] for row in corners]
            band[f"{column}.min"] = min(values) if whole else None
            band[f"{column}.max"] = max(values) if whole else None
        bands.append(band)
    return bands


def _summary(out: str) -> dict:
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def _done(out_dir: str, plan: Plan, comm: MPI.Comm) -> tuple[set[str], set[str]]:
    """The folders of the variants that a sweep of the same scene and parameters left in
    ``out_dir`` done, and those it left stopped with other values (rank 0 reads; every rank gets
    the answer, or the error)."""
    found, error = (set(), set()), None
    if comm.rank == 0:
        try:
            found = _done_on_disk(out_dir, plan)
        except SceneError as failure:
            error = str(failure)
    found, error = comm.bcast((found, error), root=0)
    if error:
        raise SceneError(error)
    return found


def _varied(record: dict[str, Any]) -> str:
    names = [repr(p) for p in record["parameters"]] + [f"the range of {r[0]!r}" for r in record["ranges"]]
    return " x ".join(names)


def _done_on_disk(out_dir: str, plan: Plan) -> tuple[set[str], set[str]]:
    path = os.path.join(out_dir, "sweep.json")
    if not os.path.isfile(path):
        return set(), set()  # nothing was swept here: every variant runs
    record = plan.record()
    try:
        with open(path) as f:
            before = json.load(f)
        swept = {key: before[key] for key in ("scene", "parameters", "ranges", "variants")}
    except (OSError, ValueError, KeyError, TypeError):
        raise SceneError(f"{path} is not a sweep's record: resume a sweep in its own folder") from None
    if swept["scene"] != record["scene"]:
        raise SceneError(f"{out_dir}: cannot resume: the scene file has changed since the sweep in it; give a new "
                         "--out")
    if _varied(swept) != _varied(record):
        raise SceneError(f"{out_dir}: cannot resume: the sweep in it varied {_varied(swept)}, not "
                         f"{_varied(record)}; give a new --out")
    done, stale = set(), set()
    for folder, overrides in record["variants"].items():
        try:
            state = _summary(os.path.join(out_dir, folder)).get("state")
        except (OSError, ValueError, AttributeError):
            continue  # not started: it runs
        same = swept["variants"].get(folder) == overrides
        if state == "done" and not same:
            raise SceneError(f"{out_dir}: cannot resume: variant {folder} was done with "
                             f"{_values(swept['variants'].get(folder))}, not {_values(overrides)}; give a new --out")
        (done if state == "done" else stale if not same else set()).add(folder)
    return done, stale


def _values(overrides: dict[str, float] | None) -> str:
    return ", ".join(f"{p} = {v!r}" for p, v in (overrides or {}).items()) or "other values"

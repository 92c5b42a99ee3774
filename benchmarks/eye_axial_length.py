"""Work-precision of the eye: the axial length change under the encircling buckle against a
much finer mesh (issue 7, the eye's row of the work-precision study).

The scene is demos/encircling_buckle_seed.toml (Q1/P0) with the sutures tied at their rest
length (so that the measure is the band's alone); the measure is the buckle's own effect, the
axial length after "tighten" less the axial length after "pressurize", on meshes n_circ = 16,
24, 32, 40 (the default) and the reference n_circ given by ``--reference`` (default 56).
``wall_s`` is ``Scene.run`` (the slowest rank's), the mesh built and the forms compiled before.
The rows, {problem: "eye axial length", element, n, cells, dofs, wall_s, value, error, ok,
failure} as in benchmarks/results/work_precision.json, go to
benchmarks/results/eye_axial_length.json under "rows" (with the run's commit, date, hardware and
load under "run"), with a log-log plot of error against wall time
(benchmarks/results/eye_axial_length.png), and are printed.

A size whose solve fails stays in the table, the JSON and the plot: marked FAILED, with the
solver's message (which step, at which load factor, why), its wall time until the failure,
and no value or error; the plot marks it with a cross at its wall time.

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/eye_axial_length.py
"""
import argparse
import json
import os
import time

from mpi4py import MPI
from provenance import run_record

from eyeball_fenicsx.errors import ConvergenceError
from eyeball_fenicsx.output.console import silence
from eyeball_fenicsx.scene.loader import load_scene

comm = MPI.COMM_WORLD
HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "demos", "encircling_buckle_seed.toml")
RESULTS = os.path.join(HERE, "results", "eye_axial_length.json")
PROBLEM = "eye axial length"


def buckle_lengthening(n_circ, out):
    """One size: {n, cells, dofs, wall_s, value (the axial length change from 'pressurize' to
    'tighten', mm), ok, failure (the solver's message when a step did not converge, else None)}."""
    scene = load_scene(SCENE, overrides={"mesh.n_circ": n_circ, "buckle_sutures.shortening": 0.0})
    row = {"problem": PROBLEM, "element": "Q1P0", "n": n_circ, "cells": None, "dofs": None, "value": None,
           "ok": True, "failure": None}
    start = time.perf_counter()
    try:
        summary = scene.run(out)
    except ConvergenceError as error:
        row.update(ok=False, failure=str(error))
        if comm.rank == 0:
            print(f"n_circ {n_circ}: FAILED: {error}", flush=True)
    row["wall_s"] = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    if row["ok"]:
        eye = {s["name"]: s["eye"] for s in summary["steps"]}
        row.update(cells=summary["cells"], dofs=summary["dofs"],
                   value=eye["tighten"]["axial_length_mm"] - eye["pressurize"]["axial_length_mm"])
    return row


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.5))
    reference = next(r for r in rows if r.get("role") == "reference")
    line = [r for r in rows if r.get("role") != "reference" and r["error"] is not None]
    ax.loglog([r["wall_s"] for r in line], [r["error"] for r in line], marker="o", label="Q1P0")
    for r in line:
        ax.annotate(str(r["n"]), (r["wall_s"], r["error"]), textcoords="offset points", xytext=(4, 4), fontsize=7)
    failed = [r for r in rows if r.get("role") != "reference" and not r["ok"]]
    if failed and line:  # a failed size has no error: a cross at its wall time, on the lowest error's level
        level = min(r["error"] for r in line)
        ax.plot([r["wall_s"] for r in failed], [level] * len(failed), "rx", label="failed (no value)")
        for r in failed:
            ax.annotate(f"{r['n']} failed", (r["wall_s"], level), textcoords="offset points", xytext=(4, -10),
                        fontsize=7, color="red")
    title = f"{PROBLEM} under the buckle, against n_circ = {reference['n']}"
    ax.set_title(title if reference["ok"] else title + " (FAILED: no errors)")
    ax.set_xlabel("wall time of the three steps [s], 2 MPI ranks")
    ax.set_ylabel("relative error (labels: n_circ)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    silence()  # no line per load increment: the tables say it
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[16, 24, 32, 40])
    parser.add_argument("--reference", type=int, default=56)
    parser.add_argument("--out", default=os.path.join("out", "eye_axial_length"))
    args = parser.parse_args()
    load = os.getloadavg()[0]
    reference = {**buckle_lengthening(args.reference, args.out), "role": "reference", "error": 0.0}
    if not reference["ok"]:
        reference["error"] = None
    rows = [reference]
    for n in args.sizes:
        row = buckle_lengthening(n, args.out)
        row["error"] = (abs(row["value"] - reference["value"]) / abs(reference["value"])
                        if row["ok"] and reference["ok"] else None)
        rows.append(row)
    run = run_record(comm, repeats=1, load_average_1min_at_start=load, sizes=args.sizes,
                     reference=args.reference)
    if comm.rank == 0:
        value = f"{reference['value']:.4f} mm" if reference["ok"] else "FAILED"
        print(f"{PROBLEM}: the buckle's lengthening (mm) against n_circ = {args.reference} "
              f"({value}, {reference['wall_s']:.0f} s)")
        print(f"{'n_circ':>7}{'cells':>8}{'dofs':>8}{'wall_s':>9}{'value':>10}{'error':>10}")
        for row in rows[1:]:
            if row["ok"]:
                error = f"{row['error']:>10.2e}" if row["error"] is not None else f"{'-':>10}"
                print(f"{row['n']:>7}{row['cells']:>8}{row['dofs']:>8}{row['wall_s']:>9.1f}{row['value']:>10.4f}"
                      f"{error}")
            else:
                print(f"{row['n']:>7}{'-':>8}{'-':>8}{row['wall_s']:>9.1f}  FAILED: {row['failure']}")
        with open(RESULTS + ".tmp", "w") as f:
            json.dump({"run": run, "rows": rows}, f, indent=1)
        os.replace(RESULTS + ".tmp", RESULTS)
        plot(rows, os.path.splitext(RESULTS)[0] + ".png")
    if not reference["ok"]:
        raise SystemExit(3)


if __name__ == "__main__":
    main()

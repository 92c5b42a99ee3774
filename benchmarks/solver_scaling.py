"""Linear solvers against the size of the eye: time, memory and iterations (issue 20).

The surgeon's scene, ``demos/encircling_buckle.toml`` (calibrated tissues, the band on the
half eye), at ``n_circ`` 40, 56, 80 and 112 sectors of the circle (the eye builder refines
through the wall in step), each with each linear solver of ``[solver] linear``:

* ``mumps``: one MUMPS factorization per new tangent (the default);
* ``mumps-blr``: MUMPS with block low-rank compression of its fronts;
* ``iterative``: Newton-Krylov, FGMRES preconditioned by the augmented-Lagrangian block
  preconditioner (system/al_preconditioner.py: the displacement block penalized element by
  element and factorized, diagonal pressure blocks).

Each run is its own ``mpirun`` (ranks 1, 2 or more; this machine has 2 cores, so more ranks
are oversubscribed and said to be), so that its peak memory is its own. A run solves the
steps named by ``--steps`` (by default the first, "pressurize": the eye filled to its
pressure with the band resting on it, the largest linear systems of the operation without its
contact onset) and records one row:

    n_circ, solver, ranks, unknowns, wall_s (the steps, forms compiled), mesh_s, setup_s,
    peak_memory_MB (the largest rank's resident peak, getrusage), mumps_memory_MB (MUMPS'
    INFOG(21), the largest rank's, when MUMPS factorizes), newton_iterations,
    krylov_iterations, factorizations, phase seconds (PETSc events: assembly, factorization
    or preconditioner set-up, Krylov/triangular solves, contact), axial_length_change_mm
    (from the unloaded mesh: the inflation by the filling, which the pressurize step is) and
    the eye's other measures.

The rows go to ``benchmarks/results/solver_scaling.json`` (a list), the projection below to
``solver_scaling_projection.json``; the table (Markdown) and the plot
(time and memory against unknowns, one line per solver) to ``solver_scaling.md`` / ``.png``.
Each solver's measures are compared with MUMPS' at the same size and ranks (relative
difference, expected below 1e-6: the Newton tolerances, not the linear solver, decide the
answer).

    .venv/bin/python3 benchmarks/solver_scaling.py [--n-circ 40 56 80 112] \\
        [--solvers mumps mumps-blr iterative] [--ranks 2] [--steps pressurize]

A projection to a 10-million-unknown eye on a cluster is fitted to the rows (power laws in
the unknowns, per solver; ``project``), with its assumptions printed beside it.
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SCENE = os.path.join(ROOT, "demos", "encircling_buckle.toml")
RESULTS = os.path.join(HERE, "results")
EVENTS = {"assembly": ("SNESFunctionEval", "SNESJacobianEval"),
          "factorization or preconditioner": ("PCSetUp",), "linear solves": ("KSPSolve",)}
MEASURES = ("axial_length_mm", "axial_length_change_from_mesh_mm", "iop_mmHg", "buckle_height_mm")
TARGET_UNKNOWNS = 10_000_000


def wall_layers(n_circ):
    """The layers through the wall that keep a fine eye's elements about as thick as long
    (README, "Fine eyes"): the default eye's below n_circ 56, twice them from there on."""
    return 1 if n_circ < 56 else 2


def fine_scene(n_circ, folder):
    """A copy of the scene with its eye's ``wall_layers`` (the shipped file has none to override)."""
    with open(SCENE) as f:
        text = f.read().replace("[mesh]\n", f"[mesh]\nwall_layers = {wall_layers(n_circ)}\n", 1)
    path = os.path.join(folder, "scene.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def worker(args):
    """One run under MPI: the scene at one size with one solver; prints its row (rank 0)."""
    from mpi4py import MPI
    from petsc4py import PETSc
    from provenance import run_record

    from eyeball_fenicsx.contact import ContactPair
    from eyeball_fenicsx.scene.loader import load_scene

    comm = MPI.COMM_WORLD
    PETSc.Log.begin()

    def events():
        return {group: comm.allreduce(sum(PETSc.Log.Event(n).getPerfInfo()["time"] for n in names), op=MPI.MAX)
                for group, names in EVENTS.items()}

    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        scene = load_scene(fine_scene(args.n_circ, folder), overrides={"mesh.n_circ": args.n_circ}, linear=args.solver)
    mesh_s = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    names = [s.name for s in scene.steps]
    scene.steps = scene.steps[: names.index(args.steps[-1]) + 1]  # the features of later steps never ramp
    start = time.perf_counter()
    scene.build()
    setup_s = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    before = events()
    start = time.perf_counter()
    summary = scene.run(None)
    wall_s = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    phases = {k: v - before[k] for k, v in events().items()}
    phases["contact"] = comm.allreduce(sum(sum(f.timing.values()) for f in scene.features
                                           if isinstance(f, ContactPair)), op=MPI.MAX)
    increments = [i for s in summary["steps"] for i in s["increments"]]
    peak_mb = comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, op=MPI.MAX)
    eye = summary["steps"][-1]["eye"]
    row = {"n_circ": args.n_circ, "wall_layers": wall_layers(args.n_circ), "solver": args.solver, "ranks": comm.size,
           "cells": summary["cells"],
           "unknowns": summary["dofs"], "steps": [s["name"] for s in summary["steps"]], "ok": summary["ok"],
           "wall_s": wall_s, "mesh_s": mesh_s, "setup_s": setup_s, "phases_s": phases,
           "peak_memory_MB": peak_mb, "mumps_memory_MB": max(i["mumps_memory_MB"] for i in increments),
           "increments": len(increments), "newton_iterations": sum(i["newton_iterations"] for i in increments),
           "krylov_iterations": sum(i["krylov_iterations"] for i in increments),
           "factorizations": sum(i["factorizations"] for i in increments),
           "axial_length_change_mm": eye["axial_length_change_from_mesh_mm"],
           "measures": {k: eye[k] for k in MEASURES if k in eye},
           "run": run_record(comm, repeats=1, oversubscribed=comm.size > os.cpu_count())}
    if comm.rank == 0:
        print("ROW " + json.dumps(row), flush=True)


def run_one(n_circ, solver, ranks, steps):
    """One ``mpirun`` of this script as a worker; its row, or a row saying how it failed."""
    command = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks), sys.executable, __file__,
               "--worker", "--n-circ", str(n_circ), "--solver", solver, "--steps", *steps]
    done = subprocess.run(command, capture_output=True, text=True, cwd=HERE)
    rows = [json.loads(line[4:]) for line in done.stdout.splitlines() if line.startswith("ROW ")]
    if rows:
        return rows[0]
    tail = (done.stderr or done.stdout).strip().splitlines()[-3:]
    return {"n_circ": n_circ, "solver": solver, "ranks": ranks, "ok": False, "error": " | ".join(tail)}


def agreement(rows):
    """Each row's largest relative difference of the eye's measures from MUMPS' at the same size
    and ranks (None where MUMPS has no row)."""
    reference = {(r["n_circ"], r["ranks"]): r for r in rows if r["solver"] == "mumps" and r["ok"]}
    for r in rows:
        ref = reference.get((r["n_circ"], r["ranks"]))
        if r["ok"] and ref is not None:
            r["difference_from_mumps"] = max(abs(r["measures"][k] - v) / max(abs(v), 1e-300)
                                             for k, v in ref["measures"].items())


def project(rows, ranks):
    """Power laws t = a N^b and m = c N^d (the process' peak and MUMPS' own) fitted per solver to
    the rows on ``ranks`` ranks, and their values at TARGET_UNKNOWNS: an extrapolation over two
    decades that assumes the same Newton iterations and the same nested-dissection fill (memory
    about N^(4/3), flops about N^2 for a 3D mesh: George 1973) at every size; README says what it
    gives on a cluster."""
    fits = {}
    for solver in sorted({r["solver"] for r in rows}):
        mine = [r for r in rows if r["solver"] == solver and r["ranks"] == ranks and r["ok"]]
        if len(mine) < 2:
            continue
        n = np.log([r["unknowns"] for r in mine])
        fit = {}
        for key in ("wall_s", "peak_memory_MB", "mumps_memory_MB"):
            if not all(r[key] for r in mine):
                continue
            b, a = np.polyfit(n, np.log([r[key] for r in mine]), 1)
            fit[key] = {"exponent": float(b), "at_target": float(np.exp(a) * TARGET_UNKNOWNS ** b)}
        fits[solver] = fit
    return fits


def table(rows):
    lines = ["| n_circ | solver | ranks | unknowns | wall (s) | peak memory (MB, largest rank) | MUMPS memory (MB) "
             "| Newton | Krylov | axial length change (mm) | vs MUMPS |", "|" + "---|" * 11]
    for r in rows:
        if not r["ok"]:
            lines.append(f"| {r['n_circ']} | {r['solver']} | {r['ranks']} | failed: {r.get('error', '')} "
                         "| | | | | | | |")
            continue
        diff = r.get("difference_from_mumps")
        lines.append(f"| {r['n_circ']} | {r['solver']} | {r['ranks']} | {r['unknowns']:,} | {r['wall_s']:.1f} | "
                     f"{r['peak_memory_MB']:.0f} | {r['mumps_memory_MB'] or ''} | {r['newton_iterations']} | "
                     f"{r['krylov_iterations'] or ''} | {r['axial_length_change_mm']:.6f} | "
                     f"{'' if diff is None else f'{diff:.1e}'} |")
    return "\n".join(lines)


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for solver in sorted({r["solver"] for r in rows}):
        for ranks in sorted({r["ranks"] for r in rows}):
            mine = sorted((r for r in rows if r["solver"] == solver and r["ranks"] == ranks and r["ok"]),
                          key=lambda r: r["unknowns"])
            if mine:
                label = f"{solver}, {ranks} rank{'s' if ranks > 1 else ''}"
                for ax, key in zip(axes, ("wall_s", "peak_memory_MB")):
                    ax.loglog([r["unknowns"] for r in mine], [r[key] for r in mine], "o-", label=label)
    for ax, title in zip(axes, ("wall time of the steps (s)", "peak memory of the largest rank (MB)")):
        ax.set_xlabel("unknowns")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-circ", type=int, nargs="*", default=[40, 56, 80, 112],
                        help="none, with --append: redraw the table, plot and projection from OUT.json")
    parser.add_argument("--solvers", nargs="+", default=["mumps", "mumps-blr", "iterative"])
    parser.add_argument("--ranks", type=int, nargs="+", default=[2])
    parser.add_argument("--steps", nargs="+", default=["pressurize"], help="the scene's steps to run, from its first")
    parser.add_argument("--out", default=os.path.join(RESULTS, "solver_scaling"), help="results, without suffix")
    parser.add_argument("--append", action="store_true",
                        help="add the rows to those already in OUT.json (a row measured again replaces its old one)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--solver", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        args.n_circ = args.n_circ[0]
        return worker(args)
    from provenance import machine_record

    rows = []
    if args.append:
        with open(args.out + ".json") as f:
            rows = json.load(f)
    for n_circ in args.n_circ:
        for ranks in args.ranks:
            for solver in args.solvers:
                row = run_one(n_circ, solver, ranks, args.steps)
                rows = [r for r in rows if (r["n_circ"], r["solver"], r["ranks"]) != (n_circ, solver, ranks)] + [row]
                print(table(rows[-1:]).splitlines()[-1], flush=True)
    agreement(rows)
    ranks = sorted({row["ranks"] for row in rows})
    projection = {"target_unknowns": TARGET_UNKNOWNS, "fits_by_ranks": {str(r): project(rows, r) for r in ranks},
                  "run": machine_record(steps=args.steps)}
    with open(args.out + ".json", "w") as f:
        json.dump(rows, f, indent=1)
    with open(args.out + "_projection.json", "w") as f:
        json.dump(projection, f, indent=1)
    with open(args.out + ".md", "w") as f:
        f.write(table(rows) + "\n")
    plot(rows, args.out + ".png")
    print(table(rows))
    print(json.dumps(projection, indent=1))


if __name__ == "__main__":
    main()

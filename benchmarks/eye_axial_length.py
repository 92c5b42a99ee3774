"""Work-precision of the eye: the axial length change under the encircling buckle against a
much finer mesh (issue 7, the eye's row of the work-precision study).

The scene is demos/encircling_buckle.toml (Q1/P0) with the sutures tied at their rest length
(so that the measure is the band's alone); the measure is the buckle's own effect, the axial length after "tighten" less the axial length after
"pressurize", on meshes n_circ = 16, 24, 32, 40 (the default) and the reference n_circ given
by ``--reference`` (default 56). ``wall_s`` is ``Scene.run`` (the slowest rank's), the mesh
built and the forms compiled before. The rows, {problem: "eye axial length", element, n, cells,
dofs, wall_s, value, error} as in benchmarks/results/work_precision.json, go to
benchmarks/results/eye_axial_length.json, with a log-log plot of error against wall time
(benchmarks/results/eye_axial_length.png), and are printed.

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/eye_axial_length.py
"""
import argparse
import json
import os
import time

from mpi4py import MPI

from eyeball_fenicsx.errors import ConvergenceError
from eyeball_fenicsx.scenefile import load_scene

comm = MPI.COMM_WORLD
HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "demos", "encircling_buckle.toml")
RESULTS = os.path.join(HERE, "results", "eye_axial_length.json")
PROBLEM = "eye axial length"


def buckle_lengthening(n_circ, out):
    """(cells, dofs, wall_s, axial length change from 'pressurize' to 'tighten'), or None if a
    step did not converge."""
    scene = load_scene(SCENE, overrides={"mesh.n_circ": n_circ, "buckle_sutures.shortening": 0.0})
    scene.log = lambda message: None
    start = time.perf_counter()
    try:
        summary = scene.run(out)
    except ConvergenceError as error:
        if comm.rank == 0:
            print(f"n_circ {n_circ}: {error}", flush=True)
        return None
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    eye = {s["name"]: s["eye"] for s in summary["steps"]}
    return summary["cells"], summary["dofs"], wall, eye["tighten"]["axial_length_mm"] - eye["pressurize"]["axial_length_mm"]


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.5))
    line = [r for r in rows if r.get("role") != "reference"]
    ax.loglog([r["wall_s"] for r in line], [r["error"] for r in line], marker="o", label="Q1P0")
    for r in line:
        ax.annotate(str(r["n"]), (r["wall_s"], r["error"]), textcoords="offset points", xytext=(4, 4), fontsize=7)
    reference = next(r for r in rows if r.get("role") == "reference")
    ax.set_title(f"{PROBLEM} under the buckle, against n_circ = {reference['n']}")
    ax.set_xlabel("wall time of the three steps [s], 2 MPI ranks")
    ax.set_ylabel("relative error (labels: n_circ)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[16, 24, 32, 40])
    parser.add_argument("--reference", type=int, default=56)
    parser.add_argument("--out", default=os.path.join("out", "eye_axial_length"))
    args = parser.parse_args()
    reference = buckle_lengthening(args.reference, args.out)
    if reference is None:
        raise SystemExit(3)
    rows = [{"problem": PROBLEM, "element": "Q1P0", "role": "reference", "n": args.reference,
             "cells": reference[0], "dofs": reference[1], "wall_s": reference[2], "value": reference[3], "error": 0.0}]
    for n in args.sizes:
        result = buckle_lengthening(n, args.out)
        if result is not None:
            cells, dofs, wall, value = result
            rows.append({"problem": PROBLEM, "element": "Q1P0", "n": n, "cells": cells, "dofs": dofs, "wall_s": wall,
                         "value": value, "error": abs(value - reference[3]) / abs(reference[3])})
    if comm.rank == 0:
        print(f"{PROBLEM}: the buckle's lengthening (mm) against n_circ = {args.reference} "
              f"({reference[3]:.4f} mm, {reference[2]:.0f} s)")
        print(f"{'n_circ':>7}{'cells':>8}{'dofs':>8}{'wall_s':>9}{'value':>10}{'error':>10}")
        for row in rows[1:]:
            print(f"{row['n']:>7}{row['cells']:>8}{row['dofs']:>8}{row['wall_s']:>9.1f}{row['value']:>10.4f}"
                  f"{row['error']:>10.2e}")
        with open(RESULTS, "w") as f:
            json.dump(rows, f, indent=1)
        plot(rows, os.path.splitext(RESULTS)[0] + ".png")


if __name__ == "__main__":
    main()

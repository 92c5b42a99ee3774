"""The same eye on 1, 2 and 3 ranks: the buckle operations' predictions, compared.

Issue 14 asks that the partition not change the answer beyond round-off (1e-6 relative). Each
scene runs as a surgeon would run it, ``mpirun -n K eyeball-fenicsx run scene.toml``, for K = 1,
2, 3, on the default eye (``--n-circ 40``) or the coarse one (16), and every eye measure and
contact force of every step is compared with the one-rank run:

    .venv/bin/python3 benchmarks/rank_agreement.py [--n-circ 40] [--ranks 1 2 3]

(not under mpirun: it starts the runs). Writes benchmarks/results/rank_agreement[_<n>].json and
.md: per scene and rank count the largest relative difference, which measure it was, the wall
time, and whether the run converged. The scenes: the seed's encircling operation, the segmental
buckle, and the surgeon's operation (calibrated tissues, the break closed, the drainage).
"""
import argparse
import json
import os
import subprocess
import sys
import time
import tomllib

import provenance
import tomli_w

from eyeball_fenicsx.scene.overrides import set_parameter

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
SCENES = {"encircling": os.path.join(REPO, "demos", "encircling_buckle_seed.toml"),
          "segmental": os.path.join(REPO, "demos", "segmental_buckle.toml"),
          "surgeon": os.path.join(REPO, "demos", "encircling_buckle.toml")}
FLOOR = 1e-9  # measures smaller than this (mm, mmHg, N) are compared absolutely


def run(scene, ranks, n_circ, out):
    """Run the scene with n_circ on ``ranks`` ranks; (summary or None, wall seconds, error)."""
    with open(SCENES[scene], "rb") as f:
        data = tomllib.load(f)
    set_parameter(data, "mesh.n_circ", n_circ)
    os.makedirs(out, exist_ok=True)
    path = os.path.join(out, "scene.toml")
    with open(path, "wb") as f:
        tomli_w.dump(data, f)
    command = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks), sys.executable, "-m",
               "eyeball_fenicsx", "run", path, "--out", out]
    start = time.perf_counter()
    # os.environ is the environment this process started with: importing eyeball_fenicsx starts
    # an MPI singleton, which adds variables to the C environment that make a child mpirun exit 1
    # without a word
    done = subprocess.run(command, capture_output=True, text=True, cwd=REPO, env=dict(os.environ))
    wall = time.perf_counter() - start
    if done.returncode != 0:
        return None, wall, (done.stderr.strip().splitlines() or ["exit %d" % done.returncode])[-1]
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f), wall, None


def measures(summary):
    """{step/measure: value} of every eye measure and contact force component."""
    values = {}
    for step in summary["steps"]:
        for key, value in step.get("eye", {}).items():
            if isinstance(value, (int, float)):
                values[f"{step['name']}/{key}"] = float(value)
        for name, contact in step.get("contact", {}).items():
            for axis, value in zip("xyz", contact["force"]):
                values[f"{step['name']}/{name} force {axis}"] = float(value)
    return values


def largest_difference(reference, other):
    """(relative difference, measure) of the measure that differs most."""
    worst = (0.0, None)
    for key, value in reference.items():
        scale = max(abs(value), FLOOR)
        difference = abs(other[key] - value) / scale
        worst = max(worst, (difference, key), key=lambda w: w[0])
    return worst


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-circ", type=int, default=40)
    parser.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 3])
    parser.add_argument("--out", default=os.path.join("out", "rank_agreement"))
    args = parser.parse_args()
    results = {"benchmark": "rank_agreement", "n_circ": args.n_circ,
               "run": provenance.machine_record(load_average_1min_at_start=os.getloadavg()[0]),
               "scenes": {}}
    rows = []
    for scene in SCENES:
        runs = {}
        for ranks in args.ranks:
            summary, wall, error = run(scene, ranks, args.n_circ, os.path.join(args.out, f"{scene}_{ranks}"))
            runs[ranks] = {"ok": summary is not None, "wall_s": wall, "error": error,
                           "measures": measures(summary) if summary else None}
        reference = runs[args.ranks[0]]["measures"]
        for ranks, record in runs.items():
            if reference is not None and record["measures"] is not None:
                difference = largest_difference(reference, record["measures"])
                record["max_relative_difference"], record["worst_measure"] = difference
            status = "converged" if record["ok"] else f"FAILED: {record['error']}"
            difference = record.get("max_relative_difference")
            rows.append(f"| {scene} | {ranks} | {status} | {record['wall_s']:.1f} | "
                        f"{'-' if difference is None else f'{difference:.1e}'} | "
                        f"{record.get('worst_measure') or '-'} |")
            print(rows[-1], flush=True)
        results["scenes"][scene] = {str(k): v for k, v in runs.items()}
    stem = os.path.join(HERE, "results", "rank_agreement" + ("" if args.n_circ == 40 else f"_{args.n_circ}"))
    with open(stem + ".json", "w") as f:
        json.dump(results, f, indent=1)
    lines = [f"# The same eye on {', '.join(map(str, args.ranks))} ranks (n_circ {args.n_circ})", "",
             f"`benchmarks/rank_agreement.py`, commit {results['run']['commit']}, {results['run']['date']}, "
             f"{results['run']['cpu']}, {results['run']['cores']} cores. Difference: the largest over every eye "
             f"measure and contact force component of every step, relative to the {args.ranks[0]}-rank run.", "",
             "| scene | ranks | status | wall s | max relative difference | measure |",
             "| --- | ---: | --- | ---: | ---: | --- |",
             *rows]
    with open(stem + ".md", "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()

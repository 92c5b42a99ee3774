"""The segmental buckle's predictions against the mesh: the eye graded around the sutures or not,
their ends spread over their bites or tied at points.

The scene (``--scene``) is demos/segmental_buckle.toml (a silicone tire sutured onto the sclera,
the sutures shortened by 0.4 mm: the planning matrix's segmental-0.4; graded along the meridian) or
demos/radial_sponge.toml (a radial sponge at 45 degrees on the whole eye; graded across the
meridians), with its defaults but for the mesh and the bite: each mesh ``N[:R[:W]]`` (``[mesh]
n_circ = N``, ``refine = R``, ``wall_layers = W``, default 1 each) is run graded around the sutures
or not (``--graded``: ``[mesh] graded``, the default true for either buckle) with each ``--bites``
length (``[buckle_sutures] bite``, mm; 0 ties each end at its point, the model before the bites). A
point force on a continuum has no mesh limit: the question is whether the predictions settle as the
mesh is refined around the eye (n_circ), through its wall (wall_layers) and along and through it
(refine).

Each row: the mesh, graded or not, bite, hexahedra, unknowns, the slowest rank's ``Scene.run`` wall time (the
mesh built and the forms compiled before), Newton iterations, and after the sutures the buckle
height (the sclera's indentation under the tire), the IOP, the axial length change, the detached
area and the reattached fraction; its difference from the finest mesh of the same grading and
bite is printed. The rows go to benchmarks/results/segmental_mesh.json (sponge_mesh.json for the
sponge; or ``--results``; with the run's record under "run") and are printed as a table.

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/segmental_mesh.py

The bite length's effect, on the default eye (graded; the sutures are 15 degrees apart, about 3 mm
at the bites, which caps a bite there):

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/segmental_mesh.py --meshes 40 \
        --graded true --bites 1 2 3 --results benchmarks/results/segmental_bites.json

The radial sponge (README, "The eye graded around the sutures"):

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/segmental_mesh.py --scene sponge --meshes 40 56
"""
import argparse
import json
import os
import time
import tomllib

import tomli_w
from mpi4py import MPI
from provenance import run_record

from eyeball_fenicsx.errors import ConvergenceError
from eyeball_fenicsx.output.console import silence
from eyeball_fenicsx.scene.loader import load_scene

comm = MPI.COMM_WORLD
HERE = os.path.dirname(os.path.abspath(__file__))
SCENES = {"segmental": "segmental_buckle.toml", "sponge": "radial_sponge.toml"}
RESULTS = {"segmental": "segmental_mesh.json", "sponge": "sponge_mesh.json"}
MEASURES = ("buckle_height_mm", "iop_mmHg", "axial_length_change_mm", "detached_area_mm2", "reattached_fraction")


def run(scene_file: str, mesh: str, graded: bool, bite: float, out: str) -> dict:
    """The scene on one mesh, graded or not, with one bite, as a copy of the scene file in its output folder."""
    out = os.path.join(out, f"{mesh.replace(':', '-')}-{'graded' if graded else 'uniform'}-bite{bite:g}")
    n_circ, refine, wall_layers = (int(n) for n in (mesh.split(":") + ["1", "1"])[:3])
    path = os.path.join(out, "scene.toml")
    if comm.rank == 0:
        with open(os.path.join(HERE, "..", "demos", scene_file), "rb") as f:
            data = tomllib.load(f)
        data["mesh"].update(n_circ=n_circ, refine=refine, wall_layers=wall_layers, graded=graded)
        data["buckle_sutures"]["bite"] = bite
        os.makedirs(out, exist_ok=True)
        with open(path, "wb") as f:
            tomli_w.dump(data, f)
    comm.barrier()
    scene = load_scene(path)
    row = {"mesh": mesh, "graded": graded, "bite_mm": bite, "ok": True, "failure": None}
    start = time.perf_counter()
    try:
        summary = scene.run(out)
    except ConvergenceError as error:
        row.update(ok=False, failure=str(error))
    row["wall_s"] = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    if row["ok"]:
        eye = summary["steps"][-1]["eye"]
        row.update(cells=summary["cells"], dofs=summary["dofs"], **{m: eye[m] for m in MEASURES},
                   newton=sum(i["newton_iterations"] for s in summary["steps"] for i in s["increments"]))
    return row


def main():
    silence()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", nargs="+", default=["40", "56", "40:1:2", "56:2"],
                        help="n_circ[:refine[:wall_layers]], the finest last")
    parser.add_argument("--graded", nargs="+", choices=["true", "false"], default=["true", "false"],
                        help="[mesh] graded: the eye graded around the sutures or not")
    parser.add_argument("--bites", type=float, nargs="+", default=[3.0], help="bite lengths, mm (0: points)")
    parser.add_argument("--scene", choices=sorted(SCENES), default="segmental", help="the tire or the radial sponge")
    parser.add_argument("--out", default=os.path.join("out", "segmental_mesh"))
    parser.add_argument("--results", help="the JSON file the rows go to (default: results/<scene>_mesh.json)")
    args = parser.parse_args()
    results = args.results or os.path.join(HERE, "results", RESULTS[args.scene])
    load = os.getloadavg()[0]
    graded = [value == "true" for value in args.graded]
    rows = [run(SCENES[args.scene], mesh, g, bite, os.path.join(args.out, args.scene))
            for g in graded for bite in args.bites for mesh in args.meshes]
    record = run_record(comm, repeats=1, load_average_1min_at_start=load, scene=SCENES[args.scene],
                        meshes=args.meshes, graded=graded, bites=args.bites)
    if comm.rank == 0:
        print(f"{SCENES[args.scene]} after the sutures; 'vs finest': the buckle height against the last mesh's, "
              "same grading and bite")
        print(f"{'mesh':>8}{'graded':>7}{'bite':>6}{'cells':>8}{'dofs':>8}{'wall_s':>8}{'Newton':>7}{'height':>9}"
              f"{'vs finest':>10}{'IOP':>8}{'axial':>9}{'detached':>10}{'reattached':>11}")
        for row in rows:
            if not row["ok"]:
                print(f"{row['mesh']:>8}{row['graded']!s:>7}{row['bite_mm']:>6g}  FAILED after {row['wall_s']:.0f} s: "
                      f"{row['failure']}")
                continue
            finest = next((r for r in reversed(rows) if r["ok"] and (r["bite_mm"], r["graded"])
                           == (row["bite_mm"], row["graded"])), row)
            row["height_vs_finest"] = row["buckle_height_mm"] / finest["buckle_height_mm"] - 1
            print(f"{row['mesh']:>8}{row['graded']!s:>7}{row['bite_mm']:>6g}{row['cells']:>8}{row['dofs']:>8}"
                  f"{row['wall_s']:>8.0f}{row['newton']:>7}{row['buckle_height_mm']:>9.4f}{row['height_vs_finest']:>+10.1%}"
                  f"{row['iop_mmHg']:>8.2f}{row['axial_length_change_mm']:>9.4f}{row['detached_area_mm2']:>10.2f}"
                  f"{row['reattached_fraction']:>11.3f}")
        with open(results + ".tmp", "w") as f:
            json.dump({"run": record, "rows": rows}, f, indent=1)
        os.replace(results + ".tmp", results)


if __name__ == "__main__":
    main()

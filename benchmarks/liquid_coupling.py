"""What the liquid costs: solid alone, the seed's new algorithm, its previous algorithm.

The same thick sphere octant (A = 1, B = 2, neo-Hooke c10 = 0.5) at increasing mesh sizes
is inflated (1) by a pressure on its inner surface, (2) by liquid injected into the cavity
with the pressure as one global unknown (the bordered system), (3) the same with the
pressure eliminated (dense tangent over the wetted dofs). The pressure load of (1) is the
pressure (2) reaches, so all three end in the same state. Each case runs with the
factorization the solver's default picks for it: LDL^T (MUMPS Cholesky) for the solid alone,
whose tangent is symmetric; LU for the bordered and the dense systems (their tangents are
not). The solid alone is also run with LU, to separate the border's cost from the
factorization's. Per case: matrix nonzeros, MUMPS factor entries and memory, time of one
numeric factorization (the fastest of ``--repeat`` interleaved runs, each the mean over the
run's factorizations), Newton iterations and factorizations, wall time of ``Scene.run``.
One increment, the solver's other defaults (factorization reuse).

    mpirun -n 2 .venv/bin/python3 benchmarks/liquid_coupling.py [--sizes 4 8 12 16] [--repeat 3]

writes benchmarks/results/liquid_coupling.json (with the commit, date, hardware and load
under "run") and prints a table.
"""
import argparse
import json
import os
import time

from mpi4py import MPI
from petsc4py import PETSc
from provenance import run_record

import eyeball_fenicsx as ef
from eyeball_fenicsx.features.cavity import LiquidCavity
from eyeball_fenicsx.meshing.builders.sphere_octant import build_sphere_octant
from eyeball_fenicsx.meshing.load import built_mesh
from eyeball_fenicsx.output.console import silence

comm = MPI.COMM_WORLD
SYMMETRY = [("sym_x", "x"), ("sym_y", "y"), ("sym_z", "z")]


def run_case(mesh, load, pc_type=None):
    """Solve one case (``pc_type``: force the factorization, else the solver's default); return
    its measurements."""
    features = [ef.Dirichlet(s, {axis: 0.0}) for s, axis in SYMMETRY]
    if load[0] == "pressure":
        features.append(ef.Pressure("inner", load[1]))
    else:
        cavity = LiquidCavity("liquid", "inner", 10.0, symmetry=["x", "y", "z"], algorithm=load[0])
        features.append(cavity)
    scene = ef.Scene("liquid-coupling", mesh, {"wall": ef.NeoHooke(0.5)}, features=features,
                     solver=ef.SolverSettings(increments=1))
    if pc_type:
        PETSc.Options()["eye_pc_type"] = pc_type
    try:
        scene.build()
    finally:
        PETSc.Options().delValue("eye_pc_type")
    if load[0] != "pressure":
        cavity.dV_inj = load[1] * cavity.V_ini
    # LU, or LDL^T when the tangent is symmetric (the solid alone): count both
    events = [PETSc.Log.Event(name) for name in ("MatLUFactorNum", "MatCholFctrNum")]
    before = [e.getPerfInfo() for e in events]
    comm.barrier()
    start = time.perf_counter()
    summary = scene.run()
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    after = [e.getPerfInfo() for e in events]
    count = sum(a["count"] - b["count"] for a, b in zip(after, before))
    spent = sum(a["time"] - b["time"] for a, b in zip(after, before))
    factor_time = comm.allreduce(spent, op=MPI.MAX) / max(count, 1)
    A = scene.problem.A
    factor = scene.newton.snes.getKSP().getPC().getFactorMatrix()
    step = summary["steps"][-1]
    return {
        "dofs": A.getSize()[0],
        "nonzeros": int(A.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"]),
        "factor_entries": int(factor.getMumpsInfog(29)),
        "mumps_memory_MB": int(factor.getMumpsInfog(22)),
        "factorization_s": factor_time,
        "newton_iterations": sum(i["newton_iterations"] for i in step["increments"]),
        "factorizations": count,
        "factorization": {"cholesky": "LDL^T", "lu": "LU"}[scene.newton.snes.getKSP().getPC().getType()],
        "solve_s": wall,
        "pressure": step.get("cavities", {}).get("liquid", {}).get("pressure", load[1]),
    }


def fastest(runs):
    """The first run's measurements, with the fastest factorization and solve of all runs."""
    row = dict(runs[0])
    for key in ("factorization_s", "solve_s"):
        row[key + "_all"] = [r[key] for r in runs]
        row[key] = min(row[key + "_all"])
    row["same_newton_iterations_every_run"] = len({r["newton_iterations"] for r in runs}) == 1
    return row


CASES = ["solid only (default: LDL^T)", "solid only, LU", "new (bordered)", "previous (dense)"]


def main():
    silence()  # no line per load increment: the tables say it
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 12, 16])
    parser.add_argument("--repeat", type=int, default=3, help="interleaved runs of every case (the fastest is kept)")
    parser.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "liquid_coupling.json"))
    args = parser.parse_args()
    load = os.getloadavg()[0]
    PETSc.Log.begin()
    rows = []
    for n in args.sizes:
        mesh = built_mesh(build_sphere_octant, comm, n=n, layers=max(n // 2, 1))
        runs = {name: [] for name in CASES}
        for _ in range(args.repeat):
            new = run_case(mesh, ("new", 0.331))  # inner stretch about 1.1
            runs["new (bordered)"].append(new)
            runs["previous (dense)"].append(run_case(mesh, ("previous", 0.331)))
            runs["solid only (default: LDL^T)"].append(run_case(mesh, ("pressure", new["pressure"])))
            runs["solid only, LU"].append(run_case(mesh, ("pressure", new["pressure"]), pc_type="lu"))
        cells = mesh.mesh.topology.index_map(3).size_global
        wetted = 3 * (3 * n * n + 3 * n + 1)  # displacement dofs on the inner surface
        for name in CASES:
            rows.append({"n": n, "cells": cells, "wetted_dofs": wetted, "algorithm": name, **fastest(runs[name])})
    run = run_record(comm, repeats=args.repeat, load_average_1min_at_start=load, sizes=args.sizes,
                     solver="defaults, 1 increment")
    if comm.rank == 0:
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        with open(args.out + ".tmp", "w") as f:
            json.dump({"run": run, "ranks": comm.size, "rows": rows}, f, indent=1)
        os.replace(args.out + ".tmp", args.out)
        print(f"{run['ranks']} ranks, {run['cpu']}, {run['cores']} cores, load {load:.2f} at the start; "
              f"factorization and solve s: fastest of {args.repeat}; 'vs default' against the solid alone with "
              f"its default LDL^T, 'vs LU' against the solid alone with LU")
        header = (f"{'cells':>6} {'wetted':>6} {'algorithm':<28} {'factor':>6} {'dofs':>6} {'nonzeros':>9} "
                  f"{'factor nz':>10} {'MB':>4} {'factor s':>8} {'Newton':>6} {'fact.':>5} {'solve s':>7} "
                  f"{'vs default':>10} {'vs LU':>6}")
        print(header)
        for row in rows:
            base = {name: next(r for r in rows if r["n"] == row["n"] and r["algorithm"] == name) for name in CASES[:2]}
            print(f"{row['cells']:>6} {row['wetted_dofs']:>6} {row['algorithm']:<28} {row['factorization']:>6} "
                  f"{row['dofs']:>6} {row['nonzeros']:>9} {row['factor_entries']:>10} {row['mumps_memory_MB']:>4} "
                  f"{row['factorization_s']:>8.4f} {row['newton_iterations']:>6} {row['factorizations']:>5} "
                  f"{row['solve_s']:>7.3f} {row['factorization_s'] / base[CASES[0]]['factorization_s']:>10.2f} "
                  f"{row['factorization_s'] / base[CASES[1]]['factorization_s']:>6.2f}")


if __name__ == "__main__":
    main()

"""What the liquid costs: solid alone, the seed's new algorithm, its previous algorithm.

The same thick sphere octant (A = 1, B = 2, neo-Hooke c10 = 0.5) at increasing mesh sizes
is inflated (1) by a pressure on its inner surface, (2) by liquid injected into the cavity
with the pressure as one global unknown (the bordered system), (3) the same with the
pressure eliminated (dense tangent over the wetted dofs). The pressure load of (1) is the
pressure (2) reaches, so all three end in the same state. Per case: matrix nonzeros,
MUMPS factor entries and memory, time of one numeric factorization, Newton iterations,
all with the same LU factorization.

    mpirun -n 2 .venv/bin/python3 benchmarks/liquid_coupling.py [--sizes 4 8 12 16]

writes benchmarks/results/liquid_coupling.json and prints a table.
"""
import argparse
import json
import os
import time

from mpi4py import MPI
from petsc4py import PETSc

import eyeball_fenicsx as ef
from eyeball_fenicsx.cavity import LiquidCavity
from eyeball_fenicsx.mesh import built_mesh
from meshes.sphere_octant import build_sphere_octant

comm = MPI.COMM_WORLD
SYMMETRY = [("sym_x", "x"), ("sym_y", "y"), ("sym_z", "z")]


def run_case(mesh, load):
    """Solve one case; return its measurements."""
    features = [ef.Dirichlet(s, {axis: 0.0}) for s, axis in SYMMETRY]
    if load[0] == "pressure":
        features.append(ef.Pressure("inner", load[1]))
    else:
        cavity = LiquidCavity("liquid", "inner", 10.0, symmetry=["x", "y", "z"], algorithm=load[0])
        features.append(cavity)
    scene = ef.Scene("liquid-coupling", mesh, {"wall": ef.NeoHooke(0.5)}, features=features,
                     solver=ef.SolverSettings(increments=1), log=lambda message: None)
    scene.build()
    if load[0] != "pressure":
        cavity.dV_inj = load[1] * cavity.V_ini
    # LU, or LDL^T when the tangent is symmetric (the solid alone): count both
    events = [PETSc.Log.Event(name) for name in ("MatLUFactorNum", "MatCholFctrNum")]
    before = [e.getPerfInfo() for e in events]
    start = time.perf_counter()
    summary = scene.run()
    wall = time.perf_counter() - start
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
        "factorization": scene.newton.snes.getKSP().getPC().getType(),
        "solve_s": wall,
        "pressure": step.get("cavities", {}).get("liquid", {}).get("pressure", load[1]),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 12, 16])
    parser.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "liquid_coupling.json"))
    args = parser.parse_args()
    PETSc.Log.begin()
    # the same factorization (LU) for all three, so that the table measures the border; the
    # solid alone would otherwise get LDL^T (see README.md: the bordered system stays on LU)
    PETSc.Options()["eye_pc_type"] = "lu"
    rows = []
    for n in args.sizes:
        mesh = built_mesh(build_sphere_octant, comm, n=n, layers=max(n // 2, 1))
        new = run_case(mesh, ("new", 0.331))  # inner stretch about 1.1
        previous = run_case(mesh, ("previous", 0.331))
        solid = run_case(mesh, ("pressure", new["pressure"]))
        cells = mesh.mesh.topology.index_map(3).size_global
        wetted = 3 * (3 * n * n + 3 * n + 1)  # displacement dofs on the inner surface
        for name, case in (("solid only", solid), ("new (bordered)", new), ("previous (dense)", previous)):
            rows.append({"n": n, "cells": cells, "wetted_dofs": wetted, "algorithm": name, **case})
    if comm.rank == 0:
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        with open(args.out + ".tmp", "w") as f:
            json.dump({"ranks": comm.size, "rows": rows}, f, indent=1)
        os.replace(args.out + ".tmp", args.out)
        header = (f"{'cells':>6} {'wetted':>6} {'algorithm':<17} {'dofs':>7} {'nonzeros':>10} {'factor nz':>11} "
                  f"{'MUMPS MB':>8} {'factor s':>8} {'Newton':>6} {'vs solid':>8}")
        print(header)
        for row in rows:
            base = next(r for r in rows if r["n"] == row["n"] and r["algorithm"] == "solid only")
            print(f"{row['cells']:>6} {row['wetted_dofs']:>6} {row['algorithm']:<17} {row['dofs']:>7} "
                  f"{row['nonzeros']:>10} {row['factor_entries']:>11} {row['mumps_memory_MB']:>8} "
                  f"{row['factorization_s']:>8.3f} {row['newton_iterations']:>6} "
                  f"{row['factorization_s'] / base['factorization_s']:>8.2f}")


if __name__ == "__main__":
    main()

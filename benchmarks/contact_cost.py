"""What deformable-deformable contact costs against the Newton solve, as the surface grows.

Two stacked blocks, 1 x 1 x 1/2 each, non-matching meshes (master n x n x n/2 hexahedra,
slave (n + 1) x (n + 1) x n/2), neo-Hooke c10 = 0.5; the top of the upper block is pushed
down 0.05 and dragged 0.1 sideways in 8 increments, so the slave nodes slide over about
n/10 master elements. Per size: contact search (bucket grid, once per increment), contact
assembly (residual and tangent, every Newton iteration), re-preallocation of the matrix
when the candidate pairs change, and the whole Newton solve, all wall seconds on the
slowest rank. "contact %" is (search + assembly) / (all Newton solves, those of increments
cut back included); "gather" is the part of search and assembly spent gathering the master
surface's displacements, which includes waiting for the other ranks.

    mpirun -n 2 python3 benchmarks/contact_cost.py [--sizes 6 12 18]

writes benchmarks/results/contact_cost.json and prints a table. Goal: contact under 15 %
of the Newton time.
"""
import argparse
import json
import os
import sys
import time

import numpy as np
from mpi4py import MPI

import eyeball_fenicsx as ef
from eyeball_fenicsx.contact import ContactPair

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
from test_contact import blocks_mesh  # noqa: E402  (the tests' builder of separate boxes)

comm = MPI.COMM_WORLD


def run(n):
    """Solve one size; return its measurements."""
    layers = max(n // 2, 1)
    axis = lambda k, lo=0.0, hi=1.0: np.linspace(lo, hi, k + 1)
    mesh = blocks_mesh(("lower", axis(n), axis(n), axis(layers, 0.0, 0.5)),
                       ("upper", axis(n + 1), axis(n + 1), axis(layers, 0.5, 1.0)))
    pair = ContactPair("interface", slave="upper_z0", master="lower_z1")
    scene = ef.Scene("contact-cost", mesh, {"lower": ef.NeoHooke(0.5), "upper": ef.NeoHooke(0.5)},
                     features=[ef.Dirichlet("lower_z0", {"x": 0.0, "y": 0.0, "z": 0.0}),
                               ef.Dirichlet("upper_z1", {"x": 0.1, "y": 0.0, "z": -0.05}), pair],
                     # a fresh tangent every Newton iteration: the cost of a full Newton step
                     solver=ef.SolverSettings(increments=8, reuse_contraction=0.0), log=lambda message: None)
    scene.build()
    spent = {"newton": 0.0, "pattern": 0.0}
    update_pattern, solve = scene.problem.update_pattern, scene.newton.solve

    def timed_update_pattern():  # re-preallocation when the candidate pairs change, search excluded
        searched, start = pair.timing["search"], time.perf_counter()
        changed = update_pattern()
        spent["pattern"] += time.perf_counter() - start - (pair.timing["search"] - searched)
        return changed

    def timed_solve(x):  # every Newton solve, those of increments cut back included
        start = time.perf_counter()
        try:
            return solve(x)
        finally:
            spent["newton"] += time.perf_counter() - start

    scene.problem.update_pattern, scene.newton.solve = timed_update_pattern, timed_solve
    pair.timing.update(search=0.0, assembly=0.0, gather=0.0)  # from the first increment on
    summary = scene.run()
    increments = summary["steps"][-1]["increments"]
    slowest = lambda seconds: comm.allreduce(seconds, op=MPI.MAX)
    contact = summary["steps"][-1]["contact"]["interface"]
    return {
        "n": n,
        "cells": summary["cells"],
        "dofs": summary["dofs"],
        "slave_points": comm.allreduce(len(pair.weight), op=MPI.SUM),
        "master_segments": len(pair.segments),
        "active_nodes": contact["active_nodes"],
        "increments": len(increments),
        "newton_iterations": sum(i["newton_iterations"] for i in increments),
        "newton_s": slowest(spent["newton"]),
        "search_s": slowest(pair.timing["search"]),
        "assembly_s": slowest(pair.timing["assembly"]),
        "gather_s": slowest(pair.timing["gather"]),
        "repreallocation_s": slowest(spent["pattern"]),
        "max_penetration": contact["max_penetration"],
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[6, 12, 18])
    parser.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "contact_cost.json"))
    args = parser.parse_args()
    rows = [run(n) for n in args.sizes]
    if comm.rank == 0:
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        with open(args.out + ".tmp", "w") as f:
            json.dump({"ranks": comm.size, "rows": rows}, f, indent=1)
        os.replace(args.out + ".tmp", args.out)
        print(f"{'cells':>6} {'dofs':>7} {'slave':>6} {'segments':>8} {'incr.':>5} {'Newton':>6} {'Newton s':>8} "
              f"{'search s':>8} {'assembly s':>10} {'(gather s)':>10} {'contact %':>9} {'re-alloc %':>10}")
        for r in rows:
            share = 100 * (r["search_s"] + r["assembly_s"]) / r["newton_s"]
            print(f"{r['cells']:>6} {r['dofs']:>7} {r['slave_points']:>6} {r['master_segments']:>8} {r['increments']:>5} "
                  f"{r['newton_iterations']:>6} {r['newton_s']:>8.3f} {r['search_s']:>8.4f} {r['assembly_s']:>10.4f} "
                  f"{r['gather_s']:>10.4f} {share:>9.1f} {100 * r['repreallocation_s'] / r['newton_s']:>10.1f}")

if __name__ == "__main__":
    main()

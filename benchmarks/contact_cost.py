"""What deformable-deformable contact costs against the whole solve, as the surface grows.

Two stacked blocks, 1 x 1 x 1/2 each, non-matching meshes (master n x n x n/2 hexahedra,
slave (n + 1) x (n + 1) x n/2), neo-Hooke c10 = 0.5; the top of the upper block is pushed
down 0.05 and dragged 0.1 sideways in 8 increments, so the slave nodes slide over about
n/10 master elements. The solver runs with its defaults (factorization reuse, the contact
penalty and smoothing from the elements), as a user's scene would. Per size, wall seconds on
the slowest rank, every cost that contact causes:

* search: the candidate segments (bucket grid, once per increment);
* assembly: the contact residual and tangent (every residual and Jacobian), with the
  selection and projection inside them and the zeros reserved in the matrix after a search;
* other calls: what the solver asks of the contact feature besides (``closing_step``, with its
  triangular solves; ``step_fraction``, the onset limiter of the line search;
  ``tangent_outdated``, a collective before reusing a factorization; ``augment``,
  ``set_increment``, ``set_load_factor``, ``begin_step``);
* re-preallocation: a new matrix when the candidate pairs leave the pattern (the rest of
  ``NewtonSolver.update_pattern``: the keys, the coupling, ``_create_matrix``, the KSP reset);
* new symbolic factorizations: a new pattern needs a new MUMPS analysis; without contact there
  is one per run, so all but one of the run's analyses (PETSc events ``MatCholFctrSym`` and
  ``MatLUFactorSym``, their mean time each);
* augmentation re-solves: the Newton solves after an augmented-Lagrangian update (the one at
  the usual tolerances that ends them included: they start from the last factorization), reported
  apart (they are Newton work that the contact law asks for, not overhead of computing it);
  the contact search, assembly and calls inside them are counted above, not again.

"contact %" is the sum of the first five over the wall time of ``Scene.run``; "+ augm. %"
adds the re-solves' own work (less the contact inside them); "of Newton %" is search + assembly
over the Newton solves (the measure this benchmark reported before, kept to compare); "gather"
is the part of search, assembly and the other calls spent gathering the master surface's
displacements, which includes waiting for the other ranks.

    mpirun -n 2 python3 benchmarks/contact_cost.py [--sizes 6 12 18]

writes benchmarks/results/contact_cost.json (with the commit, date, hardware and load under
"run") and prints a table.

**The eye** (``--eye``): the seed's encircling operation (demos/encircling_buckle_seed.toml: the
band on the sclera and the detached retina on the choroid, both deformable pairs, active from the
first step) on eyes of ``--n-circ`` sectors and ``--wall-layers``. The first increment of the
first step ("pressurize"), its first ``--iterations`` Newton iterations, each with a new tangent
(no factorization reuse): per Newton iteration, on the slowest rank, the contact's cost (the
search and the exchange of the master segments at the start of the increment, spread over the
iterations; the assembly of the contact residual and tangent with the selection and projection
inside it, the gather of the master nodes' displacements inside that, and the other calls:
the onset limit of the line search and the collective before a tangent) against the whole Newton
iteration (residual and Jacobian assembly, contact included, factorization, triangular solves,
line search), and PETSc's events for the phases:

    mpirun -n 2 python3 benchmarks/contact_cost.py --eye --n-circ 40 80 112 --wall-layers 1 2 2

writes benchmarks/results/contact_cost_eye.json and prints a table.
"""
import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

import eyeball_fenicsx as ef
from eyeball_fenicsx.contact import ContactPair
from eyeball_fenicsx.output.console import silence
from eyeball_fenicsx.scene.loader import load_scene
from eyeball_fenicsx.system.stepping import ramp

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
from provenance import run_record  # noqa: E402
from test_contact import blocks_mesh  # noqa: E402  (the tests' builder of separate boxes)

SYMBOLIC = ["MatCholFctrSym", "MatLUFactorSym"]
# what the solver asks of a contact feature besides search and assembly
OTHER_CALLS = ["closing_step", "step_fraction", "tangent_outdated", "augment", "set_increment", "set_load_factor",
               "begin_step"]

comm = MPI.COMM_WORLD
HERE = os.path.dirname(os.path.abspath(__file__))
EYE_SCENE = os.path.join(HERE, "..", "demos", "encircling_buckle_seed.toml")
PHASES = {"residual": ("SNESFunctionEval",), "jacobian": ("SNESJacobianEval",),
          "factorization": ("MatLUFactorNum", "MatCholFctrNum"), "symbolic": tuple(SYMBOLIC), "solve": ("MatSolve",)}


def master_segments(pair):
    """The master surface's segments over all ranks (before the exchange, every rank held them all)."""
    return pair.master.count if hasattr(pair, "master") else len(pair.segments)


def slowest(seconds):
    return comm.allreduce(seconds, op=MPI.MAX)


def phase_seconds():
    """Seconds so far per phase (PETSc events), on the slowest rank."""
    return {k: slowest(sum(PETSc.Log.Event(e).getPerfInfo()["time"] for e in names)) for k, names in PHASES.items()}


def symbolic():
    """(count, seconds on the slowest rank) of the symbolic factorizations so far."""
    infos = [PETSc.Log.Event(name).getPerfInfo() for name in SYMBOLIC]
    return sum(i["count"] for i in infos), comm.allreduce(sum(i["time"] for i in infos), op=MPI.MAX)


def timed(function, spent, key, minus=None):
    """``function`` that adds its wall time to spent[key], less what ``minus()`` grew meanwhile."""
    def wrapper(*args, **kwargs):
        inner, start = minus() if minus else 0.0, time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            spent[key] += time.perf_counter() - start - ((minus() if minus else 0.0) - inner)
    return wrapper


def run(n):
    """Solve one size; return its measurements."""
    layers = max(n // 2, 1)

    def axis(k, lo=0.0, hi=1.0):
        return np.linspace(lo, hi, k + 1)

    mesh = blocks_mesh(("lower", axis(n), axis(n), axis(layers, 0.0, 0.5)),
                       ("upper", axis(n + 1), axis(n + 1), axis(layers, 0.5, 1.0)))
    pair = ContactPair("interface", slave="upper_z0", master="lower_z1")
    scene = ef.Scene("contact-cost", mesh, {"lower": ef.NeoHooke(0.5), "upper": ef.NeoHooke(0.5)},
                     features=[ef.Dirichlet("lower_z0", {"x": 0.0, "y": 0.0, "z": 0.0}),
                               ef.Dirichlet("upper_z1", {"x": 0.1, "y": 0.0, "z": -0.05}), pair],
                     solver=ef.SolverSettings(increments=8))
    scene.build()
    spent = {"newton": 0.0, "augmented_newton": 0.0, "contact_in_augmented": 0.0, "pattern": 0.0, "other_calls": 0.0}
    solve = scene.newton.solve

    def contact_so_far():
        return pair.timing["search"] + pair.timing["assembly"] + spent["other_calls"]

    def timed_solve(x, **kwargs):  # every Newton solve, those of increments cut back included
        start, contact = time.perf_counter(), contact_so_far()
        try:
            return solve(x, **kwargs)
        finally:
            if kwargs.get("chord_start"):  # an augmentation re-solve; its contact calls are counted apart
                spent["augmented_newton"] += time.perf_counter() - start
                spent["contact_in_augmented"] += contact_so_far() - contact
            else:
                spent["newton"] += time.perf_counter() - start

    scene.newton.solve = timed_solve
    # the solver's update_pattern (a new matrix and the KSP reset after it), the search excluded
    scene.newton.update_pattern = timed(scene.newton.update_pattern, spent, "pattern", lambda: pair.timing["search"])
    for name in OTHER_CALLS:  # the other calls of the feature (none of them searches or assembles)
        setattr(pair, name, timed(getattr(pair, name), spent, "other_calls"))
    pair.timing.update(search=0.0, assembly=0.0, gather=0.0)  # from the first increment on
    symbolic_before = symbolic()
    comm.barrier()
    start = time.perf_counter()
    summary = scene.run()
    run_s = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    symbolic_after = symbolic()
    analyses = symbolic_after[0] - symbolic_before[0]
    analysis_s = symbolic_after[1] - symbolic_before[1]
    increments = summary["steps"][-1]["increments"]

    contact = summary["steps"][-1]["contact"]["interface"]
    row = {
        "n": n,
        "cells": summary["cells"],
        "dofs": summary["dofs"],
        "slave_points": comm.allreduce(len(pair.weight), op=MPI.SUM),
        "master_segments": master_segments(pair),
        "active_nodes": contact["active_nodes"],
        "increments": len(increments),
        "newton_iterations": sum(i["newton_iterations"] for i in increments),
        "factorizations": sum(i["factorizations"] for i in increments),
        "run_s": run_s,
        "newton_s": slowest(spent["newton"]),
        "augmentation_resolves_s": slowest(spent["augmented_newton"]),
        # the re-solves less the contact search, assembly and calls inside them (counted above)
        "augmentation_resolves_without_contact_s": slowest(spent["augmented_newton"] - spent["contact_in_augmented"]),
        "search_s": slowest(pair.timing["search"]),
        "assembly_s": slowest(pair.timing["assembly"]),
        "other_calls_s": slowest(spent["other_calls"]),
        "gather_s": slowest(pair.timing["gather"]),
        "repreallocation_s": slowest(spent["pattern"]),
        "symbolic_factorizations": analyses,
        "new_symbolic_factorizations_s": analysis_s * max(analyses - 1, 0) / max(analyses, 1),
        "max_penetration": contact["max_penetration"],
    }
    row["contact_s"] = sum(row[k] for k in ("search_s", "assembly_s", "other_calls_s", "repreallocation_s",
                                            "new_symbolic_factorizations_s"))
    row["contact_share"] = row["contact_s"] / run_s
    row["contact_share_with_augmentation"] = (row["contact_s"] + row["augmentation_resolves_without_contact_s"]) / run_s
    row["search_and_assembly_of_newton"] = (row["search_s"] + row["assembly_s"]) / (
        row["newton_s"] + row["augmentation_resolves_s"])
    return row


def eye_run(n_circ, wall_layers, iterations):
    """The first ``iterations`` Newton iterations of the operation's first increment on one eye;
    return the measurements (module docstring)."""
    with open(EYE_SCENE) as f:  # the shipped scene has no wall_layers for an override to change
        text = f.read().replace("[mesh]\n", f"[mesh]\nwall_layers = {wall_layers}\n", 1)
    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "scene.toml")
        with open(path, "w") as f:
            f.write(text)
        start = time.perf_counter()
        scene = load_scene(path, overrides={"mesh.n_circ": n_circ})
    mesh_s = slowest(time.perf_counter() - start)
    PETSc.Options()["eye_snes_max_it"] = iterations  # read again when the pattern grows: kept to the end
    scene.build()
    problem, newton = scene.problem, scene.newton
    pairs = [f for f in scene.features if isinstance(f, ContactPair)]
    spent = {"other_calls": 0.0}
    for pair in pairs:
        for name in OTHER_CALLS:
            setattr(pair, name, timed(getattr(pair, name), spent, "other_calls"))
        pair.timing.update({key: 0.0 for key in pair.timing})
    newton.reuse_contraction = 0.0  # a new tangent every iteration
    problem.begin_step(0)
    x = problem.x
    problem.state_to_vector(x)
    increments = scene.steps[0].increments or scene.solver.increments
    problem.set_load_factor([ramp(f.step, 0, 1.0 / increments) for f in problem.features])
    before = phase_seconds()
    comm.barrier()
    start = time.perf_counter()
    newton.update_pattern()  # the contact search (and exchange), a new matrix if the pattern grew
    search = sum(p.timing["search"] for p in pairs)
    increment_start_s = slowest(time.perf_counter() - start)
    problem.set_increment(False)
    factorized = newton.factorizations
    start = time.perf_counter()
    _, its, norm, reason = newton.solve(x)
    newton_s = slowest(time.perf_counter() - start)
    PETSc.Options().delValue("eye_snes_max_it")
    phases = {k: v - before[k] for k, v in phase_seconds().items()}
    timing = {key: slowest(sum(p.timing.get(key, 0.0) for p in pairs)) for key in ("search", "exchange", "gather")}
    assembly_s = slowest(sum(p.timing["assembly"] for p in pairs))
    contact_s = slowest(sum(p.timing["assembly"] for p in pairs) + spent["other_calls"] + search)
    held = [len(p.table.segments) for p in pairs] if hasattr(pairs[0], "table") else [master_segments(p) for p in pairs]
    row = {"n_circ": n_circ, "wall_layers": wall_layers,
           "cells": scene.solid.mesh_data.mesh.topology.index_map(3).size_global, "unknowns": problem.n_global,
           "slave_points": [comm.allreduce(len(p.weight), op=MPI.SUM) for p in pairs],
           "master_segments": [master_segments(p) for p in pairs],
           "master_segments_held_max_rank": [comm.allreduce(h, op=MPI.MAX) for h in held],
           "mesh_s": mesh_s, "newton_iterations": its, "factorizations": newton.factorizations - factorized,
           "residual_norm": norm, "reason": reason, "increment_start_s": increment_start_s, "newton_s": newton_s,
           "phases_s": phases, "contact_search_s": timing["search"], "contact_exchange_s": timing["exchange"],
           "contact_assembly_s": assembly_s, "contact_gather_s": timing["gather"],
           "contact_other_calls_s": slowest(spent["other_calls"]), "contact_s": contact_s}
    row["per_iteration_s"] = (newton_s + increment_start_s) / max(its, 1)
    row["contact_per_iteration_s"] = contact_s / max(its, 1)
    row["contact_share"] = contact_s / (newton_s + increment_start_s)
    return row


def eye_main(args, load):
    rows = [eye_run(n, w, args.iterations) for n, w in zip(args.n_circ, args.wall_layers)]
    run_info = run_record(comm, repeats=1, load_average_1min_at_start=load, n_circ=args.n_circ,
                          wall_layers=args.wall_layers, iterations=args.iterations,
                          solver="defaults, a new tangent every Newton iteration")
    if comm.rank != 0:
        return
    out = args.out or os.path.join(HERE, "results", "contact_cost_eye.json")
    with open(out + ".tmp", "w") as f:
        json.dump({"run": run_info, "ranks": comm.size, "rows": rows}, f, indent=1)
    os.replace(out + ".tmp", out)
    print(f"{comm.size} ranks, load {load:.2f} at the start; seconds per Newton iteration on the slowest rank")
    print(f"{'n_circ':>6} {'wall':>4} {'cells':>6} {'unknowns':>8} {'its':>3} {'iteration':>9} {'factor.':>7} "
          f"{'contact':>7} {'search+exch.':>12} {'assembly':>8} {'(gather)':>8} {'other':>6} {'share %':>7}")
    for r in rows:
        its = max(r["newton_iterations"], 1)
        print(f"{r['n_circ']:>6} {r['wall_layers']:>4} {r['cells']:>6} {r['unknowns']:>8} {its:>3} "
              f"{r['per_iteration_s']:>9.3f} {r['phases_s']['factorization'] / its:>7.3f} "
              f"{r['contact_per_iteration_s']:>7.3f} {r['contact_search_s'] / its:>12.4f} "
              f"{r['contact_assembly_s'] / its:>8.3f} {r['contact_gather_s'] / its:>8.4f} "
              f"{r['contact_other_calls_s'] / its:>6.3f} {100 * r['contact_share']:>7.1f}")


def main():
    silence()  # no line per load increment: the tables say it
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[6, 12, 18])
    parser.add_argument("--out", default=None)
    parser.add_argument("--eye", action="store_true", help="the encircling operation's first Newton iterations")
    parser.add_argument("--n-circ", type=int, nargs="+", default=[40, 80, 112])
    parser.add_argument("--wall-layers", type=int, nargs="+", default=[1, 2, 2])
    parser.add_argument("--iterations", type=int, default=4)
    args = parser.parse_args()
    load = os.getloadavg()[0]
    PETSc.Log.begin()
    if args.eye:
        return eye_main(args, load)
    args.out = args.out or os.path.join(HERE, "results", "contact_cost.json")
    rows = [run(n) for n in args.sizes]
    run_info = run_record(comm, repeats=1, load_average_1min_at_start=load, sizes=args.sizes,
                          solver="defaults, 8 increments")
    if comm.rank == 0:
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        with open(args.out + ".tmp", "w") as f:
            json.dump({"run": run_info, "ranks": comm.size, "rows": rows}, f, indent=1)
        os.replace(args.out + ".tmp", args.out)
        print(f"{run_info['ranks']} ranks, {run_info['cpu']}, {run_info['cores']} cores, load {load:.2f} at the start; "
              f"one run per size; seconds on the slowest rank")
        print(f"{'cells':>6} {'dofs':>6} {'slave':>5} {'incr':>4} {'Newton':>6} {'fact':>4} {'run s':>7} "
              f"{'search':>6} {'assembly':>8} {'other':>6} {'re-alloc':>8} {'sym.':>4} {'new sym s':>9} "
              f"{'augm. s':>7} {'contact %':>9} {'+ augm. %':>9} {'of Newton %':>11} {'(gather)':>8}")
        for r in rows:
            print(f"{r['cells']:>6} {r['dofs']:>6} {r['slave_points']:>5} {r['increments']:>4} "
                  f"{r['newton_iterations']:>6} {r['factorizations']:>4} {r['run_s']:>7.2f} {r['search_s']:>6.3f} "
                  f"{r['assembly_s']:>8.3f} {r['other_calls_s']:>6.3f} {r['repreallocation_s']:>8.3f} "
                  f"{r['symbolic_factorizations']:>4} {r['new_symbolic_factorizations_s']:>9.3f} "
                  f"{r['augmentation_resolves_s']:>7.2f} {100 * r['contact_share']:>9.1f} "
                  f"{100 * r['contact_share_with_augmentation']:>9.1f} "
                  f"{100 * r['search_and_assembly_of_newton']:>11.1f} "
                  f"{r['gather_s']:>8.3f}")


if __name__ == "__main__":
    main()

"""Thick sphere under inner pressure: accuracy and where the time goes, by mesh size.

The octant of the thick sphere (inner radius A = 1, outer B = 2, neo-Hooke c10 = 0.5, inner
follower pressure 0.6, symmetry planes) against the closed form of Ogden (1984, sec. 5.2.2),
at several structured meshes (n elements along a patch edge, radial layers). Per size: cells,
dofs, increments, Newton iterations and factorizations, the error of the inner radius
(relative to the closed-form radial displacement, and to the deformed inner radius), and
the wall time split into

* jit: FFCx/CFFI compilation of the forms, elements and expressions, with a cold cache
  (every size compiles into its own empty cache folder; the forms do not depend on the mesh);
* setup: the rest of ``Scene.build`` (spaces, sparsity, preallocation);
* solve (``Scene.run`` once the forms are compiled), split by PETSc log events into
  assembly (time inside ``Problem.F`` and ``Problem.J``), MUMPS factorization (symbolic and
  numeric, LU or LDL^T), MUMPS triangular solves, and everything else (Python stepping,
  the symmetry check, probes and the final residual for the reactions).

The solve is repeated ``--repeat`` times on fresh scenes and the fastest is reported: the
machine may be shared, and the minimum is the least disturbed run (all runs are in the JSON).

Beside the solve alone, the whole process of one simulation, from the launch of ``mpirun`` to
the end of the solve (the MPI start-up, the interpreter and the imports as this process took
them, the mesh, ``Scene.build`` and ``Scene.run``; the exit is not counted):

* whole, cold: with an empty JIT cache (the first, compiling, run of each size);
* whole, warm: the forms loaded from the cache (each of the other runs; the fastest).

Only the first size's cold run is a cold process in every sense; later sizes compile into a
new empty cache too, but the compiler's own modules are already imported (the start-up and
imports, measured once, are added to every size's whole-process time).

FEBio's figure (22 s for the 16x8 mesh) is kept with what the repository knows of it, which
is not enough to compare: see ``FEBIO``.

``--variants`` also times solver configurations on one mesh, interleaved, to measure what
each of the solver's defaults gains against the configuration before them.

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/sphere_scaling.py \\
        [--sizes 4x2 8x4 16x8 24x12] [--repeat 3] [--variants 16x8]

writes benchmarks/results/sphere_scaling.json and prints the tables.
"""
import time

START = time.time()  # before the imports: they are part of the whole process

import argparse  # noqa: E402  (the imports are timed)
import contextlib
import json
import logging
import math
import os
import shutil
import tempfile

import dolfinx.jit
from mpi4py import MPI
from petsc4py import PETSc
from provenance import run_record

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import sphere_inner_stretch
from eyeball_fenicsx.meshing.builders.sphere_octant import build_sphere_octant
from eyeball_fenicsx.meshing.load import built_mesh
from eyeball_fenicsx.system.newton import PREFIX

comm = MPI.COMM_WORLD
A, B, P = 1.0, 2.0, 0.6
C = {(1, 0): 0.5}  # neo-Hooke, shear modulus 1
LAM = sphere_inner_stretch(P, C, A, B)  # closed form (Ogden 1984, eq. 5.2.38)
# FEBio's figure, with all the repository knows of it: one sentence of issue 2 ("the thick sphere
# octant ... 6144 hexahedra (16 x 16 per cube-face patch, 8 layers) takes FEBio 4 (Pardiso, 2
# threads) about 22 s for 0.30% error in the inner radius"). No FEBio run, input file, log or
# output is in the repository or its history (git log -S "22" -S "FEBio"), and FEBio is not
# installed here: the figure cannot be re-measured or compared.
FEBIO = {
    "cells": 6144, "error_percent": 0.30, "wall_s": 22.0,
    "source": "issue 2 (its text only: 'takes FEBio 4 (Pardiso, 2 threads) about 22 s for 0.30% error in "
              "the inner radius', 'measured on this machine')",
    "version": "FEBio 4, minor version unknown", "build": "unknown", "linear_solver": "Pardiso, 2 threads",
    "machine": "said to be this machine; not recorded (CPU, load, date unknown)",
    "what_was_timed": "unknown (whole process or solve alone; increments, time steps and tolerances unknown)",
    "error_measure": "unknown whether 0.30% is of the radial displacement u_r (as compared here) or of the "
                     "deformed inner radius (0.066% here)",
    "provenance": "unknown: not comparable",
}
INCREMENTS = 2  # as demos/thick_sphere.py
QUIET = 0.25  # cores busy with other processes below which the machine counts as quiet

FACTORIZATION = ["MatLUFactorSym", "MatLUFactorNum", "MatCholFctrSym", "MatCholFctrNum"]
ASSEMBLY = ["SNESFunctionEval", "SNESJacobianEval"]
SYMMETRY_CHECK = "EyeSymmetryCheck"  # inside SNESJacobianEval, but not assembly

# Solver configurations for --variants: (name, PETSc options under eye_, SolverSettings).
BEFORE = {"pc_type": "lu"}
VARIANTS = [
    ("plain: 10 equal incr., LU, Newton", BEFORE, dict(increments=10, growth=1.0, predictor=False,
                                                            reuse_contraction=0.0)),
    ("before: LU, Newton", BEFORE, dict(reuse_contraction=0.0)),
    ("+ LDL^T", {}, dict(reuse_contraction=0.0)),
    ("+ factorization reuse (default)", {}, {}),
    ("LU + factorization reuse", BEFORE, {}),
    ("default, 1 increment", {}, dict(increments=1)),
]


class JitClock:
    """Wall time spent in ``dolfinx.jit.ffcx_jit``, which every form, element and expression
    compiles through (looked up at call time, so wrapping the module attribute sees them all)."""

    def __init__(self):
        self.seconds = 0.0
        self._jit = dolfinx.jit.ffcx_jit

    def _timed(self, *args, **kwargs):
        start = time.perf_counter()
        try:
            return self._jit(*args, **kwargs)
        finally:
            self.seconds += time.perf_counter() - start

    def start(self):
        dolfinx.jit.ffcx_jit = self._timed


jit_clock = JitClock()


@contextlib.contextmanager
def cold_jit_cache():
    """Point the DOLFINx JIT cache at a new empty folder (the same on every rank)."""
    folder = comm.bcast(tempfile.mkdtemp(prefix="sphere-jit-") if comm.rank == 0 else None, root=0)
    parameters = dolfinx.jit.DOLFINX_DEFAULT_JIT_PARAMETERS
    saved = parameters["cache_dir"]
    parameters["cache_dir"] = (folder, saved[1])
    try:
        yield
    finally:
        parameters["cache_dir"] = saved
        comm.barrier()
        if comm.rank == 0:
            shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def petsc_options(options):
    """Set eye_ options for the solvers created inside; remove them afterwards."""
    opts = PETSc.Options()
    for key, value in options.items():
        opts[PREFIX + key] = value
    try:
        yield
    finally:
        for key in options:
            opts.delValue(PREFIX + key)


def busy_cores(seconds):
    """Cores kept busy by other processes over a short window, while every rank sleeps
    (an MPI wait would spin and count itself)."""
    def ticks():
        with open("/proc/stat") as f:
            values = [int(v) for v in f.readline().split()[1:]]
        return sum(values), values[3] + values[4]  # total, idle + iowait
    if comm.rank == 0:
        total, idle = ticks()
    time.sleep(seconds)
    if comm.rank == 0:
        total_after, idle_after = ticks()
        busy = os.cpu_count() * (1 - (idle_after - idle) / max(total_after - total, 1))
    return comm.bcast(busy if comm.rank == 0 else None, root=0)


def wait_for_quiet(patience):
    """Wait (at most ``patience`` seconds) until other processes leave the cores idle; return
    how many cores they kept busy when the run starts."""
    deadline = time.perf_counter() + patience
    while True:
        busy = busy_cores(0.5)
        if busy < QUIET or time.perf_counter() > deadline:
            return busy


def since_launch():
    """Seconds since ``mpirun`` (this rank's parent) started, or since this process started when
    it was not launched by mpirun; from /proc, to 1/CLK_TCK."""
    def started(pid):
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return int(fields[19]) / os.sysconf("SC_CLK_TCK")  # starttime, since boot
    with open("/proc/uptime") as f:
        uptime = float(f.read().split()[0])
    with open(f"/proc/{os.getppid()}/comm") as f:
        parent = f.read().strip()
    pid = os.getppid() if parent in ("mpirun", "mpiexec", "orterun", "prterun") else os.getpid()
    return uptime - started(pid)


def event_seconds(names):
    """Per event: (count, seconds averaged over the ranks) so far."""
    result = {}
    for name in names:
        info = PETSc.Log.Event(name).getPerfInfo()
        result[name] = (info["count"], comm.allreduce(info["time"], op=MPI.SUM) / comm.size)
    return result


def sphere_scene(mesh, **settings):
    settings = {"increments": INCREMENTS, **settings}
    return ef.Scene("thick-sphere", mesh, {"wall": ef.MooneyRivlin(C)},
                    features=[ef.Dirichlet("sym_x", {"x": 0.0}), ef.Dirichlet("sym_y", {"y": 0.0}),
                              ef.Dirichlet("sym_z", {"z": 0.0}), ef.Pressure("inner", P)],
                    probes={"inner": [A, 0.0, 0.0]}, solver=ef.SolverSettings(**settings))


def timed_solve(scene, patience):
    """Run a built scene; return its measurements and the split of its wall time. The scene's
    solver is destroyed afterwards (it holds the MUMPS factors)."""
    names = FACTORIZATION + ASSEMBLY + ["MatSolve", SYMMETRY_CHECK]
    busy = wait_for_quiet(patience)
    before = event_seconds(names)
    comm.barrier()
    start, cpu = time.perf_counter(), time.process_time()
    summary = scene.run()
    cpu = comm.allreduce(time.process_time() - cpu, op=MPI.SUM) / comm.size
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    after = event_seconds(names)
    spent = {name: after[name][1] - before[name][1] for name in names}
    count = {name: after[name][0] - before[name][0] for name in names}
    increments = summary["steps"][-1]["increments"]
    u = summary["steps"][-1]["probes"]["inner"][0]
    exact = (LAM - 1) * A
    pc = scene.newton.snes.getKSP().getPC()
    factor = pc.getFactorMatrix()
    row = {
        "cells": summary["cells"], "dofs": summary["dofs"],
        "nonzeros": int(scene.problem.A.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)["nz_used"]),
        "factorization": "LDL^T" if pc.getType() == "cholesky" else "LU",
        "factor_entries": int(factor.getMumpsInfog(29)), "factor_flops": factor.getMumpsRinfog(3),
        "increments": len(increments),
        "newton_iterations": sum(i["newton_iterations"] for i in increments),
        "factorizations": sum(i["factorizations"] for i in increments),
        "inner_displacement": u,
        "error_of_displacement": abs(u - exact) / exact,  # of the closed-form u_r = (lambda - 1) A
        "error_of_radius": abs(u - exact) / (LAM * A),  # of the deformed inner radius a = lambda A
        "solve_s": wall,
        "solve_cpu_s": cpu,  # per rank; below the wall time when other processes took the cores
        "busy_cores_before": busy,  # taken by other processes when the solve started
        "assembly_s": sum(spent[n] for n in ASSEMBLY) - spent[SYMMETRY_CHECK],
        "factorization_s": sum(spent[n] for n in FACTORIZATION),
        "triangular_solve_s": spent["MatSolve"],
        "symbolic_factorizations": count["MatLUFactorSym"] + count["MatCholFctrSym"],
        "numeric_factorizations": count["MatLUFactorNum"] + count["MatCholFctrNum"],
    }
    row["other_s"] = wall - row["assembly_s"] - row["factorization_s"] - row["triangular_solve_s"]
    scene.newton.snes.destroy()
    return row


def fastest(rows):
    best = dict(min(rows, key=lambda row: row["solve_s"]))
    best["solve_s_all"] = [row["solve_s"] for row in rows]
    best["solve_s_median"] = sorted(best["solve_s_all"])[len(rows) // 2]
    return best


def timed_build(mesh):
    """A scene built; (scene, wall seconds of the build, of which in the JIT)."""
    jit_before = jit_clock.seconds
    comm.barrier()
    start = time.perf_counter()
    scene = sphere_scene(mesh).build()
    build_s = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    return scene, build_s, comm.allreduce(jit_clock.seconds - jit_before, op=MPI.MAX)


def measure_size(n, layers, repeat, patience, startup_s):
    """One mesh size: a cold JIT, then ``repeat`` - 1 warm builds; a solve after each build
    (``repeat`` in all) on a fresh scene; the fastest solve is kept, and the whole process
    (start-up and imports + mesh + build + solve) of the cold run and of the fastest warm one."""
    start = time.perf_counter()
    mesh = built_mesh(build_sphere_octant, comm, inner_radius=A, outer_radius=B, n=n, layers=layers)
    mesh_s = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    with cold_jit_cache():
        scene, build_s, jit_s = timed_build(mesh)
        cold = timed_solve(scene, patience)
        warm = []
        for _ in range(repeat - 1):
            scene, warm_build_s, _ = timed_build(mesh)
            warm.append({**timed_solve(scene, patience), "build_s": warm_build_s})
    whole_warm = [startup_s + mesh_s + row["build_s"] + row["solve_s"] for row in warm]
    return {"n": n, "layers": layers, "mesh_s": mesh_s, "jit_s": jit_s, "setup_s": build_s - jit_s,
            **fastest([cold] + warm),
            "whole_cold_s": startup_s + mesh_s + build_s + cold["solve_s"], "solve_cold_s": cold["solve_s"],
            "whole_warm_s": min(whole_warm) if whole_warm else None, "whole_warm_s_all": whole_warm,
            "build_warm_s": [row["build_s"] for row in warm]}


def measure_variants(n, layers, repeat, patience):
    """Solver configurations on one mesh, interleaved ``repeat`` times; fastest of each."""
    mesh = built_mesh(build_sphere_octant, comm, inner_radius=A, outer_radius=B, n=n, layers=layers)
    runs = {name: [] for name, _, _ in VARIANTS}
    for _ in range(repeat):
        for name, options, settings in VARIANTS:
            with petsc_options(options):
                scene = sphere_scene(mesh, **settings).build()
            runs[name].append(timed_solve(scene, patience))
    return [{"variant": name, "options": options, "settings": settings, **fastest(runs[name])}
            for name, options, settings in VARIANTS]


def rates(rows):
    """Observed order of the error under refinement, h ~ 1/n."""
    return [{"from": f"{a['n']}x{a['layers']}", "to": f"{b['n']}x{b['layers']}",
             "rate": math.log(a["error_of_displacement"] / b["error_of_displacement"]) / math.log(b["n"] / a["n"])}
            for a, b in zip(rows, rows[1:])]


def print_tables(rows, variants, run):
    print(f"thick sphere octant, {comm.size} MPI ranks, {INCREMENTS} load increments, closed-form inner stretch "
          f"{LAM:.6f}; {run['cpu']}, {run['cores']} cores, load {run['load_average_1min_at_start']:.2f} at the "
          f"start; times in s, the solve is the fastest of {run['repeats']}")
    print(f"{'n x layers':>10} {'cells':>6} {'dofs':>7} {'factor':>6} {'incr':>4} {'Newton':>6} {'factor.':>7} "
          f"{'err u_r %':>9} {'err a %':>8} {'jit':>5} {'setup':>5} {'solve':>6} {'assembly':>8} "
          f"{'MUMPS f':>7} {'MUMPS s':>7} {'other':>6} {'asm+other':>9} {'cpu':>6} {'busy':>4}")
    for r in rows:
        share = (r["assembly_s"] + r["other_s"]) / r["solve_s"]
        print(f"{r['n']:>5} x {r['layers']:<2} {r['cells']:>6} {r['dofs']:>7} {r['factorization']:>6} "
              f"{r['increments']:>4} {r['newton_iterations']:>6} {r['factorizations']:>7} "
              f"{100 * r['error_of_displacement']:>9.4f} {100 * r['error_of_radius']:>8.4f} {r['jit_s']:>5.1f} "
              f"{r['setup_s']:>5.2f} {r['solve_s']:>6.2f} {r['assembly_s']:>8.2f} {r['factorization_s']:>7.2f} "
              f"{r['triangular_solve_s']:>7.2f} {r['other_s']:>6.2f} {100 * share:>8.0f}% {r['solve_cpu_s']:>6.2f} "
              f"{r['busy_cores_before']:>4.1f}")
    for rate in rates(rows):
        print(f"observed order of the error of u_r, {rate['from']} -> {rate['to']}: {rate['rate']:.2f}")
    print(f"\nthe whole process (mpirun launch to the end of the solve; start-up and imports {run['startup_s']:.2f} s)")
    print(f"{'n x layers':>10} {'mesh':>5} {'jit':>5} {'setup':>5} {'solve, cold':>11} {'whole, cold':>11} "
          f"{'whole, warm':>11} {'solve alone':>11} {'whole cold / solve':>18}")
    for r in rows:
        warm = f"{r['whole_warm_s']:>11.2f}" if r["whole_warm_s"] is not None else f"{'-':>11}"
        print(f"{r['n']:>5} x {r['layers']:<2} {r['mesh_s']:>5.2f} {r['jit_s']:>5.2f} {r['setup_s']:>5.2f} "
              f"{r['solve_cold_s']:>11.2f} {r['whole_cold_s']:>11.2f} {warm} {r['solve_s']:>11.2f} "
              f"{r['whole_cold_s'] / r['solve_s']:>18.2f}")
    print(f"FEBio's {FEBIO['wall_s']:.0f} s ({FEBIO['cells']} cells): provenance {FEBIO['provenance']}")
    if variants:
        base = next(v for v in variants if v["variant"].startswith("before"))
        print(f"\nsolver configurations on the {variants[0]['cells']}-cell mesh, interleaved, fastest of "
              f"{run['repeats']} (solve alone)")
        print(f"{'configuration':<40} {'incr':>4} {'Newton':>6} {'factor.':>7} {'err u_r %':>9} {'solve':>6} "
              f"{'MUMPS f':>7} {'vs before':>9} {'cpu':>6} {'busy':>4}")
        for v in variants:
            print(f"{v['variant']:<40} {v['increments']:>4} {v['newton_iterations']:>6} {v['factorizations']:>7} "
                  f"{100 * v['error_of_displacement']:>9.4f} {v['solve_s']:>6.2f} {v['factorization_s']:>7.2f} "
                  f"{v['solve_s'] / base['solve_s']:>9.2f} {v['solve_cpu_s']:>6.2f} {v['busy_cores_before']:>4.1f}")


def size(text):
    n, layers = text.split("x")
    return int(n), int(layers)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=size, nargs="+", default=[(4, 2), (8, 4), (16, 8), (24, 12)],
                        help="n x layers, e.g. 16x8")
    parser.add_argument("--repeat", type=int, default=3, help="solves per size (the fastest is reported)")
    parser.add_argument("--variants", type=size, nargs="?", const=(16, 8), default=None,
                        help="also time the solver configurations on this size (default 16x8)")
    parser.add_argument("--patience", type=float, default=20.0,
                        help="seconds to wait before each solve for other processes to leave the cores idle")
    parser.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results",
                                                      "sphere_scaling.json"))
    args = parser.parse_args()
    startup_s = comm.allreduce(since_launch(), op=MPI.MAX)  # mpirun, the interpreter, the imports
    load = os.getloadavg()[0]
    PETSc.Log.begin()
    logging.disable(logging.INFO)  # a cold JIT logs every compiler call (CFFI, through setuptools)
    jit_clock.start()
    rows = [measure_size(n, layers, args.repeat, args.patience, startup_s) for n, layers in args.sizes]
    variants = measure_variants(*args.variants, args.repeat, args.patience) if args.variants else []
    run = run_record(comm, repeats=args.repeat, load_average_1min_at_start=load, startup_s=startup_s,
                     patience_s=args.patience, seconds=time.time() - START)
    if comm.rank == 0:
        result = {"run": run, "ranks": comm.size, "A": A, "B": B, "pressure": P, "c10": C[(1, 0)],
                  "inner_stretch": LAM,
                  "increments": INCREMENTS, "febio": FEBIO, "sizes": rows, "rates": rates(rows),
                  "variants": variants}
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        with open(args.out + ".tmp", "w") as f:
            json.dump(result, f, indent=1)
        os.replace(args.out + ".tmp", args.out)
        print_tables(rows, variants, run)


if __name__ == "__main__":
    main()

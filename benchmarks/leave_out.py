"""What a scene pays for the features it does not hold, and for idle ones.

The octant of the thick sphere (A = 1, B = 2, neo-Hooke c10 = 0.5, symmetry planes, follower
pressure 0.6 on the inner surface, one load increment; 12 x 6: 2592 hexahedra) is solved

* by a hand-written plain-DOLFINx reference: the same UFL mixed residual (``MixedSolid``'s
  energy, the follower pressure's term) in ``dolfinx.fem.petsc.NonlinearProblem`` (its own
  ``F`` and ``J``), DOLFINx Dirichlet conditions, a bare PETSc SNES with the package's
  tolerances and line search (``solver.DEFAULT_OPTIONS``) and MUMPS LU; built twice
  ("reference, again"), so that the two copies measure the noise of the machine;
* by ``Scene`` / ``Problem`` / ``NewtonSolver`` with nothing but the supports and the load
  ("bare"), with LU and a new tangent every Newton step (``-eye_pc_type lu``,
  ``reuse_contraction = 0``) so that it takes the reference's Newton steps; and once more with
  its inversion guard switched off (single calls only), to price the guard;
* by the same scene with a feature that is present but idle: a rigid plane 8 above the pole
  in contact with the whole outer surface ("idle plane, outer") or with a cap of it, a suture
  at zero tension between two outer nodes; or with a second follower pressure (0.01) on the
  whole outer surface or on the cap (the outer facets within 15 degrees of the z axis, 3 %).

Measured, interleaved (every configuration once per round, the order reversed every other
round); "fastest" is the least disturbed sample, "med" the median of the per-round ratios:

1. Newton solves from rest: iterations (they must match the reference's), and per Newton
   iteration the time of SNESSolve, of assembly (residual and Jacobian events) and of MUMPS;
2. one residual and one Jacobian at the same state (the bare scene's solution);
3. the matrix: rows, nonzeros used and allocated (MatGetInfo, summed over ranks), mallocs;
4. a follower pressure's forms assembled alone on the inner surface, the outer surface and
   the cap, against the whole bare system: assembly follows the facets of the surface;
5. what Problem.F / Problem.J do beyond the reference, and what an idle custom feature adds,
   each part timed alone.

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/leave_out.py [--n 12 --layers 6]

writes benchmarks/results/leave_out.json and prints the tables (30 s on two quiet cores, up to
two minutes on busy ones).
"""
import argparse
import dataclasses
import json
import logging
import os
import statistics
import time

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import NonlinearProblem, assemble_matrix, assemble_vector, create_matrix, create_vector, set_bc
from dolfinx.mesh import compute_midpoints, meshtags
from mpi4py import MPI
from petsc4py import PETSc
from provenance import run_record
from sphere_scaling import busy_cores, event_seconds, wait_for_quiet

import eyeball_fenicsx as ef
from eyeball_fenicsx.features.roles import ActiveSet
from eyeball_fenicsx.features.sutures import Suture
from eyeball_fenicsx.mechanics.solid import MixedSolid
from eyeball_fenicsx.meshing.builders.sphere_octant import build_sphere_octant
from eyeball_fenicsx.meshing.load import built_mesh
from eyeball_fenicsx.system.newton import DEFAULT_OPTIONS, PREFIX

comm = MPI.COMM_WORLD
C10, P, P_OUTER = 0.5, 0.6, 0.01
SYMMETRY = [("sym_x", "x"), ("sym_y", "y"), ("sym_z", "z")]
CAP_DEGREES = 15.0
FAR_PLANE = dict(shape="plane", point=[0.0, 0.0, 10.0], normal=[0.0, 0.0, -1.0])  # 8 above the pole
EVENTS = ["SNESSolve", "SNESFunctionEval", "SNESJacobianEval", "MatLUFactorNum", "MatSolve"]

# name -> the features the scene holds besides the supports and the inner pressure
CONFIGS = {
    "bare": lambda: [],
    "idle plane, outer": lambda: [ef.RigidContact("far", "outer", **FAR_PLANE)],
    "idle plane, cap": lambda: [ef.RigidContact("far", "cap", **FAR_PLANE)],
    "idle suture": lambda: [Suture("idle", [0.0, 0.0, 2.0], [2.0, 0.0, 0.0], tension=0.0,
                                   first_surface="outer", second_surface="outer")],
    "pressure, outer": lambda: [ef.Pressure("outer", P_OUTER)],
    "pressure, cap": lambda: [ef.Pressure("cap", P_OUTER)],
}
SOLVED = ["reference", "reference, again", "bare", "idle plane, outer"]
NO_GUARD = "bare, no guard"  # the bare scene without its inversion guard (single calls only)


def with_cap(mesh):
    """The same mesh with the outer facets within CAP_DEGREES of the z axis named "cap"
    (they leave "outer")."""
    msh, tags = mesh.mesh, mesh.facet_tags
    outer = mesh.facets("outer")
    x = compute_midpoints(msh, 2, outer)
    cap = outer[x[:, 2] / np.linalg.norm(x, axis=1) > np.cos(np.radians(CAP_DEGREES))]
    tag = max(mesh.surfaces.values()) + 1
    values = tags.values.copy()
    values[np.isin(tags.indices, cap)] = tag
    new = meshtags(msh, 2, tags.indices, values)
    return dataclasses.replace(mesh, facet_tags=new, surfaces={**mesh.surfaces, "cap": tag})


class Framework:
    """A scene of the package: supports, the inner pressure and ``extra`` features."""

    def __init__(self, name, mesh, extra):
        self.name = name
        features = [ef.Dirichlet(s, {axis: 0.0}) for s, axis in SYMMETRY] + [ef.Pressure("inner", P)] + extra
        self.extra = extra
        self.scene = ef.Scene("leave-out", mesh, {"wall": ef.NeoHooke(C10)}, features=features,
                              solver=ef.SolverSettings(increments=1, reuse_contraction=0.0)).build()
        self.problem = self.scene.problem
        self.w = self.scene.solid.w

    def solve(self):
        """Newton from the undeformed state; returns the Newton iterations and residual norms."""
        self.w.x.array[:] = 0.0
        summary = self.scene.run()
        increments = summary["steps"][-1]["increments"]
        assert summary["ok"] and len(increments) == 1, summary
        return increments[0]["newton_iterations"], list(self.scene.newton.residual_norms)

    def at(self, state):
        """Put the problem at a state, with every load at its full value, for F and J alone."""
        self.w.x.array[:] = state
        problem = self.problem
        problem.begin_step(0)
        problem.set_load_factor([1.0] * len(problem.features))
        problem.state_to_vector(problem.x)

    def residual(self):
        self.problem.F(None, self.problem.x, self.problem.b)

    def jacobian(self):
        self.problem.J(None, self.problem.x, self.problem.A, self.problem.A)

    @property
    def matrix(self):
        return self.problem.A


class Reference:
    """Plain DOLFINx: the same UFL residual, ``NonlinearProblem`` and a bare SNES."""

    name = "reference"

    def __init__(self, mesh):
        solid = MixedSolid(mesh, {"wall": ef.NeoHooke(C10)})  # the space and the stored energy
        self.w = solid.w
        pressure = fem.Constant(mesh.mesh, PETSc.ScalarType(P))
        residual = ufl.derivative(solid.potential(), solid.w, ufl.TestFunction(solid.W)) \
            + pressure * ufl.inner(solid.current_normal_area(), solid.v) * solid.ds(mesh.surfaces["inner"])
        bcs = []
        for surface, axis in SYMMETRY:
            Wi = solid.W.sub(0).sub("xyz".index(axis))
            dofs = fem.locate_dofs_topological(Wi, 2, mesh.facets(surface))
            bcs.append(fem.dirichletbc(PETSc.ScalarType(0.0), dofs, Wi))
        self.nlp = NonlinearProblem(residual, solid.w, bcs)
        self.A = create_matrix(self.nlp.a)
        self.b = create_vector(self.nlp.L)
        self.x = self.b.duplicate()
        opts = PETSc.Options()
        for key, value in {**DEFAULT_OPTIONS, "pc_type": "lu"}.items():
            opts["ref_" + key] = value
        self.snes = snes = PETSc.SNES().create(comm)
        snes.setOptionsPrefix("ref_")
        snes.setFunction(self.F, self.b)
        snes.setJacobian(self.J, self.A)
        snes.setMonitor(lambda snes, its, norm: self.norms.append(norm))
        snes.setFromOptions()
        self.norms = []

    def F(self, snes, x, b):
        x.copy(self.w.vector)
        self.w.x.scatter_forward()
        self.nlp.F(self.w.vector, b)

    def J(self, snes, x, A, P):
        self.nlp.J(self.w.vector, A)

    def solve(self):
        self.norms = []
        self.x.set(0.0)
        self.snes.solve(None, self.x)
        assert self.snes.getConvergedReason() > 0
        self.x.copy(self.w.vector)
        self.w.x.scatter_forward()
        return self.snes.getIterationNumber(), list(self.norms)

    def at(self, state):
        self.w.x.array[:] = state
        self.x.array[:] = state[: len(self.x.array)]

    def residual(self):
        self.F(None, self.x, self.b)

    def jacobian(self):
        self.J(None, self.x, self.A, self.A)

    @property
    def matrix(self):
        return self.A


def synchronized(call):
    """Wall time of one collective call, on the slowest rank."""
    comm.barrier()
    start = time.perf_counter()
    call()
    return comm.allreduce(time.perf_counter() - start, op=MPI.MAX)


def timed_solve(case):
    before = event_seconds(EVENTS)
    wall = synchronized(lambda: setattr(case, "last", case.solve()))
    its, norms = case.last
    after = event_seconds(EVENTS)
    spent = {name: after[name][1] - before[name][1] for name in EVENTS}
    count = {name: after[name][0] - before[name][0] for name in EVENTS}
    return {"newton_iterations": its, "residual_norms": norms, "wall_s": wall, "snes_s": spent["SNESSolve"],
            "residual_s": spent["SNESFunctionEval"], "jacobian_s": spent["SNESJacobianEval"],
            "mumps_s": spent["MatLUFactorNum"] + spent["MatSolve"], "residuals": count["SNESFunctionEval"],
            "jacobians": count["SNESJacobianEval"]}


def matrix_info(A):
    info = A.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)
    return {"rows": A.getSize()[0], "nonzeros": int(info["nz_used"]), "allocated": int(info["nz_allocated"]),
            "mallocs": int(info["mallocs"])}


def framework_parts(case, calls):
    """Time alone what Problem.F and Problem.J do beyond the reference, on the bare problem at
    its current state, and the three things a bare problem no longer does (they are kept for
    custom features and borders): seconds per call, median."""
    problem = case.problem
    n = problem.n_owned
    bw, b, A = problem.b_w, problem.b, problem.A
    w = problem.solid.w
    scratch = bw.duplicate()
    y = problem.x.duplicate()  # a zero Newton step
    y.set(0.0)

    def copy_into_bordered():
        b.array[:n] = bw.array_r[:n]

    def dirichlet_rows_in_place():
        set_bc(bw, problem.bcs, w.vector, -1.0)

    def dirichlet_rows_through_scratch():
        with scratch.localForm() as sl:
            sl.set(0.0)
        set_bc(scratch, problem.bcs, w.vector, -1.0)
        b.array[problem.bc_rows] = scratch.array_r[problem.bc_rows]

    parts = {
        "inversion guard (det F at every element, allgather)": problem.guard.check,
        "copy of the residual into the bordered vector": copy_into_bordered,
        "Dirichlet rows in place (set_bc, as the reference)": dirichlet_rows_in_place,
        **({"line-search precheck (NewtonSolver._limit_step)": lambda: case.scene.newton._limit_step(problem.x, y)}
           if hasattr(case.scene.newton, "_limit_step") else {}),
        "skipped now: VecAssembly of the residual": b.assemble,
        "skipped now: Dirichlet rows through a scratch vector": dirichlet_rows_through_scratch,
        "skipped now: MatAssembly(FLUSH) of the Jacobian": lambda: A.assemble(PETSc.Mat.AssemblyType.FLUSH),
    }
    times = {name: [] for name in parts}
    for _ in range(calls):
        for name, call in parts.items():
            times[name].append(synchronized(call))
    A.assemble()
    scratch.destroy()
    y.destroy()
    return {name: statistics.median(t) for name, t in times.items()}


def idle_parts(case, calls):
    """Time alone what an idle custom feature (contact, suture) adds to Problem.F and
    Problem.J: its own residual and Jacobian work, the collective that asks whether its
    tangent is outdated, and what the custom path does for it (VecAssembly, the Dirichlet rows
    through a scratch vector, MatZeroRows of the Dirichlet rows): seconds per call, median."""
    problem = case.problem
    feature = case.extra[0]
    A, b = problem.A, problem.b
    rows = problem.lgmap.apply(problem.bc_rows)

    def dirichlet_rows_through_scratch():
        with problem.scratch.localForm() as sl:
            sl.set(0.0)
        set_bc(problem.scratch, problem.bcs, problem.solid.w.vector, -1.0)
        b.array[problem.bc_rows] = problem.scratch.array_r[problem.bc_rows]

    parts = {
        "its residual (add_to_residual)": lambda: feature.add_to_residual(b),
        "its Jacobian (add_to_jacobian)": lambda: feature.add_to_jacobian(A),
        # contact's (an ActiveSet); a suture has no active set to ask about
        **({"tangent_outdated (a collective)": feature.tangent_outdated} if isinstance(feature, ActiveSet) else {}),
        "VecAssembly of the residual": b.assemble,
        "Dirichlet rows through a scratch vector": dirichlet_rows_through_scratch,
        "MatAssembly(FLUSH) of the Jacobian": lambda: A.assemble(PETSc.Mat.AssemblyType.FLUSH),
        "MatZeroRows of the Dirichlet rows": lambda: A.zeroRows(rows, diag=1.0),
    }
    times = {name: [] for name in parts}
    for _ in range(calls):
        for name, call in parts.items():
            if name.startswith("MatZeroRows"):
                A.assemble()  # zeroRows needs an assembled matrix; not timed (J has it anyway)
            times[name].append(synchronized(call))
    case.residual()
    case.jacobian()
    return {name: statistics.median(t) for name, t in times.items()}


def surface_forms(solid, meshes, problem, calls):
    """Assembly of a follower pressure's residual and Jacobian alone, on the inner surface,
    the outer surface and the cap, against the bare scene's whole forms (solid + inner
    pressure): (facets, residual seconds, Jacobian seconds), median of ``calls`` interleaved.
    Each surface's facets are tagged 1 in a tag set of their own, so that the three forms
    share one compiled kernel; the pressure is the feature's (``Pressure.residual``) term."""
    msh = solid.mesh_data.mesh
    pressure = fem.Constant(msh, PETSc.ScalarType(P_OUTER))
    num_owned = msh.topology.index_map(2).size_local
    forms = {}
    for name, mesh in meshes.items():
        facets = np.sort(mesh.facets(name)).astype(np.int32)
        tags = meshtags(msh, 2, facets, np.ones(len(facets), dtype=np.int32))
        ds = ufl.Measure("ds", domain=msh, subdomain_data=tags, metadata={"quadrature_degree": 2})
        residual = pressure * ufl.inner(solid.current_normal_area(), solid.v) * ds(1)
        R = fem.form(residual)
        J = fem.form(ufl.derivative(residual, solid.w, ufl.TrialFunction(solid.W)))
        forms[name] = (comm.allreduce(int(np.sum(facets < num_owned)), op=MPI.SUM), R, J)
    forms["whole bare system"] = (None, problem.R_form, problem.J_form)
    vectors = {name: create_vector(R) for name, (_, R, _) in forms.items()}
    matrices = {name: create_matrix(J) for name, (_, _, J) in forms.items()}

    def residual(name):
        b = vectors[name]
        with b.localForm() as bl:
            bl.set(0.0)
        assemble_vector(b, forms[name][1])
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)

    def jacobian(name):
        A = matrices[name]
        A.zeroEntries()
        assemble_matrix(A, forms[name][2])
        A.assemble()

    times = {name: ([], []) for name in forms}
    for round_ in range(calls):
        for name in (list(forms) if round_ % 2 else list(forms)[::-1]):
            times[name][0].append(synchronized(lambda: residual(name)))
            times[name][1].append(synchronized(lambda: jacobian(name)))
    result = {name: {"facets": forms[name][0], "residual_ms": 1e3 * statistics.median(times[name][0]),
                     "jacobian_ms": 1e3 * statistics.median(times[name][1])} for name in forms}
    for name in list(vectors):
        vectors[name].destroy()
        matrices[name].destroy()
    return result


def paired(mine, reference):
    """Median of the per-round ratios (the same round of each: robust to drift in load)."""
    return statistics.median(a / b for a, b in zip(mine, reference))


def compare(prefix, mine, reference):
    """Median and fastest (seconds -> ms), and both ratios to the reference: the ratio of the
    fastest (the least disturbed samples) and the median of the per-round ratios."""
    return {f"{prefix}_ms": 1e3 * statistics.median(mine), f"{prefix}_fastest_ms": 1e3 * min(mine),
            f"{prefix}_fastest_vs_reference": min(mine) / min(reference),
            f"{prefix}_vs_reference": paired(mine, reference)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=12, help="elements along a patch edge")
    parser.add_argument("--layers", type=int, default=6)
    parser.add_argument("--repeat", type=int, default=3, help="rounds of Newton solves (after one not counted)")
    parser.add_argument("--calls", type=int, default=15, help="rounds of single F and J calls")
    parser.add_argument("--patience", type=float, default=0.0,
                        help="before each round, wait up to this many seconds for other processes to leave the cores")
    parser.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results", "leave_out.json"))
    args = parser.parse_args()
    load = os.getloadavg()[0]
    logging.disable(logging.INFO)  # a cold JIT logs every compiler call (CFFI, through setuptools)
    PETSc.Log.begin()
    PETSc.Options()[PREFIX + "pc_type"] = "lu"  # the reference's factorization (no LDL^T choice)
    start = time.perf_counter()

    mesh = built_mesh(build_sphere_octant, comm, n=args.n, layers=args.layers)
    capped = with_cap(mesh)
    cells = mesh.mesh.topology.index_map(3).size_global
    cases = {"reference": Reference(mesh), "reference, again": Reference(mesh)}
    for name, extra in CONFIGS.items():
        cases[name] = Framework(name, capped if "cap" in name else mesh, extra())
        if name == "bare":  # what the framework's one addition to every residual costs
            cases[NO_GUARD] = Framework(NO_GUARD, mesh, [])
            cases[NO_GUARD].problem.guard.check = lambda: (np.inf, None)
    setup_s = time.perf_counter() - start

    # 1. Newton solves, interleaved; the first round (MUMPS's symbolic analysis) not counted
    solves = {name: [] for name in SOLVED}
    busy = []
    for round_ in range(args.repeat + 1):
        busy.append(wait_for_quiet(args.patience) if args.patience else busy_cores(0.3))
        for name in (SOLVED if round_ % 2 else SOLVED[::-1]):
            result = timed_solve(cases[name])
            if round_:
                solves[name].append(result)
    state = cases["bare"].w.x.array.copy()
    difference = comm.allreduce(float(np.abs(cases["reference"].w.x.array - state).max()), op=MPI.MAX)

    # 2. single residual and Jacobian evaluations at the same state, interleaved
    for case in cases.values():
        case.at(state)
        case.residual()
        case.jacobian()
    calls = {name: {"residual": [], "jacobian": []} for name in cases}
    for round_ in range(args.calls):
        if args.patience and round_ % 5 == 0:
            busy.append(wait_for_quiet(args.patience))
        for name in (list(cases) if round_ % 2 else list(cases)[::-1]):
            calls[name]["residual"].append(synchronized(cases[name].residual))
            calls[name]["jacobian"].append(synchronized(cases[name].jacobian))
    matrices = {name: matrix_info(case.matrix) for name, case in cases.items()}  # all at the same state

    # 3. where the features' forms are assembled; 4. the framework's own per-call work
    bare = cases["bare"]
    surfaces = surface_forms(bare.scene.solid, {"inner": mesh, "outer": mesh, "cap": capped}, bare.problem,
                             2 * args.calls)
    parts = framework_parts(bare, 10 * args.calls)
    idle = {name: {k: 1e3 * v for k, v in idle_parts(cases[name], 5 * args.calls).items()}
            for name in ("idle plane, outer", "idle plane, cap", "idle suture")}
    for name in ("idle plane, outer", "idle plane, cap"):
        idle[name]["slave points"] = comm.allreduce(len(cases[name].extra[0].weight), op=MPI.SUM)
    busy.append(busy_cores(0.3))

    rows = []
    for name in cases:
        row = {"configuration": name, **matrices[name],
               **compare("residual", calls[name]["residual"], calls["reference"]["residual"]),
               **compare("jacobian", calls[name]["jacobian"], calls["reference"]["jacobian"])}
        if name in solves:
            runs, ref = solves[name], solves["reference"]
            its = [r["newton_iterations"] for r in runs]
            per_it = {key: [r[key] / r["newton_iterations"] for r in runs]
                      for key in ("snes_s", "residual_s", "jacobian_s", "mumps_s")}
            per_it["assembly_s"] = [a + j for a, j in zip(per_it["residual_s"], per_it["jacobian_s"])]
            ref_it = {key: [r[key] / r["newton_iterations"] for r in ref] for key in ("snes_s",)}
            ref_it["assembly_s"] = [(r["residual_s"] + r["jacobian_s"]) / r["newton_iterations"] for r in ref]
            row.update({"newton_iterations": its[0], "same_iterations_every_run": len(set(its)) == 1,
                        "residual_evaluations": runs[0]["residuals"], "residual_norms": runs[0]["residual_norms"],
                        **compare("snes_per_iteration", per_it["snes_s"], ref_it["snes_s"]),
                        **compare("assembly_per_iteration", per_it["assembly_s"], ref_it["assembly_s"]),
                        "mumps_per_iteration_ms": 1e3 * statistics.median(per_it["mumps_s"]),
                        "outside_newton_per_solve_ms": 1e3 * statistics.median(r["wall_s"] - r["snes_s"]
                                                                                for r in runs)})
        rows.append(row)
    result = {"run": run_record(comm, repeats=args.repeat, load_average_1min_at_start=load, calls=args.calls),
              "ranks": comm.size, "n": args.n, "layers": args.layers, "cells": cells,
              "repeat": args.repeat, "calls": args.calls, "busy_cores": busy, "setup_s": setup_s,
              "max_difference_of_solution_bare_vs_reference": difference, "rows": rows,
              "surface_forms": surfaces, "framework_parts_ms": {k: 1e3 * v for k, v in parts.items()},
              "idle_feature_parts_ms": idle, "wall_s": time.perf_counter() - start}
    if comm.rank == 0:
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        with open(args.out + ".tmp", "w") as f:
            json.dump(result, f, indent=1)
        os.replace(args.out + ".tmp", args.out)
        print_tables(result)


def print_tables(result):
    rows = result["rows"]
    print(f"thick sphere octant {result['n']} x {result['layers']}: {result['cells']} cells, {result['ranks']} ranks; "
          f"cores kept busy by other processes: {', '.join(f'{b:.1f}' for b in result['busy_cores'])}")
    print(f"\nNewton solves from rest, LU, one increment ({result['repeat']} interleaved rounds); ms per Newton "
          "iteration, fastest; /ref: fastest over the reference's fastest, and the median of the per-round ratios")
    print(f"{'configuration':<18} {'Newton':>6} {'F evals':>7} {'SNES':>7} {'/ref':>5} {'med':>5} {'assembly':>8} "
          f"{'/ref':>5} {'med':>5} {'MUMPS':>6} {'outside':>7}")
    for r in rows:
        if "newton_iterations" in r:
            print(f"{r['configuration']:<18} {r['newton_iterations']:>6} {r['residual_evaluations']:>7} "
                  f"{r['snes_per_iteration_fastest_ms']:>7.1f} {r['snes_per_iteration_fastest_vs_reference']:>5.2f} "
                  f"{r['snes_per_iteration_vs_reference']:>5.2f} {r['assembly_per_iteration_fastest_ms']:>8.1f} "
                  f"{r['assembly_per_iteration_fastest_vs_reference']:>5.2f} "
                  f"{r['assembly_per_iteration_vs_reference']:>5.2f} "
                  f"{r['mumps_per_iteration_ms']:>6.1f} {r['outside_newton_per_solve_ms']:>7.1f}")
    print(f"  MUMPS: median; outside: ms per solve outside SNESSolve (median); largest |w_bare - w_reference| = "
          f"{result['max_difference_of_solution_bare_vs_reference']:.1e}")
    for r in rows:
        if r["configuration"] in ("reference", "bare"):
            print(f"  residual norms, {r['configuration']:<9}: " + " ".join(f"{v:.3e}" for v in r["residual_norms"]))
    print(f"\nOne residual (F) and one Jacobian (J) at the same state ({result['calls']} interleaved rounds; fastest, "
          "/ref and med as above), and the matrix (MatGetInfo, summed over ranks)")
    print(f"{'configuration':<18} {'F ms':>6} {'/ref':>5} {'med':>5} {'J ms':>6} {'/ref':>5} {'med':>5} {'rows':>6} "
          f"{'nonzeros':>8} {'allocated':>9} {'mallocs':>7}")
    for r in rows:
        print(f"{r['configuration']:<18} {r['residual_fastest_ms']:>6.2f} {r['residual_fastest_vs_reference']:>5.2f} "
              f"{r['residual_vs_reference']:>5.2f} {r['jacobian_fastest_ms']:>6.1f} "
              f"{r['jacobian_fastest_vs_reference']:>5.2f} {r['jacobian_vs_reference']:>5.2f} {r['rows']:>6} "
              f"{r['nonzeros']:>8} {r['allocated']:>9} {r['mallocs']:>7}")
    print("\nA follower pressure's forms assembled alone, by surface (median; ms per call):")
    print(f"{'surface':<18} {'facets':>6} {'F ms':>7} {'J ms':>7} {'F+J us/facet':>12}")
    for name, f in result["surface_forms"].items():
        per_facet = f"{1e3 * (f['residual_ms'] + f['jacobian_ms']) / f['facets']:>12.1f}" if f["facets"] else ""
        print(f"{name:<18} {f['facets'] or '':>6} {f['residual_ms']:>7.3f} {f['jacobian_ms']:>7.3f} {per_facet}")
    print("\nWhat Problem.F / Problem.J do beyond the reference, each alone on the bare problem (ms per call, median):")
    for name, ms in result["framework_parts_ms"].items():
        print(f"  {name:<55} {ms:.3f}")
    print("\nWhat an idle custom feature adds, each part alone (ms per call, median):")
    idle = result["idle_feature_parts_ms"]
    names = list(idle)
    print(f"  {'':<40}" + "".join(f"{name:>19}" for name in names))
    for part in idle[names[0]]:
        values = [idle[name].get(part) for name in names]
        print(f"  {part:<40}" + "".join(f"{'':>19}" if v is None else f"{v:>19}" if part == "slave points"
                                          else f"{v:>19.3f}" for v in values))
    print(f"\nsetup {result['setup_s']:.1f} s, total {result['wall_s']:.1f} s")


if __name__ == "__main__":
    main()

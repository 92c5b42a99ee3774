"""Work-precision: error against wall time, Q1/P0 against Q2/P1, on problems with a reference.

Problems (every one with an incompressible neo-Hooke solid, shear modulus 1, c10 = 0.5):

* ``sphere``: the octant of the thick sphere A = 1, B = 2 under the inner follower pressure
  P = 0.6; reference: the closed-form inner stretch (Ogden 1984, eq. 5.2.38,
  ``analytic.sphere_inner_stretch``); measured: the radial displacement at (A, 0, 0).
* ``liquid sphere``: the same octant filled with a liquid of bulk modulus K = 10, initial
  pressure 0.1, injected volume half the initial cavity volume (``tests/test_cavity.py``);
  reference: the closed form where the wall's pressure equals the liquid's.
* ``cook``: Cook's membrane (the tapered panel (0, 0), (48, 44), (48, 60), (0, 44), Cook 1974)
  made incompressible, one element through the unit thickness with z held on both faces
  (plane strain), clamped at x = 0, a total dead shear force 1 (traction 1/16) on x = 48;
  measured: the vertical displacement of the tip (48, 60); reference: Q2/P1 on the
  n x n x 1 mesh with n = ``--cook-reference`` (64: 166 153 dofs), run first, with n/4 and
  n/2 for a Richardson estimate of the reference's own error (the rows of the JSON whose
  ``role`` is "reference" and "reference check").
* ``hertz``: a rigid sphere (R = 10) pressed d = 0.1 into a block (a quarter, 30 contact radii
  a = (R d)^1/2 wide and deep, on a roller base) by penalty contact with its augmented
  Lagrangian (the defaults), as demos/hertz_indentation.py; measured: the force; reference:
  Hertz, F = 16/3 mu R^1/2 d^3/2 (Johnson 1985, eq. 4.23, incompressible), which is a
  half-space at small strain: the error levels off at the model's own difference from it.
  Q1P0 only (contact needs first-order displacements). Mesh size n: cells across 1.3 a, and as
  many growing geometrically to 30 a.

The octant's meshes are trilinear: their curved surfaces are polyhedra, whose geometric
error (O(h^2)) no displacement degree can beat. So on ``sphere`` Q2/P1 also runs on the same
meshes with triquadratic geometry (27-node hexahedra, nodes on the spheres), to measure that cap.

Elements on the same meshes: Q1P0 (the seed's) and Q2P1 (``formulation.ELEMENTS``). Mesh size
``n``: elements along an edge of a patch of the octant (n/2 radial layers), along both
edges of the panel, or as above for ``hertz``. ``wall_s`` is ``Scene.run`` alone (the Newton solve: assembly,
factorizations, stepping; the slowest rank's): the mesh and the compiled forms are ready
before the clock starts. Runs under 10 s are repeated (``--repeat``, default 3) and the
fastest counts. Rates are between consecutive sizes: ``rate_h`` in the mesh size h ~ 1/n,
``rate_dofs`` the slope -d log(error) / d log(dofs).

    mpirun --allow-run-as-root -n 2 .venv/bin/python3 benchmarks/work_precision.py

writes benchmarks/results/work_precision.json ({"run": the commit, date, hardware and load;
"rows"}), benchmarks/results/work_precision.png (log-log error against wall time) and prints
the table and which element reaches a given accuracy first. ``--quick`` runs small sizes only
(a smoke test, about a minute).
"""
import argparse
import json
import math
import os

import dolfinx
import numpy as np
import ufl
from dolfinx import fem
from dolfinx.io import gmshio
from mpi4py import MPI
from provenance import run_record
from scipy.optimize import brentq

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import sphere_inner_stretch, sphere_pressure
from eyeball_fenicsx.contact import RigidContact
from eyeball_fenicsx.features.base import Feature
from eyeball_fenicsx.features.cavity import LiquidCavity
from eyeball_fenicsx.meshing.builders.block import build_block
from eyeball_fenicsx.meshing.builders.cook import TIP, build_cook
from eyeball_fenicsx.meshing.builders.sphere_octant import build_sphere_octant, layer_radii, octant_directions
from eyeball_fenicsx.meshing.load import MeshData, built_mesh
from eyeball_fenicsx.output.console import silence
from eyeball_fenicsx.output.files import write_text_atomic

comm = MPI.COMM_WORLD
RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "results")
A, B, P = 1.0, 2.0, 0.6
C = {(1, 0): 0.5}
K, P_INI, INJECTED = 10.0, 0.1, 0.5  # the liquid sphere: bulk modulus, initial pressure, dV / V_ini
COOK_FORCE = 1.0
HERTZ_R, HERTZ_D = 10.0, 0.1  # sphere radius, indentation depth
HERTZ_A = math.sqrt(HERTZ_R * HERTZ_D)  # Hertz's contact radius
TARGETS = (1e-2, 3e-3, 1e-3)  # relative errors at which the elements are compared
REPEAT_BELOW = 10.0  # seconds: cheaper runs are repeated (``--repeat``), the fastest counts
SIZES = {  # (problem, element, geometry) -> mesh sizes n
    ("sphere", "Q1P0", "trilinear"): [2, 4, 8, 16],
    ("sphere", "Q2P1", "trilinear"): [2, 4, 8],
    ("sphere", "Q2P1", "triquadratic"): [2, 4, 8],
    ("liquid sphere", "Q1P0", "trilinear"): [2, 4, 8, 16],
    ("liquid sphere", "Q2P1", "trilinear"): [2, 4, 8],
    ("cook", "Q1P0", "trilinear"): [2, 4, 8, 16, 32, 64],
    ("cook", "Q2P1", "trilinear"): [2, 4, 8, 16],
    ("hertz", "Q1P0", "trilinear"): [3, 5, 7, 10, 14],
}
QUICK = {key: sizes[:2] for key, sizes in SIZES.items()}
SYMMETRY = [("sym_x", "x"), ("sym_y", "y"), ("sym_z", "z")]
QUANTITY = {"sphere": "displacement", "liquid sphere": "displacement", "cook": "tip deflection", "hertz": "force"}


class Traction(Feature):
    """A dead load: the nominal traction ``value`` (force per reference area) on a surface."""

    def __init__(self, surface, value):
        self.name = self.surface = surface
        self.value = value

    def setup(self, solid):
        self.factor = fem.Constant(solid.mesh_data.mesh, 0.0)

    def residual(self, solid):
        ds = solid.ds(solid.mesh_data.surfaces[self.surface])
        return -self.factor * ufl.inner(ufl.as_vector(self.value), solid.v) * ds

    def set_load_factor(self, factor):
        self.factor.value = factor


# -- meshes --------------------------------------------------------------------------------
# gmsh's 27-node hexahedron: the 8 corners, then the midpoints of these edges and faces, then the centre
_CORNERS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
_EDGES = [(0, 1), (0, 3), (0, 4), (1, 2), (1, 5), (2, 3), (2, 6), (3, 7), (4, 5), (4, 7), (5, 6), (6, 7)]
_FACES = [(0, 1, 2, 3), (0, 1, 5, 4), (0, 3, 7, 4), (1, 2, 6, 5), (2, 3, 7, 6), (4, 5, 6, 7)]
_HEX27 = np.array([2 * np.array(c) for c in _CORNERS]
                  + [np.add(_CORNERS[a], _CORNERS[b]) for a, b in _EDGES]
                  + [np.sum([_CORNERS[i] for i in f], axis=0) // 2 for f in _FACES] + [(1, 1, 1)])


def quadratic_sphere_octant(n, layers):
    """The octant of ``build_sphere_octant`` (A, B) with triquadratic geometry: each hexahedron
    takes the 27 nodes of the doubled grid, which lie on the spheres and on the cube-sphere map."""
    cells = np.empty((0, 27), np.int64)
    x = np.empty((0, 3))
    if comm.rank == 0:
        directions, patches = octant_directions(2 * n)
        radii = layer_radii(A, B, 2 * layers, 1.0)
        x = (radii[:, None, None] * directions[None, :, :]).reshape(-1, 3)
        # node (i, j) of a patch's doubled grid in layer k of the doubled layers, per hexahedron
        cell = np.meshgrid(np.arange(n), np.arange(n), np.arange(layers), indexing="ij")
        i, j, k = (2 * index.ravel()[:, None] + _HEX27[None, :, axis] for axis, index in enumerate(cell))
        cells = np.concatenate([k * len(directions) + patches[p][i, j] for p in range(3)])
        cells = cells[:, gmshio.cell_perm_array(dolfinx.mesh.CellType.hexahedron, 27)]
    msh = dolfinx.mesh.create_mesh(comm, cells, x, gmshio.ufl_mesh(12, 3))
    num_cells = msh.topology.index_map(3).size_local + msh.topology.index_map(3).num_ghosts
    cell_tags = dolfinx.mesh.meshtags(msh, 3, np.arange(num_cells, dtype=np.int32), np.ones(num_cells, np.int32))
    markers = {"inner": lambda x: np.isclose(np.linalg.norm(x, axis=0), A),
               "outer": lambda x: np.isclose(np.linalg.norm(x, axis=0), B),
               "sym_x": lambda x: np.isclose(x[0], 0.0), "sym_y": lambda x: np.isclose(x[1], 0.0),
               "sym_z": lambda x: np.isclose(x[2], 0.0)}
    surfaces = {name: tag for tag, name in enumerate(markers, start=2)}
    facets = [dolfinx.mesh.locate_entities_boundary(msh, 2, marker) for marker in markers.values()]
    values = np.concatenate([np.full(len(f), tag, np.int32) for f, tag in zip(facets, surfaces.values())])
    facets = np.concatenate(facets)
    order = np.argsort(facets)
    facet_tags = dolfinx.mesh.meshtags(msh, 2, facets[order], values[order])
    return MeshData(msh, cell_tags, facet_tags, {"wall": 1}, surfaces, "quadratic sphere octant")


def graded(n, fine, length):
    """Node coordinates on [0, length]: n equal cells on [0, fine], then n growing
    geometrically (ratio q, the first one q times the fine size) to ``length``."""
    h = fine / n
    q = brentq(lambda q: h * q * (q**n - 1) / (q - 1) - (length - fine), 1.0 + 1e-9, 10.0)
    coarse = fine + h * np.cumsum(q ** np.arange(1, n + 1))
    coarse[-1] = length
    return np.concatenate([np.linspace(0.0, fine, n + 1), coarse])


def hertz_block(n):
    """The quarter block [0, 30 a]^2 x [0, 30 a], graded towards the contact at (0, 0, 30 a)."""
    length = 30 * HERTZ_A
    nodes = graded(n, 1.3 * HERTZ_A, length)
    mesh = built_mesh(build_block, comm, lengths=(1.0, 1.0, 1.0), divisions=(2 * n,) * 3)
    x, uniform = mesh.mesh.geometry.x, np.linspace(0.0, 1.0, 2 * n + 1)
    x[:, 0], x[:, 1] = np.interp(x[:, 0], uniform, nodes), np.interp(x[:, 1], uniform, nodes)
    x[:, 2] = length - np.interp(1.0 - x[:, 2], uniform, nodes)
    return mesh


def mesh_for(problem, geometry, n):
    if problem == "cook":
        return built_mesh(build_cook, comm, divisions=(n, n, 1))
    if problem == "hertz":
        return hertz_block(n)
    if geometry == "triquadratic":
        return quadratic_sphere_octant(n, max(n // 2, 1))
    return built_mesh(build_sphere_octant, comm, inner_radius=A, outer_radius=B, n=n, layers=max(n // 2, 1))


# -- problems --------------------------------------------------------------------------------
def liquid_stretch():
    """Inner stretch where the wall carries the liquid's pressure p_ini - K (lam^3 - 1 - dV/V_ini)."""
    return brentq(lambda lam: sphere_pressure(lam, C, A, B) - (P_INI - K * (lam**3 - 1 - INJECTED)), 1.0, 2.5,
                  xtol=1e-14)


def solve(problem, mesh, element):
    """Build and run one case; return (summary, measured value, liquid pressure or None)."""
    quiet = dict(solver=ef.SolverSettings(increments=2), element=element)
    if problem == "hertz":
        top = 30 * HERTZ_A
        sphere = RigidContact("sphere", "z1", "sphere", center=[0.0, 0.0, top + HERTZ_R], radius=HERTZ_R,
                              displacement=[0.0, 0.0, -HERTZ_D])
        features = [ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}), ef.Dirichlet("z0", {"z": 0.0}),
                    sphere]
        scene = ef.Scene("hertz", mesh, {"solid": ef.NeoHooke(C[1, 0])}, features=features,
                         **dict(quiet, solver=ef.SolverSettings(increments=3))).build()
        summary = scene.run()
        return summary, -4 * summary["steps"][-1]["contact"]["sphere"]["force"][2], None  # four quarters
    if problem == "cook":
        features = [ef.Dirichlet("clamped", {"x": 0.0, "y": 0.0, "z": 0.0}), ef.Dirichlet("z0", {"z": 0.0}),
                    ef.Dirichlet("z1", {"z": 0.0}), Traction("loaded", [0.0, COOK_FORCE / 16.0, 0.0])]
        scene = ef.Scene("cook", mesh, {"solid": ef.NeoHooke(C[1, 0])}, features=features,
                         probes={"tip": [*TIP, 0.5]}, **quiet).build()
        summary = scene.run()
        return summary, summary["steps"][-1]["probes"]["tip"][1], None
    features = [ef.Dirichlet(surface, {axis: 0.0}) for surface, axis in SYMMETRY]
    if problem == "liquid sphere":
        cavity = LiquidCavity("liquid", "inner", K, P_INI, symmetry=["x", "y", "z"])
        features.append(cavity)
    else:
        features.append(ef.Pressure("inner", P))
    scene = ef.Scene(problem, mesh, {"wall": ef.MooneyRivlin(C)}, features=features, probes={"inner": [A, 0.0, 0.0]},
                     **quiet).build()
    if problem == "liquid sphere":
        cavity.dV_inj = INJECTED * cavity.V_ini  # a fraction of the discrete volume, as the closed form's
    summary = scene.run()
    final = summary["steps"][-1]
    return summary, final["probes"]["inner"][0], final.get("cavities", {}).get("liquid", {}).get("pressure")


def run(problem, element, geometry, n, reference, repeat=1):
    """One case: its row (with an error if there is a reference). A run that takes less than
    ``REPEAT_BELOW`` seconds is repeated, ``repeat`` times in all, on fresh scenes, and the
    fastest counts (the machine may be shared: the least disturbed run is the minimum)."""
    mesh = mesh_for(problem, geometry, n)
    summary, value, pressure = solve(problem, mesh, element)
    wall = comm.allreduce(summary["wall_s"], op=MPI.MAX)  # the same on every rank: they repeat alike
    for _ in range(repeat - 1 if wall < REPEAT_BELOW else 0):
        wall = min(wall, comm.allreduce(solve(problem, mesh, element)[0]["wall_s"], op=MPI.MAX))
    increments = summary["steps"][-1]["increments"]
    row = {"problem": problem, "element": element, "geometry": geometry, "n": n, "cells": summary["cells"],
           "dofs": summary["dofs"], "wall_s": wall, "value": value,
           "newton_iterations": sum(i["newton_iterations"] for i in increments),
           "factorizations": sum(i["factorizations"] for i in increments), "ranks": comm.size}
    if reference is not None:
        row["reference"] = reference["value"]
        row["error"] = abs(value - reference["value"]) / abs(reference["value"])
    if pressure is not None:
        row["pressure_error"] = abs(pressure - reference["pressure"]) / reference["pressure"]
    if comm.rank == 0:
        error = f"error {row['error']:.3e}" if "error" in row else f"value {value:.6f}"
        print(f"  {problem} {element} {geometry} n={n}: {error} in {row['wall_s']:.2f} s", flush=True)
    return row


def richardson(coarse, middle, fine):
    """(observed order p, extrapolated value) from values on meshes of sizes n, 2n, 4n."""
    p = math.log2(abs((middle - coarse) / (fine - middle)))
    return p, fine + (fine - middle) / (2**p - 1)


def add_rates(rows):
    """Observed rates between consecutive sizes of each problem/element/geometry."""
    previous = {}
    for row in rows:
        key = (row["problem"], row["element"], row["geometry"])
        before = previous.get(key)
        if before is not None:
            drop = math.log(before["error"] / row["error"])
            row["rate_h"] = drop / math.log(row["n"] / before["n"])
            row["rate_dofs"] = drop / math.log(row["dofs"] / before["dofs"])
        previous[key] = row


def time_to_reach(rows, target, key="error"):
    """Wall time from which a line of rows (coarse to fine) stays below the relative error
    ``target`` (of ``key``): log-log interpolated between the last run above it and the next one; the
    coarsest run's time if none is above, None if the finest is."""
    above = [i for i, r in enumerate(rows) if r[key] > target]
    if not above:
        return rows[0]["wall_s"]
    if above[-1] == len(rows) - 1:
        return None
    a, b = rows[above[-1]], rows[above[-1] + 1]
    s = math.log(a[key] / target) / math.log(a[key] / b[key])
    return math.exp((1 - s) * math.log(a["wall_s"]) + s * math.log(b["wall_s"]))


def label(row):
    return row["element"] + (" (triquadratic geometry)" if row["geometry"] == "triquadratic" else "")


def verdicts(rows):
    """Per problem (and measured quantity) and target error: the element that gets there first."""
    lines = []
    for problem in dict.fromkeys(r["problem"] for r in rows):
        lines_of = {}
        for r in rows:
            if r["problem"] == problem:
                lines_of.setdefault(label(r), []).append(r)
        with_pressure = all("pressure_error" in r for line in lines_of.values() for r in line)
        keys = [("error", QUANTITY[problem])] + [("pressure_error", "pressure")] * with_pressure
        for key, quantity in keys:
            for target in TARGETS:
                times = {name: time_to_reach(line, target, key) for name, line in lines_of.items()}
                reached = {name: t for name, t in times.items() if t is not None}
                head = f"{problem}, {quantity} error {target:g}:"
                if not reached:
                    lines.append(f"{head} not reached")
                    continue
                best = min(reached, key=reached.get)
                others = ", ".join(f"{name} {t:.2f} s" if t is not None else f"{name} not reached"
                                   for name, t in times.items() if name != best)
                lines.append(f"{head} first {best} in {reached[best]:.2f} s ({others})")
    return lines


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    for ax, problem in zip(axes.flat, ("sphere", "liquid sphere", "cook", "hertz")):
        names = dict.fromkeys(label(r) for r in rows if r["problem"] == problem)
        for name, marker in zip(names, "osd"):
            line = [r for r in rows if r["problem"] == problem and label(r) == name]
            drawn = ax.loglog([r["wall_s"] for r in line], [r["error"] for r in line], marker=marker,
                              label=name + (" displacement" if "pressure_error" in line[0] else ""))
            if "pressure_error" in line[0]:
                ax.loglog([r["wall_s"] for r in line], [r["pressure_error"] for r in line], marker=marker,
                          linestyle="--", color=drawn[0].get_color(), label=name + " pressure")
            for r in line:
                ax.annotate(str(r["n"]), (r["wall_s"], r["error"]), textcoords="offset points", xytext=(4, 4),
                            fontsize=7)
        ax.set_title(problem)
        ax.set_xlabel("wall time of the solve [s], 2 MPI ranks")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("relative error of the measured quantity")
    fig.suptitle("Work-precision, incompressible neo-Hooke (labels: mesh size n)")
    fig.tight_layout()
    tmp = f"{path}.tmp{os.getpid()}"
    fig.savefig(tmp, dpi=110, format="png")
    os.replace(tmp, path)


def print_table(rows):
    header = (f"{'problem':<14} {'element':<9} {'geometry':<12} {'n':>3} {'cells':>6} {'dofs':>7} {'wall s':>7} "
              f"{'error':>9} {'rate h':>6} {'rate dofs':>9} {'Newton':>6} {'factor':>6} {'p error':>9}")
    print(header)
    print("-" * len(header))
    for r in rows:
        rates = "".join(f" {r[k]:>{w}.2f}" if k in r else " " * (w + 1) for k, w in (("rate_h", 6), ("rate_dofs", 9)))
        pressure = f" {r['pressure_error']:>9.3e}" if "pressure_error" in r else ""
        print(f"{r['problem']:<14} {r['element']:<9} {r['geometry']:<12} {r['n']:>3} {r['cells']:>6} {r['dofs']:>7} "
              f"{r['wall_s']:>7.2f} {r['error']:>9.3e}{rates} {r['newton_iterations']:>6} {r['factorizations']:>6}"
              f"{pressure}")


def main():
    silence()  # no line per load increment: the tables say it
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes only (smoke test)")
    parser.add_argument("--cook-reference", type=int, default=64, help="mesh size n of the Q2P1 reference")
    parser.add_argument("--repeat", type=int, default=3, help=f"runs of each case under {REPEAT_BELOW:g} s")
    parser.add_argument("--out", default=os.path.join(RESULTS, "work_precision.json"))
    args = parser.parse_args()
    load = os.getloadavg()[0]
    sizes = QUICK if args.quick else SIZES
    cook_n = 8 if args.quick else args.cook_reference

    lam = liquid_stretch()
    mu = 2 * C[1, 0]
    references = {"sphere": {"value": sphere_inner_stretch(P, C, A, B) - 1.0},
                  "liquid sphere": {"value": lam - 1.0, "pressure": sphere_pressure(lam, C, A, B)},
                  "hertz": {"value": 16 / 3 * mu * math.sqrt(HERTZ_R) * HERTZ_D**1.5}}
    if comm.rank == 0:
        print(f"Cook reference: Q2P1 on {cook_n} x {cook_n} x 1, and on half and a quarter of that", flush=True)
    checks = [run("cook", "Q2P1", "trilinear", cook_n // k, None) for k in (4, 2, 1)]
    cook = checks[-1]
    references["cook"] = {"value": cook["value"]}
    for check in checks[:-1]:
        check["role"] = "reference check"
    order, extrapolated = richardson(*(r["value"] for r in checks))
    cook.update(role="reference", richardson_order=order, richardson_value=extrapolated,
                reference_error_estimate=abs(cook["value"] - extrapolated) / abs(extrapolated))
    rows = [run(problem, element, geometry, n, references[problem], args.repeat)
            for (problem, element, geometry), ns in sizes.items() for n in ns]
    add_rates(rows)
    if comm.rank == 0:
        print()
        print_table(rows)
        print(f"Cook reference: Q2P1 n={cook_n} ({cook['dofs']} dofs, {cook['wall_s']:.1f} s): tip deflection "
              f"{cook['value']:.6f}; Richardson from n = {cook_n // 4}, {cook_n // 2}, {cook_n}: order {order:.2f}, "
              f"limit {extrapolated:.6f}, so the reference is within {cook['reference_error_estimate']:.1e} (relative)")
        print()
        print("\n".join(verdicts(rows)))
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        plot(rows, os.path.splitext(args.out)[0] + ".png")
    run_info = run_record(comm, repeats=args.repeat, load_average_1min_at_start=load, quick=args.quick,
                          cook_reference=cook_n)
    write_text_atomic(args.out, json.dumps({"run": run_info, "rows": rows + checks}, indent=1, allow_nan=False) + "\n",
                      comm)


if __name__ == "__main__":
    main()

"""Stiff and extreme cases: each converges to the right answer, or stops cleanly and says where.

Covered elsewhere, not repeated here: pressure control past the limit point of a thin sphere
stops with a ConvergenceError near the limit load (``tests/test_cavity.py::
test_pressure_control_past_the_maximum_stops_cleanly``; through the command line, exit 3 with
the converged part kept: ``tests/test_scenes.py::test_pressure_beyond_the_limit_exits_3``), and
volume control carries the same sphere through it (``tests/test_cavity.py::
test_volume_control_passes_the_pressure_maximum``).
"""
import json
import math
import os

import numpy as np
import pytest
from dolfinx import fem
from mpi4py import MPI
from scipy.optimize import brentq

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import sphere_pressure, uniaxial_nominal_stress
from eyeball_fenicsx.contact import RigidContact
from eyeball_fenicsx.features.cavity import LiquidCavity
from eyeball_fenicsx.meshing.builders.hexes import add_hex_model, boundary_quads, corner_jacobians, hex_grid
from eyeball_fenicsx.meshing.load import built_mesh

A, B = 1.0, 2.0
ROLLERS = [ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}), ef.Dirichlet("z0", {"z": 0.0})]


def strict_json(path):
    """summary.json, refusing NaN and infinities (which Python's json would accept)."""
    def refuse(constant):
        raise ValueError(f"{path} holds {constant}")
    with open(path) as f:
        return json.loads(f.read(), parse_constant=refuse)


# ---------------------------------------------------------------------------------------------
# A liquid from soft to 1e6 times as stiff as the wall


@pytest.mark.parametrize("K, tolerance", [(0.1, 0.03), (1e2, 2e-3), (1e4, 2e-3), (1e6, 2e-3)],
                         ids=["K=0.1mu", "K=1e2mu", "K=1e4mu", "K=1e6mu"])
def test_liquid_from_soft_to_1e6_times_the_wall(sphere_mesh, K, tolerance):
    """The liquid-filled thick sphere (A = 1, B = 2, neo-Hooke c10 = 0.5, shear modulus mu = 1)
    with 30 % of its volume injected, the liquid's bulk modulus K from 0.1 mu to 1e6 mu.
    Closed form (tests/test_cavity.py): the inner stretch lam where the wall's pressure
    (Ogden 1984, eq. 5.2.38) equals the liquid's, p_ini - K (lam^3 - 1 - 0.3). A stiff liquid
    fixes the volume, lam -> 1.3^(1/3); a soft one lets the wall decide."""
    c, p_ini, injected = {(1, 0): 0.5}, 0.1, 0.3
    cavity = LiquidCavity("liquid", "inner", K, p_ini, symmetry=["x", "y", "z"])
    scene = ef.Scene("stiff-liquid", sphere_mesh(n=6, layers=3), {"wall": ef.MooneyRivlin(c)},
                     features=[ef.Dirichlet("sym_x", {"x": 0.0}), ef.Dirichlet("sym_y", {"y": 0.0}),
                               ef.Dirichlet("sym_z", {"z": 0.0}), cavity],
                     probes={"inner": [A, 0.0, 0.0]}, solver=ef.SolverSettings(increments=2))
    scene.build()
    cavity.dV_inj = injected * cavity.V_ini
    final = scene.run()["steps"][-1]
    lam = brentq(lambda lam: sphere_pressure(lam, c, A, B) - (p_ini - K * (lam**3 - 1 - injected)), 0.5, 2.5,
                 xtol=1e-14)
    # converged in the two increments asked for, without a cut-back, at any K: the bordered
    # system stays regular as K grows (its corner -V_ini / K -> 0 makes a volume constraint)
    assert [i["load_factor"] for i in final["increments"]] == pytest.approx([0.5, 1.0])
    # the inner stretch to the discretization error of this 216-cell octant: 2.1 % for the soft
    # liquid, where the wall's stiffness (and its Q1/P0 error) decides, 0.06 % where the
    # liquid's volume does
    assert final["probes"]["inner"][0] == pytest.approx(lam - 1, rel=tolerance)
    result = final["cavities"]["liquid"]
    # the liquid's law holds at the solution to solver tolerance, however stiff the liquid
    V, V_ini = result["volume"], result["initial_volume"]
    assert V - V_ini * (1 + injected) == pytest.approx(-(result["pressure"] - p_ini) * V_ini / K,
                                                     rel=1e-6, abs=1e-12 * V_ini)
    # the pressure, to the wall's discretization error (2 % here, falling as h^2)
    assert result["pressure"] == pytest.approx(sphere_pressure(lam, c, A, B), rel=0.03)


# ---------------------------------------------------------------------------------------------
# Material contrast 1e4 in one mesh


def build_lens_retina(divisions=(2, 2, 2)):
    """Gmsh model: two unit cubes side by side along y, [0, 1]^3 "lens" and
    [0, 1] x [1, 2] x [0, 1] "retina", bonded (shared nodes); surfaces x0, x1, y0, z0."""
    nx, ny, nz = divisions
    axes = [np.linspace(0, 1, nx + 1), np.linspace(0, 2, 2 * ny + 1), np.linspace(0, 1, nz + 1)]
    nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    hexes = hex_grid(np.arange(len(nodes)).reshape(nx + 1, 2 * ny + 1, nz + 1))
    surfaces = {name: boundary_quads(hexes, side) for name, side in
                (("x0", "u-"), ("x1", "u+"), ("y0", "v-"), ("z0", "w-"))}
    add_hex_model("lens_retina", nodes, None, None, surfaces,
                  regions={"lens": hexes[:, :ny].reshape(-1, 8), "retina": hexes[:, ny:].reshape(-1, 8)})


def test_contrast_1e4_side_by_side_in_tension():
    """A lens-like block (c10 = 10 MPa) bonded to a retina-like one (c10 = 0.0008 MPa, 12 500
    times softer), pulled together along x to the stretch l = 1.5. Side by side (in parallel)
    both take the same homogeneous uniaxial deformation F = diag(l, l^-1/2, l^-1/2), which
    keeps the bonded face y = 1 compatible, and each carries its own stress: the nominal
    stress 2 c10 (l - l^-2) on its unit face (Ogden 1984, sec. 7.2), and the pressure
    p = 2 c10 (l^-1 - l^2) / 3 that makes sigma_yy = 2 c10 dev(B)_yy - p vanish. The Q1/P0
    solution is that homogeneous one exactly, so the soft block's stress, 1e-4 of the stiff
    one's, must come out to solver precision next to it."""
    stretch = 1.5
    mesh = built_mesh(build_lens_retina, MPI.COMM_WORLD)
    laws = {"lens": {(1, 0): 10.0}, "retina": {(1, 0): 0.0008}}
    scene = ef.Scene("contrast", mesh, {region: ef.MooneyRivlin(c) for region, c in laws.items()},
                     features=ROLLERS + [ef.Dirichlet("x1", {"x": stretch - 1})],
                     probes={"corner": [1.0, 2.0, 1.0]}, solver=ef.SolverSettings(increments=2))
    final = scene.run()["steps"][-1]
    total = sum(uniaxial_nominal_stress(stretch, c) for c in laws.values())
    assert final["reactions"]["x1"][0] == pytest.approx(total, rel=1e-10)
    assert final["probes"]["corner"] == pytest.approx([stretch - 1, 2 * (stretch**-0.5 - 1), stretch**-0.5 - 1],
                                                      rel=1e-10)
    pressure, to_W = scene.solid.W.sub(1).collapse()
    p = scene.solid.w.x.array[to_W]
    for region, c in laws.items():
        cells = mesh.cells(region)
        dofs = np.concatenate([pressure.dofmap.cell_dofs(cell) for cell in cells])
        assert p[dofs] == pytest.approx(2 * c[1, 0] * (1 / stretch - stretch**2) / 3, rel=1e-10)


# ---------------------------------------------------------------------------------------------
# Strongly distorted elements


def distorted_cube(n=4, amplitude=0.3, seed=7):
    """Nodes and hexahedra of the unit cube in n^3 cells whose nodes are moved at random by up
    to ``amplitude`` times the spacing along each axis; boundary nodes only within their faces,
    so the faces stay plane."""
    axis = np.linspace(0, 1, n + 1)
    nodes = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    shift = np.random.default_rng(seed).uniform(-amplitude / n, amplitude / n, nodes.shape)
    on_face = np.isclose(nodes, 0.0) | np.isclose(nodes, 1.0)
    nodes = nodes + np.where(on_face, 0.0, shift)
    return nodes, hex_grid(np.arange(len(nodes)).reshape(n + 1, n + 1, n + 1))


def build_distorted_cube():
    """Gmsh model of ``distorted_cube``, surfaces x0 .. z1 as the block's."""
    nodes, hexes = distorted_cube()
    sides = {"x0": "u-", "x1": "u+", "y0": "v-", "y1": "v+", "z0": "w-", "z1": "w+"}
    add_hex_model("distorted", nodes, hexes.reshape(-1, 8), "solid",
                  {name: boundary_quads(hexes, side) for name, side in sides.items()})


def test_distorted_cube_is_valid_but_strongly_distorted():
    nodes, hexes = distorted_cube()
    det, scaled = corner_jacobians(nodes, hexes.reshape(-1, 8))
    assert det.min() > 0  # valid: no inverted corner
    # strongly distorted: the scaled Jacobian (1 at a right-angled corner, sin(alpha) at a corner
    # of angle alpha) drops to 0.096 here, a corner of about 5.5 degrees
    assert scaled.min() < 0.1


@pytest.mark.parametrize("element", ["Q1P0", "Q2P1"])
def test_distorted_mesh_passes_the_patch_test(element):
    """Uniaxial tension to the stretch 1.8 on the distorted cube: the exact solution is the
    homogeneous one, an affine displacement and a constant pressure, which Q1/P0 (and Q2/P1)
    represent on any valid trilinear hexahedra; the reaction is the nominal stress
    P = 2 c10 (l - l^-2) (Ogden 1984, sec. 7.2) and the lateral stretch l^-1/2."""
    stretch, c = 1.8, {(1, 0): 0.5}
    mesh = built_mesh(build_distorted_cube, MPI.COMM_WORLD)
    scene = ef.Scene("distorted", mesh, {"solid": ef.MooneyRivlin(c)}, element=element,
                     features=ROLLERS + [ef.Dirichlet("x1", {"x": stretch - 1})],
                     probes={"inside": [0.61, 0.37, 0.53]}, solver=ef.SolverSettings(increments=2))
    final = scene.run()["steps"][-1]
    assert final["reactions"]["x1"][0] == pytest.approx(uniaxial_nominal_stress(stretch, c), rel=1e-10)
    assert final["probes"]["inside"] == pytest.approx(
        [0.61 * (stretch - 1), 0.37 * (stretch**-0.5 - 1), 0.53 * (stretch**-0.5 - 1)], rel=1e-10)


# ---------------------------------------------------------------------------------------------
# Indentation to half the wall thickness


def test_indentation_to_half_the_wall_thickness(block_mesh):
    """A rigid sphere (radius 2) pressed 0.5 into a wall of thickness 1 (incompressible
    neo-Hooke, bonded to a rigid base; a quarter, symmetry planes x = 0 and y = 0): far beyond
    Hertz (contact radius ~ the thickness), no closed form, so the checks are what must hold at
    any depth. It converges to the full depth; the top point under the sphere sits at the
    depth (the augmented Lagrangian leaves a penetration below 1e-3 of the top elements' depth,
    1/4); the base carries
    the sphere's push (z is held there only, so the z balance is exact); no element is
    inverted."""
    thickness, radius, depth = 1.0, 2.0, 0.5
    sphere = RigidContact("sphere", "z1", "sphere", center=[0.0, 0.0, thickness + radius], radius=radius,
                          displacement=[0.0, 0.0, -depth])
    scene = ef.Scene("indent", block_mesh((8, 8, 4), lengths=(4.0, 4.0, thickness)), {"solid": ef.NeoHooke(0.5)},
                     features=[ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}),
                               ef.Dirichlet("z0", {"x": 0.0, "y": 0.0, "z": 0.0}), sphere],
                     probes={"top": [0.0, 0.0, thickness]}, solver=ef.SolverSettings(increments=4))
    final = scene.run()["steps"][-1]
    contact = final["contact"]["sphere"]
    assert final["increments"][-1]["load_factor"] == pytest.approx(1.0)
    assert final["probes"]["top"][2] == pytest.approx(-depth, abs=1e-3 * thickness / 4)
    assert 0 <= contact["max_penetration"] < 1e-3 * thickness / 4
    assert final["reactions"]["z0"][2] == pytest.approx(-contact["force"][2], rel=1e-8)
    assert contact["force"][2] < 0  # pushed down
    assert scene.problem.guard.check()[0] > 0


# ---------------------------------------------------------------------------------------------
# A load that inverts an element


def test_crushing_point_force_stops_cleanly_and_says_where(block_mesh, shared_tmp):
    """A point force of 1e3 times the shear modulus on one corner node of a unit cube has no
    equilibrium without inverted elements on this mesh: Newton's first step throws the node
    through the cube. The run must stop with a ConvergenceError that names the inverted element's
    location, and leave a summary.json with "ok": false and only finite numbers (strict parse),
    and fields of the last converged (here: the undeformed) state, finite too."""
    corner = [1.0, 1.0, 1.0]
    scene = ef.Scene("crush", block_mesh((2, 2, 2)), {"solid": ef.NeoHooke(0.5)},
                     features=ROLLERS + [ef.NodalForce([-1e3, -1e3, -1e3], point=corner)],
                     probes={"corner": corner}, solver=ef.SolverSettings(increments=1, max_cutbacks=1))
    out = os.path.join(shared_tmp, "crush")
    with pytest.raises(ef.ConvergenceError) as failure:
        scene.run(out)
    message = str(failure.value)
    assert "inverted" in message
    location = [float(v) for v in message.split("near [")[1].split("]")[0].split(",")]
    assert all(v in (0.25, 0.75) for v in location)  # the midpoint of one of the 2 x 2 x 2 elements
    summary = strict_json(os.path.join(out, "summary.json"))
    assert summary["ok"] is False and "inverted" in summary["error"]
    (step,) = summary["steps"]
    assert step["increments"] == []  # not even the smallest increment converged
    assert step["probes"]["corner"] == [0.0, 0.0, 0.0]
    assert all(math.isfinite(v) for reaction in step["reactions"].values() for v in reaction)
    # what the fields were written from (fields.h5 holds these, interpolated)
    assert np.isfinite(scene.solid.w.x.array).all()
    mises = fem.Function(fem.FunctionSpace(scene.mesh.mesh, ("DG", 0)))
    mises.interpolate(fem.Expression(scene.solid.mises_expression(),
                                     mises.function_space.element.interpolation_points()))
    assert np.isfinite(mises.x.array).all()

"""The incompressible hyperelastic core against closed forms."""
import numpy as np
import pytest

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import sphere_inner_stretch, uniaxial_nominal_stress
from eyeball_fenicsx.scene.scene import Step

# Mooney-Rivlin with higher-order terms (values of the order of soft tissue, MPa)
COEFFICIENTS = {(1, 0): 0.4, (0, 1): 0.1, (2, 0): 0.05, (1, 1): 0.02, (0, 2): 0.01}


def tension_scene(mesh, stretch, increments=2):
    """Unit cube, symmetry on x0/y0/z0, the face x1 pulled to the given stretch."""
    return ef.Scene("uniaxial", mesh, {"solid": ef.MooneyRivlin(COEFFICIENTS)},
                    features=[ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}),
                              ef.Dirichlet("z0", {"z": 0.0}), ef.Dirichlet("x1", {"x": stretch - 1.0})],
                    probes={"corner": [1.0, 1.0, 1.0]}, solver=ef.SolverSettings(increments=increments))


@pytest.mark.parametrize("stretch", [1.8, 0.6])
def test_uniaxial_tension_and_compression(block_mesh, stretch):
    final = tension_scene(block_mesh((2, 2, 2)), stretch).run()["steps"][-1]
    # face area is 1 in the reference configuration: the reaction is the nominal stress
    expected = uniaxial_nominal_stress(stretch, COEFFICIENTS)
    assert final["reactions"]["x1"][0] == pytest.approx(expected, rel=1e-8)
    assert final["reactions"]["x0"][0] == pytest.approx(-expected, rel=1e-8)
    # incompressible: the lateral stretch is lambda^(-1/2)
    assert final["probes"]["corner"][1] == pytest.approx(stretch**-0.5 - 1, rel=1e-8)


def test_nodal_force_gives_the_uniaxial_stretch(block_mesh):
    """A total force F on the face x1 produces the stretch whose nominal stress is F."""
    force = 0.3
    scene = ef.Scene("force", block_mesh((2, 1, 1)), {"solid": ef.MooneyRivlin(COEFFICIENTS)},
                     features=[ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}),
                               ef.Dirichlet("z0", {"z": 0.0}), ef.NodalForce([force, 0, 0], surface="x1")],
                     probes={"corner": [1.0, 1.0, 1.0]}, solver=ef.SolverSettings(increments=2))
    stretch = 1 + scene.run()["steps"][-1]["probes"]["corner"][0]
    # on a face of one element the four nodes carry F/4 each, which is the consistent load
    assert uniaxial_nominal_stress(stretch, COEFFICIENTS) == pytest.approx(force, rel=1e-7)


def test_steps_hold_and_ramp(block_mesh):
    """A load of the second step ramps from the state the first one left."""
    mesh = block_mesh((2, 1, 1))
    scene = ef.Scene("two-steps", mesh, {"solid": ef.NeoHooke(0.5)},
                     features=[ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}),
                               ef.Dirichlet("z0", {"z": 0.0}), ef.Dirichlet("x1", {"x": 0.5}),
                               ef.Dirichlet("y1", {"y": 0.2}, step=1)],
                     probes={"corner": [1.0, 1.0, 1.0]}, steps=[Step("pull"), Step("widen")],
                     solver=ef.SolverSettings(increments=1))
    steps = scene.run()["steps"]
    assert steps[0]["probes"]["corner"][0] == pytest.approx(0.5)
    assert steps[0]["probes"]["corner"][1] == pytest.approx(1.5**-0.5 - 1)
    assert steps[1]["probes"]["corner"][:2] == pytest.approx([0.5, 0.2])
    assert steps[1]["probes"]["corner"][2] == pytest.approx(1 / (1.5 * 1.2) - 1)  # J = 1


def sphere_error(mesh, c, P):
    """Relative error of the inner radial displacement of the thick sphere A=1, B=2."""
    scene = ef.Scene("sphere", mesh, {"wall": ef.MooneyRivlin(c)},
                     features=[ef.Dirichlet("sym_x", {"x": 0.0}), ef.Dirichlet("sym_y", {"y": 0.0}),
                               ef.Dirichlet("sym_z", {"z": 0.0}), ef.Pressure("inner", P)],
                     probes={"inner": [1.0, 0.0, 0.0]}, solver=ef.SolverSettings(increments=2))
    u = scene.run()["steps"][-1]["probes"]["inner"][0]
    exact = sphere_inner_stretch(P, c, 1.0, 2.0) - 1.0
    return abs(u - exact) / exact


@pytest.mark.parametrize("c, P", [({(1, 0): 0.5}, 0.6), (COEFFICIENTS, 0.5)], ids=["neo-hooke", "mooney-rivlin"])
def test_thick_sphere_converges_to_the_closed_form(sphere_mesh, c, P):
    """Inner stretch of the inflated thick sphere (Ogden 1984, eq. 5.2.38), error falling
    at second order under uniform refinement (observed rate 1.9-2.0, Q1/P0)."""
    coarse = sphere_error(sphere_mesh(n=4, layers=2), c, P)
    fine = sphere_error(sphere_mesh(n=8, layers=4), c, P)
    assert fine < 0.015
    assert np.log2(coarse / fine) > 1.7

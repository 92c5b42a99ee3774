"""Liquid cavities (the seed's solid-liquid coupling) against the closed form of a
liquid-filled thick sphere.

A thick incompressible sphere (radii A < B) filled with a liquid of bulk modulus K, initial
pressure p_ini and injected volume dV is in equilibrium at the inner stretch lam where the
pressure the wall carries (Ogden 1984, eq. 5.2.38, ``analytic.sphere_pressure``) equals the
liquid's, p = p_ini - K (V - V_ini - dV) / V_ini with V = lam^3 V_ini.
"""
import numpy as np
import pytest
from scipy.optimize import brentq

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import sphere_inner_stretch, sphere_pressure
from eyeball_fenicsx.features.cavity import Injection, LiquidCavity

A, B = 1.0, 2.0
SYMMETRY = [ef.Dirichlet("sym_x", {"x": 0.0}), ef.Dirichlet("sym_y", {"y": 0.0}), ef.Dirichlet("sym_z", {"z": 0.0})]


def filled_sphere(mesh, c, K, p_ini, injected_fraction, algorithm="new", increments=2):
    """Run the octant with its liquid; return (final step entry, cavity)."""
    cavity = LiquidCavity("liquid", "inner", K, p_ini, 0.0, symmetry=["x", "y", "z"], algorithm=algorithm)
    scene = ef.Scene("filled-sphere", mesh, {"wall": ef.MooneyRivlin(c)}, features=SYMMETRY + [cavity],
                     probes={"inner": [A, 0.0, 0.0]}, solver=ef.SolverSettings(increments=increments))
    scene.build()
    cavity.dV_inj = injected_fraction * cavity.V_ini  # a fraction of the discrete initial volume
    return scene.run()["steps"][-1], cavity


def equilibrium_stretch(c, K, p_ini, injected_fraction, A=A, B=B):
    return brentq(lambda lam: sphere_pressure(lam, c, A, B) - (p_ini - K * (lam**3 - 1 - injected_fraction)),
                  0.5, 2.5, xtol=1e-14)


MOONEY_RIVLIN = {(1, 0): 0.4, (0, 1): 0.1, (2, 0): 0.05}


@pytest.mark.parametrize("c, K, p_ini, injected", [
    ({(1, 0): 0.5}, 10.0, 0.1, 0.5),            # soft liquid, neo-Hooke wall, injection
    (MOONEY_RIVLIN, 10.0, 0.1, -0.1),           # Mooney-Rivlin wall, liquid removed
    ({(1, 0): 0.0008}, 2083.3, 0.002, 0.05),    # the seed's vitreous (K = 2083.3 MPa) in a retina-soft wall
    ({(1, 0): 0.0008}, 2083.3, 0.002, -0.02),   # ... and a paracentesis
], ids=["soft-liquid", "mooney-rivlin-removal", "stiff-liquid", "stiff-liquid-removal"])
def test_filled_sphere_against_closed_form(sphere_mesh, c, K, p_ini, injected):
    final, cavity = filled_sphere(sphere_mesh(n=6, layers=3), c, K, p_ini, injected)
    lam = equilibrium_stretch(c, K, p_ini, injected)
    p_exact = sphere_pressure(lam, c, A, B)
    result = final["cavities"]["liquid"]
    lam_fe = 1 + final["probes"]["inner"][0]
    # the inner stretch to the discretization error of this coarse mesh (Q1/P0, 216 cells)
    assert lam_fe - 1 == pytest.approx(lam - 1, rel=0.01)
    # the pressure to the discretization error, which is ~2.5% here (it falls as h^2)
    assert result["pressure"] == pytest.approx(p_exact, rel=0.03)
    # the liquid's law holds exactly at the solution: the volume change is what the
    # liquid's compressibility allows for the pressure reached
    V, V_ini = result["volume"], result["initial_volume"]
    assert V - V_ini * (1 + injected) == pytest.approx(-(result["pressure"] - p_ini) * V_ini / K,
                                                     rel=1e-6, abs=1e-12 * V_ini)


def test_new_and_previous_algorithms_agree(sphere_mesh):
    """The bordered system (one global pressure unknown) and the dense tangent of the
    seed's previous algorithm solve the same equations."""
    mesh = sphere_mesh(n=4, layers=2)
    new, _ = filled_sphere(mesh, MOONEY_RIVLIN, 10.0, 0.05, 0.3, algorithm="new")
    previous, _ = filled_sphere(mesh, MOONEY_RIVLIN, 10.0, 0.05, 0.3, algorithm="previous")
    assert new["cavities"]["liquid"]["pressure"] == pytest.approx(previous["cavities"]["liquid"]["pressure"], rel=1e-9)
    assert new["probes"]["inner"] == pytest.approx(previous["probes"]["inner"], rel=1e-9, abs=1e-14)


def test_volume_control_passes_the_pressure_maximum(sphere_mesh):
    """A thin neo-Hookean sphere (B/A = 1.1) has a pressure maximum near lam = 1.4
    (analytic.sphere_pressure); injecting liquid carries it to lam = 1.8 on the falling
    branch, where the pressure matches the closed form."""
    c = {(1, 0): 0.5}
    lam_target = 1.8
    mesh = sphere_mesh(n=6, layers=2, outer_radius=1.1)
    final, _ = filled_sphere(mesh, c, 1e3, 0.0, lam_target**3 - 1, increments=4)
    lam_fe = 1 + final["probes"]["inner"][0]
    lams = np.linspace(1.05, 2.0, 200)
    lam_peak = lams[np.argmax([sphere_pressure(lam, c, A, 1.1) for lam in lams])]
    assert lam_peak < 1.5 < lam_fe
    assert lam_fe == pytest.approx(lam_target, rel=2e-3)  # the liquid is nearly incompressible
    assert final["cavities"]["liquid"]["pressure"] == pytest.approx(sphere_pressure(lam_fe, c, A, 1.1), rel=0.01)


def test_pressure_control_past_the_maximum_stops_cleanly(sphere_mesh):
    """Pressure control of the same thin sphere at 1.2 x its maximum pressure must stop with
    a ConvergenceError close to the limit load, keeping the converged increments."""
    c = {(1, 0): 0.5}
    p_max = max(sphere_pressure(lam, c, A, 1.1) for lam in np.linspace(1.05, 2.0, 400))
    scene = ef.Scene("limit", sphere_mesh(n=6, layers=2, outer_radius=1.1), {"wall": ef.MooneyRivlin(c)},
                     features=SYMMETRY + [ef.Pressure("inner", 1.2 * p_max)], probes={"inner": [A, 0.0, 0.0]},
                     solver=ef.SolverSettings(increments=4, max_cutbacks=5))
    with pytest.raises(ef.ConvergenceError, match="did not converge") as failure:
        scene.run()
    reached = failure.value.increments[-1].load_factor * 1.2 * p_max
    assert 0.9 * p_max < reached < 1.01 * p_max


def test_open_surface_is_rejected(sphere_mesh):
    """Without its symmetry planes the octant's inner surface does not enclose a volume."""
    cavity = LiquidCavity("liquid", "inner", 10.0, symmetry=["x", "y"])
    scene = ef.Scene("open", sphere_mesh(n=2, layers=1), {"wall": ef.NeoHooke(0.5)}, features=SYMMETRY + [cavity])
    with pytest.raises(ef.SceneError, match=r"not closed: \d+ open edge\(s\), e\.g\. near \[.*, 0\.0\]"):
        scene.build()


@pytest.mark.parametrize("algorithm", ["new", "previous"])
def test_pressurize_fills_to_the_pressure_then_holds_the_liquid(sphere_mesh, algorithm):
    """Step 1 fills the cavity to p_ini (pressure control: the inner stretch is the closed
    form's at P = p_ini); step 2 injects dV more into a liquid of bulk modulus K about the
    filled state V_1: the closed form with p_ini -> P_1, V_ini -> V_1 (the stretch now
    measured from the reference: lam^3 V_ini = V). The previous algorithm's condensed block
    enters the Newton matrix only once the cavity is filled, into room kept for it from the
    matrix's first assembly (system/problem.py): no assembly mallocs, which also cost MUMPS a
    new symbolic analysis (a matrix that dropped that room grew at every assembly of step 2)."""
    c, K, p_ini = {(1, 0): 0.5}, 10.0, 0.2
    cavity = LiquidCavity("liquid", "inner", K, p_ini, symmetry=["x", "y", "z"], pressurize=True, algorithm=algorithm)
    injection = Injection(cavity, 0.05, step=1)
    scene = ef.Scene("fill", sphere_mesh(n=6, layers=3), {"wall": ef.MooneyRivlin(c)},
                     features=SYMMETRY + [cavity, injection], probes={"inner": [A, 0.0, 0.0]},
                     steps=[ef.Step("fill"), ef.Step("inject")], solver=ef.SolverSettings(increments=2))
    filled, injected = scene.run()["steps"]
    lam1 = 1 + filled["probes"]["inner"][0]
    assert filled["cavities"]["liquid"]["pressure"] == pytest.approx(p_ini, rel=1e-9)
    assert lam1 - 1 == pytest.approx(sphere_inner_stretch(p_ini, c, A, B) - 1, rel=0.03)  # 216 cells: ~2.3%
    V1, V_ini = filled["cavities"]["liquid"]["volume"], filled["cavities"]["liquid"]["initial_volume"]
    lam = brentq(lambda lam: sphere_pressure(lam, c, A, B) - (p_ini - K * (lam**3 * V_ini - V1 - 0.05) / V1),
                 lam1, 2.0, xtol=1e-14)
    result = injected["cavities"]["liquid"]
    assert 1 + injected["probes"]["inner"][0] - lam1 == pytest.approx(lam - lam1, rel=0.03)
    assert result["pressure"] == pytest.approx(sphere_pressure(lam, c, A, B), rel=0.03)
    # the liquid's law about the filled state holds exactly
    assert result["pressure"] == pytest.approx(p_ini - K * (result["volume"] - V1 - 0.05) / V1, rel=1e-7)
    assert result["injected_volume"] == pytest.approx(V1 - V_ini + 0.05, rel=1e-9)
    assert scene.problem.A.getInfo()["mallocs"] == 0


BREAK_SCENE = """
name = "retinal-break"
tissues = "seed"
[mesh]
builder = "eye"
sector_deg = 180.0
n_circ = 16
detachment = { polar_deg = 0.0, extent_deg = 25.0, gap = 0.1 }
[[step]]
name = "fill"
[[step]]
name = "close"
[[step]]
name = "drain"
[[dirichlet]]
surface = "optic_nerve_end"
x = 0.0
y = 0.0
z = 0.0
[[dirichlet]]
surface = "cut_0"
y = 0.0
[[dirichlet]]
surface = "cut_1"
y = 0.0
[[cavity]]
name = "vitreous"
surface = "vitreous_wall"
bulk_modulus = 2083.3
initial_pressure = 0.002
pressurize = true
symmetry = ["y"]
[[cavity]]
name = "subretinal"
surface = ["retina_outer", "choroid_inner"]
bulk_modulus = 2083.3
symmetry = ["y"]
break_into = "vitreous"
break_closes = "close"
drain = "drain"
drain_fraction = 0.5
"""


def test_retinal_break_and_drainage(shared_tmp):
    """A pole-centred detachment on the coarse half eye: the subretinal space is one liquid with
    the vitreous while the break is open (the vitreous' prescribed pressure on both), closing the
    break in a step that changes nothing leaves the state as it was (both laws restart from it),
    and draining half of the subretinal liquid halves the space while the vitreous keeps its
    liquid: its volume changes only by the liquid law's -V dp / K."""
    from test_scenes import read_summary, scene_file

    from eyeball_fenicsx.scene.loader import load_scene
    load_scene(scene_file(shared_tmp, BREAK_SCENE)).run(shared_tmp)
    steps = {s["name"]: s["cavities"] for s in read_summary(shared_tmp)["steps"]}
    fill, close, drain = steps["fill"], steps["close"], steps["drain"]
    assert fill["subretinal"]["break"] == "open" and close["subretinal"]["break"] == "closed"
    assert fill["subretinal"]["pressure"] == fill["vitreous"]["pressure"] == pytest.approx(0.002, rel=1e-9)
    assert fill["subretinal"]["volume"] > 1.5 * fill["subretinal"]["initial_volume"]  # the wall inflated
    for name in ("vitreous", "subretinal"):
        for key in ("pressure", "volume"):
            assert close[name][key] == pytest.approx(fill[name][key], rel=1e-9), (name, key)
    assert drain["subretinal"]["volume"] / close["subretinal"]["volume"] == pytest.approx(0.5, rel=1e-6)
    assert drain["subretinal"]["drained_volume"] == pytest.approx(0.5 * close["subretinal"]["volume"], rel=1e-12)
    dp = drain["vitreous"]["pressure"] - close["vitreous"]["pressure"]
    assert drain["vitreous"]["volume"] / close["vitreous"]["volume"] - 1 == pytest.approx(-dp / 2083.3, abs=1e-9)
    assert drain["subretinal"]["pressure"] < drain["vitreous"]["pressure"]  # the retina pressed outward

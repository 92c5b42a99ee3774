"""Newton's globalization (system/newton.py): convergence judged block by block, stagnation ends a
solve at once, an inverting step is shortened, and the increments follow the target rule."""
import contextlib

import numpy as np
import pytest
from petsc4py import PETSc
from scipy.optimize import brentq

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import sphere_pressure, uniaxial_nominal_stress
from eyeball_fenicsx.features.cavity import LiquidCavity
from eyeball_fenicsx.system import newton
from eyeball_fenicsx.system.newton import PREFIX, STAGNATION_WINDOW

SYMMETRY = [ef.Dirichlet("sym_x", {"x": 0.0}), ef.Dirichlet("sym_y", {"y": 0.0}), ef.Dirichlet("sym_z", {"z": 0.0})]
ROLLERS = [ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}), ef.Dirichlet("z0", {"z": 0.0})]


@contextlib.contextmanager
def petsc_options(**options):
    """PETSc options of the scenes built inside, removed again on leaving (same on every rank)."""
    database = PETSc.Options()
    for key, value in options.items():
        database[PREFIX + key] = value
    try:
        yield
    finally:
        for key in options:
            database.delValue(PREFIX + key)


# ---------------------------------------------------------------------------------------------
# 1. Every block of the residual against its own scale


def filled_sphere(sphere_mesh, rtol):
    """The seed's vitreous (K = 2083.3 MPa) in a retina-soft thick sphere (c10 = 0.0008 MPa,
    A = 1, B = 2), 5 % of its volume injected in one increment, plain Newton: the wall's
    forces are 1e-5 of the liquid's volume residual. Returns (final step, scene)."""
    with petsc_options(snes_rtol=rtol):
        cavity = LiquidCavity("liquid", "inner", 2083.3, 0.0, symmetry=["x", "y", "z"])
        scene = ef.Scene("vitreous", sphere_mesh(n=4, layers=2), {"wall": ef.NeoHooke(0.0008)},
                         features=SYMMETRY + [cavity], probes={"inner": [1.0, 0.0, 0.0]},
                         solver=ef.SolverSettings(increments=1, reuse_contraction=0.0)).build()
        cavity.dV_inj = 0.05 * cavity.V_ini
        return scene.run()["steps"][-1], scene


def test_a_small_block_is_not_hidden_by_a_large_one(sphere_mesh):
    """With snes_rtol = 1e-4, the whole residual falls below 1e-4 of its first norm (the
    liquid's volume residual) one Newton iteration before the wall's forces fall below 1e-4 of
    theirs: a test on the whole residual (PETSc's default) would stop there. Judged block by
    block, Newton goes on until each block is below 1e-4 of its own largest norm, and the
    pressure and displacement are those a tight tolerance gives."""
    rtol, atol = 1e-4, 1e-11
    final, scene = filled_sphere(sphere_mesh, rtol)
    newton = scene.newton
    names = [name for name, _ in scene.problem.residual_blocks]
    assert names == ["force", "prescribed", "incompressibility", "liquid"]
    blocks, whole = np.array(newton.block_norms), np.array(newton.residual_norms)
    force, liquid = names.index("force"), names.index("liquid")
    assert blocks[:, force].max() < 1e-4 * blocks[:, liquid].max()  # the wall's block is the small one

    stops_whole = next(k for k in range(1, len(whole)) if whole[k] <= max(rtol * whole[0], atol))
    assert stops_whole < len(whole) - 1
    assert blocks[stops_whole, force] > 3 * max(rtol * blocks[:, force].max(), atol)
    tolerances = np.maximum(rtol * blocks.max(axis=0), atol)
    assert np.all(blocks[-1] <= tolerances)

    tight, _ = filled_sphere(sphere_mesh, 1e-12)
    assert final["cavities"]["liquid"]["pressure"] == pytest.approx(tight["cavities"]["liquid"]["pressure"], rel=1e-8)
    assert final["probes"]["inner"] == pytest.approx(tight["probes"]["inner"], rel=1e-8)


def test_blocks_follow_the_problem(sphere_mesh):
    """Every owned row of the residual is in exactly one block: the displacement dofs split
    into free and prescribed, the pressure dofs, and the cavity's row on the last rank."""
    cavity = LiquidCavity("liquid", "inner", 10.0, symmetry=["x", "y", "z"])
    scene = ef.Scene("rows", sphere_mesh(n=2, layers=1), {"wall": ef.NeoHooke(0.5)},
                     features=SYMMETRY + [cavity]).build()
    problem = scene.problem
    problem.begin_step(0)
    rows = np.concatenate([rows for _, rows in problem.residual_blocks])
    assert np.array_equal(np.sort(rows), np.arange(problem.n_owned + problem.n_extra_local))
    prescribed = dict(problem.residual_blocks)["prescribed"]
    assert np.array_equal(prescribed, problem.bc_rows)


# ---------------------------------------------------------------------------------------------
# 2. Stagnation


def sphere_beyond_its_largest_pressure(sphere_mesh):
    """A thin neo-Hookean sphere (B/A = 1.1) under 1.2 times its largest pressure (Ogden 1984,
    eq. 5.2.38: the pressure has a maximum in the inner stretch): it has no equilibrium."""
    c = {(1, 0): 0.5}
    p_max = max(sphere_pressure(lam, c, 1.0, 1.1) for lam in np.linspace(1.05, 2.0, 400))
    return ef.Scene("beyond", sphere_mesh(n=6, layers=2, outer_radius=1.1), {"wall": ef.MooneyRivlin(c)},
                    features=SYMMETRY + [ef.Pressure("inner", 1.2 * p_max)],
                    solver=ef.SolverSettings(increments=1, max_cutbacks=0))


def test_newton_without_an_equilibrium_stops_as_stagnated(sphere_mesh, monkeypatch):
    """The sphere beyond its largest pressure: Newton without a line search, with the 30
    iterations a contact scene gets, must stop as soon as its residual stops falling, not spend
    them (with the swing check, the next test, off)."""
    monkeypatch.setattr(newton, "MAX_STEP_GROWTH", np.inf)
    scene = sphere_beyond_its_largest_pressure(sphere_mesh)
    with petsc_options(snes_linesearch_type="basic", snes_max_it=30), \
            pytest.raises(ef.ConvergenceError, match="last try: stagnated"):
        scene.run()
    iterations = len(scene.newton.residual_norms) - 1
    assert iterations <= STAGNATION_WINDOW + 3  # the window, counted from the first iterate, and one or two more


def test_newton_steps_that_grow_end_the_solve(sphere_mesh):
    """The sphere beyond its largest pressure inflates without bound: Newton's steps grow, and
    the one that would move the wall MAX_STEP_GROWTH times farther than the first step ends the
    solve, before stagnation would (without a line search, as in a contact scene; with the
    backtracking one, a step of this sphere inverts an element first)."""
    scene = sphere_beyond_its_largest_pressure(sphere_mesh)
    with petsc_options(snes_linesearch_type="basic", snes_max_it=30), \
            pytest.raises(ef.ConvergenceError, match="last try: a Newton step 3 times the first"):
        scene.run()
    iterations = len(scene.newton.residual_norms) - 1
    assert iterations < STAGNATION_WINDOW + 1  # stagnation needs the window's iterates after the first
    # the failed solve's growing norms stay out of the increment's scales: a solve of the same
    # increment again (after an abandoned augmentation) is judged at the converged solves' ones
    assert np.all(scene.newton.increment_scales == 0.0)  # set by the solve (None before any), and left at zero


# ---------------------------------------------------------------------------------------------
# 3. An inverting Newton step is shortened


@pytest.mark.parametrize("line_search", ["basic", "bt"])
def test_inverting_step_is_shortened_not_cut_back(block_mesh, line_search):
    """A compressive force of 4 mu on the unit face of an incompressible neo-Hookean block,
    in one increment. Newton's first step is the linear one, a strain of -4 mu / E = -4/3
    (E = 3 mu): it turns the block inside out. Halved, it does not, and Newton converges in
    that one increment, with either line search, to the uniaxial stretch whose nominal stress
    is the force (Ogden 1984, sec. 7.2)."""
    c, force = {(1, 0): 0.5}, -4.0  # mu = 2 c10 = 1
    scene = ef.Scene("crush", block_mesh((2, 1, 1)), {"solid": ef.MooneyRivlin(c)},
                     features=ROLLERS + [ef.NodalForce([force, 0.0, 0.0], surface="x1")],
                     probes={"corner": [1.0, 1.0, 1.0]},
                     solver=ef.SolverSettings(increments=1, max_cutbacks=0))
    with petsc_options(snes_linesearch_type=line_search):
        final = scene.run()["steps"][-1]
    assert [i["load_factor"] for i in final["increments"]] == [1.0]
    assert scene.newton.step_halvings[0] >= 1
    stretch = 1 + final["probes"]["corner"][0]
    assert stretch == pytest.approx(brentq(lambda lam: uniaxial_nominal_stress(lam, c) - force, 0.05, 1.0), rel=1e-9)
    assert scene.problem.guard.check()[0] > 0


def test_an_element_inverted_at_a_quadrature_point_only_is_seen(block_mesh):
    """The corner (2, 1, 1) of the block [0, 2] x [0, 1] x [0, 1] (two hexahedra) moved by
    -s (1, 1, 1): u = -s xi_1 xi_2 xi_3 (1, 1, 1) in the second element's reference coordinates
    xi, so F = I - s (1, 1, 1) (xi_2 xi_3, xi_1 xi_3, xi_1 xi_2)^T and det F = 1 - s (xi_2 xi_3 +
    xi_1 xi_3 + xi_1 xi_2), least at the 2 x 2 x 2 Gauss point nearest the corner, xi = (a, a, a),
    a = (3 + sqrt 3) / 6: 1 - 3 s a^2 = -0.49 for s = 0.8, where the laws are not a number
    (J^(-2/3)); the midpoint keeps 1 - 3 s / 4 = 0.4. The guard must see the Gauss point."""
    scene = ef.Scene("corner", block_mesh((2, 1, 1), lengths=(2.0, 1.0, 1.0)), {"solid": ef.NeoHooke(0.5)},
                     features=ROLLERS)
    scene.build()
    s, a = 0.8, (3 + np.sqrt(3)) / 6
    u = scene.problem.solid.w.sub(0)
    u.interpolate(lambda x: -s * np.maximum(x[0] - 1.0, 0.0) * x[1] * x[2] * np.ones((3, 1)))
    scene.problem.solid.w.x.scatter_forward()
    det_min, where = scene.problem.guard.check()
    assert det_min == pytest.approx(1 - 3 * s * a**2, rel=1e-10)
    assert where == pytest.approx([1.5, 0.5, 0.5])


# ---------------------------------------------------------------------------------------------
# 4. Increments: the target rule


def corner_force(block_mesh, growth):
    """A point force of 2 mu (1, 1, 1) pressing on a corner of the unit cube, in 4 increments
    to start with, the rule aimed at 5 tangents an increment. No secant predictor:
    extrapolated, this state inverts an element at a Gauss point, and a cut-back would break
    the rule's chain."""
    scene = ef.Scene("corner", block_mesh((2, 2, 2)), {"solid": ef.NeoHooke(0.5)},
                     features=ROLLERS + [ef.NodalForce([-2.0, -2.0, -2.0], point=[1.0, 1.0, 1.0])],
                     probes={"corner": [1.0, 1.0, 1.0]},
                     solver=ef.SolverSettings(increments=4, growth=growth, predictor=False, easy_iterations=5))
    return scene.run()["steps"][-1]


def test_increments_shrink_after_hard_ones_and_grow_again(block_mesh):
    """The first increment is hard (more tangents than the target of 5): the next is smaller;
    then easy ones let it grow again, each by target / tangents within [1/2, 2] (the last takes
    what is left of the step if that is under 1.5 times its size). With
    growth = 1 the increments stay equal. A hyperelastic solid under a dead load ends in the
    same equilibrium whichever path the increments take."""
    final = corner_force(block_mesh, growth=2.0)
    t = np.array([0.0] + [i["load_factor"] for i in final["increments"]])
    tangents = [i["factorizations"] for i in final["increments"]]
    sizes = np.diff(t)
    assert tangents[0] > 5 and sizes[1] < sizes[0]
    assert max(sizes[2:-1]) > sizes[1]
    for k in range(len(sizes) - 1):
        expected, left = sizes[k] * np.clip(5 / tangents[k], 0.5, 2.0), 1 - t[k + 1]
        # an increment that would leave less than half its size to the end takes that too
        assert sizes[k + 1] == pytest.approx(left if left < 1.5 * expected else expected, rel=1e-12)

    equal = corner_force(block_mesh, growth=1.0)
    assert [i["load_factor"] for i in equal["increments"]] == pytest.approx([0.25, 0.5, 0.75, 1.0], rel=1e-14)
    assert equal["increments"][0]["factorizations"] > 5  # hard, yet the next one is not smaller
    assert final["probes"]["corner"] == pytest.approx(equal["probes"]["corner"], rel=1e-9)


def test_growth_below_one_is_rejected():
    with pytest.raises(ef.SceneError, match="growth must be at least 1"):
        ef.SolverSettings(growth=0.5)

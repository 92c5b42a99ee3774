"""Sutures and band tightening against closed forms."""
import numpy as np
import pytest
from mpi4py import MPI
from scipy.optimize import brentq

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import uniaxial_nominal_stress
from eyeball_fenicsx.errors import SceneError
from eyeball_fenicsx.features.band import BandTightening
from eyeball_fenicsx.features.sutures import SLIDE_STIFFNESS, SUTURE_EA, Suture
from eyeball_fenicsx.mechanics.solid import MixedSolid
from eyeball_fenicsx.meshing.builders.band import build_band
from eyeball_fenicsx.meshing.load import built_mesh

C = {(1, 0): 0.4, (0, 1): 0.1}
CORNERS = [[1.0, y, z] for y in (0.0, 1.0) for z in (0.0, 1.0)]
SYMMETRY = [ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}), ef.Dirichlet("z0", {"z": 0.0})]


def pulled_block(block_mesh, sutures):
    # plain Newton (no factorization reuse), so that the iterations show the tangent's quality
    scene = ef.Scene("sutured", block_mesh((2, 1, 1)), {"solid": ef.MooneyRivlin(C)}, features=SYMMETRY + sutures,
                     probes={"corner": [1.0, 1.0, 1.0]},
                     solver=ef.SolverSettings(increments=2, reuse_contraction=0.0))
    return scene, scene.run()["steps"][-1]


def test_sutures_with_tension_give_the_uniaxial_stress(block_mesh):
    """Four sutures pulling the corners of the unit face x = 1 toward far anchors along +x
    load it with 4 T; the face of one element carries the uniaxial nominal stress
    (analytic.uniaxial_nominal_stress, Ogden 1984)."""
    T = 0.05
    sutures = [Suture(f"s{i}", corner, [1e6, corner[1], corner[2]], tension=T, anchored=True)
               for i, corner in enumerate(CORNERS)]
    _, final = pulled_block(block_mesh, sutures)
    stretch = 1 + final["probes"]["corner"][0]
    assert uniaxial_nominal_stress(stretch, C) == pytest.approx(4 * T, rel=1e-6)
    assert final["sutures"]["s0"]["tension"] == pytest.approx(T)
    assert final["reactions"]["x0"][0] == pytest.approx(-4 * T, rel=1e-6)  # in balance with the sutures


def test_shortened_sutures_balance_the_block(block_mesh):
    """Strings from each corner to anchors a distance L further along x, shortened by s:
    the tension k (s - u) of each of the four strings (k = EA / L, sutures.SUTURE_EA = 40)
    carries the uniaxial stress at the stretch 1 + u; solve that scalar equation for u. The
    anchors sit on the lines the corners end on (lateral stretch (1 + u)^-1/2) and far
    away, so the strings end axial and their lengths differ from L by < 1e-5 L."""
    L, s = 1000.0, 7.0
    k = 40.0 / L
    u = brentq(lambda u: 4 * k * (s - u) - uniaxial_nominal_stress(1 + u, C), 0.0, s)
    lateral = (1 + u) ** -0.5
    sutures = [Suture(f"s{i}", corner, [1.0 + L, corner[1] * lateral, corner[2] * lateral], shortening=s,
                      anchored=True) for i, corner in enumerate(CORNERS)]
    scene, final = pulled_block(block_mesh, sutures)
    assert final["probes"]["corner"][0] == pytest.approx(u, rel=1e-5)
    assert final["sutures"]["s0"]["tension"] == pytest.approx(k * (s - u), rel=1e-5)
    # the consistent tangent: Newton converges quadratically
    norms = scene.newton.residual_norms
    assert norms[-1] < 1e-9 * norms[0] and len(norms) <= 6


# a bite on each face, across element boundaries: the end is the mean of its points
BITES = (np.stack([np.ones(9), np.linspace(0.1, 0.9, 9), np.linspace(0.2, 0.7, 9)], axis=1),
         np.stack([np.linspace(0.15, 0.85, 8), np.full(8, 0.3), np.ones(8)], axis=1))


@pytest.mark.parametrize("surfaces, ends", [((None, None), ([1.0, 1.0, 1.0], [1.0, 0.25, 1.0])),
                                            (("x1", "z1"), ([1.0, 0.8, 0.55], [0.7, 0.3, 1.0])),
                                            (("x1", "z1"), BITES)], ids=["nodes", "between nodes", "bites"])
def test_suture_between_two_points_is_in_balance(block_mesh, surfaces, ends):
    """A suture tying two points of a block, neither on a support, pulls them together with
    equal and opposite forces: the supports carry nothing. Tied between nodes (the points on
    the surfaces x1 and z1, MaterialPoint), each end's force is shared by the nodes of its
    element in the proportions that interpolate its position, so the string's forces stay in
    balance, moments included; so with each end spread over a bite, a line of points across
    several elements."""
    suture = Suture("tie", *ends, tension=0.02, first_surface=surfaces[0], second_surface=surfaces[1])
    scene = ef.Scene("tie", block_mesh((2, 4, 2)), {"solid": ef.NeoHooke(0.5)}, features=SYMMETRY + [suture],
                     probes={"a": [1.0, 1.0, 1.0], "b": [1.0, 0.25, 1.0]})
    final = scene.run()["steps"][-1]
    for support in ("x0", "y0", "z0"):
        assert np.allclose(final["reactions"][support], 0.0, atol=1e-12)
    assert final["sutures"]["tie"]["length"] < suture.initial_length  # the ends moved toward each other
    if surfaces[0] is None:
        assert final["probes"]["a"][1] < 0  # the corner moved toward the other end


@pytest.mark.parametrize("a, b", [([1.0, 0.3, 0.6], [0.35, 1.0, 0.2]), (BITES[0], BITES[1][:, [0, 2, 1]])],
                         ids=["points", "bites"])
def test_suture_ends_between_nodes_move_with_their_elements(block_mesh, a, b):
    """Four strings of tension T pull the corners of the face x = 1 along +x, a uniaxial stretch
    lambda (analytic.uniaxial_nominal_stress); a fifth string of no tension ties two points of the
    faces x1 and y1 that lie between the nodes of the 2 x 1 x 1 block (the nearest nodes 0.5 and 0.25
    away), or two bites on them, each the mean of a line of points across the block's elements. Its
    ends move with the homogeneous deformation F = diag(lambda, lambda^-1/2, lambda^-1/2) that the
    trilinear elements interpolate exactly, and so does a mean of points: its length is
    |F (b - a)|, a and b the ends' (mean) points."""
    T = 0.05
    sutures = [Suture(f"s{i}", corner, [1e6, corner[1], corner[2]], tension=T, anchored=True)
               for i, corner in enumerate(CORNERS)]
    probe = Suture("probe", a, b, tension=0.0, first_surface="x1", second_surface="y1")
    _, final = pulled_block(block_mesh, sutures + [probe])
    a, b = np.mean(np.atleast_2d(a), axis=0), np.mean(np.atleast_2d(b), axis=0)
    stretch = brentq(lambda lam: uniaxial_nominal_stress(lam, C) - 4 * T, 1.0, 3.0)
    F = np.diag([stretch, stretch**-0.5, stretch**-0.5])
    assert probe.initial_length == pytest.approx(np.linalg.norm(b - a), rel=1e-12)
    assert final["sutures"]["probe"]["length"] == pytest.approx(np.linalg.norm(F @ (b - a)), rel=1e-8)


def test_free_band_shrinks_by_the_reduction():
    """A free thin ring (t/R = 0.02) whose rest length is shortened by Delta settles at the
    circumference C - Delta (exact for a thin ring; the thickness adds O((t/R)^2))."""
    R, t = 10.0, 0.2
    mesh = built_mesh(build_band, MPI.COMM_WORLD, inner_radius=R, thickness=t, width=0.5, z_center=0.25,
                      n_circ=16, n_thick=2, n_width=2, sector=90.0)
    band = BandTightening("band", 0.1 * 2 * np.pi * (R + t / 2))
    scene = ef.Scene("ring", mesh, {"band": ef.NeoHooke(0.3)},
                     features=[ef.Dirichlet("band_cut_0", {"y": 0.0}), ef.Dirichlet("band_cut_1", {"x": 0.0}),
                               ef.Dirichlet("band_back", {"z": 0.0}), band],
                     probes={"mid": [R + t / 2, 0.0, 0.0]}, solver=ef.SolverSettings(increments=2))
    final = scene.run()["steps"][-1]
    report = final["bands"]["band"]
    assert report["circumference"] == pytest.approx(report["initial_circumference"] - band.reduction, rel=1e-4)
    assert R + t / 2 + final["probes"]["mid"][0] == pytest.approx(0.9 * (R + t / 2), rel=1e-3)


def test_bilateral_sutures_also_push(block_mesh):
    """A total force F pulls the face x = 1 toward far anchors: four bilateral strings
    (k = EA / L each, sutures.SUTURE_EA = 40) get shorter and push back, so
    F = P(1 + u) + 4 k u with P the uniaxial nominal stress; a one-way string would go slack."""
    L, F = 1000.0, 0.3
    k = 40.0 / L
    u = brentq(lambda u: uniaxial_nominal_stress(1 + u, C) + 4 * k * u - F, 0.0, 1.0)
    lateral = (1 + u) ** -0.5
    sutures = [Suture(f"s{i}", corner, [1.0 + L, corner[1] * lateral, corner[2] * lateral], shortening=0.0,
                      anchored=True, bilateral=True) for i, corner in enumerate(CORNERS)]
    _, final = pulled_block(block_mesh, sutures + [ef.NodalForce([F, 0.0, 0.0], surface="x1")])
    assert final["probes"]["corner"][0] == pytest.approx(u, rel=1e-5)
    assert final["sutures"]["s0"]["tension"] == pytest.approx(-k * u, rel=1e-4)


def test_a_tension_loop_holds_at_rest_until_its_step(block_mesh):
    """Four bilateral tension-driven strings on the face x = 1, toward far anchors along +x, pulling
    in the second step: in the first a force F pushes the face away from the anchors and the loops,
    tied at rest, hold it as stiff strings (k = EA / L), F = 4 k u - P(1 - u) (P the uniaxial
    nominal stress, negative in compression, u the face's shortening); in the second each pulls with
    its tension T alone, Newton converging quadratically (a consistent tangent):
    P(1 + u) = 4 T - F. Without the hold nothing but the block would carry the first step's load,
    and a buckle held by such loops alone would float off the sclera (features/sutures.py). The
    anchors sit on the lines the corners end on in the second step, so those strings end axial; in
    the first they tilt by 6e-5, which moves the face by about 1e-4 of u."""
    L, F, T = 1000.0, 0.02, 0.05
    k = SUTURE_EA / L
    pushed = brentq(lambda u: -uniaxial_nominal_stress(1 - u, C) + 4 * k * u - F, 0.0, 0.5)
    pulled = brentq(lambda u: uniaxial_nominal_stress(1 + u, C) - (4 * T - F), 0.0, 1.0)
    lateral = (1 + pulled) ** -0.5
    sutures = [Suture(f"s{i}", corner, [1.0 + L, corner[1] * lateral, corner[2] * lateral], tension=T, anchored=True,
                      bilateral=True, step=1) for i, corner in enumerate(CORNERS)]
    scene = ef.Scene("held", block_mesh((2, 1, 1)), {"solid": ef.MooneyRivlin(C)},
                     features=SYMMETRY + sutures + [ef.NodalForce([-F, 0.0, 0.0], surface="x1")],
                     probes={"corner": [1.0, 1.0, 1.0]}, steps=[ef.Step("push"), ef.Step("pull")],
                     solver=ef.SolverSettings(increments=2, reuse_contraction=0.0))
    push, pull = scene.run()["steps"]
    norms = scene.newton.residual_norms
    assert norms[-1] < 1e-9 * norms[0] and len(norms) <= 6
    assert push["probes"]["corner"][0] == pytest.approx(-pushed, rel=1e-3)
    assert push["sutures"]["s0"]["tension"] == pytest.approx(k * pushed, rel=1e-3)
    assert pull["probes"]["corner"][0] == pytest.approx(pulled, rel=1e-6)
    assert pull["sutures"]["s0"]["tension"] == pytest.approx(T)


def test_tied_loop_resists_a_slide_across_its_string(block_mesh):
    """A bilateral suture between two nodes, its second end moved: its force on that end is minus
    the gradient of Pi = k/2 (l - l_0)^2 + k_s/2 (s . (u_b - u_a))^2 (sutures.py: s = E x N / |E x N|,
    N = X_a / |X_a| here, k_s = SLIDE_STIFFNESS k), and its tangent the Hessian, both checked
    against central differences of that potential written out here; a slide along s alone meets
    k_s."""
    solid = MixedSolid(block_mesh((2, 2, 2)), {"solid": ef.NeoHooke(0.5)})
    a, b = np.array([1.0, 0.0, 0.0]), np.array([1.0, 1.0, 1.0])
    suture = Suture("s", a, b, shortening=0.0, bilateral=True)
    suture.setup(solid)
    suture.set_load_factor(0.0)
    k = SUTURE_EA / np.sqrt(2.0)
    s = np.cross(b - a, a) / np.linalg.norm(np.cross(b - a, a))

    def potential(ub):
        return (0.5 * k * (np.linalg.norm(b + ub - a) - np.sqrt(2.0)) ** 2
                + 0.5 * SLIDE_STIFFNESS * k * (s @ ub) ** 2)

    def pulled(ub):
        """The force the suture puts on its second end with that end displaced by ub."""
        if solid.comm.rank == suture.b.owner:
            solid.w.x.array[suture.b.local] = ub
        suture.state_changed()
        return np.array(suture.report()["force_on_second"])

    ub, h = np.array([0.01, -0.02, 0.015]), 1e-6
    unit = np.eye(3)
    gradient = np.array([(potential(ub + h * e) - potential(ub - h * e)) / (2 * h) for e in unit])
    assert pulled(ub) == pytest.approx(-gradient, rel=1e-6, abs=1e-9)
    pulled(ub)
    hessian = np.array([(pulled(ub - h * e) - pulled(ub + h * e)) / (2 * h) for e in unit]).T
    pulled(ub)
    assert sum(suture._blocks()) == pytest.approx(hessian, rel=1e-5, abs=1e-7)
    # slid by 1e-3 along s (across the string, which lengthens by 1e-6 / 2 l_0 only): held back by k_s
    assert s @ pulled(1e-3 * s) == pytest.approx(-SLIDE_STIFFNESS * k * 1e-3, rel=1e-3)


def test_tied_loop_holds_the_buckle_base_it_is_given(block_mesh):
    """A bilateral suture whose loop holds another node h of the body of its second end (a
    buckle's base under the string's end b: features/sutures.py): its potential is
    k/2 (l - l_0)^2 + k_s/2 (s . (u_h - u_a))^2, so moving h alone along s meets k_s there and
    leaves the string's force on b at zero; the body of b and h takes the hold's force, and the
    first end the opposite (a pair: no net force). The hold's tangent block is k_s s s^T."""
    solid = MixedSolid(block_mesh((2, 2, 2)), {"solid": ef.NeoHooke(0.5)})
    a, b, h = np.array([1.0, 0.0, 0.0]), np.array([1.0, 1.0, 1.0]), np.array([0.5, 1.0, 1.0])
    suture = Suture("s", a, b, shortening=0.0, bilateral=True, hold=h)
    suture.setup(solid)
    suture.set_load_factor(0.0)
    k = SUTURE_EA / np.sqrt(2.0)
    s = np.cross(b - a, a) / np.linalg.norm(np.cross(b - a, a))
    assert suture.h.reference == pytest.approx(h) and suture.b.reference == pytest.approx(b)
    uh = 1e-3 * s + np.array([0.0, 2e-3, 0.0])  # slid along s, and moved along the string's plane
    if solid.comm.rank == suture.h.owner:
        solid.w.x.array[suture.h.local] = uh
    suture.state_changed()
    assert suture.length == pytest.approx(np.sqrt(2.0), rel=1e-12)  # the string's ends did not move
    assert suture.report()["force_on_second"] == pytest.approx(-SLIDE_STIFFNESS * k * (s @ uh) * s, rel=1e-9)
    string, hold = suture._blocks()
    assert string @ s == pytest.approx(np.zeros(3), abs=1e-12)  # at rest: no stiffness across the string
    assert hold == pytest.approx(SLIDE_STIFFNESS * k * np.outer(s, s), rel=1e-12)


def test_a_bite_is_in_the_scene_fingerprint():
    """A checkpoint is resumed only by the scene that wrote it (output/fingerprint.py): two buckle
    sutures that differ only in their bites' length (so in their ends' points, more than fit in a
    fingerprint entry by entry) have fingerprints that differ at the end's points."""
    from eyeball_fenicsx.meshing.builders.buckled_eye import suture_points
    from eyeball_fenicsx.output.fingerprint import attributes, first_difference

    def described(bite):
        point = suture_points({"n_circ": 16, "sector_deg": 180.0}, bite=bite)[0]
        suture = Suture(point["name"], point["sclera_bite"], point["buckle_bite"], shortening=0.1,
                        first_surface="sclera_outer", second_surface="band_outer")
        return {"suture": attributes(suture)}
    assert first_difference(described(3.0), described(3.0)) is None
    assert first_difference(described(3.0), described(2.0)).startswith("suture.first_point")


@pytest.mark.parametrize("ends, options, fragment", [
    ((BITES[0], [0.0, 0.0, 0.0]), {}, "first is 9 points .a bite.: give the surface"),
    (([1.0, 0.5, 0.5], BITES[1]), {"first_surface": "x1", "anchored": True}, "second is 8 points"),
    (([1.0, 0.5], [0.0, 0.0, 0.0]), {}, "first must be a point"),
])
def test_a_bite_needs_its_surface(ends, options, fragment):
    """A bite's points are spread over the elements of the surface they are on: given without it (or
    as an anchored end, a point in space), a suture is refused with a line that says which end."""
    with pytest.raises(SceneError, match=fragment):
        Suture("s", *ends, tension=0.1, **options)

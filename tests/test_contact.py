"""Contact kinematics against finite differences, and contact against closed forms."""
import gmsh
import numpy as np
import pytest
from mpi4py import MPI

import eyeball_fenicsx as ef
from eyeball_fenicsx.analytic import hertz_layer_force
from eyeball_fenicsx.contact import (
    ContactPair,
    Cylinder,
    Quad,
    RigidContact,
    Sphere,
    Triangle,
    candidate_pairs,
    patches,
    pressure,
    project,
    traction,
)
from eyeball_fenicsx.contact.policy import PENALTY_FACTOR
from eyeball_fenicsx.meshing.builders.hexes import HEXAHEDRON, QUADRANGLE, boundary_quads, hex_grid
from eyeball_fenicsx.meshing.load import built_mesh
from eyeball_fenicsx.output.console import increment_lines

_SIDES = {"x0": "u-", "x1": "u+", "y0": "v-", "y1": "v+", "z0": "w-", "z1": "w+"}


def build_blocks(blocks):
    """gmsh model of separate boxes of hexahedra (rank 0, gmsh initialized).

    Args:
        blocks: ``[(region, xs, ys, zs), ...]``, the node coordinates along each axis of each
            box; surfaces ``"<region>_x0"`` (the face x = xs[0]) ... ``"<region>_z1"``.
    """
    gmsh.model.add("blocks")
    node, element = 1, 1
    for volume, (region, *axes) in enumerate(blocks, start=1):
        axes = [np.asarray(a, dtype=float) for a in axes]
        nodes = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        hexes = hex_grid(np.arange(len(nodes)).reshape([len(a) for a in axes]))
        surfaces = [(100 * volume + i, f"{region}_{name}", boundary_quads(hexes, side))
                    for i, (name, side) in enumerate(_SIDES.items())]
        for tag, _, _ in surfaces:
            gmsh.model.addDiscreteEntity(2, tag)
        gmsh.model.addDiscreteEntity(3, volume, [tag for tag, _, _ in surfaces])
        gmsh.model.mesh.addNodes(3, volume, np.arange(node, node + len(nodes)), nodes.ravel())
        hexes = hexes.reshape(-1, 8) + node
        gmsh.model.mesh.addElementsByType(volume, HEXAHEDRON, np.arange(element, element + len(hexes)), hexes.ravel())
        element += len(hexes)
        gmsh.model.addPhysicalGroup(3, [volume], volume)
        gmsh.model.setPhysicalName(3, volume, region)
        for tag, name, quads in surfaces:
            gmsh.model.mesh.addElementsByType(tag, QUADRANGLE, np.arange(element, element + len(quads)),
                                              (quads + node).ravel())
            element += len(quads)
            gmsh.model.addPhysicalGroup(2, [tag], tag)
            gmsh.model.setPhysicalName(2, tag, name)
        node += len(nodes)
    gmsh.model.mesh.reclassifyNodes()


def blocks_mesh(*blocks, comm=MPI.COMM_WORLD):
    """One distributed mesh of several boxes, see :func:`build_blocks`."""
    return built_mesh(build_blocks, comm, blocks=list(blocks))


def graded(length, fine, n_fine, n_coarse):
    """Nodes on [0, length]: n_fine equal cells on [0, fine], then n_coarse cells growing
    geometrically from that size to fill the rest."""
    h = fine / n_fine
    lo, hi = 1.0, 10.0
    for _ in range(100):  # bisection for the growth ratio q: h (q + q^2 + ... + q^n) = length - fine
        q = 0.5 * (lo + hi)
        lo, hi = (lo, q) if h * q * (q**n_coarse - 1) / (q - 1) > length - fine else (q, hi)
    coarse = fine + h * np.cumsum(q ** np.arange(1, n_coarse + 1))
    return np.concatenate([np.linspace(0.0, fine, n_fine + 1), coarse[:-1], [length]])


def uniaxial_stress(c10, stretch):
    """Nominal stress of incompressible neo-Hooke in uniaxial tension/compression,
    P = 2 c10 (lambda - lambda^-2) (Ogden, Non-linear Elastic Deformations, 1984, sect. 7.2)."""
    return 2 * c10 * (stretch - stretch**-2)


# -- (a) kinematics ---------------------------------------------------------------------------
def _warped_grid():
    """A 3 x 3 patch of warped quadrilaterals (16 nodes) and the same split into triangles."""
    rng = np.random.default_rng(3)
    xs = np.linspace(0.0, 3.0, 4)
    X = np.array([[x, y, 0.1 * np.sin(x + 2 * y)] for y in xs for x in xs]) + 0.05 * rng.standard_normal((16, 3))
    quads = np.array([[4 * j + i, 4 * j + i + 1, 4 * (j + 1) + i + 1, 4 * (j + 1) + i]
                      for j in range(3) for i in range(3)])
    return X, quads, np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


@pytest.mark.parametrize("smoothing", [0.0, 0.02], ids=["sharp", "smoothed"])
@pytest.mark.parametrize("kind", [Quad, Triangle], ids=["bilinear-quad", "triangle"])
def test_projection_and_traction_tangent_are_the_derivatives(kind, smoothing):
    """The gap g_n along the master's interpolated nodal normal, the normal n and the foot's
    shape functions N_a, as functions of the slave facet's and the master patch's node
    positions, and the traction residual r = -W p(g_n) Gamma built from them: their analytic
    derivatives against central differences (truncation O(h^2) ~ 1e-12, round-off ~ 1e-10)."""
    X, quads, triangles = _warped_grid()
    segments = quads if kind is Quad else triangles
    patch = patches(segments, X)
    s = 4  # the middle quadrilateral (or a triangle of the middle), whose patch is complete
    slave = np.array([[1.2, 1.05, -0.05], [1.9, 1.1, -0.02], [1.8, 1.9, 0.03], [1.1, 1.8, -0.04]])
    N_s = Quad.shape(Quad.gauss_points)[0]
    rows = patch.rows(np.full(4, s))
    alpha, W = 3.0, np.array([0.2, 0.3, 0.25, 0.15])

    def run(q, derivatives=False):
        q = q.reshape(-1, 3)
        return project(N_s @ q[:4], N_s, np.repeat(q[None, 4:], 4, axis=0), rows, kind, derivatives)

    def residual(q):
        proj = run(q, True)
        p, k = pressure(proj.g, np.full(4, 0.01), np.full(4, alpha), smoothing)
        return traction(W, p, k, proj, N_s, patch.nodes.shape[1])

    q0 = np.vstack([slave, X[patch.nodes[s]]]).ravel()
    proj = run(q0, True)
    assert np.any(proj.g < 0) and np.any(proj.inside)  # points in contact, on the segment
    h = 1e-6

    def fd(f):
        return np.moveaxis(np.array([(f(q0 + h * e) - f(q0 - h * e)) / (2 * h) for e in np.eye(q0.size)]), 0, -1)

    assert np.abs(fd(lambda q: run(q).g) - proj.dg).max() < 1e-9
    assert np.abs(fd(lambda q: run(q).normal) - proj.dnormal).max() < 1e-9
    assert np.abs(fd(lambda q: run(q).N) - proj.dN).max() < 1e-9
    r, K = residual(q0)
    assert np.abs(fd(lambda q: residual(q)[0]) - K).max() < 1e-9 * np.abs(K).max()


def test_normal_field_is_continuous_across_a_fold():
    """A point 0.05 below the fold between two segments, along the fold's nodal normal,
    projects on both segments to the same foot on their common edge, with the same gap and
    normal: the interpolated nodal normal is continuous, while the two facets' own normals
    differ there by the fold angle; the nodal normal bisects the fold."""
    fold = 0.4  # radians: the second facet, as long as the first, rises at this angle
    c, s = 1 + np.cos(fold), np.sin(fold)
    X = np.array([[0, 0, 0], [1, 0, 0], [c, 0, s], [0, 1, 0], [1, 1, 0], [c, 1, s]], dtype=float)
    quads = np.array([[0, 1, 4, 3], [1, 2, 5, 4]])
    patch = patches(quads, X)
    bisector = np.array([-np.sin(fold / 2), 0.0, np.cos(fold / 2)])
    point = np.array([[1.0, 0.5, 0.0]]) - 0.05 * bisector
    results = [project(point, np.ones((1, 1)), X[patch.nodes[seg]][None], patch.rows(np.array([seg])), Quad)
               for seg in (0, 1)]
    for result in results:
        assert result.inside[0]
        assert result.g[0] == pytest.approx(-0.05, rel=1e-10)
        assert result.normal[0] == pytest.approx(bisector, abs=1e-12)


def test_smoothed_law_is_the_penalty_away_from_contact():
    """Deep in (g << -delta) the smoothed pressure is the sharp -alpha g plus the exponentially
    small alpha delta log(1 + exp(g/delta)); far out (g >> delta) it is alpha delta exp(-g/delta);
    its stiffness k = -dp/dg (central differences)."""
    alpha, delta = np.array([2.0, 2.0]), 0.01
    g = np.array([-0.2, 0.2])
    p, k = pressure(g, np.zeros(2), alpha, delta)
    assert p[0] == pytest.approx(-alpha[0] * g[0], rel=1e-9)
    assert p[1] == pytest.approx(alpha[1] * delta * np.exp(-g[1] / delta), rel=1e-8)
    g = np.array([-0.003, 0.004])
    h = 1e-7
    dp = (pressure(g + h, np.full(2, 0.01), alpha, delta)[0]
          - pressure(g - h, np.full(2, 0.01), alpha, delta)[0]) / (2 * h)
    assert -dp == pytest.approx(pressure(g, np.full(2, 0.01), alpha, delta)[1], rel=1e-7)


def test_a_touching_point_has_the_penalty_stiffness_at_zero_pressure():
    """At g = 0 with no multiplier the sharp law presses with p = 0. A point that touches (a
    clearance closed at the start, ``ContactPair``'s adjust) takes the stiffness of the side it
    is pressed into, -dp/dg from g < 0 (alpha): Newton's first step sees the surfaces press; one
    that does not, the open side's (0)."""
    alpha, h = np.array([3.0, 3.0]), 1e-6
    p, k = pressure(np.zeros(2), np.zeros(2), alpha, 0.0, np.array([True, False]))
    pressed = pressure(np.full(2, -h), np.zeros(2), alpha, 0.0)[0]
    opened = pressure(np.full(2, h), np.zeros(2), alpha, 0.0)[0]
    assert np.all(p == 0.0)
    assert k[0] == pytest.approx((pressed[0] - p[0]) / h, rel=1e-9)
    assert k[1] == pytest.approx(-(opened[1] - p[1]) / h, abs=1e-12)


@pytest.mark.parametrize("shape, point", [
    (Sphere([0, 0, 0], 1.0), [0.5, 0.4, 0.3]),
    (Sphere([0, 0, 0], 1.0, inside=True), [0.8, 0.7, 0.3]),
    (Cylinder([0, 0, 0], [0, 0.3, 1], 1.0), [0.5, 0.4, 0.3]),
    (Cylinder([0, 0, 0], [0, 0.3, 1], 1.0, inside=True), [0.9, 0.6, 0.3]),
], ids=["sphere", "sphere-inside", "cylinder", "cylinder-inside"])
def test_rigid_gap_gradient_and_curvature(shape, point):
    """grad g and Hess g of the rigid shapes (which give the exact nodal tangent) against
    central differences."""
    x, h = np.array([point], dtype=float), 1e-6
    g, grad, hess = shape.gap(x, np.zeros(3))
    assert g[0] < 0  # the test points penetrate
    grad_fd = [(shape.gap(x + h * e, 0)[0] - shape.gap(x - h * e, 0)[0]) / (2 * h) for e in np.eye(3)]
    hess_fd = [(shape.gap(x + h * e, 0)[1] - shape.gap(x - h * e, 0)[1]) / (2 * h) for e in np.eye(3)]
    assert np.ravel(grad_fd) == pytest.approx(grad[0], abs=1e-9)
    assert np.array(hess_fd)[:, 0] == pytest.approx(hess[0], abs=1e-8)


def test_bucket_search_finds_exactly_the_brute_force_pairs():
    rng = np.random.default_rng(3)
    points = rng.random((400, 3))
    lo = rng.random((300, 3)) * 0.9
    hi = lo + 0.02 + 0.1 * rng.random((300, 3))
    point, box = candidate_pairs(points, lo, hi)
    inside = np.all((points[:, None] >= lo[None]) & (points[:, None] <= hi[None]), axis=2)
    assert sorted(zip(point, box)) == sorted(zip(*np.nonzero(inside)))


# -- (b) the contact patch test on non-matching meshes: tests/test_contact_convergence.py


# -- (c) rigid plane --------------------------------------------------------------------------
def _pressed_block(mesh, c10, d, **penalty):
    """The unit cube of neo-Hookean c10 on rollers (x0, y0, z0) pressed by a rigid plane moved
    down by d onto its top z1, in two increments: (its contact report, the top's stretch)."""
    plane = RigidContact("press", "z1", "plane", point=[0, 0, 1], normal=[0, 0, -1], displacement=[0, 0, -d],
                         **penalty)
    scene = ef.Scene("plane", mesh, {"solid": ef.NeoHooke(c10)},
                     features=[ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}),
                               ef.Dirichlet("z0", {"z": 0.0}), plane],
                     probes={"top": [1.0, 1.0, 1.0]}, solver=ef.SolverSettings(increments=2))
    final = scene.run()["steps"][-1]
    return final, 1 + final["probes"]["top"][2]


def test_rigid_plane_compresses_a_block_homogeneously(block_mesh):
    """A rigid plane moved down by d on the unit cube (rollers on x0, y0, z0): uniaxial
    compression, nominal stress P = 2 c10 (lambda - lambda^-2), lambda = 1 - d: the augmented
    Lagrangian leaves no penetration to speak of (it stops when its updates move the surface
    by less than 1e-3 of the top elements' depth, 1/3: AUGMENT_DEPTH)."""
    c10, d = 0.5, 0.2
    final, stretch = _pressed_block(block_mesh((2, 2, 3)), c10, d)
    contact = final["contact"]["press"]
    assert contact["force"][2] == pytest.approx(uniaxial_stress(c10, stretch), rel=1e-8)  # exact: homogeneous
    assert stretch == pytest.approx(1 - d + contact["max_penetration"], rel=1e-10)
    assert contact["max_penetration"] < 1e-3 / 3
    assert final["reactions"]["z0"][2] == pytest.approx(-contact["force"][2], rel=1e-8)  # in balance
    assert contact["active_nodes"] == 9


def test_penalty_from_the_scene_is_reported_and_leaves_no_penetration(block_mesh):
    """penalty = 50 MPa/mm, per unit area: reported as given; augmented, it leaves no
    penetration to speak of."""
    plane = RigidContact("press", "z1", "plane", penalty=50.0, point=[0, 0, 1], normal=[0, 0, -1],
                         displacement=[0, 0, -0.1])
    scene = ef.Scene("plane", block_mesh((1, 1, 2)), {"solid": ef.NeoHooke(0.5)},
                     features=[ef.Dirichlet("x0", {"x": 0.0}), ef.Dirichlet("y0", {"y": 0.0}),
                               ef.Dirichlet("z0", {"z": 0.0}), plane], solver=ef.SolverSettings(increments=1))
    contact = scene.run()["steps"][-1]["contact"]["press"]
    assert contact["penalty"] == 50.0
    assert contact["max_penetration"] < 1e-3 / 2  # of the element's depth, 1/2 (AUGMENT_DEPTH)


@pytest.mark.parametrize("make, message", [
    (lambda: RigidContact("c", "z1", "cone", center=[0, 0, 0], radius=1.0),
     r"contact 'c': unknown rigid shape 'cone'; choose one of \['cylinder', 'plane', 'sphere'\]"),
    (lambda: RigidContact("c", "z1", "sphere", center=[0, 0, 0]),
     r"contact 'c': rigid sphere: .*missing 1 required positional argument: 'radius'"),
    (lambda: RigidContact("c", "z1", "sphere", center=[0, 0, 0], radius=-1.0),
     r"contact 'c': rigid sphere: radius must be a positive number, got -1\.0"),
    (lambda: RigidContact("c", "z1", "plane", point=[0, 0, 0], normal=[0, 0, 0]),
     r"contact 'c': rigid plane: plane normal must be a non-zero vector of three numbers, got \[0, 0, 0\]"),
    (lambda: RigidContact("c", "z1", "plane", point=[0, 0, 0], normal=[0, 0, 1], penalty=0.0),
     r"contact 'c': penalty must be a positive number \(pressure per unit penetration\), got 0\.0"),
    (lambda: ContactPair("c", "z1", "z1"), r"contact 'c': slave and master are both 'z1'; name two surfaces"),
], ids=["unknown-shape", "missing-radius", "negative-radius", "zero-normal", "zero-penalty", "self"])
def test_invalid_contact_is_a_scene_error(make, message):
    with pytest.raises(ef.SceneError, match=message):
        make()


# -- (d) Hertz ----------------------------------------------------------------------------------
def test_hertz_rigid_sphere_on_incompressible_half_space():
    """Rigid sphere (R = 10) pressed d = 0.1 into an incompressible neo-Hooke half-space:
    F = 4/3 E* R^1/2 d^3/2 with E* = E / (1 - nu^2) = 4 mu (nu = 1/2), i.e.
    F = 16/3 mu R^1/2 d^3/2 (Johnson, Contact Mechanics, 1985, eq. 4.23), mu = 2 c10.

    Quarter model (symmetry x0, y0; the sphere's centre on the edge x = y = 0) of a block
    30 a deep and wide, a = (R d)^1/2 the contact radius, on a roller base, graded from
    7 elements across 1.3 a to the far boundary. The block is a layer of depth L on a frictionless
    base, which multiplies the force by 1 + 0.884 chi + 0.781 chi^2 + 0.386 chi^3 + 0.0048 chi^4,
    chi = a / L (Dimitriadis et al., Biophys. J. 82 (2002) 2798, eq. 11, non-bonded, nu = 1/2):
    3.0 % at d. Against that, the final force within 2 %, the error of Q1/P0 with 7 elements across
    1.3 a (tests/test_contact_convergence.py: +1.0 % on 5, -0.7 % on 7); the increments before
    the last carry the penalty's penetration (the augmented Lagrangian completes at the step's
    end; one update per increment before it) and fewer elements across their smaller a: within
    3 % with a penalty of 30 E / h (ten times the default, which gives -10 % at the first)."""
    c10, R, d = 0.5, 10.0, 0.1
    a = np.sqrt(R * d)
    L = 30 * a
    xs = graded(L, 1.3 * a, 7, 7)
    zs = L - xs[::-1]
    penalty = 10 * PENALTY_FACTOR * 6 * c10 / (zs[-1] - zs[-2])
    sphere = RigidContact("sphere", "solid_z1", "sphere", center=[0, 0, L + R], radius=R, displacement=[0, 0, -d],
                          penalty=penalty)
    curve = []
    scene = ef.Scene("hertz", blocks_mesh(("solid", xs, xs, zs)), {"solid": ef.NeoHooke(c10)},
                     features=[ef.Dirichlet("solid_x0", {"x": 0.0}), ef.Dirichlet("solid_y0", {"y": 0.0}),
                               ef.Dirichlet("solid_z0", {"z": 0.0}), sphere],
                     solver=ef.SolverSettings(increments=4, growth=1.0))
    with increment_lines(lambda line: curve.append((-sphere.shift[2], -4 * sphere.report()["force"][2]))):
        scene.run()
    depth, force = np.array(curve).T
    hertz = hertz_layer_force(2 * c10, R, depth, L)
    assert force[-1] == pytest.approx(hertz[-1], rel=0.02), force / hertz
    assert force[1:] == pytest.approx(hertz[1:], rel=0.03), force / hertz
    slope = np.log(force[-1] / force[1]) / np.log(depth[-1] / depth[1])
    assert slope == pytest.approx(1.5, abs=0.05)


# -- (e) sliding --------------------------------------------------------------------------------
def slide(solver):
    """A block pressed onto a longer one and dragged 1.5 along it (4.5 master elements, 10 slave
    elements); returns the last step of the summary and every increment's residual history."""

    def n(k, lo=0.0, hi=1.0):
        return np.linspace(lo, hi, k + 1)

    mesh = blocks_mesh(("lower", n(9, 0, 3), n(3), n(2, 0, 0.5)), ("upper", n(4, 0, 0.6), n(4), n(2, 0.5, 1.0)))
    histories = []
    scene = ef.Scene("slide", mesh, {"lower": ef.NeoHooke(0.5), "upper": ef.NeoHooke(0.5)},
                     features=[ef.Dirichlet("lower_z0", {"x": 0.0, "y": 0.0, "z": 0.0}),
                               ef.Dirichlet("lower_y0", {"y": 0.0}), ef.Dirichlet("upper_y0", {"y": 0.0}),
                               ef.Dirichlet("upper_z1", {"x": 1.5, "z": -0.05}),
                               ContactPair("slide", slave="upper_z0", master="lower_z1")],
                     probes={"corner": [0.6, 1.0, 1.0]}, solver=solver)
    with increment_lines(lambda line: histories.append(list(scene.newton.residual_norms))):
        final = scene.run()["steps"][-1]
    return final, histories


@pytest.fixture(scope="module")
def slid_in_small_increments():
    """1/16 of a master element per increment, a fresh tangent every Newton step: the
    convergence rate is the point here."""
    return slide(ef.SolverSettings(increments=24, growth=1.0, reuse_contraction=0.0))


def test_sliding_block_crosses_many_master_elements_with_quadratic_newton(slid_in_small_increments):
    """Frictionless, so the contact force stays normal and balances the base's reaction, and
    Newton converges quadratically once the active set settles."""
    final, histories = slid_in_small_increments
    contact, reactions = final["contact"]["slide"], final["reactions"]
    assert final["probes"]["corner"][0] == pytest.approx(1.5)
    assert reactions["lower_z0"][2] == pytest.approx(-reactions["upper_z1"][2], rel=1e-7)
    assert contact["force"][2] == pytest.approx(reactions["lower_z0"][2], rel=1e-7)
    # frictionless, yet the block ploughs through the dent it makes: a drag of 0.9 % of the
    # normal force, carried by the supports
    assert contact["force"][0] == pytest.approx(reactions["lower_z0"][0], rel=1e-7)
    assert abs(contact["force"][0]) < 0.02 * contact["force"][2]
    assert contact["max_penetration"] < 0.02 * 0.15  # 1.2 % of a slave element, at its trailing edge
    assert max(len(h) - 1 for h in histories) <= 6
    # quadratic convergence: r_(k+1) / r_k^2 stays bounded while above roundoff
    for history in histories[1:]:
        r = np.array(history) / history[0]
        pairs = [(r[k], r[k + 1]) for k in range(len(r) - 1) if r[k + 1] > 1e-12]
        for before, after in pairs[1:]:
            assert after < 10 * before**2


def test_block_dragged_past_its_search_in_one_increment_ends_where_small_increments_do(slid_in_small_increments):
    """Dragged 1.5 in one increment, the points move six times the search's reach (half the
    master's segment size, 0.7 of its edge): the converged state's check searches again
    and solves again. Without it every point would have lost its candidates and the block would
    sink into the base with no contact force. An elastic, frictionless state does not depend on
    the path: the forces are those of 24 increments, to the augmented Lagrangian's tolerance."""
    final, _ = slide(ef.SolverSettings(increments=1))
    small = slid_in_small_increments[0]
    assert len(final["increments"]) == 1  # converged without a cut-back
    assert final["contact"]["slide"]["force"][2] == pytest.approx(small["contact"]["slide"]["force"][2], rel=1e-4)
    assert final["contact"]["slide"]["active_points"] == small["contact"]["slide"]["active_points"]


@pytest.mark.parametrize("penalty", [1e0, 1e1, 1e2, 1e3, 1e4, 1e5])
def test_penalties_over_five_decades_converge(block_mesh, penalty):
    """A rigid plane pushed d = 0.1 into the unit cube: every penalty from 1 to 1e5 MPa/mm
    (the default here is about 9) converges, the augmented Lagrangian leaves no penetration
    to speak of, and the stress is the uniaxial closed form P = 2 c10 (lambda - lambda^-2) at
    lambda = 1 - d + g."""
    c10, d = 0.5, 0.1
    final, stretch = _pressed_block(block_mesh((1, 1, 2)), c10, d, penalty=penalty)
    contact = final["contact"]["press"]
    assert contact["max_penetration"] < 1e-3 / 2  # of the element's depth, 1/2 (AUGMENT_DEPTH)
    assert stretch == pytest.approx(1 - d + contact["max_penetration"], rel=1e-8)
    assert contact["force"][2] == pytest.approx(uniaxial_stress(c10, stretch), rel=1e-8)

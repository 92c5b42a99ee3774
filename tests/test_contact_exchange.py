"""The contact search's bounding-box exchange (contact/master.py) against every master segment on
every rank, as the search had it before: the same contact residual, tangent and report."""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from test_contact import blocks_mesh

import eyeball_fenicsx as ef
from eyeball_fenicsx.contact import ContactPair


def _contact_terms(pair, problem):
    """The pair's residual (a global vector, the owned entries) and tangent (its Frobenius norm and
    the product with a fixed vector) at the current state."""
    b = problem.b.duplicate()
    b.set(0.0)
    pair.add_to_residual(b)
    b.assemble()
    A = problem.A.duplicate()
    A.zeroEntries()
    pair.add_to_jacobian(A)
    A.assemble()
    x, y = A.createVecs()
    x.setArray(np.cos(np.arange(*x.getOwnershipRange())))
    A.mult(x, y)
    return b.array.copy(), A.norm(PETSc.NormType.FROBENIUS), y.array.copy()


def test_the_exchange_gives_the_forces_of_the_whole_master_surface():
    """A long block pressed on another and dragged along it (the slave's Gauss points over 2 to 3
    master segments each): the contact terms from the segments each rank receives equal those
    from the whole master surface on every rank, and (on more than one rank) no rank needs all."""
    def axis(k, lo, hi):
        return np.linspace(lo, hi, k + 1)

    mesh = blocks_mesh(("lower", axis(12, 0, 4), axis(2, 0, 1), axis(1, 0, 0.5)),
                       ("upper", axis(13, 0, 4), axis(3, 0, 1), axis(1, 0.5, 1.0)))
    pair = ContactPair("slide", slave="upper_z0", master="lower_z1", penalty=100.0)  # few augmentations
    scene = ef.Scene("exchange", mesh, {"lower": ef.NeoHooke(0.5), "upper": ef.NeoHooke(0.5)},
                     features=[ef.Dirichlet("lower_z0", {"x": 0.0, "y": 0.0, "z": 0.0}),
                               ef.Dirichlet("upper_z1", {"x": 0.1, "y": 0.0, "z": -0.02}), pair],
                     solver=ef.SolverSettings(increments=1))
    summary = scene.run()
    assert summary["ok"]
    comm = MPI.COMM_WORLD
    received = comm.allreduce(len(pair.table.segments), op=MPI.SUM)
    if comm.size > 1:
        assert received < comm.size * pair.master.count
    exchanged = _contact_terms(pair, scene.problem)
    report = pair.report()
    assert report["active_points"] > 0

    # the reference: every rank receives every segment (its slave box covers the model)
    exchange = pair.master.exchange
    far = np.array([[-1e3, -1e3, -1e3], [1e3, 1e3, 1e3]])
    pair.master.exchange = lambda points, corners, reach: exchange(np.vstack([points, far]), corners, reach)
    pair._search()
    assert len(pair.table.segments) == pair.master.count
    whole = _contact_terms(pair, scene.problem)
    scale = np.abs(whole[0]).max()
    assert np.allclose(exchanged[0], whole[0], rtol=0.0, atol=1e-13 * scale)
    assert exchanged[1] == whole[1] or abs(exchanged[1] - whole[1]) < 1e-13 * whole[1]
    assert np.allclose(exchanged[2], whole[2], rtol=0.0, atol=1e-13 * np.abs(whole[2]).max())
    again = pair.report()  # the same points and nodes loaded, the same force and deepest penetration
    for key in ("active_points", "active_nodes"):
        assert again[key] == report[key]
    assert np.allclose(again["force"], report["force"], rtol=0.0, atol=1e-13 * np.linalg.norm(report["force"]))
    assert abs(again["max_penetration"] - report["max_penetration"]) < 1e-13  # mm, on blocks 1 mm high


def test_the_matrix_pattern_outlives_the_search_it_was_made_from():
    """A search that finds fewer candidates keeps the matrix (its pattern has room for them), but
    its table may no longer hold the master nodes of the old pattern: the pattern's dofs must
    still be those the matrix was made for, since another contact feature may ask for a new
    matrix before this one does (in a whole eye, the retina's pair after the band's)."""
    def axis(k, lo, hi):
        return np.linspace(lo, hi, k + 1)

    mesh = blocks_mesh(("lower", axis(6, 0, 2), axis(2, 0, 1), axis(1, 0, 0.5)),
                       ("upper", axis(5, 0, 2), axis(3, 0, 1), axis(1, 0.5, 1.0)))
    pair = ContactPair("touch", slave="upper_z0", master="lower_z1")
    scene = ef.Scene("pattern", mesh, {"lower": ef.NeoHooke(0.5), "upper": ef.NeoHooke(0.5)},
                     features=[ef.Dirichlet("lower_z0", {"x": 0.0, "y": 0.0, "z": 0.0}), pair])
    scene.build()
    comm = MPI.COMM_WORLD
    w, made_for = pair.solid.w, [array.copy() for array in pair.coupling()]
    for _ in range(10):  # the slave surface lifted off the master, 0.2 at a time
        w.x.array[pair.facet_dofs[..., 2]] += 0.2
        if comm.allreduce(pair.begin_increment(), op=MPI.LOR):  # a new matrix, made for these candidates
            made_for = [array.copy() for array in pair.coupling()]
    assert comm.allreduce(len(made_for[0]), op=MPI.SUM) > 0
    assert comm.allreduce(len(pair.table.segments), op=MPI.SUM) == 0  # 2 off: none left near
    assert all(np.array_equal(a, b) for a, b in zip(made_for, pair.coupling()))

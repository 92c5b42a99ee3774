"""A scene assembles only what it holds: no cavity, contact or suture, no cost for them."""
import numpy as np
from dolfinx.fem.petsc import assemble_matrix
from mpi4py import MPI
from petsc4py import PETSc

import eyeball_fenicsx as ef
from eyeball_fenicsx.features.cavity import LiquidCavity

SYMMETRY = [ef.Dirichlet("sym_x", {"x": 0.0}), ef.Dirichlet("sym_y", {"y": 0.0}), ef.Dirichlet("sym_z", {"z": 0.0})]


def assembled(scene):
    problem = scene.problem
    problem.begin_step(0)
    problem.set_load_factor([1.0] * len(problem.features))
    problem.state_to_vector(problem.x)
    problem.F(None, problem.x, problem.b)
    problem.J(None, problem.x, problem.A, problem.A)
    info = problem.A.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)
    return problem.A.getSize()[0], int(info["nz_used"]), int(info["nz_allocated"])


def test_bare_scene_is_the_plain_hyperelastic_system(sphere_mesh):
    """Without cavities, contact or sutures the Newton matrix is exactly DOLFINx's matrix
    of the mixed u-p form: same size, same nonzeros, nothing allocated beyond them."""
    scene = ef.Scene("bare", sphere_mesh(n=4, layers=2), {"wall": ef.NeoHooke(0.5)},
                     features=SYMMETRY + [ef.Pressure("inner", 0.1)]).build()
    assert not scene.problem.global_unknowns and not scene.problem.nodal_residuals and scene.problem.m == 0
    size, used, allocated = assembled(scene)
    reference = assemble_matrix(scene.problem.J_form, scene.problem.bcs)
    reference.assemble()
    info = reference.getInfo(PETSc.Mat.InfoType.GLOBAL_SUM)
    assert (size, used) == (reference.getSize()[0], int(info["nz_used"]))
    assert allocated == used


def test_a_cavity_adds_one_border_over_its_wetted_dofs(sphere_mesh):
    """The liquid's global pressure adds one row and one column, nonzero only on the
    displacement dofs of the wetted surface (3 per node), plus its diagonal entry."""
    mesh = sphere_mesh(n=4, layers=2)
    bare = ef.Scene("bare", mesh, {"wall": ef.NeoHooke(0.5)}, features=SYMMETRY + [ef.Pressure("inner", 0.1)]).build()
    cavity = LiquidCavity("liquid", "inner", 10.0, symmetry=["x", "y", "z"])
    filled = ef.Scene("filled", mesh, {"wall": ef.NeoHooke(0.5)}, features=SYMMETRY + [cavity]).build()
    bare_size, bare_nnz, _ = assembled(bare)
    size, nnz, _ = assembled(filled)
    wetted = MPI.COMM_WORLD.allreduce(len(cavity.wetted), op=MPI.SUM)
    n = 4
    assert wetted == 3 * (3 * n * n + 3 * n + 1)  # nodes on the octant's inner surface (3 n^2 + 3 n + 1)
    assert size == bare_size + 1
    assert nnz == bare_nnz + 2 * wetted + 1
    assert np.isfinite(filled.problem.b.norm())

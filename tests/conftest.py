"""Shared fixtures: meshes built in memory on rank 0 and distributed over the test's ranks."""
import os

import pytest
from mpi4py import MPI

from eyeball_fenicsx.meshing.builders.block import build_block
from eyeball_fenicsx.meshing.builders.sphere_octant import build_sphere_octant
from eyeball_fenicsx.meshing.load import built_mesh

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture
def block_mesh():
    """Factory: the box [0, L]^3 in hexahedra, surfaces x0, x1, y0, y1, z0, z1."""
    def make(divisions=(2, 2, 2), lengths=(1.0, 1.0, 1.0), comm=MPI.COMM_WORLD, region="solid"):
        return built_mesh(build_block, comm, lengths=lengths, divisions=divisions, region=region)
    return make


@pytest.fixture
def sphere_mesh():
    """Factory: the octant of a thick spherical shell, surfaces inner, outer, sym_x/y/z."""
    def make(n=4, layers=2, inner_radius=1.0, outer_radius=2.0, comm=MPI.COMM_WORLD, grading=1.0):
        return built_mesh(build_sphere_octant, comm, inner_radius=inner_radius, outer_radius=outer_radius,
                          n=n, layers=layers, grading=grading)
    return make


@pytest.fixture
def shared_tmp(tmp_path):
    """A temporary folder that is the same on every rank (rank 0's)."""
    return MPI.COMM_WORLD.bcast(str(tmp_path), root=0)


def on_rank0(task, *args, **kwargs):
    """Run ``task(*args, **kwargs)`` on rank 0 only (it writes files, starts a process, checks a
    gathered array) and give every rank its result; if it fails, every rank fails, so that no rank
    is left waiting in a collective."""
    result = failure = None
    if MPI.COMM_WORLD.rank == 0:
        try:
            result = task(*args, **kwargs)
        except Exception as error:
            failure = repr(error)
    result, failure = MPI.COMM_WORLD.bcast((result, failure), root=0)
    if failure:
        raise RuntimeError(f"on rank 0: {failure}")
    return result

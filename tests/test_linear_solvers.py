"""The linear solvers of the Newton steps (system/linear_solvers.py) give the same converged answer:
the coarse eye at rest brought to its pressure with MUMPS with block low-rank compression
("mumps-blr") predicts what plain MUMPS predicts, to 1e-6 relative. The reference is another
solver (an exact LU / LDL^T factorization), not a number from the code's output; the two can
differ only by what the BLR compression drops (CNTL(7)), which Newton's residual tolerances
must absorb.
"""
import os

import pytest
from conftest import REPO

from eyeball_fenicsx.scene.loader import load_scene

SCENE = os.path.join(REPO, "demos", "eye_at_rest.toml")
COARSE = {"mesh.n_circ": 16}
MEASURES = ("axial_length_mm", "axial_length_change_from_mesh_mm", "iop_mmHg")


def _eye(linear):
    """The eye measures and increments after the eye at rest's step, with the linear solver ``linear``."""
    scene = load_scene(SCENE, overrides=COARSE, linear=linear)
    step = scene.run()["steps"][-1]
    return step["eye"], step["increments"]


@pytest.fixture(scope="module")
def mumps():
    return _eye("mumps")


def test_blr_predicts_what_mumps_predicts(mumps):
    eye, increments = _eye("mumps-blr")
    reference, _ = mumps
    for key in MEASURES:
        assert eye[key] == pytest.approx(reference[key], rel=1e-6), key
    for tissue, stress in reference["max_mises_MPa"].items():
        assert eye["max_mises_MPa"][tissue] == pytest.approx(stress, rel=1e-6), tissue
    # MUMPS reported its memory (INFOG(21), MB) and no Krylov iterations
    assert all(i["mumps_memory_MB"] > 0 and i["krylov_iterations"] == 0 for i in increments)

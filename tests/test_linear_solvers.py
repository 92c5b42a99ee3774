"""The linear solvers of the Newton steps (system/linear_solvers.py) give the same converged answer:
the coarse eye at rest brought to its pressure with MUMPS with block low-rank compression
("mumps-blr") predicts what plain MUMPS predicts, to 1e-6 relative; so does the Newton-Krylov
path ("iterative": FGMRES with the augmented-Lagrangian preconditioner), on the coarse eye of the
surgeon's scene filled to its pressure with the band on it (demos/encircling_buckle.toml) and on
the thick incompressible sphere (demos/thick_sphere.toml). The reference is another solver (an
exact LU / LDL^T factorization), not a number from the code's output; the two can differ only by
what the BLR compression drops (CNTL(7)) or the Krylov solves leave (their relative tolerance
1e-8), which Newton's residual tolerances must absorb, and, with contact, by where the
augmentations stop (the closing step, with a factorization only, changes the path of the
iterative solver's Newton steps through a contact onset; 1e-6 still holds on the coarse eye).
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


def _agree(eye, reference):
    for key in MEASURES:
        assert eye[key] == pytest.approx(reference[key], rel=1e-6), key
    for tissue, stress in reference["max_mises_MPa"].items():
        assert eye["max_mises_MPa"][tissue] == pytest.approx(stress, rel=1e-6), tissue


def test_blr_predicts_what_mumps_predicts(mumps):
    eye, increments = _eye("mumps-blr")
    _agree(eye, mumps[0])
    # MUMPS reported its memory (INFOG(21), MB) and no Krylov iterations
    assert all(i["mumps_memory_MB"] > 0 and i["krylov_iterations"] == 0 for i in increments)


def test_iterative_path_on_the_coarse_buckled_eye_predicts_what_mumps_predicts():
    """The surgeon's scene's first step on the coarse eye: the calibrated tissues (shear moduli
    550 times apart), thin layers, three bordered cavities, the band in contact with the sclera."""
    runs = {}
    for linear in ("mumps", "iterative"):
        scene = load_scene(os.path.join(REPO, "demos", "encircling_buckle.toml"), overrides=COARSE, linear=linear)
        scene.steps = scene.steps[:1]  # "pressurize"
        runs[linear] = scene.run()["steps"][-1]
    _agree(runs["iterative"]["eye"], runs["mumps"]["eye"])
    assert runs["iterative"]["eye"]["buckle_height_mm"] == pytest.approx(runs["mumps"]["eye"]["buckle_height_mm"],
                                                                         rel=1e-6)
    # Krylov iterations were counted; the factorization of the displacement block alone took
    # less memory than MUMPS' of the whole matrix
    memory = {linear: max(i["mumps_memory_MB"] for i in run["increments"]) for linear, run in runs.items()}
    assert all(i["krylov_iterations"] > 0 for i in runs["iterative"]["increments"])
    assert 0 < memory["iterative"] < memory["mumps"]


def test_iterative_path_on_the_thick_sphere_predicts_what_mumps_predicts():
    """Inner and outer radial displacements of the incompressible neo-Hookean sphere under inner
    pressure (Ogden's closed form is the demo's check), Newton-Krylov against MUMPS."""
    path = os.path.join(REPO, "demos", "thick_sphere.toml")
    runs = {linear: load_scene(path, linear=linear).run() for linear in ("mumps", "iterative")}
    probes = {linear: run["steps"][-1]["probes"] for linear, run in runs.items()}
    for name, displacement in probes["mumps"].items():
        assert probes["iterative"][name][0] == pytest.approx(displacement[0], rel=1e-6), name
    increments = [i for step in runs["iterative"]["steps"] for i in step["increments"]]
    assert all(i["krylov_iterations"] > 0 for i in increments)

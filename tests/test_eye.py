"""The eye model at rest: it reaches its IOP, and the answer does not depend on the ranks."""
import os

import pytest
from mpi4py import MPI

from conftest import REPO
from eyeball_fenicsx.scenefile import load_scene

SCENE = os.path.join(REPO, "demos", "eye_at_rest.toml")


def at_rest(comm):
    scene = load_scene(SCENE, comm, overrides={"mesh.n_circ": 16})
    scene.log = lambda message: None
    return scene.run()["steps"][-1]


def test_eye_at_rest_on_one_and_two_ranks():
    together = at_rest(MPI.COMM_WORLD)
    alone = at_rest(MPI.COMM_SELF)
    eye, cavities = together["eye"], together["cavities"]
    # filled to 15 mmHg = 0.002 MPa (1 MPa = 7500.62 mmHg)
    assert eye["iop_mmHg"] == pytest.approx(15.0, rel=1e-3)
    assert cavities["aqueous"]["pressure"] == pytest.approx(0.002, rel=1e-3)
    # the vitreous cavity of the model holds 5.3 mL unloaded (in-vivo MRI of emmetropic
    # eyes: 5.41 +- 0.32 mL, Feng et al. 2011); filling to IOP adds a little
    assert 4.0e3 < cavities["vitreous"]["initial_volume"] < 6.0e3
    assert cavities["vitreous"]["volume"] > cavities["vitreous"]["initial_volume"]
    # the pressurized eye is longer, by much less than its 24 mm
    assert 0 < eye["axial_length_change_mm"] < 2.0
    # the same on one rank
    for key in ("axial_length_mm", "iop_mmHg"):
        assert alone["eye"][key] == pytest.approx(eye[key], rel=1e-8)
    for tissue, value in eye["max_mises_MPa"].items():
        assert alone["eye"]["max_mises_MPa"][tissue] == pytest.approx(value, rel=1e-6)

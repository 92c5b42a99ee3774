"""Every demo is also a test: it runs in this process (on the test's MPI ranks) and its
results are checked against the closed forms or the physics it prints."""
import os
import runpy

import pytest
from mpi4py import MPI

from conftest import REPO

# demo -> (environment for a quick run, [(result variable, upper bound or (lower, upper))])
DEMOS = {
    # thick sphere, 768 Q1/P0 hexahedra: ~1.2% of the radial displacement (falls as h^2)
    "thick_sphere.py": ({}, [("error", 0.015)]),
    # liquid-filled thin sphere through the pressure maximum: ~0.1% of the peak pressure
    "liquid_sphere.py": ({}, [("error", 0.005)]),
    # rigid sphere on an incompressible block: Hertz F = 16/3 mu R^1/2 d^3/2 within 3%
    "hertz_indentation.py": ({}, [("error", 0.03)]),
    # the eye filled to 15 mmHg; after injecting and withdrawing 60 microlitres an elastic
    # eye is back at its IOP and axial length (to the solver's tolerance)
    "eye_at_rest.py": ({"EYE_N_CIRC": "16"}, [("iop_error", 0.01), ("back_to_rest", 1e-6)]),
    # the encircling buckle's three steps on a coarse eye: contact and sutures hold the band, exactly
    # along x and z, and along y to Laplace's law for its hoop tension (1.9 % on this mesh); the
    # buckle pushes the choroid onto the retina, and most of the detachment closes (24 % stays open)
    "encircling_buckle.py": ({"EYE_N_CIRC": "16", "DEMO_COMM": "self"},
                             [("balance_error", 1e-6), ("hoop_error", 0.05), ("still_detached", 0.5)]),
    # a segmental tire pressed in by its sutures on a coarse eye: contact and sutures hold it,
    # exactly along x and z, and the sutures indent the sclera (0.11 mm more on this mesh)
    "segmental_buckle.py": ({"EYE_N_CIRC": "16"}, [("balance_error", 1e-6), ("indentation", (0.05, 1.0))]),
}


def test_every_demo_is_listed():
    demos = sorted(f for f in os.listdir(os.path.join(REPO, "demos")) if f.endswith(".py"))
    assert demos == sorted(DEMOS)


RESULTS = {}  # demo -> its variables, for the tests below that compare runs


def run_demo(demo, environment, out, monkeypatch):
    monkeypatch.setenv("DEMO_OUT", out)
    for key, value in environment.items():
        monkeypatch.setenv(key, value)
    return runpy.run_path(os.path.join(REPO, "demos", demo), run_name="__main__")


@pytest.mark.parametrize("demo", sorted(DEMOS))
def test_demo(demo, shared_tmp, monkeypatch):
    environment, checks = DEMOS[demo]
    result = RESULTS[demo] = run_demo(demo, environment, shared_tmp, monkeypatch)
    for variable, bound in checks:
        low, high = bound if isinstance(bound, tuple) else (float("-inf"), bound)
        assert low < result[variable] < high, variable


def test_encircling_buckle_agrees_on_one_and_two_ranks(shared_tmp, monkeypatch):
    """The operation on the coarse eye, each rank alone (test_demo) and both ranks together: the
    same predictions, to the solver's tolerance and the penalty's, well within 1 %."""
    environment = DEMOS["encircling_buckle.py"][0]
    alone = RESULTS.get("encircling_buckle.py") or run_demo("encircling_buckle.py", environment,
                                                           os.path.join(shared_tmp, "alone"), monkeypatch)
    together = run_demo("encircling_buckle.py", {**environment, "DEMO_COMM": "world"},
                        os.path.join(shared_tmp, "together"), monkeypatch)
    assert together["comm"].size == MPI.COMM_WORLD.size
    for key in ("axial_length_change_mm", "iop_mmHg", "buckle_height_mm", "detached_area_mm2"):
        assert together["final"]["eye"][key] == pytest.approx(alone["final"]["eye"][key], rel=0.01), key
    assert together["still_detached"] == pytest.approx(alone["still_detached"], abs=0.01)

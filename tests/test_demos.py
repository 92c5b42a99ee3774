"""Every demo is also a test: it runs in this process (on the test's MPI ranks) and its
result is checked against the closed form it prints."""
import os
import runpy

import pytest

from conftest import REPO

# demo -> (result variable, bound): the demos compute their error against closed forms
DEMOS = {
    # thick sphere, 768 Q1/P0 hexahedra: ~1.2% of the radial displacement (falls as h^2)
    "thick_sphere.py": ("error", 0.015),
    # liquid-filled thin sphere through the pressure maximum: ~0.1% of the peak pressure
    "liquid_sphere.py": ("error", 0.005),
}


def test_every_demo_is_listed():
    demos = sorted(f for f in os.listdir(os.path.join(REPO, "demos")) if f.endswith(".py"))
    assert demos == sorted(DEMOS)


@pytest.mark.parametrize("demo", sorted(DEMOS))
def test_demo(demo, shared_tmp, monkeypatch):
    monkeypatch.setenv("DEMO_OUT", shared_tmp)
    variable, bound = DEMOS[demo]
    result = runpy.run_path(os.path.join(REPO, "demos", demo), run_name="__main__")
    assert result[variable] < bound

"""The planning sweep (eyeball_fenicsx/scene/sweep.py): its inputs are checked before any variant
runs, and a sweep that was stopped resumes: the variants that are done are not run again, the
one that was stopped continues from its checkpoint, and the table is the uninterrupted one.
"""
import json
import os

import pytest
from mpi4py import MPI

from eyeball_fenicsx.errors import Interrupted, SceneError
from eyeball_fenicsx.scene.scene import Scene
from eyeball_fenicsx.scene.sweep import run_sweep
from eyeball_fenicsx.system.signals import StopRequests

COMM = MPI.COMM_WORLD

# The block of two cells (one per rank) on rollers, pulled along x in a first step and squeezed
# along y in a second, one increment each: a variant stopped between them has a checkpoint.
SCENE = """
[mesh]
builder = "block"
divisions = [2, 1, 1]
[materials.solid]
model = "neo-hooke"
c10 = 0.5
[[step]]
name = "pull"
increments = 1
[[step]]
name = "squeeze"
increments = 1
[[dirichlet]]
surface = "x0"
x = 0.0
[[dirichlet]]
surface = "y0"
y = 0.0
[[dirichlet]]
surface = "z0"
z = 0.0
[[dirichlet]]
surface = "x1"
x = 0.1
step = "pull"
[[dirichlet]]
surface = "y1"
y = -0.05
step = "squeeze"
"""
PARAMETER, VALUES = "dirichlet.3.x", (0.1, 0.2, 0.3)


@pytest.fixture
def scene_path(shared_tmp):
    path = os.path.join(shared_tmp, "block.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write(SCENE)
    COMM.barrier()
    return path


def read_summary(folder):
    with open(os.path.join(folder, "summary.json")) as f:
        return json.load(f)


def stopping_in(folder_name, monkeypatch):
    """Make ``Scene.run`` into the folder ``folder_name`` stop after its first step, as if a
    signal had come during it (``StopRequests.requested`` names none before the first step, and
    one from then on: the steps here converge in one increment, so it is next asked before the
    second step)."""
    run = Scene.run

    def run_and_stop(self, out_dir=None, resume=False):
        if os.path.basename(out_dir) != folder_name:
            return run(self, out_dir, resume)
        asked = []

        def requested(self):
            asked.append(True)
            return "SIGTERM" if len(asked) > 1 else None

        with monkeypatch.context() as patch:
            patch.setattr(StopRequests, "requested", requested)
            return run(self, out_dir, resume)

    monkeypatch.setattr(Scene, "run", run_and_stop)


def test_a_stopped_sweep_resumes(scene_path, shared_tmp, monkeypatch):
    whole = run_sweep(scene_path, PARAMETER, VALUES, os.path.join(shared_tmp, "whole"))
    out = os.path.join(shared_tmp, "stopped")
    with monkeypatch.context() as patch:
        stopping_in("01", patch)
        with pytest.raises(Interrupted):
            run_sweep(scene_path, PARAMETER, VALUES, out)
    assert read_summary(os.path.join(out, "00"))["state"] == "done"
    stopped = read_summary(os.path.join(out, "01"))
    assert stopped["state"] == "interrupted" and [s["name"] for s in stopped["steps"]] == ["pull"]
    assert not os.path.exists(os.path.join(out, "02"))
    first = os.path.join(out, "00", "summary.json")
    before = os.stat(first).st_mtime_ns, open(first).read()
    COMM.barrier()

    resumed = run_sweep(scene_path, PARAMETER, VALUES, out, resume=True)
    assert (os.stat(first).st_mtime_ns, open(first).read()) == before  # the done variant was not run again
    again = read_summary(os.path.join(out, "01"))
    assert again["state"] == "done" and again["resumed"][0]["step"] == "squeeze"  # from its checkpoint
    assert read_summary(os.path.join(out, "02"))["state"] == "done"
    assert [row[PARAMETER] for row in resumed] == list(VALUES)
    for row, reference in zip(resumed, whole, strict=True):
        assert row.keys() == reference.keys() and row["ok"] is True
        for column, value in reference.items():
            if column != "wall_s" and not isinstance(value, bool):
                assert row[column] == pytest.approx(value, rel=1e-10, abs=1e-12), column
    # a second resume runs nothing: its rows are the summaries'
    assert [row["wall_s"] for row in run_sweep(scene_path, PARAMETER, VALUES, out, resume=True)] == \
        [read_summary(os.path.join(out, k))["wall_s"] for k in ("00", "01", "02")]


def test_resume_refuses_another_sweep(scene_path, shared_tmp):
    out = os.path.join(shared_tmp, "sweep")
    run_sweep(scene_path, PARAMETER, VALUES[:1], out)
    with pytest.raises(SceneError, match="cannot resume: the sweep in it varied 'dirichlet.3.x', not 'dirichlet.4.y'"):
        run_sweep(scene_path, "dirichlet.4.y", (-0.1,), out, resume=True)
    with pytest.raises(SceneError, match=r"variant 00 was done with dirichlet.3.x = 0.1, not 0.3"):
        run_sweep(scene_path, PARAMETER, (0.3,), out, resume=True)
    if COMM.rank == 0:
        with open(scene_path, "a") as f:
            f.write("[[probe]]\nname = \"corner\"\npoint = [1.0, 1.0, 1.0]\n")
    COMM.barrier()
    with pytest.raises(SceneError, match="cannot resume: the scene file has changed"):
        run_sweep(scene_path, PARAMETER, VALUES[:1], out, resume=True)


@pytest.mark.parametrize("values, message", [([], "give one or more values"),
                                             ([0.1, float("nan")], "finite numbers, got nan"),
                                             ([float("inf")], "finite numbers, got inf"),
                                             ([True], "finite numbers, got True")])
def test_values_must_be_finite_numbers(scene_path, shared_tmp, values, message):
    out = os.path.join(shared_tmp, "sweep")
    with pytest.raises(SceneError, match=message):
        run_sweep(scene_path, PARAMETER, values, out)
    assert not os.path.exists(out)  # checked before anything runs


def test_an_integer_entry_takes_whole_numbers(scene_path, shared_tmp):
    """The command line's values are floats: 3.0 for ``divisions = [2, 1, 1]``'s first entry is
    the integer 3 (the builder wants an integer), and each variant has that many cells."""
    out = os.path.join(shared_tmp, "sweep")
    rows = run_sweep(scene_path, "mesh.divisions.0", [2.0, 3.0], out)
    assert [row["ok"] for row in rows] == [True, True]
    assert [read_summary(os.path.join(out, k))["cells"] for k in ("00", "01")] == [2, 3]

"""The planning sweep (eyeball_fenicsx/scene/sweep.py): its inputs are checked before any variant
runs, and a sweep that was stopped resumes: the variants that are done are not run again, the
one that was stopped continues from its checkpoint, and the table is the uninterrupted one.
"""
import json
import os
import tomllib

import pytest
from mpi4py import MPI

from eyeball_fenicsx.errors import Interrupted, OutputError, SceneError
from eyeball_fenicsx.scene import sweep
from eyeball_fenicsx.scene.loader import load_scene
from eyeball_fenicsx.scene.scene import Scene
from eyeball_fenicsx.scene.sweep import run_sweep
from eyeball_fenicsx.scene.sweep_plan import plan_sweep
from eyeball_fenicsx.scene.tissues import TISSUE_SETS
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
GRID = {PARAMETER: VALUES}


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
    whole = run_sweep(scene_path, GRID, os.path.join(shared_tmp, "whole"))
    out = os.path.join(shared_tmp, "stopped")
    with monkeypatch.context() as patch:
        stopping_in("01", patch)
        with pytest.raises(Interrupted):
            run_sweep(scene_path, GRID, out)
    assert read_summary(os.path.join(out, "00"))["state"] == "done"
    stopped = read_summary(os.path.join(out, "01"))
    assert stopped["state"] == "interrupted" and [s["name"] for s in stopped["steps"]] == ["pull"]
    assert not os.path.exists(os.path.join(out, "02"))
    first = os.path.join(out, "00", "summary.json")
    before = os.stat(first).st_mtime_ns, open(first).read()
    COMM.barrier()

    resumed = run_sweep(scene_path, GRID, out, resume=True)
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
    assert [row["wall_s"] for row in run_sweep(scene_path, GRID, out, resume=True)] == \
        [read_summary(os.path.join(out, k))["wall_s"] for k in ("00", "01", "02")]


def test_resume_refuses_another_sweep(scene_path, shared_tmp):
    out = os.path.join(shared_tmp, "sweep")
    run_sweep(scene_path, {PARAMETER: VALUES[:1]}, out)
    with pytest.raises(SceneError, match="cannot resume: the sweep in it varied 'dirichlet.3.x', not 'dirichlet.4.y'"):
        run_sweep(scene_path, {"dirichlet.4.y": (-0.1,)}, out, resume=True)
    with pytest.raises(SceneError, match=r"variant 00 was done with dirichlet.3.x = 0.1, not dirichlet.3.x = 0.3"):
        run_sweep(scene_path, {PARAMETER: (0.3,)}, out, resume=True)
    if COMM.rank == 0:
        with open(scene_path, "a") as f:
            f.write("[[probe]]\nname = \"corner\"\npoint = [1.0, 1.0, 1.0]\n")
    COMM.barrier()
    with pytest.raises(SceneError, match="cannot resume: the scene file has changed"):
        run_sweep(scene_path, {PARAMETER: VALUES[:1]}, out, resume=True)


@pytest.mark.parametrize("values, message", [([], "give one or more values"),
                                             ([0.1, float("nan")], "finite numbers, got nan"),
                                             ([float("inf")], "finite numbers, got inf"),
                                             ([True], "finite numbers, got True")])
def test_values_must_be_finite_numbers(scene_path, shared_tmp, values, message):
    out = os.path.join(shared_tmp, "sweep")
    with pytest.raises(SceneError, match=message):
        run_sweep(scene_path, {PARAMETER: values}, out)
    assert not os.path.exists(out)  # checked before anything runs


def test_an_integer_entry_takes_whole_numbers(scene_path, shared_tmp):
    """The command line's values are floats: 3.0 for ``divisions = [2, 1, 1]``'s first entry is
    the integer 3 (the builder wants an integer), and each variant has that many cells."""
    out = os.path.join(shared_tmp, "sweep")
    rows = run_sweep(scene_path, {"mesh.divisions.0": [2.0, 3.0]}, out)
    assert [row["ok"] for row in rows] == [True, True]
    assert [read_summary(os.path.join(out, k))["cells"] for k in ("00", "01")] == [2, 3]


def test_a_sweep_picture_rank_0_cannot_draw_is_an_error_on_every_rank(scene_path, shared_tmp, monkeypatch):
    """Rank 0 draws sweep.png alone: its failure is an OutputError on every rank that names it,
    not the other ranks left waiting for rank 0, and the table it was drawn from is kept."""
    def unable(*args, **kwargs):
        raise ValueError("no room for the legend")
    monkeypatch.setattr(sweep, "plot_sweep", unable)
    out = os.path.join(shared_tmp, "sweep")
    with pytest.raises(OutputError, match="could not draw the sweep's pictures .*ValueError: no room for the legend"):
        run_sweep(scene_path, {PARAMETER: VALUES[:2]}, out)
    assert os.path.exists(os.path.join(out, "sweep.csv"))


# The grid and the bands. The unit cube on rollers pulled along x to the stretch l = 1 + x and then
# (the second step) squeezed along y to m = 0.95, the z faces free: in the incompressible
# neo-Hookean solid W = c10 (I1 - 3) the stretch along z is n = 1 / (l m), the stress along z is
# zero, and the force on the face x1 is its Cauchy stress 2 c10 (l^2 - n^2) times its area m n:
# F = 2 c10 (l^2 - n^2) m n = 2 c10 (l - n^2 / l) (Ogden, Non-linear Elastic Deformations,
# 1984, section 7.2). The deformation is homogeneous, so the two Q1 cells give it exactly.
C10 = "materials.solid.c10"
GRID2 = {PARAMETER: (0.1, 0.2), C10: (0.5, 1.0)}


def pull(x, c10):
    """The force on the face x1 (the closed form above)."""
    stretch, squeeze = 1.0 + x, 0.95
    across = 1.0 / (stretch * squeeze)
    return 2.0 * c10 * (stretch - across**2 / stretch)


def test_a_grid_row_per_point_each_the_closed_form(scene_path, shared_tmp):
    out = os.path.join(shared_tmp, "grid")
    rows = run_sweep(scene_path, GRID2, out)
    assert [(row[PARAMETER], row[C10]) for row in rows] == [(0.1, 0.5), (0.1, 1.0), (0.2, 0.5), (0.2, 1.0)]
    for row in rows:
        assert row["ok"] is True
        assert row["reactions.x1.0"] == pytest.approx(pull(row[PARAMETER], row[C10]), rel=1e-9)
    assert os.path.isfile(os.path.join(out, "sweep.png"))  # the contour plots
    with open(os.path.join(out, "sweep.csv")) as f:
        assert f.readline().startswith(f"{PARAMETER},{C10},ok,")
        assert len(f.readlines()) == 4


def test_bands_bracket_the_closed_forms_at_the_range_ends(scene_path, shared_tmp):
    """c10 in [0.4, 0.7] at each of two pulls: the force is proportional to c10, so its band is
    the closed form at the range's ends; the scene's own c10 = 0.5 is the row, inside the band."""
    out = os.path.join(shared_tmp, "bands")
    rows = run_sweep(scene_path, {PARAMETER: (0.1, 0.2)}, out, ranges=[(C10, 0.4, 0.7)])
    with open(os.path.join(out, "bands.csv")) as f:
        header, *lines = [line.strip().split(",") for line in f]
    bands = [dict(zip(header, line)) for line in lines]
    assert [float(band[PARAMETER]) for band in bands] == [0.1, 0.2]
    for row, band in zip(rows, bands, strict=True):
        x = row[PARAMETER]
        assert (band["corners"], band["corners_ok"]) == ("2", "2")
        assert float(band["reactions.x1.0.min"]) == pytest.approx(pull(x, 0.4), rel=1e-9)
        assert float(band["reactions.x1.0.max"]) == pytest.approx(pull(x, 0.7), rel=1e-9)
        assert row["reactions.x1.0"] == pytest.approx(pull(x, 0.5), rel=1e-9)
    assert sorted(d for d in os.listdir(out) if d[0].isdigit()) == ["00", "00-h", "00-l", "01", "01-h", "01-l"]


def test_a_stopped_grid_resumes(scene_path, shared_tmp, monkeypatch):
    """A grid of two parameters with a range (three runs a point) stopped in the second point's
    low corner: the resumed sweep runs the rest only, and its rows are the closed forms."""
    out, ranges = os.path.join(shared_tmp, "grid"), [(C10, 0.4, 0.7)]
    grid = {PARAMETER: (0.1, 0.2), "dirichlet.4.y": (-0.1,)}
    with monkeypatch.context() as patch:
        stopping_in("01-l", patch)
        with pytest.raises(Interrupted):
            run_sweep(scene_path, grid, out, ranges=ranges)
    assert read_summary(os.path.join(out, "01-l"))["state"] == "interrupted"
    assert not os.path.exists(os.path.join(out, "01-h"))
    first = os.path.join(out, "00-h", "summary.json")
    before = open(first).read()
    COMM.barrier()
    rows = run_sweep(scene_path, grid, out, resume=True, ranges=ranges)
    assert open(first).read() == before  # done: not run again
    assert read_summary(os.path.join(out, "01-l"))["resumed"][0]["step"] == "squeeze"
    assert [row[PARAMETER] for row in rows] == [0.1, 0.2]
    for row in rows:  # the squeeze is -0.1: the closed form with m = 1 + y
        stretch, squeeze = 1.0 + row[PARAMETER], 1.0 + row["dirichlet.4.y"]
        across = 1.0 / (stretch * squeeze)
        assert row["reactions.x1.0"] == pytest.approx(2 * 0.5 * (stretch - across**2 / stretch), rel=1e-9)
    with pytest.raises(SceneError, match=r"varied 'dirichlet.3.x' x 'dirichlet.4.y' x the range of "
                                         r"'materials.solid.c10', not 'dirichlet.3.x' x 'dirichlet.4.y'"):
        run_sweep(scene_path, grid, out, resume=True)


def test_a_range_reaches_the_tissue_set(shared_tmp):
    """``materials.sclera.c.10`` of an eye whose sclera comes from ``tissues = "calibrated"`` (the
    scene has no [materials.sclera]): the variant's sclera has that c10 and the set's c20."""
    with open(os.path.join(TISSUE_SETS, "calibrated.toml"), "rb") as f:
        sclera = tomllib.load(f)["materials"]["sclera"]["c"]
    path = os.path.join(shared_tmp, "eye.toml")
    if COMM.rank == 0:
        with open(path, "w") as f:
            f.write('tissues = "calibrated"\n[mesh]\nbuilder = "eye"\nsector_deg = 90\nn_circ = 16\n')
    COMM.barrier()
    assert plan_sweep(path, {}, [("materials.sclera.c.10", 0.5, 0.8)]).corners() == \
        [("l", {"materials.sclera.c.10": 0.5}), ("h", {"materials.sclera.c.10": 0.8})]
    law = load_scene(path, overrides={"materials.sclera.c.10": 0.5}).materials["sclera"]
    assert law.c == {(1, 0): 0.5, (2, 0): sclera["20"]}


def test_a_stopped_variant_of_another_grid_starts_again(scene_path, shared_tmp, monkeypatch):
    """The grid changed at a point that was stopped (0.2 there, now 0.3): that variant is not
    resumed from the other value's checkpoint but run from its first step; the point done stays."""
    out = os.path.join(shared_tmp, "changed")
    with monkeypatch.context() as patch:
        stopping_in("01", patch)
        with pytest.raises(Interrupted):
            run_sweep(scene_path, {PARAMETER: (0.1, 0.2)}, out)
    first = os.path.join(out, "00", "summary.json")
    before = open(first).read()
    COMM.barrier()
    rows = run_sweep(scene_path, {PARAMETER: (0.1, 0.3)}, out, resume=True)
    assert open(first).read() == before
    again = read_summary(os.path.join(out, "01"))
    assert again["state"] == "done" and "resumed" not in again
    assert rows[1]["reactions.x1.0"] == pytest.approx(pull(0.3, 0.5), rel=1e-9)

"""The run's page, report.html (eyeball_fenicsx/output/report.py), read as a browser reads it.

A coarse half eye with a band and a detachment (test_eye_measures.SCENE: two steps, one
increment each) is run three ways: to the end; stopped by a stop request after its first step,
then resumed; and a block whose second step cannot converge. Each page must parse as HTML with
its elements closed in order, embed every picture the run left in its folder (the same bytes,
one image each), show every eye measure of summary.json in its predictions table (each cell's
full value in its data-value, compared with the file, never with the report's own code) under
a readable name, and say the run's state. The page written after the first step, while the run
goes on, says "running" (a run killed outright keeps it).
"""
import base64
import json
import os
from html.parser import HTMLParser

import pytest
from mpi4py import MPI
from test_eye_measures import SCENE
from test_scenes import scene_file

from eyeball_fenicsx.errors import ConvergenceError, Interrupted
from eyeball_fenicsx.output.files import flatten
from eyeball_fenicsx.scene.loader import load_scene
from eyeball_fenicsx.system.signals import StopRequests

COMM = MPI.COMM_WORLD
VOID = {"meta", "img", "br", "hr", "link", "input"}  # HTML elements without an end tag
# A block pulled, then crushed to less than nothing: the second step cannot converge.
CRUSHED = ('name = "block-crushed"\n[mesh]\nbuilder = "block"\ndivisions = [2, 1, 1]\n'
           '[materials.solid]\nmodel = "neo-hooke"\nc10 = 0.5\n[[step]]\nname = "pull"\n[[step]]\nname = "crush"\n'
           + "".join(f'[[dirichlet]]\nsurface = "{a}0"\n{a} = 0.0\n' for a in "xyz")
           + '[[dirichlet]]\nsurface = "x1"\nx = 0.2\nstep = "pull"\n'
           '[[dirichlet]]\nsurface = "x1"\nx = -1.5\nstep = "crush"\n[solver]\nincrements = 1\nmax_cutbacks = 1\n')


class Page(HTMLParser):
    """What a browser would show of the page: its images, tables (rows of cells with their
    attributes and text), the text of the elements with an id, and whether it nests properly."""

    def __init__(self, text):
        super().__init__(convert_charrefs=True)
        self.images, self.tables, self.ids, self.open, self.errors = [], [], {}, [], []
        self._cell = self._id = None
        self.feed(text)
        self.close()

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag not in VOID:
            self.open.append(tag)
        if tag == "img":
            self.images.append(attrs["src"])
        elif tag == "table":
            self.tables.append([])
        elif tag == "tr":
            self.tables[-1].append([])
        elif tag in ("td", "th"):
            self._cell = {"attrs": attrs, "text": ""}
            self.tables[-1][-1].append(self._cell)
        if "id" in attrs:
            self._id = attrs["id"]
            self.ids[self._id] = ""

    def handle_endtag(self, tag):
        if not self.open or self.open.pop() != tag:
            self.errors.append(f"</{tag}> closes nothing open")
        if tag in ("td", "th"):
            self._cell = None
        if tag in ("span", "p"):
            self._id = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell["text"] += data
        if self._id is not None:
            self.ids[self._id] += data


def read_page(out):
    with open(os.path.join(out, "report.html"), encoding="utf-8") as f:
        page = Page(f.read())
    assert page.errors == [] and page.open == []  # every element closed, in order
    return page


def read_summary(out):
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def check_page(out, state):
    """The page in ``out`` against summary.json and the pictures there (rank 0)."""
    page, summary = read_page(out), read_summary(out)
    assert summary["state"] == state and page.ids["state"] == state
    # one embedded PNG per picture file of the run, byte for byte
    pictures = sorted(name for name in os.listdir(out) if name.endswith(".png"))
    embedded = [base64.b64decode(src.removeprefix("data:image/png;base64,")) for src in page.images]
    assert all(src.startswith("data:image/png;base64,") for src in page.images)
    files = []
    for name in pictures:
        with open(os.path.join(out, name), "rb") as f:
            files.append(f.read())
    assert sorted(embedded) == sorted(files) and len(embedded) == len(pictures)
    # the predictions table: a column per step, a row per eye measure, summary.json's values
    predictions = page.tables[0]
    assert [cell["text"] for cell in predictions[0][1:]] == [step["name"] for step in summary["steps"]]
    shown = {}
    for row in predictions[1:]:
        name = row[0]["text"]
        assert "_" not in name and "." not in name.split("(")[0], name  # a readable name, not a key
        for column, cell in enumerate(row[1:]):
            if "data-key" in cell["attrs"]:
                shown[(column, cell["attrs"]["data-key"])] = float(cell["attrs"]["data-value"])
    expected = {(column, f"eye.{key}"): value for column, step in enumerate(summary["steps"])
                for key, value in flatten(step["eye"]).items() if isinstance(value, (int, float))}
    assert shown == expected
    return page, summary, pictures


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return COMM.bcast(str(tmp_path_factory.mktemp("report")) if COMM.rank == 0 else None, root=0)


def test_the_page_of_a_run(folder):
    out = os.path.join(folder, "done")
    load_scene(scene_file(folder, SCENE, "done.toml"), COMM).run(out)
    if COMM.rank == 0:
        _, summary, pictures = check_page(out, "done")
        # the eye's outer surface, its section and the retina's gap after each step, and the measures
        kinds = ("surface", "section", "retina_gap")
        assert pictures == sorted([f"{kind}_{step}.png" for kind in kinds for step in ("at_rest", "inflate")]
                                  + ["eye_measures.png"])


def test_a_stopped_run_says_so_and_its_resumed_page_shows_every_step(folder, monkeypatch):
    out = os.path.join(folder, "stopped")
    asked, pages = [], []

    def requested(self):  # asked before each step and after each increment: stop after the first step
        asked.append(True)
        if len(asked) > 1 and COMM.rank == 0:
            pages.append(read_page(out).ids["state"])
        return "SIGTERM" if len(asked) > 1 else None

    scene = load_scene(scene_file(folder, SCENE, "stopped.toml"), COMM)
    with monkeypatch.context() as patch:
        patch.setattr(StopRequests, "requested", requested)
        with pytest.raises(Interrupted):
            scene.run(out)
    if COMM.rank == 0:
        assert pages[0] == "running"  # the page written after the first step, while the run went on
        page, summary, pictures = check_page(out, "interrupted")
        assert [step["name"] for step in summary["steps"]] == ["at rest"]
        assert "interrupted by SIGTERM" in page.ids["error"]
        assert not any("inflate" in name for name in pictures)
    scene.run(out, resume=True)
    if COMM.rank == 0:
        _, summary, _ = check_page(out, "done")
        assert [step["name"] for step in summary["steps"]] == ["at rest", "inflate"]


def test_a_failed_run_says_so(folder):
    out = os.path.join(folder, "failed")
    with pytest.raises(ConvergenceError):
        load_scene(scene_file(folder, CRUSHED, "crushed.toml"), COMM).run(out)
    if COMM.rank == 0:
        page, summary = read_page(out), read_summary(out)
        assert summary["state"] == "failed" and page.ids["state"] == "failed"
        assert "step 'crush' did not converge" in page.ids["error"]
        assert page.images == []  # no eye, no pictures
        solver = page.tables[-1]
        assert [cell["text"] for cell in solver[0]] == ["step", "pull", "crush (not converged)"]
        rows = {row[0]["text"]: row[1:] for row in solver[1:]}
        for column, step in enumerate(summary["steps"]):
            cell = rows["their Newton iterations"][column]
            assert int(cell["attrs"]["data-value"]) == sum(i["newton_iterations"] for i in step["increments"])

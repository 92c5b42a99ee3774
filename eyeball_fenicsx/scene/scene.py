"""A scene is one simulation: a mesh, region materials, features, probes, load steps and
observers.

Python API::

    from eyeball_fenicsx import Scene, NeoHooke, Dirichlet, Pressure, load_mesh
    scene = Scene("sphere", load_mesh("sphere.msh"), {"wall": NeoHooke(0.5)},
                  features=[Dirichlet("sym_x", {"x": 0}), Pressure("inner", 0.6)],
                  probes={"inner": [1.0, 0.0, 0.0]})
    summary = scene.run("out")

Only what the scene holds is assembled: a scene without cavities or contact solves
exactly the bare hyperelastic system.

Data path of a run: scene -> problem -> Newton per step -> observers -> outputs. ``build``
makes the solid (mechanics/solid.py) and the problem, the solid plus the scene's features
(system/problem.py), then sets up the observers (output/observer.py): they find what they
observe (a probe outside the mesh is an error here) and build their forms, once. ``run``
advances each step of the load path with Newton (system/stepping.py, system/newton.py); after
each step, converged or failed, the observers read the state: the probes, the reactions and the
features' reports (output/reports.py), then the scene's ``observers`` (the eye measures of a
scene file's ``[eye]`` table and their pictures: output/measures.py, output/eye_pictures.py; a
scene file's page of the run, last: output/report.py), then the field output of a run with an
output folder (output/files.py). They fill the step's entry of summary.json, which is written
after every step and at the end. A second ``run`` starts from the state the first left, with
the observers ``build`` set up. Each load increment is logged (output/console.py prints it on
rank 0).

A run that survives: summary.json's ``"state"`` is "running" until the last step converged
("done", the only state with ``"ok": true``), "failed" when a step did not converge, or
"interrupted" when a signal stopped the run (system/signals.py: at the next converged increment,
collectively). A run with an output folder writes a checkpoint after every converged step
(output/checkpoint.py); ``run(out_dir, resume=True)`` restores the last one and runs the steps
that remain, as the interrupted run would have.
"""
from __future__ import annotations

import dataclasses
import functools
import logging
import os
import re
import time
from typing import TYPE_CHECKING

from ..errors import ConvergenceError, Interrupted, SceneError
from ..mechanics.solid import MixedSolid
from ..output.checkpoint import Checkpoint, Saved
from ..output.console import print_on_rank0
from ..output.files import FieldOutput, write_json_atomic
from ..output.fingerprint import scene_fingerprint
from ..output.reports import FeatureReports, Probes
from ..system.newton import NewtonSolver
from ..system.problem import Problem
from ..system.settings import SolverSettings
from ..system.signals import StopRequests
from ..system.stepping import run_step

if TYPE_CHECKING:
    from collections.abc import Callable

    from ..meshing.load import MeshData
    from ..output.observer import Observer

log = logging.getLogger(__name__)


@dataclasses.dataclass
class Step:
    """One step of the load path: the features whose ``step`` is this one ramp in it."""

    name: str
    increments: int | None = None  # default: the solver's


@dataclasses.dataclass
class Scene:
    """One simulation.

    Args:
        name: the scene's name (in summary.json and the pictures' titles).
        mesh: the distributed mesh with its regions and surfaces (meshing/load.py).
        materials: {region: material law}.
        features: what acts on the solid (supports, loads, cavities, contact...), in this order.
        probes: {name: reference point} where the displacement is reported.
        steps: the load path.
        solver: the load stepping's settings.
        element: the mixed element, a name of ``mechanics.solid.ELEMENTS`` (None: by cell type).
        observers: what else reads the state after each step (``EyeMeasures``, then its
            ``EyePictures``), in this order; set up by ``build``, so give them before it.
    """

    name: str
    mesh: MeshData
    materials: dict
    features: list = dataclasses.field(default_factory=list)
    probes: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    steps: list[Step] = dataclasses.field(default_factory=lambda: [Step("load")])
    solver: SolverSettings = dataclasses.field(default_factory=SolverSettings)
    element: str | None = None
    observers: list[Observer] = dataclasses.field(default_factory=list)

    def __post_init__(self) -> None:
        for f in self.features:
            if not 0 <= f.step < len(self.steps):
                raise SceneError(f"{type(f).__name__} {f.name!r} ramps in step {f.step}, "
                                 f"but the scene has {len(self.steps)} step(s)")

    def build(self) -> Scene:
        """Create the solid, the Newton problem and the solver (compiles the forms), and set up
        the observers: the probes, the reports and the scene's ``observers``."""
        self.fingerprint  # noqa: B018 (taken now: of the scene as given, before its features are set up)
        self.solid = MixedSolid(self.mesh, self.materials, self.element)
        self.problem = Problem(self.solid, self.features)
        self.newton = NewtonSolver(self.problem, linear=self.solver.linear)
        self.reports = [Probes(self.probes), FeatureReports()]
        for observer in [*self.reports, *self.observers]:
            observer.setup(self.solid, self.problem)
        return self

    @functools.cached_property
    def fingerprint(self) -> dict:
        """What decides the scene's answer (output/fingerprint.py), taken once, before it is built."""
        return scene_fingerprint(self)

    def run(self, out_dir: str | None = None, resume: bool = False) -> dict:
        """Solve every step; write fields, summary.json and a checkpoint after each step into
        out_dir (if given).

        Args:
            out_dir: the output folder, or None (no files).
            resume: continue from the checkpoint in out_dir: the steps it holds are not run
                again. Without a checkpoint there, the run starts from the first step (and says so).

        Returns the summary dict. Raises ``ConvergenceError`` if a step fails and ``Interrupted``
        if a signal stops the run, after writing the summary ("failed" or "interrupted") with the
        last converged state; ``SceneError`` if the checkpoint to resume is damaged or another
        scene's (nothing in out_dir is changed then).
        """
        clock = time.perf_counter()
        print_on_rank0()
        comm = self.mesh.mesh.comm
        checkpoint = Checkpoint(out_dir, comm) if out_dir else None
        if resume and checkpoint is None:
            raise SceneError("resume: give the output folder whose checkpoint the run continues")
        with StopRequests(comm) as stop:
            saved = self._saved(checkpoint, resume)
            if not hasattr(self, "problem"):
                self.build()
            summary, first = self._begin(checkpoint, saved)
            elapsed = summary["wall_s"]
            fields = self._field_output(out_dir, first)
            observers = [*self.reports, *self.observers, *fields]
            for observer in observers:
                observer.start(self.name, out_dir)
            for f in fields if first else []:  # a resumed run's fields begin with the restored state
                f.after_step(self.steps[first - 1].name, first - 1, {}, True)
            self._walk(first, summary, observers, checkpoint, stop.requested,
                       lambda: elapsed + time.perf_counter() - clock)
        return summary

    def _saved(self, checkpoint: Checkpoint | None, resume: bool) -> Saved | None:
        """The checkpoint a resumed run continues (checked against this scene), or None."""
        if checkpoint is None:
            return None
        if not resume:
            if checkpoint.exists():
                log.info("%s holds a checkpoint: this run starts from the first step and replaces it once a step "
                         "converges (--resume continues it)", checkpoint.folder)
            return None
        saved = checkpoint.read(self.fingerprint, len(self.steps))
        if saved is None:
            log.info("no checkpoint in %s: the run starts from the first step", checkpoint.out_dir)
        return saved

    def _begin(self, checkpoint: Checkpoint | None, saved: Saved | None) -> tuple[dict, int]:
        """The summary so far and the index of the first step to run: a new run's, or the state a
        checkpoint holds, restored."""
        if saved is None:
            return self._summary(), 0
        checkpoint.restore(saved, self.problem, [*self.reports, *self.observers])
        summary, first = saved.summary, saved.next_step
        if first == len(self.steps):
            log.info("the run in %s is done: nothing to resume", checkpoint.out_dir)
            return summary, first
        done = ", ".join(repr(step["name"]) for step in summary["steps"])
        log.info("resuming the run in %s (written on %d rank(s)) after step(s) %s, from step %r", checkpoint.out_dir,
                 saved.ranks, done, self.steps[first].name)
        summary["ranks"] = self.solid.comm.size
        summary.setdefault("resumed", []).append({"step": self.steps[first].name, "ranks": self.solid.comm.size})
        return summary, first

    def _walk(self, first: int, summary: dict, observers: list[Observer], checkpoint: Checkpoint | None,
              stop: Callable[[], str | None], wall: Callable[[], float]) -> None:
        """Run the steps from ``first`` on; after each converged one, its checkpoint and the
        summary ("running", or "done" after the last); before each, stop if asked to (a signal
        that came while the scene was built, or during the step before)."""
        last, resumable = len(self.steps) - 1, first
        try:
            self._write_summary(checkpoint, summary, wall)
            for index in range(first, len(self.steps)):
                signal = stop()
                if signal:
                    raise Interrupted(f"interrupted by {signal} before step {self.steps[index].name!r}", signal)
                self._run_step(index, self.steps[index], summary, observers, stop)
                summary["state"] = "done" if index == last else "running"
                summary["ok"] = index == last
                if checkpoint is not None:
                    summary["wall_s"] = wall()
                    checkpoint.write(index + 1, summary, self.fingerprint, self.problem,
                                     [*self.reports, *self.observers])
                    resumable = index + 1
                self._write_summary(checkpoint, summary, wall)
        except BaseException as error:
            summary["ok"] = False
            summary["state"] = "interrupted" if isinstance(error, (Interrupted, KeyboardInterrupt)) else "failed"
            summary["error"] = str(error) or type(error).__name__
            if isinstance(error, Interrupted):
                summary["error"] = self._resumable(error, checkpoint, resumable)
                raise Interrupted(summary["error"], error.signal) from None
            raise
        finally:
            summary["wall_s"] = wall()
            for observer in observers:
                observer.finish(summary)
            self._write_summary(checkpoint, summary, wall)

    def _write_summary(self, checkpoint: Checkpoint | None, summary: dict, wall: Callable[[], float]) -> None:
        if checkpoint is not None:
            summary["wall_s"] = wall()
            write_json_atomic(os.path.join(checkpoint.out_dir, "summary.json"), summary, self.solid.comm)

    def _resumable(self, error: Interrupted, checkpoint: Checkpoint | None, resumable: int) -> str:
        """The interruption, and where a resumed run starts: after the last step checkpointed."""
        if checkpoint is None:
            return f"{error}; no output folder, so no checkpoint to resume"
        if resumable == 0:
            return f"{error}; no step of this run had converged, so it wrote no checkpoint"
        return (f"{error}; summary.json holds the last converged state, and --resume continues from the checkpoint "
                f"in {checkpoint.folder} with step {self.steps[resumable].name!r}")

    def _field_output(self, out_dir: str | None, first: int) -> list[FieldOutput]:
        """A run's field output, set up for it, if the run writes files and has steps to run: a
        resumed run's in its own file, ``fields_from_<step>``, which starts with the restored state."""
        if not out_dir or first == len(self.steps):
            return []
        name = "fields" if first == 0 else "fields_from_" + re.sub(r"[^\w.-]+", "_", self.steps[first].name)
        fields = FieldOutput(name)
        fields.setup(self.solid, self.problem)
        return [fields]

    def _summary(self) -> dict:
        """The head of summary.json: the scene, its size, and no step yet."""
        msh = self.mesh.mesh
        return {"ok": False, "state": "running", "scene": self.name, "ranks": self.solid.comm.size,
                "cells": msh.topology.index_map(msh.topology.dim).size_global,
                "dofs": self.problem.n_global + self.problem.m, "element": self.solid.element,
                "wall_s": 0.0, "steps": []}

    def _run_step(self, index: int, step: Step, summary: dict, observers: list[Observer],
                  stop: Callable[[], str | None]) -> None:
        """Step ``index`` of the load path, then its entry of the summary from the observers
        (also when it fails or is interrupted: then the state is the last converged one)."""
        entry = {"name": step.name, "increments": []}
        summary["steps"].append(entry)
        try:
            done = run_step(self.problem, self.newton, self.solver, index, step.name,
                            step.increments or self.solver.increments, stop)
        except (ConvergenceError, Interrupted) as error:
            self._observe(observers, step, index, entry, error.increments, converged=False)
            raise
        self._observe(observers, step, index, entry, done, converged=True)

    @staticmethod
    def _observe(observers: list[Observer], step: Step, index: int, entry: dict, increments: list,
                 converged: bool) -> None:
        entry["increments"] = [dataclasses.asdict(i) for i in increments]
        for observer in observers:
            observer.after_step(step.name, index, entry, converged)

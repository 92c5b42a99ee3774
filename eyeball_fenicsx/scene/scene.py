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
scene file's ``[eye]`` table and their pictures: output/measures.py, output/eye_pictures.py),
then the field output of a run with an output folder (output/files.py). They fill the step's
entry of summary.json, which is written after every step and at the end. A second ``run``
starts from the state the first left, with the observers ``build`` set up. Each load increment
is logged (output/console.py prints it on rank 0).
"""
from __future__ import annotations

import dataclasses
import time
from typing import TYPE_CHECKING

from ..errors import ConvergenceError, SceneError
from ..mechanics.solid import MixedSolid
from ..output.console import print_on_rank0
from ..output.files import FieldOutput, write_json_atomic
from ..output.reports import FeatureReports, Probes
from ..system.newton import NewtonSolver
from ..system.problem import Problem
from ..system.settings import SolverSettings
from ..system.stepping import run_step

if TYPE_CHECKING:
    from ..meshing.load import MeshData
    from ..output.observer import Observer


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
        self.solid = MixedSolid(self.mesh, self.materials, self.element)
        self.problem = Problem(self.solid, self.features)
        self.newton = NewtonSolver(self.problem)
        self.reports = [Probes(self.probes), FeatureReports()]
        for observer in [*self.reports, *self.observers]:
            observer.setup(self.solid, self.problem)
        return self

    def run(self, out_dir: str | None = None) -> dict:
        """Solve every step; write fields and summary.json into out_dir (if given).

        Returns the summary dict. Raises ConvergenceError (after writing the summary with
        ``"ok": false`` and the last converged state) if a step fails.
        """
        start = time.perf_counter()
        print_on_rank0()
        if not hasattr(self, "problem"):
            self.build()
        summary = self._summary()
        observers = [*self.reports, *self.observers, *self._field_output(out_dir)]
        for observer in observers:
            observer.start(self.name, out_dir)
        try:
            for index, step in enumerate(self.steps):
                self._run_step(index, step, summary, observers)
                if out_dir:
                    summary["wall_s"] = time.perf_counter() - start
                    write_json_atomic(f"{out_dir}/summary.json", summary, self.solid.comm)
        finally:
            summary["wall_s"] = time.perf_counter() - start
            for observer in observers:
                observer.finish(summary)
            if out_dir:
                write_json_atomic(f"{out_dir}/summary.json", summary, self.solid.comm)
        return summary

    def _field_output(self, out_dir: str | None) -> list[FieldOutput]:
        """A run's field output, set up for it, if the run writes files."""
        if not out_dir:
            return []
        fields = FieldOutput()
        fields.setup(self.solid, self.problem)
        return [fields]

    def _summary(self) -> dict:
        """The head of summary.json: the scene, its size, and no step yet."""
        msh = self.mesh.mesh
        return {"ok": True, "scene": self.name, "ranks": self.solid.comm.size,
                "cells": msh.topology.index_map(msh.topology.dim).size_global,
                "dofs": self.problem.n_global + self.problem.m, "element": self.solid.element,
                "wall_s": 0.0, "steps": []}

    def _run_step(self, index: int, step: Step, summary: dict, observers: list[Observer]) -> None:
        """Step ``index`` of the load path, then its entry of the summary from the observers
        (also when it fails: then the state is the last converged one)."""
        entry = {"name": step.name, "increments": []}
        summary["steps"].append(entry)
        try:
            done = run_step(self.problem, self.newton, self.solver, index, step.name,
                            step.increments or self.solver.increments)
        except ConvergenceError as error:
            self._observe(observers, step, index, entry, error.increments, converged=False)
            summary["ok"] = False
            summary["error"] = str(error)
            raise
        self._observe(observers, step, index, entry, done, converged=True)

    @staticmethod
    def _observe(observers: list[Observer], step: Step, index: int, entry: dict, increments: list,
                 converged: bool) -> None:
        entry["increments"] = [dataclasses.asdict(i) for i in increments]
        for observer in observers:
            observer.after_step(step.name, index, entry, converged)

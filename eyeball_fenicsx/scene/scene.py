"""A scene is one simulation: a mesh, region materials, features, probes, load steps.

Python API::

    from eyeball_fenicsx import Scene, NeoHooke, Dirichlet, Pressure, load_mesh
    scene = Scene("sphere", load_mesh("sphere.msh"), {"wall": NeoHooke(0.5)},
                  features=[Dirichlet("sym_x", {"x": 0}), Pressure("inner", 0.6)],
                  probes={"inner": [1.0, 0.0, 0.0]})
    summary = scene.run("out")

Only what the scene holds is assembled: a scene without cavities or contact solves
exactly the bare hyperelastic system.

A scene with eye measures (an ``EyeMeasures`` feature: the ``[eye]`` table of a scene file)
also draws, into the output folder, ``section_<step>.png`` after each step (the deformed
meridional section coloured by von Mises stress), ``retina_gap_<step>.png`` with a detachment
(the retina's gap from the choroid, flattened) and ``eye_measures.png`` at the end (the scalar
eye measures over the steps).
"""
import dataclasses
import os
import re
import time

from mpi4py import MPI

from ..errors import ConvergenceError, SceneError
from ..features.loads import Dirichlet
from ..mechanics.solid import MixedSolid
from ..output.eye_pictures import eye_measures_png, retina_gap_png, stress_section_png
from ..output.files import FieldOutput, Probes, write_json_atomic
from ..output.measures import EyeMeasures
from ..system.newton import NewtonSolver
from ..system.problem import Problem
from ..system.stepping import SolverSettings, run_step


@dataclasses.dataclass
class Step:
    """One step of the load path: the features whose ``step`` is this one ramp in it."""

    name: str
    increments: int = None  # default: the solver's


def _print_on_rank0(message):
    if MPI.COMM_WORLD.rank == 0:
        print(message, flush=True)


@dataclasses.dataclass
class Scene:
    name: str
    mesh: object  # mesh.MeshData
    materials: dict
    features: list = dataclasses.field(default_factory=list)
    probes: dict = dataclasses.field(default_factory=dict)
    steps: list = dataclasses.field(default_factory=lambda: [Step("load")])
    solver: SolverSettings = dataclasses.field(default_factory=SolverSettings)
    element: str = None
    log: object = _print_on_rank0

    def __post_init__(self):
        for f in self.features:
            if not 0 <= f.step < len(self.steps):
                raise SceneError(f"{type(f).__name__} {f.name!r} ramps in step {f.step}, "
                                 f"but the scene has {len(self.steps)} step(s)")

    def build(self):
        """Create the solid, the Newton problem and the solver (compiles the forms)."""
        self.solid = MixedSolid(self.mesh, self.materials, self.element)
        self.problem = Problem(self.solid, self.features)
        self.newton = NewtonSolver(self.problem)
        self.probe_points = Probes(self.solid, self.probes)
        return self

    def run(self, out_dir=None):
        """Solve every step; write fields and summary.json into out_dir (if given).

        Returns the summary dict. Raises ConvergenceError (after writing the summary with
        ``"ok": false`` and the last converged state) if a step fails.
        """
        start = time.perf_counter()
        if not hasattr(self, "problem"):
            self.build()
        comm = self.solid.comm
        msh = self.mesh.mesh
        summary = {"ok": True, "scene": self.name, "ranks": comm.size,
                   "cells": msh.topology.index_map(msh.topology.dim).size_global,
                   "dofs": self.problem.n_global + self.problem.m, "element": self.solid.element,
                   "wall_s": 0.0, "steps": []}
        fields = FieldOutput(self.solid, out_dir) if out_dir else None
        eye = next((f for f in self.features if isinstance(f, EyeMeasures)), None) if out_dir else None
        try:
            for index, step in enumerate(self.steps):
                entry = {"name": step.name, "increments": []}
                summary["steps"].append(entry)
                try:
                    done = run_step(self.problem, self.newton, self.solver, index, step.name,
                                    step.increments or self.solver.increments, self.log)
                except ConvergenceError as error:
                    entry["increments"] = [dataclasses.asdict(i) for i in error.increments]
                    entry.update(self.measure())
                    summary["ok"] = False
                    summary["error"] = str(error)
                    raise
                finally:
                    if fields:
                        fields.write(float(index + 1))
                entry["increments"] = [dataclasses.asdict(i) for i in done]
                entry.update(self.measure())
                if eye:  # its stress and gap are those of this state: measure() just updated them
                    label = re.sub(r"[^\w.-]+", "_", step.name)
                    stress_section_png(self.solid, eye.mises, os.path.join(out_dir, f"section_{label}.png"),
                                       title=f"{self.name}, step {step.name}: von Mises stress (MPa)")
                    retina_gap_png(eye, os.path.join(out_dir, f"retina_gap_{label}.png"),
                                   title=f"{self.name}, step {step.name}: the detached retina")
                if out_dir:
                    summary["wall_s"] = time.perf_counter() - start
                    write_json_atomic(f"{out_dir}/summary.json", summary, comm)
        finally:
            summary["wall_s"] = time.perf_counter() - start
            if fields:
                fields.close()
            if eye and comm.rank == 0:
                eye_measures_png(summary["steps"], os.path.join(out_dir, "eye_measures.png"))
            if out_dir:
                write_json_atomic(f"{out_dir}/summary.json", summary, comm)
        return summary

    def measure(self):
        """Probes, reactions and every feature's report at the current state."""
        result = {"probes": self.probe_points.displacements(), "reactions": {}}
        residual = self.problem.assemble_residual_unconstrained().array_r
        for f in self.features:
            if isinstance(f, Dirichlet) and f.active:
                result["reactions"][f.name] = f.reaction(residual)
            report = f.report()
            if report is not None and f.name is None:  # the report is the whole section
                result.setdefault(f.section, {}).update(report)
            elif report is not None:
                result.setdefault(f.section, {})[f.name] = report
        return result

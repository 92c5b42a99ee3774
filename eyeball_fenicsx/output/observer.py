"""What reads the state after each step of a run: the observer interface.

Data path: ``Scene.build`` makes the solid and the problem, then calls ``setup`` of each of the
scene's observers once (what is found in the mesh and the forms built: a probe outside the mesh
is reported there). Each ``Scene.run`` calls ``start`` (the run's name and output folder), and
after each step it solves (system/stepping.py) ``after_step`` of each observer in order; they
read the converged state (the solid's fields, the problem's features) and add their entries to
the step's entry of summary.json, or write files. They never change the state. The order: the
probes, then the reactions and the features' reports (output/reports.py), then the observers
the scene was given (the eye measures and their pictures: output/measures.py,
output/eye_pictures.py; last, the run's page, report.html: output/report.py, which the loader adds
to every scene file), then the field output of a run that writes files (output/files.py,
set up by that run).

A class that derives from ``Observer`` inherits methods that do nothing, and overrides those it
needs.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from ..mechanics.solid import MixedSolid
    from ..system.problem import Problem


class Observer(Protocol):
    """Called by the scene: ``setup`` once when it is built, then at each ``Scene.run``:
    ``start`` before the first step, ``after_step`` after each step (collective), ``finish``
    once at the end, also when a step failed (collective)."""

    def setup(self, solid: MixedSolid, problem: Problem) -> None:
        """The scene is built: find what is observed in ``solid`` and ``problem`` (collective)."""

    def start(self, scene: str, out_dir: str | None) -> None:
        """A run begins: ``scene`` is its name, and files go into ``out_dir`` (None: no files)."""

    def after_step(self, step: str, index: int, entry: dict, converged: bool) -> None:
        """Step ``index`` (named ``step``) ended, converged or not (then the state is the last
        converged one); add to ``entry``, the step's entry of summary.json."""

    def finish(self, summary: dict) -> None:
        """The run ended (after its last step, or a failed one) with this summary."""

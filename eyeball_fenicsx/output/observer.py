"""What reads the state after each step of a run: the observer interface.

Data path: the scene solves a step (system/stepping.py), then calls ``after_step`` of each of
its observers in order; they read the converged state (the solid's fields, the problem's
features) and add their entries to the step's entry of summary.json, or write files. They
never change the state. The scene's own observers come first, in this order: the probes and
the features' reports (output/reports.py), then those the scene was given (the eye measures:
output/measures.py), then the field output (output/files.py).

A class that derives from ``Observer`` inherits methods that do nothing, and overrides those it
needs.
"""
from typing import Protocol


class Observer(Protocol):
    """Called by ``Scene.run``: ``start`` once before the first step, ``after_step`` after each
    step (collective), ``finish`` once at the end, also when a step failed (collective)."""

    def start(self, scene: str, solid, problem, out_dir: str | None) -> None:
        """The run begins: ``scene`` is its name, ``solid`` and ``problem`` are built, and files go
        into ``out_dir`` (None: no files)."""

    def after_step(self, step: str, index: int, entry: dict, converged: bool) -> None:
        """Step ``index`` (named ``step``) ended, converged or not (then the state is the last
        converged one); add to ``entry``, the step's entry of summary.json."""

    def finish(self, summary: dict) -> None:
        """The run ended (after its last step, or a failed one) with this summary."""

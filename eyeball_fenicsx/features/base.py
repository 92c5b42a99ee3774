"""What every feature of a scene shares: its place on the load path and its report.

A feature is one physical thing a scene holds besides the solid (a load, a support, a liquid,
a string, a contact). All of them share this lifecycle, which the problem
(``system.problem.Problem``) and the load path (``system.stepping``) drive:

* ``setup(solid)``: once, when the problem is built (locate surfaces, make forms);
* ``begin_step(step_index)``: when a step of the load path starts;
* ``set_load_factor(factor)``: the ramp, 0 -> 1 in the feature's own ``step`` (an index),
  held at 1 after it;
* ``report()``: what it writes into summary.json after a step, under ``section``.

What a feature contributes to the Newton system is told by the roles it plays
(``features/roles.py``: a UFL term, Dirichlet conditions, nodal assembly of the residual or
the tangent, global unknowns, a state it follows, an active set), each a small Protocol: a
feature takes a role by defining its members, and the problem sorts its features by role
once (as FEBio's model sums the ``Residual`` and ``StiffnessMatrix`` of what it holds).
"""
from __future__ import annotations

AXES = {"x": 0, "y": 1, "z": 2}  # a coordinate's name -> its index


class Feature:
    """The lifecycle of a feature; by itself it contributes nothing."""

    name: str | None = ""
    step: int = 0  # the index of the step it ramps in
    section: str | None = None  # the summary.json key it reports under, if any

    def setup(self, solid) -> None:
        """Called once, when the problem is built; locate surfaces, create forms."""

    def begin_step(self, step_index: int) -> None:
        """Called when a step of the load path starts."""

    def set_load_factor(self, factor: float) -> None:
        """Set the ramped value: factor runs 0 -> 1 in this feature's step."""

    def report(self) -> dict | None:
        """What this feature writes into summary.json at the end of a step: a dict under
        ``section`` -> ``name``, or merged into ``section`` itself if ``name`` is None."""
        return None

"""What every contact feature shares: points with a gap, the law, assembly, the Newton-step
limit at contact onset and the report.

A contact feature is a set of *points* of its slave surface (Gauss points of the slave
facets for a deformable pair, nodes against a rigid body), each with an area weight W, a
penalty alpha (per unit area) and a multiplier lambda (``law.py``). At every state the
subclass selects what each point projects on and its gap g (``_select``), and gives the
residual and tangent of the points that carry a pressure (``_forces``).

**Augmented Lagrangian.** The multipliers live on the slave nodes, are interpolated to the
points and take Uzawa's updates between Newton solves (``augmented.py``).

**Contact onset.** The tangent knows nothing of an open point, so a Newton step that closes
gaps would drive the surfaces through each other by the whole step. A step that would close a
point, or open a pressing one, first takes the penalty of the points it would press and drops
that of the points it would release, with a factorized tangent (compliance.py's closing step);
then, where a point would still close deeper than d = max(f / (alpha W), ONSET_DEPTH h) (f the
largest force out of balance on the slave nodes, h the thickness of the point's element), it
is shortened to where the first closing point reaches its d, by regula falsi along the step.
A step that changes no point's contact is not touched (Newton's quadratic convergence stays as
it was).

A contact feature plays the roles (``features/roles.py``) of nodal assembly of the residual
and the tangent, and of an active set: the solver watches its search, its onset limit and
its augmentations.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np
from dolfinx import fem
from mpi4py import MPI
from petsc4py import PETSc

from ..errors import SceneError
from ..features.base import Feature
from .augmented import AugmentedLagrangian
from .compliance import Respond, closing_step
from .law import pressure
from .policy import (
    ACTIVE_RANGE,
    NEWTON_OPTIONS,
    ONSET_DEPTH,
    ONSET_ITERATIONS,
    OPEN_RANGE,
)
from .surface import check_penalty

_ADD = PETSc.InsertMode.ADD_VALUES


@dataclasses.dataclass
class Selection:
    """The points that project on something at a state, what on (a segment, or -1), their
    gaps (less the gap in the mesh where ``ContactPair``'s adjust closes it), and (a deformable
    pair) their ``geometry.Projection``."""

    point: np.ndarray
    target: np.ndarray
    g: np.ndarray
    projection: object = None


class ContactFeature(AugmentedLagrangian, Feature):
    """Base of ``ContactPair`` and ``RigidContact`` (see the module docstring).

    Subclasses set, in ``setup``: ``weight``, ``alpha``, ``thickness``, ``point_X`` (reference
    coordinates), ``point_nodes`` (the local x-dofs of the slave nodes the point interpolates, (n, k))
    and ``point_N`` (their weights) per point, ``slave_dofs`` (the owned slave nodes' local dofs,
    (n, 3)), then call ``_setup_common`` (which sets ``mean_penalty``); and give ``_positions()``
    (collective: the state the selection depends on), ``_select(positions)``, ``_forces(selection,
    index, p, k, tangent)`` and ``_gaps_along(du)`` (the points, their gaps now, and at fractions of
    du, of all points or some).
    """

    section = "contact"
    symmetric_tangent = False  # True in a subclass whose tangent is the Hessian of a potential
    newton_options = NEWTON_OPTIONS  # the plain line search its onset limit needs (policy.py)

    def __init__(self, name: str, slave: str, penalty: float | None, step: int, smoothing: float):
        self.name, self.slave_name, self.step = name, slave, step
        self.penalty = check_penalty(name, penalty)
        self.smoothing = float(smoothing)
        self.reach = ACTIVE_RANGE * self.smoothing  # smoothed: points with (gap - lambda/alpha) below carry force
        self.open_gap = OPEN_RANGE * self.smoothing  # ... and above this they are open for step_fraction
        self.active = False
        self._start_multipliers()
        self._selection = None  # (the positions it was made at, the Selection)
        # wall seconds, for benchmarks; "gather" (the master nodes' displacements) and "exchange" (of the
        # master segments near each rank's points, at a search: part of "search") include the slowest rank's wait
        self.timing = {"search": 0.0, "assembly": 0.0, "gather": 0.0, "exchange": 0.0}
        self._contacts = {"residual": None, "jacobian": None}  # who touches what, at the last of each

    # -- the state -----------------------------------------------------------------------
    def _selection_now(self):
        """The selection at the current state (collective); reused while the state holds."""
        positions = self._positions()
        last = self._selection
        if last is None or not all(np.array_equal(a, b) for a, b in zip(last[0], positions)):
            self._selection = (positions, self._select(positions))
        return self._selection[1]

    def _pressures(self, node_multiplier=None):
        """The selection, which of its points carry force, and their pressure and stiffness (with
        the multipliers in force, or with the nodal ones ``node_multiplier``)."""
        sel = self._selection_now()
        multiplier = self._point_multipliers(node_multiplier)[sel.point]
        p, k = pressure(sel.g, multiplier, self.alpha[sel.point], self.smoothing, self.adjusted[sel.point])
        if self.smoothing > 0.0:
            on = sel.g - multiplier / self.alpha[sel.point] < self.reach
        else:
            on = k > 0.0
        return sel, on, p, k

    def _state(self, tangent):
        sel, on, p, k = self._pressures()
        index = np.flatnonzero(on)
        rows, r, K, direction = self._forces(sel, index, p[index], k[index], tangent)
        return {"point": sel.point[index], "g": sel.g[index], "p": p[index], "rows": rows, "r": r, "K": K,
                "direction": direction, "contacts": np.column_stack([sel.point[index], sel.target[index]])}

    # -- Newton --------------------------------------------------------------------------
    def begin_step(self, step_index: int) -> None:
        self.active = step_index >= self.step

    def begin_increment(self) -> bool:
        """Search anew before an increment; True if the matrix pattern must grow (not by default:
        a rigid body's points couple only their own node)."""
        return False

    def coupling(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The entries beyond the mesh's pattern that contact may touch (none by default)."""
        return None

    def tangent_outdated(self, corrected: bool = False) -> bool:
        """True (on every rank: collective) if the contacts changed since the last tangent was
        assembled: a factorization of that tangent then is no Newton step. With ``corrected``,
        only if they changed in a way the closing step cannot correct: points that press now and
        did not then, or the other way round, it corrects (compliance.py), unless the law is
        smoothed; a point of the tangent now on another segment or on none, or a new penalty, it
        does not."""
        if not self.active:
            return False
        correctable = corrected and self.smoothing == 0.0
        sel = self._selection_now() if correctable else None  # collective: on every rank alike
        tangent, residual = self._contacts["jacobian"], self._contacts["residual"]
        fits = tangent is not None and residual is not None
        if fits and not np.array_equal(tangent, residual):
            fits = correctable
            if fits:  # every point of the tangent still on its segment
                _, i, j = np.intersect1d(tangent[:, 0], sel.point, return_indices=True)
                fits = len(i) == len(tangent) and np.array_equal(tangent[i, 1], sel.target[j])
        return self.solid.comm.allreduce(not fits, op=MPI.LOR)

    def in_tangent(self, point: np.ndarray) -> np.ndarray:
        """Which of the points press in the last tangent assembled (on the segments they are on
        now, where ``tangent_outdated(corrected=True)`` is False)."""
        tangent = self._contacts["jacobian"]
        return np.isin(point, tangent[:, 0]) if tangent is not None else np.zeros(len(point), dtype=bool)

    def add_to_residual(self, b: PETSc.Vec) -> None:
        if not self.active:
            return
        start = time.perf_counter()
        state = self._state(tangent=False)
        self._contacts["residual"] = state["contacts"]
        b.setValues(state["rows"].ravel(), state["r"].ravel(), addv=_ADD)
        self.timing["assembly"] += time.perf_counter() - start

    def add_to_jacobian(self, A: PETSc.Mat) -> None:
        start = time.perf_counter()
        if self.active:
            state = self._state(tangent=True)
            self._contacts["jacobian"] = state["contacts"]
            if len(state["rows"]):  # one dense block per point, set in one call (PETSc loops)
                A.setValuesRCV(state["rows"], state["rows"], state["K"], addv=_ADD)
        self.timing["assembly"] += time.perf_counter() - start

    def search_covers(self) -> bool:
        """True: no search to outgrow by default (a rigid body's points couple only their own node)."""
        return True

    def _nodal_sums(self, point, values):
        """sum over the points of values * N_i at every slave node, ghosts included (collective)."""
        work = self._work.x
        work.array[:] = 0.0
        np.add.at(work.array, self.point_nodes[point], self.point_N[point] * values[:, None])
        self._work.vector.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        work.scatter_forward()
        return work.array.copy()

    def closing_step(self, du: np.ndarray, respond: Respond) -> np.ndarray | None:
        """compliance.py's closing step (a smoothed law has every near point in its tangent)."""
        return closing_step(self, du, respond) if self.active and self.smoothing == 0.0 else None

    def _ghosted(self, values):
        """A mixed vector's owned entries, with this rank's ghost entries filled (collective)."""
        work = self._work
        work.x.array[: len(values)] = values
        work.x.scatter_forward()
        return work.x.array

    def onset_depth(self, point: np.ndarray, residual: np.ndarray) -> np.ndarray:
        """How deep each of the points may close in one Newton step, d = max(f / (alpha W),
        ONSET_DEPTH h), f the largest force of the ``residual`` on the slave nodes (collective)."""
        force = self.solid.comm.allreduce(np.abs(residual[self.slave_dofs]).max(initial=0.0), op=MPI.MAX)
        return np.maximum(force / (self.alpha[point] * self.weight[point]), ONSET_DEPTH * self.thickness[point])

    def step_fraction(self, du: np.ndarray, residual: np.ndarray) -> float:
        """The largest fraction (at most 1) of the state change ``du`` (the owned entries of the
        mixed vector) at which no closing point is deeper than its onset depth (module
        docstring; collective)."""
        if not self.active:
            return 1.0
        point, now, gaps = self._gaps_along(du)
        shift = self._point_multipliers()[point] / self.alpha[point]
        depth = self.onset_depth(point, residual)
        now, new = now - shift + depth, gaps(1.0) - shift + depth
        closing = np.flatnonzero((now > depth + self.open_gap) & (new < 0))  # only these are searched
        shift, depth = shift[closing], depth[closing]
        lo, hi, f_lo, f_hi = np.zeros(len(closing)), np.ones(len(closing)), now[closing], new[closing]
        for _ in range(ONSET_ITERATIONS if self.solid.comm.allreduce(len(closing) > 0, op=MPI.LOR) else 0):
            trial = lo + (hi - lo) * f_lo / (f_lo - f_hi)
            f = gaps(trial, closing) - shift + depth
            below = f < 0
            f_lo, lo = np.where(below, 0.5 * f_lo, f), np.where(below, lo, trial)  # Illinois: halve the
            f_hi, hi = np.where(below, f, 0.5 * f_hi), np.where(below, trial, hi)  # end that stays
        return self.solid.comm.allreduce(np.min(hi, initial=1.0), op=MPI.MIN)

    # -- output --------------------------------------------------------------------------
    def point_pressures(self) -> tuple[np.ndarray, np.ndarray]:
        """Reference coordinates (n, 3) of this rank's points and their contact pressure (n,)."""
        result = np.zeros(len(self.weight))
        if self.active:
            sel, on, p, _ = self._pressures()
            result[sel.point[on]] = p[on]
        return self.point_X, result

    def report(self) -> dict:
        """Total force on the slave surface, deepest penetration and where (reference
        coordinates), the points and slave nodes that carry a pressure, the mean penalty
        (per unit area) and the augmentations so far."""
        comm = self.solid.comm
        if not self.active:  # its step has not come yet
            return {"force": [0.0, 0.0, 0.0], "max_penetration": 0.0, "where": None, "active_points": 0,
                    "active_nodes": 0, "penalty": float(self.mean_penalty), "augmentations": 0}
        state = self._state(tangent=False)
        force = (self.weight[state["point"]] * state["p"])[:, None] * state["direction"]
        force = comm.allreduce(force.sum(axis=0), op=MPI.SUM)
        depth = -state["g"]
        local = (0.0, None)
        if len(depth):
            local = (float(depth.max()), self.point_X[state["point"][depth.argmax()]].tolist())
        deepest = max(comm.allgather(local), key=lambda item: item[0])
        return {"force": force.tolist(), "max_penetration": max(deepest[0], 0.0),
                "where": deepest[1] if deepest[0] > 0 else None,
                "active_points": int(comm.allreduce(len(state["point"]), op=MPI.SUM)),
                "active_nodes": self._loaded_nodes(state["point"]),
                "penalty": float(self.mean_penalty * self._growth),
                "augmentations": int(self.augmentations)}

    def _setup_common(self, solid):
        size = solid.comm.allreduce(float(np.max(self.thickness, initial=0.0)), op=MPI.MAX)
        if self.smoothing >= size:  # the smoothed law would press at gaps of up to ACTIVE_RANGE sizes
            raise SceneError(f"contact {self.name!r}: smoothing {self.smoothing:g} mm is not below the size of the "
                             f"elements at its slave surface ({size:.3g} mm): the smoothed law would push the "
                             "surfaces apart before they touch; give a small fraction of it, or none")
        self.solid = solid
        self.adjusted = np.zeros(len(self.weight), dtype=bool)  # points whose mesh clearance is closed (pair.py)
        self._work = fem.Function(solid.W)
        self._num_owned = solid.W.dofmap.index_map.size_local
        self._setup_multipliers()
        totals = solid.comm.allreduce(np.array([self.weight.sum(), (self.weight * self.alpha).sum()]), op=MPI.SUM)
        self.mean_penalty = totals[1] / totals[0]

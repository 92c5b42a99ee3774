"""The augmented Lagrangian of a contact feature: nodal multipliers and their updates.

The multipliers live on the slave nodes and are interpolated to the points (lambda = sum_i
N_i lambda_i). After Newton converges at the end of a step, each node's multiplier takes
Uzawa's update with its weighted gap,

    lambda_i <- <lambda_i - alpha_i g_i>_+,   g_i = sum_pts W N_i g / sum_pts W N_i
                                             (over the points that carry a pressure),

and Newton runs again (with Aitken's relaxation of the updates; loosely until the updates
settle, then once at the usual tolerances: system/stepping.py), until no node's update,
read as the penetration it would remove (|Delta lambda_i| / alpha_i), exceeds AUGMENT_DEPTH
of the thickness of the element under it: the weighted gaps then vanish, to that depth,
wherever the surfaces press, whatever the penalty. One constraint per slave node, as in
mortar methods: one per Gauss point would be more constraints than the slave surface has
nodes, and the pressure modes that move no node would never converge. A pass that removes
less than half of the penetration left (PENALTY_GROWTH_TEST: a structure behind the surfaces
far stiffer than the penalty, such as sutures pulling a buckle in) multiplies the penalty by
PENALTY_GROWTH for the rest of the increment, up to MAX_PENALTY_GROWTH; a pass whose solve
fails is abandoned (the converged state before it stands, as at the cap of passes), never
turned into a cut-back of the increment; so is the last, settled update, taken because Newton
solves once more anyway (at the usual tolerances, or for another feature's pass), unless it
would press or release a point: an update that moves no node by more than the settled depth is
not worth the contacts it would change (points standing just off the master, pressing only
through their neighbours' multipliers, flip so; benchmarks/README.md), which that solve's chord
steps from the last factorization would have to correct (compliance.py). A penalty that grows
outdates the tangent (no chord step with the old one). Increments inside a step take one update
each, without solving again (it starts the next increment closer).

``AugmentedLagrangian`` is a mixin of ``ContactFeature`` (base.py), which gives it ``active``,
``solid``, the points (``weight``, ``alpha``, ``thickness``, ``point_nodes``, ``point_N``), their
pressures at the current state (``_pressures``) and the nodal sums over them (``_nodal_sums``, on
``_work``, whose first ``_num_owned`` dofs are owned). New multipliers drop the feature's cached
selection (``_selection``), and a new penalty also drops its last tangent (``_contacts``).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

from .policy import (
    AITKEN_BOUNDS,
    AUGMENT_DEPTH,
    MAX_AUGMENTATIONS,
    MAX_PENALTY_GROWTH,
    PENALTY_GROWTH,
    PENALTY_GROWTH_TEST,
)


class AugmentedLagrangian:
    """The nodal multipliers of a contact feature, Uzawa's updates of them, their checkpoint."""

    def _start_multipliers(self):
        """The state before any step (``__init__``): no pending update, the elements' penalty, and
        an increment's start (``set_increment``)."""
        self._pending, self._growth = None, 1.0  # the penalty's growth in this increment (augment)
        self.set_increment(True)

    def _setup_multipliers(self):
        """Zero multipliers, and the change that counts as settled at each slave node (``setup``)."""
        self.node_multiplier = np.zeros(len(self._work.x.array))
        self.augmentations = 0
        # a multiplier update of less than this moves its node's surface by less than
        # AUGMENT_DEPTH of the element under it (the penalty's nodal mean, times that depth)
        every = np.arange(len(self.weight))
        area = self._nodal_sums(every, self.weight)
        settled = AUGMENT_DEPTH * self._nodal_sums(every, self.weight * self.alpha * self.thickness)
        self._settled_change = np.divide(settled, area, out=np.full(len(area), np.inf), where=area > 0)

    def set_increment(self, final: bool) -> None:
        """Whether the coming increment ends its step (the augmentations then go to the end);
        the last increment's update of the multipliers is taken now."""
        self.final_increment, self._passes = final, 0
        self._relaxation, self._last_update, self._last_unsettled = 1.0, None, None
        self._before = None  # the multipliers and penalty growth before the last augmentation (abandon)
        if self._growth != 1.0:  # each increment starts from the penalty of the elements
            self._grow_penalty(1.0 / self._growth)
        if self._pending is not None:
            self.node_multiplier, self._pending, self._selection = self._pending, None, None

    def abandon_augmentation(self) -> bool:
        """The solve after the last augmentation failed: back to the multipliers and penalty the
        converged state had, and no more augmentations in this increment; whether it took any back."""
        taken_back, self._passes = self._before is not None, MAX_AUGMENTATIONS
        if taken_back:
            self.node_multiplier = self._before[0]
            self._grow_penalty(self._before[1] / self._growth)
            self._before, self._last_update = None, None
        return taken_back

    def _uzawa_update(self, point, area, gap):
        """Each slave node's Uzawa change of its multiplier, from its weighted gap."""
        alpha = self._nodal_sums(point, self.weight[point] * self.alpha[point])
        seen = area > 0
        target = np.zeros_like(self.node_multiplier)
        target[seen] = np.maximum(self.node_multiplier[seen] - alpha[seen] * gap[seen] / area[seen] ** 2, 0.0)
        return target - self.node_multiplier

    def _grow_penalty(self, factor):
        """Multiply the penalty by ``factor`` (the settled change with it); Aitken starts again."""
        self.alpha, self._settled_change = self.alpha * factor, self._settled_change * factor
        self._growth *= factor
        self._relaxation, self._last_update, self._selection = 1.0, None, None
        self._contacts["jacobian"] = None  # the last tangent had the old penalty

    def _point_multipliers(self, node_multiplier=None):
        """The multipliers at the points, interpolated from the nodal ones in force (or ``node_multiplier``)."""
        nodal = self.node_multiplier if node_multiplier is None else node_multiplier
        return np.einsum("na,na->n", self.point_N, nodal[self.point_nodes])

    def _keeps_contacts(self, on: np.ndarray, update: np.ndarray) -> bool:
        """Whether the multipliers changed by ``update`` leave every point pressing as it is (``on``),
        at the current state (collective)."""
        _, pressing, _, _ = self._pressures(self.node_multiplier + update)
        return not self.solid.comm.allreduce(bool(np.any(pressing != on)), op=MPI.LOR)

    def augment(self, solving: bool) -> bool:
        """Uzawa's update of the nodal multipliers (module docstring; collective). Returns True
        if nothing is left to do: not this feature's step yet, an increment inside a step (one
        update, no new solve), or updates that move no node by more than AUGMENT_DEPTH of its element
        (taken all the same when Newton solves again anyway: ``solving``); False if Newton must solve again."""
        if not self.active:
            return True
        sel, on, _, _ = self._pressures()
        point, g = sel.point[on], sel.g[on]
        w = self.weight[point]
        area = self._nodal_sums(point, w)
        gap = self._nodal_sums(point, w * g)
        owned = (area > 0) & (np.arange(len(area)) < self._num_owned)
        update = self._uzawa_update(point, area, gap)
        # |update| / settled change: the penetration it removes, in units of the settled depth
        # (the penalty cancels), so the rule below may change the penalty between two passes
        unsettled = self.solid.comm.allreduce(
            (np.abs(update[: self._num_owned]) / self._settled_change[: self._num_owned]).max(initial=0.0), op=MPI.MAX)
        settled = unsettled <= 1.0 or self._passes >= MAX_AUGMENTATIONS
        last = settled and solving and self._passes < MAX_AUGMENTATIONS  # Newton solves once more anyway
        free = last and self._keeps_contacts(on, update)  # a free last update: its tangent stays (module docstring)
        self._before = (self.node_multiplier, self._growth) if last or not settled else None  # abandon's
        if settled:
            self._last_update = None
            if free:
                self.node_multiplier, self._selection = self.node_multiplier + update, None
                self.augmentations += int(unsettled > 0.0)  # an update that moves something
            return True
        # the penetration shrinks slowly: the structure behind the surfaces (a suture pulling a
        # buckle in) is far stiffer than the penalty, so Uzawa contracts as k / (k + alpha);
        # the penalty grows, as in the augmented Lagrangian methods of Conn, Gould and Toint
        # (SIAM J. Numer. Anal. 28 (1991) 545) and Bertsekas (1982, sec. 2.2)
        if self._last_unsettled is not None and unsettled > PENALTY_GROWTH_TEST * self._last_unsettled \
                and self._growth * PENALTY_GROWTH <= MAX_PENALTY_GROWTH:
            self._grow_penalty(PENALTY_GROWTH)
            update = self._uzawa_update(point, area, gap)
        self._last_unsettled = unsettled
        # Aitken's relaxation of the increments (Irons and Tuck 1969; Kuettler and Wall,
        # Comput. Mech. 43 (2008) 61-72): omega <- -omega r_(k-1) . (r_k - r_(k-1)) / |r_k - r_(k-1)|^2
        if self._last_update is not None:
            weighted = area * owned
            change = update - self._last_update
            dots = self.solid.comm.allreduce(np.array([np.sum(weighted * self._last_update * change),
                                                       np.sum(weighted * change**2)]), op=MPI.SUM)
            if dots[1] > 0:
                self._relaxation = float(np.clip(-self._relaxation * dots[0] / dots[1], *AITKEN_BOUNDS))
        self._last_update = update
        relaxed = np.maximum(self.node_multiplier + self._relaxation * update, 0.0)
        self.augmentations += 1
        if not self.final_increment:  # taken when the next increment starts: the state reported is this one's
            self._pending = relaxed
            return True
        self.node_multiplier, self._selection = relaxed, None
        self._passes += 1
        return False

    # -- a checkpoint (output/checkpoint.py) ----------------------------------------------
    def checkpoint_state(self) -> dict:
        """The nodal multipliers in force and the update the next increment takes (None: none), as
        dof arrays, the augmentations so far and the penalty's growth in the last increment."""
        return {"node_multiplier": self.node_multiplier, "pending": self._pending,
                "augmentations": int(self.augmentations), "penalty_growth": self._growth}

    def restore_state(self, state: dict) -> None:
        self.node_multiplier = np.array(state["node_multiplier"])
        self._pending = None if state["pending"] is None else np.array(state["pending"])
        self.augmentations = state["augmentations"]
        self._grow_penalty(state["penalty_growth"] / self._growth)

"""The roles a feature plays in the Newton system, one small Protocol each.

A feature takes a role by defining the role's members (no flag says so); the problem
(``system.problem.Problem``) sorts its features by role once, when it is built, into lists in
scene order, and sums each role's contributions in that order. Roles, with who plays them:

* ``FormTerm``: a UFL term of the residual; its tangent comes from ``ufl.derivative``
  (a follower pressure, a liquid's load on its walls);
* ``Constraint``: Dirichlet conditions and the reaction they carry (a prescribed displacement);
* ``NodalResidual``: adds to the assembled residual by global index (nodal forces, sutures,
  contact); these act on constrained nodes too, so the Dirichlet rows are set after them;
* ``NodalTangent``: adds to the assembled tangent by global index, in entries it names
  beforehand (sutures, contact, a liquid of the seed's previous algorithm);
* ``GlobalUnknowns``: scalar unknowns that border the matrix (a liquid's pressure of the seed's
  new algorithm), see ``system/problem.py``;
* ``StateDependent``: follows every change of the state (a string's length, a liquid's volume);
* ``ActiveSet``: a set that the state selects and the solver must watch: contact, whose
  search, onset limit and augmented Lagrangian shape each Newton solve.

The tangents of the features of ``NodalTangent`` and ``GlobalUnknowns`` declare whether they
are symmetric (``symmetric_tangent``), which lets Newton factorize by LDL^T.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np
import ufl
from petsc4py import PETSc

from ..mechanics.solid import MixedSolid


@runtime_checkable
class FormTerm(Protocol):
    def residual(self, solid: MixedSolid) -> ufl.Form:
        """The UFL term, linear in the solid's test functions, added to the residual."""


@runtime_checkable
class Constraint(Protocol):
    active: bool  # the conditions hold in this step

    def dirichlet_bcs(self) -> list:
        """The DOLFINx Dirichlet conditions imposed in this step (none while inactive)."""

    def reaction(self, residual: np.ndarray) -> list:
        """The reaction force (collective) from the residual without Dirichlet rows (local array)."""


@runtime_checkable
class NodalResidual(Protocol):
    def add_to_residual(self, b: PETSc.Vec) -> None:
        """Add to the residual (global indices, ADD_VALUES; the problem assembles b)."""


@runtime_checkable
class NodalTangent(Protocol):
    symmetric_tangent: bool

    def coupling(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(rows, cols): global indices of the entries ``add_to_jacobian`` may touch beyond the
        mesh's own pattern, or None. Rows may be owned by any rank."""

    def add_to_jacobian(self, A: PETSc.Mat) -> None:
        """Add to the tangent (global indices, ADD_VALUES)."""


@runtime_checkable
class GlobalUnknowns(Protocol):
    num_unknowns: int
    unknowns: np.ndarray  # their values, the same on every rank
    symmetric_tangent: bool

    def unknown_residuals(self) -> list:
        """The residual of each unknown's equation."""

    def border(self) -> list:
        """Per unknown, (owned dofs, column dR_u/dg, row dR_g/du, dR_g/dg) of the bordered matrix."""


@runtime_checkable
class StateDependent(Protocol):
    def state_changed(self) -> None:
        """Called whenever Newton moves the state, before anything is assembled."""


@runtime_checkable
class ActiveSet(Protocol):
    newton_options: dict  # PETSc options (without prefix) Newton needs while the set may change
    def begin_increment(self) -> bool:
        """Before each load increment (after the loads are set): search; True if ``coupling()``
        changed, so that the matrix is preallocated anew."""

    def tangent_outdated(self, corrected: bool = False) -> bool:
        """Collective: the last tangent no longer fits the state (the active set changed), so
        Newton must not reuse its factorization; ``corrected``: unless the closing step
        (``closing_step``) corrects the difference."""

    def step_fraction(self, du: np.ndarray, residual: np.ndarray) -> float:
        """Collective: the largest fraction (at most 1) of the state change ``du`` that Newton may
        take in one step; du and the residual are the owned entries of mixed vectors."""

    def set_increment(self, final: bool) -> None:
        """Before each load increment: ``final`` if it ends the step."""

    def search_covers(self) -> bool:
        """Collective: the last search (``begin_increment``) still holds everything the converged
        state may touch; False if it must search again, and Newton solve again."""

    def closing_step(self, du: np.ndarray, respond: Callable) -> np.ndarray | None:
        """Collective: the change of Newton's state change du (local entries of the bordered
        vector) for what it changes in the set, through ``respond``
        (``NewtonSolver.respond``: the state change that cancels a residual change, by the
        factorized tangent); None: none."""

    def augment(self, solving: bool) -> bool:
        """Collective: after Newton converged an increment, update what the converged state
        decides; False if Newton must solve again (``solving``: it will anyway)."""

    def abandon_augmentation(self) -> bool:
        """Collective: the solve after ``augment`` failed; take back its update (the converged
        state before it stands), augment no more in this increment, and return whether there was
        an update to take back."""


def check_whole_role(feature: object, role: type) -> None:
    """Raise TypeError if ``feature`` defines some of ``role``'s methods but lacks one of its
    members: it would be left out of the role without a word (a Protocol checks only that
    members exist)."""
    methods = [name for name, value in vars(role).items() if callable(value) and not name.startswith("_")]
    members = methods + list(vars(role).get("__annotations__", {}))
    missing = [name for name in members if not hasattr(feature, name)]
    if missing and any(hasattr(feature, name) for name in methods):
        raise TypeError(f"{type(feature).__name__} {getattr(feature, 'name', '')!r} plays part of the role "
                        f"{role.__name__} (features/roles.py) but lacks {missing}")

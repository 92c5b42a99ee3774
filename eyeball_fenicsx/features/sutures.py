"""Sutures: strings that tie two material points and pull them together.

As in the seed, a suture applies equal and opposite forces along the *current* string
direction e = (x_b - x_a) / l at its two ends. An end given with its surface is the nearest
point of that surface's elements to where the suture is tied (``mechanics.solid.MaterialPoint``):
its motion is interpolated from the nodes of its element, x = sum_i N_i x_i, and its force shared
among them as N_i f, so the suture is where it was put on any mesh; an end given without a surface
is the nearest node. An end given as several points of its surface is their mean, its force spread
evenly over them: a bite, the thread's pass through the tissue, which a point force would not be
(under a point force a continuum's displacement has no limit as the mesh is refined, so what the
string reaches would depend on the elements around its end). It derives from a potential:

* tension-driven: Pi = T l, the force T e on end a (toward b), -T e on end b;
* shortening-driven: a stiff string whose rest length is shortened by s,
  Pi = k/2 <l - (l_0 - s)>^2 (slack strings carry nothing), T = k <l - l_0 + s>.

Its consistent tangent on the two ends is +-[dT/dl e e^T + T/l (I - e e^T)], N_i N_j times that
between their nodes i and j. The second end may instead be a fixed point in space
(``anchored=True``): the surgeon's hand.

A suture tied around a buckle holds it both ways (``bilateral=True``, the seed's constrained
suture points): it also resists shortening, T = k (l - l_rest) of either sign, so the
buckle cannot float off the sclera before contact holds it. A tension-driven loop holds its
buckle so too, a stiff string at rest, until its step pulls it; from then on it pulls with its
tension alone, ramped from the step's first increment (the force jumps there from the one it held
at rest; without the hold, a segmental tire tied by tension floated as the eye was pressurized and
"pressurize" stagnated, cut back again and again). Nor slide along it: a string
has no stiffness across itself but T / l, none while it is slack, and the strings of a
buckle's sutures all lie in the planes through the sclera's normal at their bites (the
meridian planes of a tire, the planes of latitude of a radial sponge), so a buckle on the
frictionless sphere could slide along the sclera across its strings, a motion that neither
contact nor the strings resist: the problem has no unique answer and Newton's matrix is
singular (a half model's symmetry plane hides it for a tire centred on it; the whole eye does
not). The tied loop therefore also resists that motion, across the string and along the
sclera: the relative displacement of its ends along s = E x N / |E x N| (E the string's
reference direction, N the sclera's normal at the bite, both fixed) is held by a spring of
``SLIDE_STIFFNESS`` times the string's stiffness, Pi_s = k_s / 2 (s . (u_h - u_a))^2, which
picks the state that has not slid and carries almost nothing (a thousandth of the string's
stiffness: a slide of 0.1 mm costs 1e-4 of k, against the string's tensions of k times a
tenth of a mm). It ties the bite a to the buckle's point h that rests on the sclera (``hold``:
the point of the buckle's inner surface under the string's end b; b itself if not given). The
hold's two forces, +-k_s (s . (u_h - u_a)) s, are not along the line from a to h, so they make
a couple (x_h - x_a) x f, which nothing in the eye balances but the support: tied to the top
of a buckle of height H, that line has a part H along the radius and the couple of the slides
at the two bites of a suture add up (a moment about the sclera's tangent, 2 H f, which tilts a
whole eye held by its optic nerve); tied to the buckle's base, the line a-h lies in the
sclera's tangent plane but for the buckle's clearance and its indentation, so each couple is
about the normal and those of a suture's two bites, mirror images, cancel (the README's "The
whole eye" gives the couples measured on a radial sponge, 2 mm high).

Units: the default string stiffness assumes mm and N: a 5-0 polyester suture, E about
5 GPa (5000 N/mm^2) and diameter 0.1 mm, has EA of about 40 N, and k = EA / l_0.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from dolfinx import cpp
from mpi4py import MPI
from petsc4py import PETSc

from .. import checks
from ..errors import SceneError
from ..mechanics.solid import MaterialNode, MaterialPoint, MixedSolid
from .base import Feature

SUTURE_EA = 40.0  # N, 5-0 polyester (see the module docstring)
SLIDE_STIFFNESS = 1e-3  # a tied loop's hold against sliding across it, per unit of the string's stiffness


class Suture(Feature):
    """A string from a point ``first`` to a point ``second`` (reference coordinates).

    Args:
        tension: prescribed string tension (ramped in the suture's step; a bilateral loop holds at
            rest before it), or
        shortening: prescribed shortening of the string's rest length (ramped).
        stiffness: k of the string for shortening, and of a bilateral loop at rest (default:
            SUTURE_EA / initial length).
        first_surface, second_surface: the surfaces the ends are on: an end is then the nearest
            point of that surface's elements to ``first`` (``second``), its motion interpolated
            from the nodes of the element there (``MaterialPoint``), or, given several points
            (m, 3), their mean, its force shared evenly among them (a bite); without a surface, the
            nearest mesh node.
        anchored: the second end is a fixed point in space, not a node.
        bilateral: the string also pushes (a loop tied around a buckle), see the module docstring.
        hold, hold_surface: a bilateral suture's point of the buckle held against sliding along the
            sclera (its base under ``second``, see the module docstring); default: the second end.
        share: the part of the suture in the model: 1/2 for a suture on a symmetry plane, whose
            mirror image holds the other half (its tension, stiffness and forces are halved).
    """

    section = "sutures"
    symmetric_tangent = True  # the Hessian of the string's potential

    def __init__(self, name: str, first: Sequence[float], second: Sequence[float], tension: float | None = None,
                 shortening: float | None = None, stiffness: float | None = None, first_surface: str | None = None,
                 second_surface: str | None = None, anchored: bool = False, bilateral: bool = False,
                 share: float = 1.0, hold: Sequence[float] | None = None, hold_surface: str | None = None,
                 step: int = 0):
        if (tension is None) == (shortening is None):
            raise SceneError(f"suture {name!r}: give exactly one of tension or shortening")
        what = f"suture {name!r}: "
        tension = None if tension is None else checks.number(tension, what + "tension", "nonnegative")
        shortening = None if shortening is None else checks.number(shortening, what + "shortening", "nonnegative")
        stiffness = None if stiffness is None else checks.number(stiffness, what + "stiffness", "positive")
        if not 0 < checks.number(share, what + "share") <= 1:
            raise SceneError(f"{what}share must be in (0, 1], got {share!r}")
        self.name, self.step, self.share = name, step, float(share)
        self.first_point, self.second_point = np.asarray(first, float), np.asarray(second, float)
        for key, points, surface in (("first", self.first_point, first_surface),
                                     ("second", self.second_point, None if anchored else second_surface)):
            if points.shape[-1:] != (3,) or points.ndim > 2:
                raise SceneError(f"{what}{key} must be a point (x, y, z) or a list of them, got shape {points.shape}")
            if points.ndim == 2 and surface is None:  # a bite is spread over its surface's elements
                raise SceneError(f"{what}{key} is {len(points)} points (a bite): give the surface they are on "
                                 f"({key}_surface; an anchored end is one point)")
        self.tension, self.shortening, self.stiffness = tension, shortening, stiffness
        self.surfaces, self.anchored, self.bilateral = (first_surface, second_surface), anchored, bilateral
        self.hold_point = None if hold is None else (np.asarray(hold, float), hold_surface)
        self.factor = 0.0

    def setup(self, solid: MixedSolid) -> None:
        self.a = _end(solid, self.first_point, self.surfaces[0])
        self.b = None if self.anchored else _end(solid, self.second_point, self.surfaces[1])
        self.comm = solid.comm
        self._check_ends(solid)
        self.initial_length = np.linalg.norm(self._ends()[1] - self._ends()[0])
        if self.initial_length == 0:
            raise SceneError(f"suture {self.name!r}: its two ends, first = {self.first_point.tolist()} and second = "
                             f"{self.second_point.tolist()}, are the same point; move them apart")
        if self.stiffness is None and (self.shortening is not None or self.bilateral):
            self.stiffness = SUTURE_EA / self.initial_length
        self.across = np.zeros(3)  # s, the direction of the loop's slide spring (bilateral only)
        self.h = self.b
        if self.bilateral and not self.anchored:
            if self.hold_point is not None:
                self.h = _end(solid, *self.hold_point)
            xa, xb = self.a.reference, self.b.reference
            across = np.cross(xb - xa, xa)  # the sclera's normal at the bite: the radius (its centre is the origin)
            if np.linalg.norm(across) > 1e-12 * np.linalg.norm(xa) * self.initial_length:
                self.across = across / np.linalg.norm(across)
            self.slide_stiffness = SLIDE_STIFFNESS * self.stiffness

    def _check_ends(self, solid):
        """An end ties the point of its surface (or the mesh node) nearest to its point: a point
        farther from it than the largest element is a mistake (a wrong sign, unit or surface)."""
        msh = solid.mesh_data.mesh
        cells = np.arange(msh.topology.index_map(msh.topology.dim).size_local, dtype=np.int32)
        local = float(cpp.mesh.h(msh._mesh, msh.topology.dim, cells).max()) if len(cells) else 0.0
        largest = self.comm.allreduce(local, op=MPI.MAX)
        ends = [("first", self.a, self.first_point, self.surfaces[0])]
        if self.b is not None:
            ends.append(("second", self.b, self.second_point, self.surfaces[1]))
        for key, node, point, surface in ends:
            if node.distance > largest:
                where = f"surface {surface!r}" if surface else "the nearest node of the mesh"
                raise SceneError(f"suture {self.name!r}: {key} = {point.tolist()} is {node.distance:.4g} from "
                                 f"{where}, farther than the largest element ({largest:.4g}); "
                                 "give a point on it")

    def _ends(self):
        return self.a.position(), (self.second_point if self.anchored else self.b.position())

    def set_load_factor(self, factor: float) -> None:
        self.factor = factor

    def state_changed(self) -> None:
        xa, xb = self._ends()
        if self.across.any():  # the loop's slide: s . (u_h - u_a)
            self.slide = self.across @ ((self.h.position() - self.h.reference) - (xa - self.a.reference))
        self.length = np.linalg.norm(xb - xa)
        self.direction = (xb - xa) / self.length
        if self.tension is not None and (self.factor > 0 or not self.bilateral):
            self.force, self.slope = self.share * self.factor * self.tension, 0.0
        else:  # a stiff string (a tension-driven loop: at rest, before its step pulls)
            shortening = 0.0 if self.shortening is None else self.factor * self.shortening
            stretch = self.length - (self.initial_length - shortening)
            # taut from its rest length on: a string tied at rest already holds what it ties
            taut = stretch >= 0 or self.bilateral
            k = self.share * self.stiffness
            self.force, self.slope = (k * stretch, k) if taut else (0.0, 0.0)

    def _blocks(self):
        """The tangent's blocks: the string's on (a, b), the loop's hold on (a, h) (or None)."""
        e = self.direction
        string = self.slope * np.outer(e, e) + self.force / self.length * (np.eye(3) - np.outer(e, e))
        s = self.across
        return string, (self.share * self.slide_stiffness * np.outer(s, s) if s.any() else None)

    def _hold(self):
        """The loop's hold on the first end, toward the buckle's point h (module docstring)."""
        if not self.across.any():
            return np.zeros(3)
        return self.share * self.slide_stiffness * self.slide * self.across

    def add_to_residual(self, b: PETSc.Vec) -> None:
        if self.comm.rank != self.a.owner:  # one rank adds, PETSc sends rows to their owners
            return
        f = self.force * self.direction  # the string's pull on the first end, toward the second
        hold = self._hold()
        b.setValues(self.a.dofs, np.kron(self.a.weights, -(f + hold)), addv=PETSc.InsertMode.ADD_VALUES)
        if self.b is not None:
            b.setValues(self.b.dofs, np.kron(self.b.weights, f), addv=PETSc.InsertMode.ADD_VALUES)
            b.setValues(self.h.dofs, np.kron(self.h.weights, hold), addv=PETSc.InsertMode.ADD_VALUES)

    def add_to_jacobian(self, A: PETSc.Mat) -> None:
        if self.comm.rank != self.a.owner:
            return
        a = self.a
        for other, K in zip((self.b, self.h), self._blocks()):
            if K is None:
                continue
            ends = [(a, a, 1.0)] if other is None else [(a, a, 1.0), (other, other, 1.0), (a, other, -1.0),
                                                        (other, a, -1.0)]
            for row, column, sign in ends:  # an end's nodes take their weights' share
                A.setValues(row.dofs, column.dofs, np.kron(np.outer(row.weights, column.weights), sign * K),
                            addv=PETSc.InsertMode.ADD_VALUES)

    def coupling(self) -> tuple[np.ndarray, np.ndarray] | None:
        if self.comm.rank != self.a.owner:
            return None
        ends = [self.a.dofs] if self.b is None else [self.a.dofs, self.b.dofs, self.h.dofs]
        dofs = np.unique(np.concatenate(ends))
        return np.repeat(dofs, len(dofs)), np.tile(dofs, len(dofs))

    def radial_push(self) -> float:
        """How far the string's shortening s pushes its second end in along the radius r from the
        origin, to first order, if its first end (the bite) held still and the body of the second did
        not deform: s / |e . r|, e the string's direction (in the reference configuration, between its
        ends' means). A kinematic bound on a buckle's indentation (demos/segmental_buckle.py)."""
        first, second = self.a.reference, self.b.reference
        e = (second - first) / np.linalg.norm(second - first)
        return self.shortening / abs(e @ (second / np.linalg.norm(second)))

    def report(self) -> dict:
        """The thread's tension, current and initial length, and the force the suture puts on the
        body of its second end in the model: the string's, -share T e, and the loop's hold (at the
        point h); the first end takes the opposite."""
        return {"tension": float(self.force / self.share), "share": self.share, "length": float(self.length),
                "initial_length": float(self.initial_length),
                "force_on_second": (-self.force * self.direction - self._hold()).tolist()}


def _end(solid: MixedSolid, point, surface: str | None):
    """A suture's end: the nearest point of ``surface``'s elements to ``point``, or the nearest mesh node."""
    return MaterialNode(solid, point) if surface is None else MaterialPoint(solid, point, surface)

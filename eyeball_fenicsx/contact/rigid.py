"""Frictionless contact of a surface's nodes with a rigid plane, sphere or cylinder.

A rigid shape has an exact, smooth gap function g(x) with its gradient and Hessian, so its
points are the slave nodes (with their tributary areas) and the law acts along grad g:
residual -W p grad g and the exact tangent W (k grad g grad g^T - p Hess g) (the normal of a
sphere or cylinder turns with the node).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .. import checks
from ..errors import SceneError
from ..mechanics.solid import MixedSolid
from .base import ContactFeature, Selection
from .surface import SolidTables, default_penalty, surface


def _point(value: Sequence[float], what: str) -> np.ndarray:
    return np.array(checks.vector(value, what))


def _unit(vector: Sequence[float], what: str) -> np.ndarray:
    v = np.array(checks.nonzero_vector(vector, what))
    return v / np.linalg.norm(v)


class Plane:
    """The half-space the solid must stay in: (x - point) . normal >= 0."""

    def __init__(self, point: Sequence[float], normal: Sequence[float]):
        self.point, self.normal = _point(point, "plane point"), _unit(normal, "plane normal")

    def gap(self, x: np.ndarray, shift: np.ndarray) -> tuple:
        """Gap g (n,), grad g (n, 3) and Hess g (n, 3, 3; None: zero) at points x (n, 3)."""
        g = (x - self.point - shift) @ self.normal
        return g, np.broadcast_to(self.normal, x.shape), None


class _Round:
    """Sphere or cylinder: g = +-(rho - radius), rho the distance to the centre (or axis)."""

    def __init__(self, radius: float, inside: bool):
        if not checks.number(radius, "radius") > 0:
            raise SceneError(f"radius must be a positive number, got {radius!r}")
        self.radius, self.sign = float(radius), -1.0 if inside else 1.0

    def gap(self, x: np.ndarray, shift: np.ndarray) -> tuple:
        r = self._radial(x - self.origin - shift)
        rho = np.linalg.norm(r, axis=1)
        e = r / rho[:, None]
        # Hessian of rho: (I - a a^T - e e^T) / rho, without the a a^T term for a sphere
        hessian = (self._projector - e[:, :, None] * e[:, None, :]) / rho[:, None, None]
        return self.sign * (rho - self.radius), self.sign * e, self.sign * hessian


class Sphere(_Round):
    def __init__(self, center: Sequence[float], radius: float, inside: bool = False):
        super().__init__(radius, inside)
        self.origin, self._projector = _point(center, "sphere center"), np.eye(3)

    def _radial(self, d):
        return d


class Cylinder(_Round):
    def __init__(self, point: Sequence[float], axis: Sequence[float], radius: float, inside: bool = False):
        super().__init__(radius, inside)
        self.origin, self.axis = _point(point, "cylinder point"), _unit(axis, "cylinder axis")
        self._projector = np.eye(3) - np.outer(self.axis, self.axis)

    def _radial(self, d):
        return d @ self._projector


SHAPES = {"plane": Plane, "sphere": Sphere, "cylinder": Cylinder}


class RigidContact(ContactFeature):
    """Frictionless penalty contact, augmented, of a surface's nodes with a rigid body.

    Args:
        name: name in summary.json.
        slave: the solid's surface that touches the rigid body.
        shape: "plane" (point, normal: the solid stays on the side the normal points to),
            "sphere" (center, radius) or "cylinder" (point, axis, radius): the solid stays
            outside, or inside with ``inside=True``.
        penalty: pressure per unit penetration (MPa/mm); default PENALTY_FACTOR * E / h of
            the slave's elements (``policy.py``); an expert's knob.
        displacement: rigid translation of the body, reached at the end of its step
            (ramped with the load factor); None: it stays.
        step: index of the load step from which the contact acts.
        smoothing: as for ``ContactPair``.
        **shape_params: the shape's parameters.
    """

    symmetric_tangent = True  # the Hessian of a potential

    def __init__(self, name: str, slave: str, shape: str, penalty: float | None = None, step: int = 0,
                 displacement: Sequence[float] | None = (0.0, 0.0, 0.0), smoothing: float = 0.0, **shape_params):
        super().__init__(name, slave, penalty, step, smoothing)
        if shape not in SHAPES:
            raise SceneError(f"contact {name!r}: unknown rigid shape {shape!r}; choose one of {sorted(SHAPES)}")
        try:
            self.shape = SHAPES[shape](**shape_params)
        except TypeError as error:
            raise SceneError(f"contact {name!r}: rigid {shape}: {error}".replace("__init__() ", "")) from None
        except SceneError as error:
            raise SceneError(f"contact {name!r}: rigid {shape}: {error}") from None
        self.displacement = np.zeros(3) if displacement is None else \
            _point(displacement, f"contact {name!r}: displacement")
        self.shift = np.zeros(3)

    def setup(self, solid: MixedSolid) -> None:
        tables = self.tables = SolidTables(solid)
        s = surface(solid, tables, self.slave_name)
        self.weight = s.node_area
        self.alpha = np.full(len(s.nodes), self.penalty) if self.penalty is not None else \
            default_penalty(s.node_stiffness, np.inf)
        self.thickness = np.sqrt(s.node_area)  # the size of the elements around the node
        self.slave_dofs = tables.dofs[s.nodes]
        self.slave_global = tables.global_index[self.slave_dofs]
        self.point_X = tables.X[s.nodes]
        self.point_nodes, self.point_N = self.slave_dofs[:, :1], np.ones((len(s.nodes), 1))
        self._setup_common(solid)

    def set_load_factor(self, factor: float) -> None:
        self.shift = factor * self.displacement

    def _positions(self):
        return (self.point_X + self.solid.w.x.array[self.slave_dofs], self.shift.copy())

    def _select(self, positions):
        g = self.shape.gap(positions[0], self.shift)[0]
        return Selection(np.arange(len(g)), np.full(len(g), -1), g)

    def _forces(self, sel, index, p, k, tangent):
        x = self._selection[0][0][sel.point[index]]
        _, grad, hess = self.shape.gap(x, self.shift)
        grad = np.ascontiguousarray(grad)
        w = self.weight[sel.point[index]]
        r = -(w * p)[:, None] * grad
        K = None
        if tangent:
            K = (w * k)[:, None, None] * grad[:, :, None] * grad[:, None, :]
            if hess is not None:
                K -= (w * p)[:, None, None] * hess
        return self.slave_global[sel.point[index]], r, K, grad

    def _gaps_along(self, du):
        x, dx = self._positions()[0], du[self.slave_dofs]
        point = np.arange(len(x))

        def gaps(fraction, index=slice(None)):
            y, dy = x[index], dx[index]
            return self.shape.gap(y + np.broadcast_to(fraction, len(y))[:, None] * dy, self.shift)[0]
        return point, gaps(0.0), gaps

    def _loaded_nodes(self, point):
        return int(self.solid.comm.allreduce(len(point)))

"""Material laws: each is a small class that gives its strain energy W(F) only.

Stresses and tangents come from ``ufl.derivative`` of the energy, never by hand (as
fenicsx-pulse's material models). Incompressible laws depend on the reduced invariants; J = 1
is enforced by the pressure Lagrange multiplier of the mixed formulation (``solid.py``).
"""
from __future__ import annotations

import dataclasses

import ufl

from .. import checks
from ..errors import SceneError
from .kinematics import green_lagrange, reduced_invariants


@dataclasses.dataclass(frozen=True)
class MooneyRivlin:
    """Generalized Mooney-Rivlin: W = sum c_rs (I1bar - 3)^r (I2bar - 3)^s, incompressible.

    Args:
        c: coefficients by exponent pair, ``{(1, 0): c10, (0, 1): c01, (2, 0): c20, ...}``.
    """

    c: dict
    incompressible = True
    volume_ratio = 1.0  # det of the rest-state change; J = volume_ratio is enforced

    def __post_init__(self):
        if not self.c:
            raise SceneError("c needs at least one coefficient, e.g. c = { \"10\" = 0.5 }")
        for (r, s), value in self.c.items():
            if not (isinstance(r, int) and isinstance(s, int) and r >= 0 and s >= 0 and r + s > 0):
                raise SceneError(f"c: exponents must be non-negative integers, not both zero, got ({r}, {s})")
            if isinstance(value, ufl.core.expr.Expr):
                continue  # cell-wise constants gathered from laws that were checked (solid.py)
            checks.number(value, f"c{r}{s}")
        if not any(isinstance(value, ufl.core.expr.Expr) for value in self.c.values()):
            checks.number(self.shear_modulus, "the initial shear modulus 2 (c10 + c01)", "positive")

    @property
    def shear_modulus(self) -> float:
        """Initial shear modulus mu = 2 (c10 + c01)."""
        return 2 * (self.c.get((1, 0), 0.0) + self.c.get((0, 1), 0.0))

    @property
    def youngs_modulus(self) -> float:
        """Initial Young's modulus of an incompressible law, E = 3 mu."""
        return 3.0 * self.shear_modulus

    def strain_energy(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        I1bar, I2bar, _ = reduced_invariants(F)
        return sum(c * (I1bar - 3) ** r * (I2bar - 3) ** s for (r, s), c in self.c.items())


def NeoHooke(c10: float) -> MooneyRivlin:
    """Neo-Hooke, W = c10 (I1bar - 3): the seed's law for all soft tissue."""
    checks.number(c10, "c10", "positive")
    return MooneyRivlin({(1, 0): c10})


@dataclasses.dataclass(frozen=True)
class LinearElastic:
    """Compressible linear elastic law made geometrically exact (St Venant-Kirchhoff).

    W = lambda/2 (tr E)^2 + mu tr(E^2), with E the Green-Lagrange strain, so that large
    rotations of stiff fibres (Zinn's zonule) carry no spurious stress.
    """

    E: float
    nu: float
    incompressible = False
    volume_ratio = 1.0

    def __post_init__(self):
        checks.number(self.E, "E", "positive")
        if not -1 < checks.number(self.nu, "nu") < 0.5:
            raise SceneError(f"nu must be a number in (-1, 0.5), got {self.nu!r}")

    @property
    def shear_modulus(self) -> float:
        return self.E / (2 * (1 + self.nu))

    @property
    def youngs_modulus(self) -> float:
        return self.E

    def strain_energy(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        lmbda = self.E * self.nu / ((1 + self.nu) * (1 - 2 * self.nu))
        E = green_lagrange(F)
        return lmbda / 2 * ufl.tr(E) ** 2 + self.shear_modulus * ufl.inner(E, E)


@dataclasses.dataclass(frozen=True)
class Prestretched:
    """A law whose rest state is changed by a prescribed deformation F_g (growth, shrink).

    W(F) = det(F_g) W_law(F F_g^-1): the energy of the elastic part of F per reference
    volume; an incompressible law then enforces J = det(F_g). A band whose rest length is
    shortened (``features.band.BandTightening``, through ``MixedSolid.prestretch``) is the use here.
    """

    law: object
    F_g: object  # UFL tensor, may hold Constants that ramp

    @property
    def incompressible(self) -> bool:
        return self.law.incompressible

    @property
    def shear_modulus(self) -> float:
        return self.law.shear_modulus

    @property
    def youngs_modulus(self) -> float:
        return self.law.youngs_modulus

    @property
    def volume_ratio(self) -> ufl.core.expr.Expr:
        return ufl.det(self.F_g)

    def strain_energy(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        return ufl.det(self.F_g) * self.law.strain_energy(F * ufl.inv(self.F_g))

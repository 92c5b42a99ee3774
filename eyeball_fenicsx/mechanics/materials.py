"""Material laws: each is a small class that gives its strain energy W(F) only.

Stresses and tangents come from ``ufl.derivative`` of the energy, never by hand (as
fenicsx-pulse's material models). Incompressible laws depend on the reduced invariants; J = 1
is enforced by the pressure Lagrange multiplier of the mixed formulation (``solid.py``).

``FibreReinforced`` is the sclera as a collagen composite: a neo-Hookean matrix and families of
fibres in the plane tangent to a sphere, each with the exponential energy of Holzapfel, Gasser &
Ogden (J Elasticity 2000;61:1), W_f = k1 / (2 k2) (exp(k2 <I4bar - 1>^2) - 1), that acts only
while the fibre is stretched (the Macaulay bracket <x> = max(x, 0): crimped collagen carries no
compression; Battaglioli & Kamm, IOVS 1984;25:59, found the sclera's compressive modulus over a
hundred times below its tensile one). The fibres lie in the tangent plane of the sphere about
``centre``, at angles from the circumferential direction about ``axis`` towards the meridional
one: scleral lamellae lie tangential to the scleral surface, in an isotropic matrix (the
microstructural sclera models of Grytz et al., e.g. IOVS ARVO article 2277049, and of Coudrillier
et al., J Biomech Eng 2015;137:041006, doi 10.1115/1.4029430: fibres and interfibre matrix).
"""
from __future__ import annotations

import dataclasses
import math

import ufl
from ufl.domain import extract_unique_domain

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
class FibreReinforced:
    """Neo-Hookean matrix and tension-only exponential fibres in the tangent plane of a sphere.

    W = c10 (I1bar - 3) + sum over fibres a of k1 / (2 k2) (exp(k2 <I4bar - 1>^2) - 1), with
    I4bar = J^(-2/3) a.C a and a = cos(angle) e_circ + sin(angle) e_merid at the reference point X:
    e_r = (X - centre) / |X - centre|, e_circ along axis x e_r, e_merid = e_r x e_circ.

    Args:
        c10: matrix constant (MPa); k1: fibre stiffness (MPa); k2: fibre stiffening (-).
        fibre_angles_deg: one fibre family per angle, from the circumferential direction.
        axis, centre: the sphere's axis and centre (the eye builders': z and the origin).
    """

    c10: float
    k1: float
    k2: float
    fibre_angles_deg: tuple = (0.0, 90.0)
    axis: tuple = (0.0, 0.0, 1.0)
    centre: tuple = (0.0, 0.0, 0.0)
    incompressible = True
    volume_ratio = 1.0

    def __post_init__(self):
        checks.number(self.c10, "c10", "positive")
        checks.number(self.k1, "k1", "positive")
        checks.number(self.k2, "k2", "positive")
        checks.numbers(self.fibre_angles_deg, "fibre_angles_deg")
        checks.nonzero_vector(self.axis, "axis")
        checks.vector(self.centre, "centre")

    @property
    def shear_modulus(self) -> float:
        """Initial shear modulus of the matrix, 2 c10 (the fibres are slack at rest)."""
        return 2 * self.c10

    @property
    def youngs_modulus(self) -> float:
        """Initial modulus in tension along a fibre, 6 c10 + 4 k1."""
        return 6 * self.c10 + 4 * self.k1

    def fibre_directions(self, X: ufl.core.expr.Expr) -> list:
        """The unit fibre directions at the reference point X (UFL vectors)."""
        radial = X - ufl.as_vector(self.centre)
        radial = radial / ufl.sqrt(ufl.dot(radial, radial))
        circumferential = ufl.cross(ufl.as_vector(self.axis), radial)
        # off the axis; the regularisation only acts within 1e-12 of it, where no quadrature point lies
        circumferential = circumferential / ufl.sqrt(ufl.dot(circumferential, circumferential) + 1e-24)
        meridional = ufl.cross(radial, circumferential)
        return [math.cos(math.radians(angle)) * circumferential + math.sin(math.radians(angle)) * meridional
                for angle in self.fibre_angles_deg]

    def strain_energy(self, F: ufl.core.expr.Expr) -> ufl.core.expr.Expr:
        I1bar, _, J = reduced_invariants(F)
        C = F.T * F
        W = self.c10 * (I1bar - 3)
        for a in self.fibre_directions(ufl.SpatialCoordinate(extract_unique_domain(F))):
            stretch = J ** (-2 / 3) * ufl.dot(a, C * a) - 1
            taut = ufl.conditional(ufl.gt(stretch, 0), stretch, 0)
            W = W + self.k1 / (2 * self.k2) * (ufl.exp(self.k2 * taut**2) - 1)
        return W


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

"""Closed-form solutions the validation demos, tests and benchmarks compare against.

Generalized Mooney-Rivlin coefficients are given as ``{(r, s): c_rs}``.
"""
from collections.abc import Sequence

import numpy as np
from scipy.integrate import quad
from scipy.optimize import brentq

Coefficients = dict[tuple[int, int], float]  # {(r, s): c_rs}
Layers = Sequence[tuple[float, float, Coefficients]]  # [(A, B, c)], reference radii inside out


def energy_derivatives(I1: float, I2: float, c: Coefficients) -> tuple[float, float]:
    """(dW/dI1, dW/dI2) of W = sum c_rs (I1 - 3)^r (I2 - 3)^s."""
    W1 = sum(v * r * (I1 - 3) ** (r - 1) * (I2 - 3) ** s for (r, s), v in c.items() if r)
    W2 = sum(v * s * (I1 - 3) ** r * (I2 - 3) ** (s - 1) for (r, s), v in c.items() if s)
    return W1, W2


def uniaxial_nominal_stress(stretch: float, c: Coefficients) -> float:
    """Homogeneous uniaxial nominal stress of an incompressible isotropic solid,
    P = 2 (lambda - lambda^-2) (W1 + W2 / lambda) with I1 = lambda^2 + 2/lambda,
    I2 = 2 lambda + lambda^-2 (Ogden, Non-linear elastic deformations, 1984, sec. 7.2)."""
    W1, W2 = energy_derivatives(stretch**2 + 2 / stretch, 2 * stretch + stretch**-2, c)
    return 2 * (stretch - stretch**-2) * (W1 + W2 / stretch)


def hoop_energy_derivative(lam: float, c: Coefficients) -> float:
    """d/dlambda of W at the equibiaxial stretch (lambda, lambda, lambda^-2)."""
    W1, W2 = energy_derivatives(2 * lam**2 + lam**-4, lam**4 + 2 * lam**-2, c)
    return W1 * (4 * lam - 4 * lam**-5) + W2 * (4 * lam**3 - 4 * lam**-3)


def sphere_pressure(lam_a: float, c: Coefficients, A: float, B: float) -> float:
    """Inner pressure that inflates a thick incompressible sphere (radii A < B) to the inner
    stretch lam_a: P = integral from lam_b to lam_a of W'(l) / (l^3 - 1) dl, with
    lam_b^3 = 1 + (lam_a^3 - 1) A^3 / B^3 (Ogden 1984, sec. 5.2.2, eq. 5.2.38)."""
    if lam_a == 1.0:
        return 0.0
    lam_b = (1 + (lam_a**3 - 1) * A**3 / B**3) ** (1 / 3)
    return quad(lambda lam: hoop_energy_derivative(lam, c) / (lam**3 - 1), lam_b, lam_a, epsabs=1e-14)[0]


def sphere_inner_stretch(P: float, c: Coefficients, A: float, B: float, upper: float = 3.0) -> float:
    """Inner stretch a/A of the thick sphere under inner pressure P (on the rising branch)."""
    return brentq(lambda lam: sphere_pressure(lam, c, A, B) - P, 1.0, upper, xtol=1e-14)


def layered_sphere_pressure(k: float, layers: Layers) -> float:
    """Inner pressure of a thick sphere of bonded incompressible layers ``[(A, B, c), ...]``
    (reference radii inside out, coefficients) whose cavity grew by 4 pi k / 3: a radial motion
    keeps r^3 - R^3 = k through every layer, and each layer carries ``sphere_pressure`` at its
    inner stretch (Ogden 1984, sec. 5.2.2)."""
    return sum(sphere_pressure(((A**3 + k) / A**3) ** (1 / 3), c, A, B) for A, B, c in layers)


def layered_sphere_growth(P: float, layers: Layers) -> float:
    """k = a^3 - A^3 of the layered sphere under inner pressure P (on the rising branch)."""
    inner = layers[0][0] ** 3
    return brentq(lambda k: layered_sphere_pressure(k, layers) - P, 0.0, inner, xtol=1e-12 * inner)


def wall_volume_change(P0: float, P1: float, angles: np.ndarray, layers: Sequence[Sequence[tuple[float, float, str]]],
                       materials: dict[str, Coefficients]) -> float:
    """Cavity volume added from pressure P0 to P1 inside a wall of revolution that is, direction
    by direction, a layered sphere: 2 pi / 3 integral of (k(P1) - k(P0)) sin(angle) (trapezoid
    rule on the given polar angles; ``layers`` one list per angle of ``(A, B, tissue)``, inside
    out, and ``materials`` the coefficients of each tissue).

    Adding the directions independently is exact for a closed spherical membrane of any thickness
    in linear theory: its stress resultants are N = P R / 2 whatever the thickness (statically
    determinate), each patch strains as its own thickness requires, and the volume change,
    (R / 2) integral of (e_theta + e_phi) dA, takes no part from the meridional displacement
    (it integrates to a boundary term, zero on a closed surface). The per-direction thick sphere
    then carries the finite strain and the wall's thickness."""
    walls = [[(A, B, materials[tissue]) for A, B, tissue in wall] for wall in layers]
    k = np.array([[layered_sphere_growth(P, wall) for wall in walls] for P in (P0, P1)])
    return 2 * np.pi / 3 * np.trapz((k[1] - k[0]) * np.sin(angles), angles)


def hertz_layer_force(mu: float, R: float, depth: float, L: float) -> float:
    """Force of a rigid sphere of radius R pressed ``depth`` into an incompressible layer of
    shear modulus mu and depth L on a frictionless base: Hertz's half-space force
    16/3 mu R^1/2 d^3/2 (Johnson 1985, eq. 4.23, nu = 1/2) times the finite-depth factor
    1 + 0.884 chi + 0.781 chi^2 + 0.386 chi^3 + 0.0048 chi^4, chi = a / L with a = (R d)^1/2
    (Dimitriadis et al., Biophys. J. 82 (2002) 2798, eq. 11, non-bonded, nu = 1/2)."""
    chi = np.sqrt(R * depth) / L
    return 16 / 3 * mu * np.sqrt(R) * depth**1.5 * (1 + 0.884 * chi + 0.781 * chi**2 + 0.386 * chi**3 + 0.0048 * chi**4)

"""Closed-form solutions the validation demos, tests and benchmarks compare against.

Generalized Mooney-Rivlin coefficients are given as ``{(r, s): c_rs}``.
"""
from scipy.integrate import quad
from scipy.optimize import brentq


def energy_derivatives(I1, I2, c):
    """(dW/dI1, dW/dI2) of W = sum c_rs (I1 - 3)^r (I2 - 3)^s."""
    W1 = sum(v * r * (I1 - 3) ** (r - 1) * (I2 - 3) ** s for (r, s), v in c.items() if r)
    W2 = sum(v * s * (I1 - 3) ** r * (I2 - 3) ** (s - 1) for (r, s), v in c.items() if s)
    return W1, W2


def uniaxial_nominal_stress(stretch, c):
    """Homogeneous uniaxial nominal stress of an incompressible isotropic solid,
    P = 2 (lambda - lambda^-2) (W1 + W2 / lambda) with I1 = lambda^2 + 2/lambda,
    I2 = 2 lambda + lambda^-2 (Ogden, Non-linear elastic deformations, 1984, sec. 7.2)."""
    W1, W2 = energy_derivatives(stretch**2 + 2 / stretch, 2 * stretch + stretch**-2, c)
    return 2 * (stretch - stretch**-2) * (W1 + W2 / stretch)


def hoop_energy_derivative(lam, c):
    """d/dlambda of W at the equibiaxial stretch (lambda, lambda, lambda^-2)."""
    W1, W2 = energy_derivatives(2 * lam**2 + lam**-4, lam**4 + 2 * lam**-2, c)
    return W1 * (4 * lam - 4 * lam**-5) + W2 * (4 * lam**3 - 4 * lam**-3)


def sphere_pressure(lam_a, c, A, B):
    """Inner pressure that inflates a thick incompressible sphere (radii A < B) to the inner
    stretch lam_a: P = integral from lam_b to lam_a of W'(l) / (l^3 - 1) dl, with
    lam_b^3 = 1 + (lam_a^3 - 1) A^3 / B^3 (Ogden 1984, sec. 5.2.2, eq. 5.2.38)."""
    if lam_a == 1.0:
        return 0.0
    lam_b = (1 + (lam_a**3 - 1) * A**3 / B**3) ** (1 / 3)
    return quad(lambda lam: hoop_energy_derivative(lam, c) / (lam**3 - 1), lam_b, lam_a, epsabs=1e-14)[0]


def sphere_inner_stretch(P, c, A, B, upper=3.0):
    """Inner stretch a/A of the thick sphere under inner pressure P (on the rising branch)."""
    return brentq(lambda lam: sphere_pressure(lam, c, A, B) - P, 1.0, upper, xtol=1e-14)

"""Kinematics of finite deformation, in UFL.

The reduced (isochoric) invariants of the right Cauchy-Green tensor C = F^T F are
``I1bar = J^(-2/3) tr C`` and ``I2bar = J^(-4/3) (tr(C)^2 - tr(C^2)) / 2``. They are the
arguments of the seed's strain energy ``W(I1bar, I2bar)``; the volume change J is
controlled separately (by the pressure Lagrange multiplier for incompressible tissue).
"""
from __future__ import annotations

import ufl
from ufl.core.expr import Expr


def deformation_gradient(u: Expr) -> Expr:
    """F = I + grad u, with grad taken in the reference configuration."""
    return ufl.Identity(len(u)) + ufl.grad(u)


def reduced_invariants(F: Expr) -> tuple[Expr, Expr, Expr]:
    """Return (I1bar, I2bar, J) of the deformation gradient F."""
    C = F.T * F
    J = ufl.det(F)
    I1 = ufl.tr(C)
    I2 = (I1**2 - ufl.tr(C * C)) / 2
    return J ** (-2 / 3) * I1, J ** (-4 / 3) * I2, J


def green_lagrange(F: Expr) -> Expr:
    """E = (C - I) / 2."""
    return (F.T * F - ufl.Identity(F.ufl_shape[0])) / 2


def cauchy_stress(first_piola: Expr, F: Expr) -> Expr:
    """sigma = P F^T / J."""
    return first_piola * F.T / ufl.det(F)


def von_mises(sigma: Expr) -> Expr:
    """Von Mises equivalent of a (3x3) Cauchy stress."""
    s = ufl.dev(sigma)
    return ufl.sqrt(3 / 2 * ufl.inner(s, s))

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


def determinant(F: Expr) -> Expr:
    """J = det F (3 x 3) as the triple product of its columns: a polynomial in F, which UFL
    differentiates into polynomials. ``ufl.det``'s derivative rule goes through F^-1 (the
    adjugate over det F), whose derivatives make longer compiled kernels."""
    return ufl.dot(F[:, 0], ufl.cross(F[:, 1], F[:, 2]))


def cofactor(F: Expr) -> Expr:
    """cof F = J F^-T (3 x 3), column by column: cof[:, a] = F[:, b] x F[:, c] with (a, b, c)
    cyclic; a polynomial in F, as ``determinant``."""
    columns = [ufl.cross(F[:, 1], F[:, 2]), ufl.cross(F[:, 2], F[:, 0]), ufl.cross(F[:, 0], F[:, 1])]
    return ufl.as_matrix([[columns[a][i] for a in range(3)] for i in range(3)])


def reduced_invariants(F: Expr) -> tuple[Expr, Expr, Expr]:
    """Return (I1bar, I2bar, J) of the deformation gradient F."""
    C = F.T * F
    J = determinant(F)
    I1 = ufl.tr(C)
    I2 = (I1**2 - ufl.tr(C * C)) / 2
    return J ** (-2 / 3) * I1, J ** (-4 / 3) * I2, J


def green_lagrange(F: Expr) -> Expr:
    """E = (C - I) / 2."""
    return (F.T * F - ufl.Identity(F.ufl_shape[0])) / 2


def cauchy_stress(first_piola: Expr, F: Expr) -> Expr:
    """sigma = P F^T / J."""
    return first_piola * F.T / determinant(F)


def von_mises(sigma: Expr) -> Expr:
    """Von Mises equivalent of a (3x3) Cauchy stress."""
    s = ufl.dev(sigma)
    return ufl.sqrt(3 / 2 * ufl.inner(s, s))

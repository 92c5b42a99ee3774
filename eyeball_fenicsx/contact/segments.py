"""The segments of contact surfaces: facets as the first-order element sees them.

A bilinear quadrilateral (the facet of a hexahedron) on [-1, 1]^2 and a linear triangle (of a
tetrahedron), nodes counter-clockwise seen from outside: their shape functions N_a(xi) and
derivatives, the same interpolation written as a polynomial in xi (the coefficients of 1,
xi_1, xi_2 and, on the quadrilateral, xi_1 xi_2: sum_a N_a v_a = sum_j xi^(j) c_j with
c_j = sum_a polynomial[j, a] v_a), their Gauss points (2 x 2 on the quadrilateral; degree 2,
Strang and Fix, on the triangle), and how far outside a segment a point of coordinates xi lies.
"""
from __future__ import annotations

import numpy as np


class Triangle:
    """Linear triangle: N = (1 - xi_1 - xi_2, xi_1, xi_2)."""

    corners = 3
    centre = (1.0 / 3.0, 1.0 / 3.0)
    bounds = (-1.0, 2.0)
    _dN = np.array([[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]])
    # sum_a N_a v_a = c_0 + xi_1 c_1 + xi_2 c_2, c_j = sum_a polynomial[j, a] v_a
    polynomial = np.array([[1.0, 0.0, 0.0], [-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])
    # degree-2 Gauss points (Strang and Fix): the weights sum to the reference area 1/2
    gauss_points = np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])
    gauss_weights = np.full(3, 1 / 6)

    @staticmethod
    def shape(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """N (n, 3) and dN/dxi (n, 3, 2) at points xi (n, 2)."""
        N = np.column_stack([1.0 - xi[:, 0] - xi[:, 1], xi[:, 0], xi[:, 1]])
        return N, np.broadcast_to(Triangle._dN, (len(xi), 3, 2))

    @staticmethod
    def outside(xi: np.ndarray) -> np.ndarray:
        """How far outside the segment a point lies, as a fraction of its size."""
        return np.maximum(0.0, -np.min(Triangle.shape(xi)[0], axis=1))


class Quad:
    """Bilinear quadrilateral on [-1, 1]^2, nodes counter-clockwise."""

    corners = 4
    centre = (0.0, 0.0)
    bounds = (-2.0, 2.0)
    _signs = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    # sum_a N_a v_a = c_0 + xi_1 c_1 + xi_2 c_2 + xi_1 xi_2 c_3, c_j = sum_a polynomial[j, a] v_a
    polynomial = 0.25 * np.array([[1, 1, 1, 1], [-1, 1, 1, -1], [-1, -1, 1, 1], [1, -1, 1, -1]], dtype=float)
    gauss_points = _signs / np.sqrt(3.0)  # 2 x 2 Gauss points, weight 1 each
    gauss_weights = np.ones(4)

    @staticmethod
    def shape(xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = Quad._signs
        f = 1.0 + xi[:, None, :] * s[None, :, :]  # (n, 4, 2): 1 + s_b xi_b
        N = 0.25 * f[:, :, 0] * f[:, :, 1]
        dN = 0.25 * np.stack([s[:, 0] * f[:, :, 1], s[:, 1] * f[:, :, 0]], axis=-1)
        return N, dN

    @staticmethod
    def outside(xi: np.ndarray) -> np.ndarray:
        return np.maximum(0.0, 0.5 * (np.max(np.abs(xi), axis=1) - 1.0))

"""The closing step: a Newton step that presses at once every point it closes.

The tangent knows nothing of an open point, so Newton's step du0 drives every point it closes
through the master (the onset limit, ``base.py``, then shortens it to the first contact: one
closing point per Newton iteration). Instead, where one would close deeper than the limit
allows (``ContactFeature.onset_depth``), the points outside the tangent that du0 would press
(shifted gap s = g + Gamma . du0 - lambda / alpha < 0; Gamma: the gap's gradient) take the
penalty now. The step solves (K + sum_C W alpha Gamma Gamma^T) du = -F by the Woodbury
identity: du = du0 + du(mu), with the pressures mu >= 0 at the closing set C from

    W (mu / alpha + C mu) = -W s    (per point of C),

where a pressure mu at the points changes the residual by -W mu Gamma (``_forces``), the
tangent K already factorized for Newton turns that into the state change du(mu), and C mu =
Gamma . du(mu) is the contact compliance (through everything the tangent holds: tissues,
cavities' volumes, the pressing points' penalty). C is applied matrix-free, one triangular
solve per product (``NewtonSolver.respond``), inside conjugate gradients on the closing
points' pressures, preconditioned by the penalty's part alone. This is the semismooth Newton
step of the penalty law (Hintermueller, Ito and Kunisch, SIAM J. Optim. 13 (2003) 865: the
primal-dual active set), with C chosen again (points with mu <= 0 leave it, newly pressed ones
join; a point left with mu < 0 when the rounds run out pulls in this step only, which the next
Newton step corrects) at most CLOSING_ROUNDS times. C is symmetric where the tangent is; a
contact pair's tangent is not quite (its curvature terms), and CG then still gives the
approximate solve the step needs: an inexact Newton step (to COMPLIANCE_RTOL, a tenth: each
product costs about a twentieth of a factorization, and the first few do most of the work),
which the onset limit checks afterwards, as it checks any step. Each contact feature takes its
closing step in turn, the step already changed by the ones before (``Problem.close_gaps``), not
in one system with them.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from mpi4py import MPI

from .policy import CLOSING_ROUNDS, COMPLIANCE_PROBE, COMPLIANCE_RTOL, MAX_COMPLIANCE_PRODUCTS

Respond = Callable[[np.ndarray, np.ndarray], np.ndarray]


def conjugate_gradients(apply, rhs, scaling, dot, start):
    """Preconditioned CG for A x = rhs, ``apply(x)`` giving (A x, y(x)) for a y linear in x (the
    state change the pressures cause), from ``start``, until the residual is COMPLIANCE_RTOL of
    the right side's, or MAX_COMPLIANCE_PRODUCTS products (``scaling``: the diagonal preconditioner,
    zero off the unknowns; ``dot``: the global inner product over the unknowns). Returns x and
    y(x), summed along the way (no product more; None if x is the zero start, untouched; collective)."""
    x = start.copy()
    if dot(x, x) > 0.0:
        product, response = apply(x)
        r = rhs - product
    else:
        r, response = rhs.copy(), None
    z = scaling * r
    direction, rz, size = z.copy(), dot(r, z), np.sqrt(dot(rhs, rhs))
    for _ in range(MAX_COMPLIANCE_PRODUCTS):
        product, change = apply(direction)
        curvature = dot(direction, product)
        if not curvature > 0.0:  # nothing left to do, or not positive: stop where it is
            break
        step = rz / curvature
        x += step * direction
        response = step * change if response is None else response + step * change
        r -= step * product
        if np.sqrt(dot(r, r)) <= COMPLIANCE_RTOL * size:
            break
        z = scaling * r
        rz_next = dot(r, z)
        direction, rz = z + (rz_next / rz) * direction, rz_next
    return x, response


def gap_rate(feature, du: np.ndarray, index=slice(None)) -> np.ndarray:
    """d g / dt of the selected points' gaps (``index``: which; default all) at the state changed
    by t du (local entries), at t = 0 (a difference over a change whose largest entry is
    COMPLIANCE_PROBE at most; collective)."""
    du = du[: feature._num_owned]
    largest = feature.solid.comm.allreduce(float(np.abs(du).max(initial=0.0)), op=MPI.MAX)
    if largest == 0.0:
        return np.zeros(len(feature._selection_now().point))[index]
    t = COMPLIANCE_PROBE / largest
    _, _, gaps = feature._gaps_along(du)
    return (gaps(t, index) - gaps(0.0, index)) / t


def pressure_response(feature, sel, index: np.ndarray, pressure: np.ndarray, respond: Respond) -> np.ndarray:
    """The state change (local entries) that pressures at the selected points ``index`` cause
    through the factorized tangent (collective)."""
    zero = np.zeros(len(index))
    rows, r, _, _ = feature._forces(sel, index, pressure, zero, False)
    return respond(rows.ravel(), r.ravel())


def closing_step(feature, du: np.ndarray, residual: np.ndarray, respond: Respond) -> np.ndarray | None:
    """The change of Newton's step du (local entries) that presses the points it closes
    (module docstring), or None if none would close deeper than its onset depth (``onset_depth``,
    at the Newton ``residual``: the onset limit would not shorten the step; collective)."""
    comm = feature.solid.comm
    sel, on, _, _ = feature._pressures()
    shift = feature._point_multipliers()[sel.point] / feature.alpha[sel.point]
    predicted = sel.g + gap_rate(feature, du) - shift
    closing = ~on & (predicted < 0.0)
    deep = closing & (predicted < -feature.onset_depth(sel.point, residual))
    if not comm.allreduce(bool(deep.any()), op=MPI.LOR):
        return None
    alpha, weight = feature.alpha[sel.point], feature.weight[sel.point]
    mu = np.zeros(len(sel.point))
    for _ in range(CLOSING_ROUNDS):
        index = np.flatnonzero(closing)

        def apply(x):
            out, change = np.zeros_like(x), pressure_response(feature, sel, index, x[index], respond)
            out[index] = weight[index] * (x[index] / alpha[index] + gap_rate(feature, change, index))
            return out, change

        def dot(a, b):
            return comm.allreduce(float(np.dot(a[index], b[index])), op=MPI.SUM)
        rhs, scaling = np.zeros_like(mu), np.zeros_like(mu)
        rhs[index], scaling[index] = -weight[index] * predicted[index], alpha[index] / weight[index]
        mu, change = conjugate_gradients(apply, rhs, scaling, dot, np.where(closing, mu, 0.0))
        if change is None:  # no step taken: no pressure
            change = np.zeros_like(du)
        chosen = (closing & (mu > 0.0)) | (~on & (predicted + gap_rate(feature, change) < 0.0))
        if not comm.allreduce(bool(np.any(chosen != closing)), op=MPI.LOR):
            break
        closing = chosen
    return change

"""The closing step: a Newton step that presses at once every point it closes, and releases
every point it opens.

The tangent holds the points that press (the active set A) and knows nothing of the others,
so Newton's step du0 drives every point it closes through the master (the onset limit,
``base.py``, then shortens it to the first contact: one closing point per Newton iteration;
a point that closes less than its onset depth enters the tangent at the next iteration), and
it still pulls on every point of A that it opens: those leave the tangent at the next
iteration only, so that a band pressed over its whole width lets go of its edges a few rows
per Newton iteration (the seed's "tighten": 320, 160, then 80 pressing points). Instead,
where a point would close or a point of A would open, the step is taken with the active set
it predicts. With the shifted gap s = g + Gamma . du0 - lambda / alpha of each point after du0
(Gamma: the gap's gradient), the points outside A with s < 0 (the closing set) take the
penalty now, and the points of A with s > 0 (the opening set) lose it. The step solves
K' du = -F, K' the tangent with the closing points' penalty W alpha Gamma Gamma^T added and
the opening points' taken out (their forces too), by the Woodbury identity: du = du0 + du(e),
with the pressures e at the changing set S from

    e / alpha + sigma C e = -sigma s    (per point of S; sigma = +1 closing, -1 opening),

where a pressure e at the points changes the residual by -W e Gamma (``_forces``), the
tangent K already factorized for Newton turns that into the state change du(e), and C e =
Gamma . du(e) is the contact compliance (through everything the tangent holds: tissues,
cavities' volumes, the pressing points' penalty). At a closing point e is its new pressure;
at an opening one, e cancels the pressure alpha (lambda / alpha - g - Gamma . du) that the
tangent's linear model still gives it, so the point is free. C is applied matrix-free, one
triangular solve per product (``NewtonSolver.respond``), inside GMRES on the system's rows
scaled by alpha, in the inner product of the pressures weighted by W / alpha. The system is
not symmetric (sigma), but in that inner product its symmetric part is block-diagonal and
positive definite where the tangent is (W C is symmetric there: I / alpha + C at the closing
points, and I / alpha - C at the opening ones, which the Woodbury identity shows positive
definite where the tangent without them is), so GMRES converges on it (Elman's bound for
positive-real systems). This is the semismooth Newton step of the penalty law
(Hintermueller, Ito and Kunisch, SIAM J. Optim. 13 (2003) 865: the primal-dual active set),
with S chosen again (points of S with e <= 0 leave it, newly changing ones join; a point left
with e < 0 when the rounds run out pulls (closing) or is let through (opening) in this step
only, which the next Newton step corrects) at most CLOSING_ROUNDS times. Where many points
change, the set takes several rounds to settle. A round costs a few triangular solves; a set
left unsettled costs Newton iterations, a factorization each, and can cycle across them
(benchmarks/README.md measures both).

A chord step's tangent (newton.py) was assembled with the points that pressed then (T), and
the state's pressing points (P, whose forces the residual holds) may have changed since (an
augmentation moved the multipliers). The same identity gives the step with the predicted set
Q from any T and P: the pressure e a point takes is the predicted law's, -q alpha (s0 + Gamma .
du), less the linear model's, r p0 - t alpha Gamma . du (s0 = g - lambda / alpha the shifted gap
now, p0 = -alpha s0 its pressure; q, r, t whether the point is in Q, P, T), so

    e / alpha + sigma C e = (r - q) s0 - sigma Gamma . du0,    sigma = q - t,

the system above where P = T (s = s0 + Gamma . du0). A point whose r and t differ stays in S:
if q is t, its row fixes e (its force, -alpha s0, put in or taken out), which leaves the
system block-triangular with the rows above; the rounds move it between the two kinds by the
gap they leave it. Only the penalty's part of the tangent is corrected: the terms that scale
with the pressure (the curvature of the master, or of a rigid sphere or cylinder) stay as the
tangent had them, exact for a flat rigid body and otherwise what makes the chord step a chord
step, which converges linearly (newton.py takes a new tangent once one contracts too little).

A contact pair's tangent is not quite symmetric (its curvature terms), and GMRES then gives the
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


def gmres(apply, rhs, dot, start):
    """GMRES (Saad and Schultz, SIAM J. Sci. Stat. Comput. 7 (1986) 856) for A x = rhs, ``apply(x)``
    giving (A x, y(x)) for a y linear in x (the state change the pressures cause), from ``start``,
    until the residual is COMPLIANCE_RTOL of the right side's, or MAX_COMPLIANCE_PRODUCTS products
    (``dot``: the global inner product over the unknowns). A start within that tolerance still
    takes a step (unless it solves the system exactly): it is the round before's, for another set
    of points, and taken as it is it can cancel Newton's step (the test of this). Returns x and
    y(x), combined from the products' (None if x is the zero start, untouched; collective)."""
    x, response = start.copy(), None
    r = rhs.copy()
    if dot(x, x) > 0.0:
        product, response = apply(x)
        r -= product
    beta, size = np.sqrt(dot(r, r)), np.sqrt(dot(rhs, rhs))
    if not beta > 0.0:
        return x, response
    basis, changes, hessenberg = [r / beta], [], np.zeros((MAX_COMPLIANCE_PRODUCTS + 1, MAX_COMPLIANCE_PRODUCTS))
    target = np.zeros(MAX_COMPLIANCE_PRODUCTS + 1)
    target[0] = beta
    for k in range(MAX_COMPLIANCE_PRODUCTS):
        w, change = apply(basis[k])
        changes.append(change)
        for j, v in enumerate(basis):  # modified Gram-Schmidt
            hessenberg[j, k] = dot(w, v)
            w -= hessenberg[j, k] * v
        hessenberg[k + 1, k] = np.sqrt(dot(w, w))
        h = hessenberg[: k + 2, : k + 1]
        y = np.linalg.lstsq(h, target[: k + 2], rcond=None)[0]
        residual = np.linalg.norm(h @ y - target[: k + 2])  # lstsq's own is empty if h is rank deficient
        done = not hessenberg[k + 1, k] > 1e-14 * beta or residual <= COMPLIANCE_RTOL * size
        if done or k + 1 == MAX_COMPLIANCE_PRODUCTS:
            break
        basis.append(w / hessenberg[k + 1, k])
    x += sum(c * v for c, v in zip(y, basis))
    step = sum(c * change for c, change in zip(y, changes))
    return x, step if response is None else response + step


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


def closing_step(feature, du: np.ndarray, respond: Respond) -> np.ndarray | None:
    """The change of Newton's step du (local entries) that presses the points it closes and
    releases those it opens, and gives the tangent's set of points the state's (module
    docstring), or None if it changes no point's contact (collective)."""
    comm = feature.solid.comm
    sel, on, _, _ = feature._pressures()
    alpha, weight = feature.alpha[sel.point], feature.weight[sel.point]
    tangent = feature.in_tangent(sel.point)
    multiplier = feature._point_multipliers()[sel.point]
    predicted = sel.g + gap_rate(feature, du) - multiplier / alpha
    shifted = sel.g - multiplier / alpha
    press = np.where(tangent, ~(predicted > 0.0), predicted < 0.0)  # as the rule before it, NaN included
    if not comm.allreduce(bool(np.any((press != tangent) | (press != on))), op=MPI.LOR):
        return None
    settled = on == tangent  # the state's pressing points are the tangent's
    held = (on.astype(float) - tangent) * shifted  # (r - t) s0: a force the residual holds and the tangent not
    e = np.zeros(len(sel.point))
    for _ in range(CLOSING_ROUNDS):
        changing = (press != tangent) | (press != on)
        index = np.flatnonzero(changing)
        sign = press.astype(float) - tangent  # +1 closing, -1 opening, 0 the tangent's as it is

        def apply(x):
            out, change = np.zeros_like(x), pressure_response(feature, sel, index, x[index], respond)
            out[index] = x[index] + sign[index] * alpha[index] * gap_rate(feature, change, index)
            return out, change

        def dot(a, b):
            return comm.allreduce(float(np.sum(weight[index] / alpha[index] * a[index] * b[index])), op=MPI.SUM)
        rhs = np.zeros_like(e)
        rhs[index] = alpha[index] * (held[index] - sign[index] * predicted[index])
        e, change = gmres(apply, rhs, dot, np.where(changing, e, 0.0))
        if change is None:  # no step taken: no pressure
            change = np.zeros_like(du)
        after = predicted + gap_rate(feature, change)
        chosen = np.where(settled & changing, np.where(e > 0.0, press, tangent),
                          np.where(tangent, ~(after > 0.0), after < 0.0))
        if not comm.allreduce(bool(np.any(chosen != press)), op=MPI.LOR):
            break
        press = chosen
    return change

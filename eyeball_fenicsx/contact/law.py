"""The normal contact law: pressure from the gap, with an augmented-Lagrangian multiplier.

With the penalty alpha (pressure per unit penetration) and the multiplier lambda of the
point (the pressure of the last augmentation), the contact pressure is

    p = <lambda - alpha g>_+                                   (sharp),
    p = alpha delta log(1 + exp((lambda / alpha - g) / delta))  (smoothed over delta),

and its stiffness k = -dp/dg is alpha where p > 0 (sharp; and at p = 0 for a point that
touches, a clearance closed at the start), alpha / (1 + exp(-(lambda/alpha -
g)/delta)) (smoothed: continuous). Uzawa's update lambda <- p(g) between Newton solves drives
the penetration to zero where the surfaces press (Simo and Laursen, Comput. Struct. 42
(1992) 97-116; Wriggers, Computational Contact Mechanics, 2006, sect. 6.3), so the answer
no longer depends on alpha, nor on delta where p >> alpha delta.
"""
from __future__ import annotations

import numpy as np


def pressure(g: np.ndarray, multiplier: np.ndarray, alpha: np.ndarray, smoothing: float,
             touching: np.ndarray | bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Contact pressure p (>= 0) and its stiffness k = -dp/dg at gaps g; a ``touching`` point
    (sharp law) has the stiffness at p = 0 too, so that surfaces that touch with no pressure
    yet are in the tangent (a clearance closed at the start, ``ContactPair``'s ``adjust``)."""
    shifted = multiplier / alpha - g
    if smoothing > 0.0:
        s = shifted / smoothing
        return alpha * smoothing * np.logaddexp(0.0, s), alpha * 0.5 * (1.0 + np.tanh(0.5 * s))
    p = alpha * np.maximum(shifted, 0.0)
    return p, np.where((shifted > 0.0) | (touching & (shifted == 0.0)), alpha, 0.0)

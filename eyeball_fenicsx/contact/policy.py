"""Every policy constant of contact, in one place (each is explained where it is used).

Penalty: a contact pressure per unit penetration (MPa/mm) of PENALTY_FACTOR times the
stiffness E/h of the two surface layers of elements in series (``surface.py``). The
augmented Lagrangian (``base.py``) removes its penetration, so the factor only sets how
many augmentations a step needs against how hard the Newton problem is.
"""
PENALTY_FACTOR = 30.0
SEARCH_FACTOR = 1.0  # candidate segments lie within this many segment sizes of a point (plus the last motion)
ACTIVE_RANGE = 20.0  # a smoothed law acts up to gaps of this many smoothing lengths (force e^-20)
OPEN_RANGE = 3.0  # ... and its stiffness is below 5 % of the penalty beyond this many: "open"
ONSET_DEPTH = 0.05  # a point closing in one Newton step may go this deep (fraction of its element's thickness)
ONSET_ITERATIONS = 8  # regula falsi steps to find where along a Newton step a gap reaches that depth
AUGMENT_TOLERANCE = 1e-5  # the contact pressure field changes by less than this (relative, L2): augmented
MAX_AUGMENTATIONS = 30  # Newton solves of one increment's end at most, for the augmentations
AITKEN_BOUNDS = (0.1, 10.0)  # the relaxation of the multipliers' updates stays within these

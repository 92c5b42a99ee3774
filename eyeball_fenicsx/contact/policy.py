"""Every policy constant of contact, in one place (each is explained where it is used).

Penalty: a contact pressure per unit penetration (MPa/mm) of PENALTY_FACTOR times the
stiffness E/h of the two surface layers of elements in series (``surface.py``). The
augmented Lagrangian (``augmented.py``) removes its penetration, so the factor only sets how
many augmentations a step needs (a softer penalty: more) against how hard contact onset is
for Newton (a stiffer one: a point that closes in one step meets a pressure far above the
loads). The factor is the one of 1, 3, 10 and 30 with which the encircling operation takes
the fewest Newton iterations (the study is in the git log and benchmarks/README.md).
"""
PENALTY_FACTOR = 3.0
SEARCH_FACTOR = 0.5  # candidates: within this many of the master's largest segment size (pair.py; checked)
ACTIVE_RANGE = 20.0  # a smoothed law acts up to gaps of this many smoothing lengths (force e^-20)
OPEN_RANGE = 3.0  # ... and its stiffness is below 5 % of the penalty beyond this many: "open"
ONSET_DEPTH = 0.05  # a point closing in one Newton step may go this deep (fraction of its element's thickness)
ONSET_ITERATIONS = 8  # regula falsi steps to find where along a Newton step a gap reaches that depth
AUGMENT_DEPTH = 1e-3  # augmented: no multiplier update moves its node more than this (fraction of its element's depth)
MAX_AUGMENTATIONS = 30  # Newton solves of one increment's end at most, for the augmentations
PENALTY_GROWTH_TEST = 0.5  # an augmentation that removes less than half of the penetration left ...
PENALTY_GROWTH = 2.0  # ... multiplies the penalty by this for the next passes of the increment,
MAX_PENALTY_GROWTH = 16.0  # up to this many times the elements' penalty
AITKEN_BOUNDS = (0.1, 10.0)  # the relaxation of the multipliers' updates stays within these
CLOSING_ROUNDS = 8  # closing step (compliance.py): the changing set chosen again at most this many times
COMPLIANCE_RTOL = 0.1  # ... its GMRES stops at this relative residual (an inexact step)
MAX_COMPLIANCE_PRODUCTS = 60  # ... or after this many products (a triangular solve each)
COMPLIANCE_PROBE = 1e-6  # the largest entry of the change whose difference gives the gaps' rates (mm, MPa)
# Newton's options (``system/newton.py``) with contact: the onset limit already shortens the
# Newton step, and a backtracking line search would take a fraction of that again (a shortened
# Newton step decreases the residual less than its sufficient-decrease test asks), and crawl;
# and a contact onset may still cost iterations, so an increment where many nodes close needs more of them
NEWTON_OPTIONS = {"snes_linesearch_type": "basic", "snes_max_it": 30}

"""The eye's node azimuths, and the butterfly discs of the cores that cross its axis
(eye_revolution.py revolves the meridional section over them and sweeps the discs).

Around given meridians (``graded_azimuths``: a radial sponge's sides and its sutures' bites,
buckle_sutures.py) the azimuths are graded as the meridian's columns are at the circles of
latitude (eye_meridian.py): measured along the equator, the spacing is ``FINE_SPACING`` (over
``refine``) at each such meridian and grows by ``GRADING`` per mm away from the nearest, up to the
usual 2 pi R_o / n_circ (lines closer than FINE_SPACING / 2 share a node, as the meridian's
circles share a column); the azimuths 0 and pi stay nodes (the section pictures cut the plane
y = 0), and the count is raised to a multiple of 8 for the cores.

A core does not need the azimuths that crowd at the sponge: going round from azimuth 0, every
three graded elements that together are no wider than the even 2 pi / n_circ become one element
of a smaller disc, joined to the graded circle by a transition ring of conforming 1-to-3
templates (one quadrilateral against the smaller disc, three against the graded circle, and two
nodes between them: four quadrilaterals; hexahedra, as everywhere in a core, by sweeping the disc
through the core's layers), and so on inwards while three merge (a ring merges none more than
``SPREAD`` times wider than its narrowest, leaving the wider to the deeper rings inside). The
innermost disc's square still has its boundary nodes evenly spread, so its rings turn them onto
the azimuths left: the square is smaller (``GRADED_CORE_SQUARE``), its nodes are first moved out onto a circle
(``ROUND``), and from there each node's angle changes in proportion to the logarithm of the radius,
so that every ring's quadrilaterals are sheared alike, with a ring per ``MAX_RING_TURN`` of the
largest turn (each node goes to the graded azimuth the same number of places on, the shift that
turns the nodes least). On the default eye graded around a radial sponge, 72 azimuths become 56,
then 48: a core disc on all 72 has 428 quadrilaterals instead of 684. The same coarser sets
(:func:`coarser_levels`) serve the revolved columns away from the sponge (eye_revolution.py), so
that with a sponge's ``graded_between`` the cores take the coarsest directly (288 quadrilaterals).
"""
import itertools
import math

import numpy as np

from .eye_meridian import CORE_SQUARE, FINE_SPACING, divided, graded_spacing, integrated

MAX_RING_TURN = math.radians(20.0)  # the largest turn of a graded core's ring about the axis
GRADED_CORE_SQUARE = 0.14  # a graded core's square, smaller, so that its rings have room to turn ...
ROUND = 0.25              # ... from a circle just outside it
TEMPLATE_DEPTH = 2.0  # a graded core's transition ring is this many times as deep as its merged elements' median width,
SPREAD = 4.0          # ... and merges none wider than this many times the narrowest it merges (but four);
MIDDLE_DEPTHS = np.linspace(0.3, 0.7, 5)  # its templates' middle nodes: the best of these depths (of the ring's)
MIDDLE_BLENDS = np.linspace(0.0, 1.0, 5)  # ... and of these steps from their graded azimuths to the even thirds


def disc(n_circ, rings, azimuths=None):
    """Butterfly mesh of the unit disc: a square of (n_circ / 4)^2 quadrilaterals inside ``rings``
    rings of n_circ quadrilaterals, whose outer nodes are at angles 2 pi k / n_circ. Given the
    graded ``azimuths`` (increasing from 0, a multiple of 8 of them, as :func:`node_azimuths` gives
    them; n_circ then the eye's even count, which sets how wide merged elements may be), the outer
    nodes are at those: a transition ring (:func:`_transition`) takes a smaller disc's nodes at some
    of them (:func:`_kept_inside`) out to all of them, its depth ``TEMPLATE_DEPTH`` times the merged
    elements' median width; and so on inwards while elements merge (:func:`coarser_levels`); the
    innermost disc is :func:`_butterfly`'s, turned onto the azimuths left.

    Returns:
        ``(points, quads)``: coordinates, shape ``(N, 2)``, and counter-clockwise quadrilaterals.
    """
    if azimuths is None:
        return _butterfly(n_circ, rings)
    levels, kept = coarser_levels(azimuths, n_circ)
    points, quads = _butterfly(len(levels[-1]), rings, levels[-1])
    for finer, inside_kept in zip(levels[-2::-1], kept[::-1]):  # the transition rings, outwards
        merged = np.diff(np.append(inside_kept, len(finer))) == 3
        merged_widths = np.diff(np.append(finer[inside_kept], 2 * np.pi))[merged]
        inside = 1.0 - TEMPLATE_DEPTH * np.median(merged_widths) / 3  # the smaller disc's radius
        points, quads = _transition(inside * points, quads, finer, inside_kept, inside)
    return points, quads


def _butterfly(n_circ, rings, azimuths=None):
    """The butterfly disc of :func:`disc`, its outer nodes at 2 pi k / n_circ, or at the graded
    ``azimuths`` (n_circ of them; then a rounding ring and at least ``rings`` more, enough to turn
    to them: :func:`_turns`)."""
    m = n_circ // 4
    ticks = (CORE_SQUARE if azimuths is None else GRADED_CORE_SQUARE) * np.linspace(-1.0, 1.0, m + 1)
    grid = np.arange((m + 1) ** 2).reshape(m + 1, m + 1)  # grid[i, j] at (ticks[i], ticks[j])
    points = [np.stack(np.meshgrid(ticks, ticks, indexing="ij"), axis=-1).reshape(-1, 2)]
    quads = [np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=-1).reshape(-1, 4)]
    # The square's boundary counter-clockwise from (CORE_SQUARE, 0), the point of angle 0.
    half = m // 2
    boundary = np.concatenate([grid[m, half:], grid[m - 1::-1, m], grid[0, m - 1::-1], grid[1:, 0],
                               grid[m, 1:half]])
    square = points[0][boundary]
    if azimuths is None:
        angles = 2 * np.pi * np.arange(n_circ) / n_circ
        circle = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
        ring_points = [(1 - t) * square + t * circle for t in np.arange(1, rings + 1) / rings]
    else:
        ring_points = _turns(square, azimuths, rings)
    previous = boundary
    for ring, ring_point in enumerate(ring_points):
        ids = (m + 1) ** 2 + ring * n_circ + np.arange(n_circ)
        points.append(ring_point)
        quads.append(np.stack([previous, ids, np.roll(ids, -1), np.roll(previous, -1)], axis=-1))
        previous = ids
    points = np.concatenate(points)
    points[np.abs(points) < 1e-15] = 0.0
    return points, np.concatenate(quads)


def _kept_inside(azimuths, n_circ):
    """The indices of the ``azimuths`` (increasing from 0) that the disc inside a transition ring keeps:
    going round from azimuth 0, every three elements that together span no more than the even
    2 pi / n_circ become one, the others stay; those wider than ``SPREAD`` times the narrowest
    merged are split again (they may merge in the next ring inwards, a deeper one), but four if
    fewer pass, and so are the widest left until the count is a multiple of 8 (an even square)."""
    n, i, starts = len(azimuths), 0, []
    closed = np.append(azimuths, 2 * np.pi)
    half = np.flatnonzero(azimuths == np.pi)  # pi stays a node (the section pictures)
    while i + 3 <= n:
        if closed[i + 3] - closed[i] <= 2 * np.pi / n_circ * (1 + 1e-9) and not np.any((i < half) & (half < i + 3)):
            starts.append(i)
            i += 3
        else:
            i += 1
    starts = np.array(starts, dtype=int)
    width = closed[starts + 3] - closed[starts]
    widest_last = np.argsort(width, kind="stable")
    count = max(np.sum(width <= SPREAD * width.min(initial=np.inf)), min(4, len(starts)))
    starts = np.sort(starts[widest_last[:count - count % 4]])
    keep = np.ones(n, dtype=bool)
    keep[np.concatenate([starts + 1, starts + 2])] = False
    return np.flatnonzero(keep)


def _transition(points, quads, azimuths, kept, inside):
    r"""The ring from a disc of radius ``inside`` (``points``, ``quads``; its last len(kept) points its
    outer circle, at azimuths[kept]) out to the unit circle at every one of the ``azimuths``. An
    inner element e-f over one graded element is one quadrilateral; over three, a-b-c-d, the 1-to-3
    template of four: e-a-b-p, p-b-c-q, q-c-d-f and e-p-q-f, whose middle nodes p and q lie where
    the template's worst corner is best among ``MIDDLE_DEPTHS`` x ``MIDDLE_BLENDS`` (between the
    azimuths of b and c and the inner element's thirds)::

        a    b    c    d      (the unit circle)
        |    |    |    |
        |    p----q    |
        |  /        \  |
        e--------------f      (the circle of radius ``inside``)

    The unit circle's nodes come last, in the azimuths' order."""
    n, total = len(azimuths), len(points)
    inner = total - len(kept) + np.arange(len(kept))  # their node k is at azimuths[kept[k + shift]] (_turns)
    first = np.arctan2(points[inner[0], 1], points[inner[0], 0])
    inner = np.roll(inner, np.argmin(np.abs(np.remainder(azimuths[kept] - first + np.pi, 2 * np.pi) - np.pi)))
    over_three = np.diff(np.append(kept, n)) == 3  # the inner elements that are templates
    templates = kept[over_three]
    between = (templates[:, None] + [1, 2]).ravel()
    middle = total + np.arange(len(between)).reshape(-1, 2)  # the templates' middle nodes
    outer = total + len(between) + np.arange(n)
    new_quads = transition_quads(kept, n, inner, outer, middle)
    circle = np.stack([np.cos(azimuths), np.sin(azimuths)], axis=-1)
    thirds = template_thirds(azimuths, templates)
    e, f = inner[over_three], np.roll(inner, -1)[over_three]
    xe, xa, xb, xc, xd, xf = points[e], *(circle[(templates + k) % n] for k in range(4)), points[f]
    best, quality = np.zeros((len(templates), 2, 2)), np.full(len(templates), -np.inf)
    for depth, toward_thirds in itertools.product(MIDDLE_DEPTHS, MIDDLE_BLENDS):
        angles = toward_thirds * thirds + (1 - toward_thirds) * azimuths[between].reshape(-1, 2)
        middles = (1 - depth * (1 - inside)) * np.stack([np.cos(angles), np.sin(angles)], axis=-1)
        xp, xq = middles[:, 0], middles[:, 1]
        worst = np.min([_worst_corner(np.stack(quad, axis=1)) for quad in
                        ([xe, xa, xb, xp], [xp, xb, xc, xq], [xq, xc, xd, xf], [xe, xp, xq, xf])], axis=0)
        best[worst > quality] = middles[worst > quality]
        quality = np.maximum(quality, worst)
    if np.any(quality <= 0):
        raise RuntimeError("eye: a graded core's transition template is inverted wherever its middle nodes go")
    points = np.concatenate([points, best.reshape(-1, 2), circle])
    points[np.abs(points) < 1e-15] = 0.0
    return points, np.concatenate([quads, new_quads])


def transition_quads(kept: np.ndarray, n: int, inner: np.ndarray, outer: np.ndarray,
                     middle: np.ndarray) -> np.ndarray:
    """The quadrilaterals between a line of nodes ``inner`` at azimuths[kept] and a line ``outer`` at
    all ``n`` azimuths (both closed round the circle): one over each inner element that spans one
    outer element, the 1-to-3 template (:func:`_transition`) over each that spans three, with its
    two ``middle`` nodes (a row per template, in the order of ``kept``), in the node order of
    ``inner``, ``outer``, ``outer``, ``inner`` as a ring's."""
    span = np.diff(np.append(kept, n))
    templates = kept[span == 3]
    ring = np.column_stack([inner, outer[kept], outer[(kept + 1) % n], np.roll(inner, -1)])[span == 1]
    e, f = inner[span == 3], np.roll(inner, -1)[span == 3]
    a, b, c, d = (outer[(templates + k) % n] for k in range(4))
    p, q = middle[:, 0], middle[:, 1]
    return np.concatenate([ring, *(np.column_stack(corners) for corners in
                                   ([e, a, b, p], [p, b, c, q], [q, c, d, f], [e, p, q, f]))])


def template_thirds(azimuths: np.ndarray, templates: np.ndarray) -> np.ndarray:
    """The azimuths a third and two thirds across each 1-to-3 template starting at ``templates``."""
    closed = np.append(azimuths, 2 * np.pi)
    return closed[templates, None] + (closed[templates + 3] - closed[templates])[:, None] * [1 / 3, 2 / 3]


def coarser_levels(azimuths: np.ndarray, n_circ: int) -> tuple[list, list]:
    """The graded ``azimuths`` and the coarser sets inside them, as the cores' transition rings take
    them (:func:`_kept_inside`): the sets (the first the graded one) and, for each but the last,
    the indices of the next set's azimuths in it."""
    levels, kept = [azimuths], []
    while len(inside := _kept_inside(levels[-1], n_circ)) < len(levels[-1]):
        kept.append(inside)
        levels.append(levels[-1][inside])
    return levels, kept


def _worst_corner(quads):
    """The smallest scaled Jacobian (sine of the angle) at the corners of counter-clockwise
    quadrilaterals ``quads``, shape ``(count, 4, 2)``."""
    out = np.roll(quads, -1, axis=1) - quads
    back = np.roll(quads, 1, axis=1) - quads
    cross = out[..., 0] * back[..., 1] - out[..., 1] * back[..., 0]
    return np.min(cross / (np.linalg.norm(out, axis=-1) * np.linalg.norm(back, axis=-1)), axis=1)


def _turns(square, azimuths, rings):
    """The rings' points from the core square's boundary nodes (evenly spread) out to the unit
    circle's at the graded ``azimuths``. The first ring is the square's nodes moved out along
    their directions onto the circle of radius ``ROUND``; from there square node k turns to the
    azimuth k + shift (the shift that turns the nodes least), by steps of the same ratio of radius,
    so that r d(angle) / d(radius) is the same at every radius, with at least one ring per
    ``MAX_RING_TURN`` of the largest turn."""
    n = len(azimuths)
    psi = np.unwrap(np.arctan2(square[:, 1], square[:, 0]))
    k = np.arange(n)
    best = None
    for shift in range(n):
        turn = azimuths[(k + shift) % n] + 2 * np.pi * ((k + shift) // n) - psi
        turn -= 2 * np.pi * round(float(np.mean(turn)) / (2 * np.pi))
        if best is None or np.abs(turn).max() < np.abs(best).max():
            best = turn
    rings = max(rings, math.ceil(np.abs(best).max() / MAX_RING_TURN))
    out = [ROUND * np.stack([np.cos(psi), np.sin(psi)], axis=-1)]
    for t in np.arange(1, rings + 1) / rings:
        angle = psi + t * best
        out.append(ROUND ** (1 - t) * np.stack([np.cos(angle), np.sin(angle)], axis=-1))
    return out


def node_azimuths(n_circ: int, sector_deg: float, graded=(), radius: float = 1.0, refine: int = 1) -> np.ndarray:
    """The eye's node azimuths (rad), increasing from 0: 2 pi k / n_circ over the model's sector (with
    both ends in a wedge); on the whole eye, graded around the azimuths ``graded`` (rad) at the
    equator's ``radius`` (module docstring)."""
    if len(graded):
        return _graded_azimuths(n_circ, np.mod(graded, 2 * np.pi), radius, refine)
    sectors = round(n_circ * sector_deg / 360.0)
    return 2 * np.pi * np.arange(sectors + (0 if sector_deg >= 360.0 else 1)) / n_circ


def _graded_azimuths(n_circ, lines, radius, refine):
    """The whole circle's azimuths graded around ``lines`` (rad, in [0, 2 pi)): each piece between two
    breaks (the lines and the azimuths 0 and pi, but a line within FINE_SPACING / 2 of a break before it) is
    divided where equal steps of the integral of 1 / spacing fall, and the pieces whose steps are
    longest are given one more until the count is a multiple of 8. Two lines just over FINE_SPACING / 2
    apart (a sponge's bites at two latitudes) leave an element that long between them."""
    fine = FINE_SPACING / refine / radius  # rad
    breaks = [0.0, np.pi]
    for line in sorted(lines):
        if min(abs(math.remainder(line - b, 2 * np.pi)) for b in breaks) > fine / 2:
            breaks.append(line)
    breaks = np.sort(breaks)

    def density(phi):  # elements per radian
        away = np.min(np.abs(np.remainder(phi[:, None] - lines + np.pi, 2 * np.pi) - np.pi), axis=1)
        return radius * refine / graded_spacing(radius * away, 2 * np.pi * radius * refine / n_circ)

    pieces = [integrated(a, b, density) for a, b in zip(breaks, [*breaks[1:], 2 * np.pi])]
    counts = np.array([max(1, round(integral[-1])) for _, integral in pieces])
    while counts.sum() % 8:
        counts[np.argmax([integral[-1] / count for (_, integral), count in zip(pieces, counts)])] += 1
    return np.concatenate([divided(phi, integral, count)[:-1] for (phi, integral), count in zip(pieces, counts)])


def cos_sin(azimuths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cosines and sines of azimuths, with those below 1e-15 in magnitude set to 0 (so that nodes on
    the planes x = 0 and y = 0 are exactly on them)."""
    cos, sin = np.cos(azimuths), np.sin(azimuths)
    cos[np.abs(cos) < 1e-15] = 0.0
    sin[np.abs(sin) < 1e-15] = 0.0
    return cos, sin

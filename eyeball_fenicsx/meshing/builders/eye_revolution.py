"""The eye's hexahedra (eyeball_fenicsx/meshing/builders/eye.py): its meridional section revolved about the optic axis.

Each structured block of the section (:class:`eye_meridian.Meridian`) is revolved in ``n_circ``
sectors of the full circle (of the model's sector, ``sector_deg``), its node rows becoming rings
of nodes at the azimuths 2 pi k / n_circ. A block cannot be revolved down to the axis (its first
column would collapse into wedges), so every part that crosses the axis -- the cornea, the lens
and the posterior pole stack optic nerve / sclera / choroid / retina -- has a butterfly core
instead: a disc of radius q_1 meshed as a square of (n_circ / 4)^2 quadrilaterals inside one ring
of quadrilaterals, mapped onto each of the part's node surfaces by its meridional arc length q
and azimuth. Its outer circle has the n_circ nodes of the revolved column q = q_1, so the core
and the revolved mesh conform. Nodes that the parts have in common are merged (within 1e-7 of the
model's size): bonded tissues share nodes. Hexahedra whose corner Jacobians are all negative are
turned over, so that every element is positively oriented.

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
then 48: a core disc of 428 quadrilaterals instead of 684, a quarter of the mesh's hexahedra.
"""
import itertools
import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .eye_meridian import (
    CHOROID_LAYERS,
    CORE_SQUARE,
    CORNEA_CORE,
    FINE_SPACING,
    LENS_COLUMNS,
    LENS_CORE,
    LENS_LAYERS,
    NERVE_LAYERS,
    SCLERA_LAYERS,
    ZONULE_COLUMNS,
    Meridian,
    divided,
    graded_spacing,
    integrated,
)
from .hexes import corner_jacobians, hex_grid

MAX_RING_TURN = math.radians(20.0)  # the largest turn of a graded core's ring about the axis
GRADED_CORE_SQUARE = 0.14  # a graded core's square, smaller, so that its rings have room to turn ...
ROUND = 0.25              # ... from a circle just outside it
TEMPLATE_DEPTH = 2.0  # a graded core's transition ring is this many times as deep as its merged elements' median width,
SPREAD = 4.0          # ... and merges none wider than this many times the narrowest it merges (but four);
MIDDLE_DEPTHS = np.linspace(0.3, 0.7, 5)  # its templates' middle nodes: the best of these depths (of the ring's)
MIDDLE_BLENDS = np.linspace(0.0, 1.0, 5)  # ... and of these steps from their graded azimuths to the even thirds


def _disc(n_circ, rings, azimuths=None):
    """Butterfly mesh of the unit disc: a square of (n_circ / 4)^2 quadrilaterals inside ``rings``
    rings of n_circ quadrilaterals, whose outer nodes are at angles 2 pi k / n_circ. Given the
    graded ``azimuths`` (increasing from 0, a multiple of 8 of them, as :func:`node_azimuths` gives
    them; n_circ then the eye's even count, which sets how wide merged elements may be), the outer
    nodes are at those: a transition ring (:func:`_transition`) takes a smaller disc's nodes at some
    of them (:func:`_kept_inside`) out to all of them, its depth ``TEMPLATE_DEPTH`` times the merged
    elements' median width; and so on inwards while elements merge; the innermost disc is
    :func:`_butterfly`'s, turned onto the azimuths left.

    Returns:
        ``(points, quads)``: coordinates, shape ``(N, 2)``, and counter-clockwise quadrilaterals.
    """
    if azimuths is None:
        return _butterfly(n_circ, rings)
    kept = _kept_inside(azimuths, n_circ)
    if len(kept) == len(azimuths):
        return _butterfly(len(kept), rings, azimuths)
    points, quads = _disc(n_circ, rings, azimuths[kept])
    merged_widths = np.diff(np.append(azimuths[kept], 2 * np.pi))[np.diff(np.append(kept, len(azimuths))) == 3]
    inside = 1.0 - TEMPLATE_DEPTH * np.median(merged_widths) / 3  # the smaller disc's radius
    return _transition(inside * points, quads, azimuths, kept, inside)


def _butterfly(n_circ, rings, azimuths=None):
    """The butterfly disc of :func:`_disc`, its outer nodes at 2 pi k / n_circ, or at the graded
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
    while i + 3 <= n:
        if closed[i + 3] - closed[i] <= 2 * np.pi / n_circ * (1 + 1e-9):
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
    span = np.diff(np.append(kept, n))
    templates = kept[span == 3]
    between = (templates[:, None] + [1, 2]).ravel()
    middle = total + np.arange(len(between)).reshape(-1, 2)  # the templates' middle nodes
    outer = total + len(between) + np.arange(n)
    ring = np.column_stack([inner, outer[kept], outer[(kept + 1) % n], np.roll(inner, -1)])[span == 1]
    e, f = inner[span == 3], np.roll(inner, -1)[span == 3]
    a, b, c, d = (outer[(templates + k) % n] for k in range(4))
    p, q = middle[:, 0], middle[:, 1]
    new_quads = np.concatenate([ring, *(np.column_stack(corners) for corners in
                                        ([e, a, b, p], [p, b, c, q], [q, c, d, f], [e, p, q, f]))])
    circle = np.stack([np.cos(azimuths), np.sin(azimuths)], axis=-1)
    closed = np.append(azimuths, 2 * np.pi)
    thirds = closed[templates, None] + (closed[templates + 3] - closed[templates])[:, None] * [1 / 3, 2 / 3]
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


class _Assembly:
    """Hexahedra of the revolved blocks and the butterfly cores, before their common nodes are merged."""

    def __init__(self, m, n_circ, sector_deg, graded):
        self.full = sector_deg >= 360.0
        refine = m.p["refine"]
        azimuths = node_azimuths(n_circ, sector_deg, graded, m.Ro, refine)
        self.azimuths = azimuths
        self.cos, self.sin = cos_sin(azimuths)
        points, quads = _disc(n_circ, refine, azimuths if len(graded) else None)
        if not self.full:  # keep the cells of the wedge 0 <= azimuth <= sector
            centre = points[quads].mean(axis=1)
            azimuth = np.mod(np.arctan2(centre[:, 1], centre[:, 0]), 2 * np.pi)
            quads = quads[azimuth < np.radians(sector_deg)]
        used = np.unique(quads)
        renumber = np.full(len(points), -1)
        renumber[used] = np.arange(len(used))
        self.disc_points, self.disc_quads = points[used], renumber[quads]
        self.nodes, self.hexes, self.regions = [], [], []
        self.count = 0

    def _add(self, nodes, hexes, regions):
        self.nodes.append(nodes)
        self.hexes.append(hexes + self.count)
        self.regions.append(regions)
        self.count += len(nodes)

    def revolve(self, section, regions):
        """Revolve a structured block: ``section`` (columns, rows, 2) in (rho, z); ``regions`` per cell."""
        rho, z = section[..., 0, None], section[..., 1, None]
        nodes = np.stack([rho * self.cos, rho * self.sin, np.broadcast_to(z, rho.shape[:-1] + self.cos.shape)],
                         axis=-1)
        ids = np.arange(nodes[..., 0].size).reshape(nodes.shape[:-1])
        if self.full:
            ids = np.concatenate([ids, ids[..., :1]], axis=-1)
        hexes = hex_grid(ids)
        cell_regions = np.broadcast_to(np.asarray(regions)[..., None], hexes.shape[:-1])
        self._add(nodes.reshape(-1, 3), hexes.reshape(-1, 8), cell_regions.ravel())

    def core(self, radius, surfaces, regions):
        """A butterfly core of meridional radius ``radius``: ``surfaces`` are functions q -> (rho, z)
        of its node surfaces, from the first to the last; ``regions`` names its layers."""
        q = radius * np.linalg.norm(self.disc_points, axis=1)
        direction = np.divide(self.disc_points, q[:, None] / radius, out=np.zeros_like(self.disc_points),
                              where=q[:, None] > 0)
        nodes = []
        for surface in surfaces:
            section = surface(q)
            nodes.append(np.column_stack([section[:, :1] * direction, section[:, 1]]))
        size = len(q)
        hexes = np.concatenate([np.hstack([self.disc_quads + k * size, self.disc_quads + (k + 1) * size])
                                for k in range(len(regions))])
        cell_regions = np.repeat(np.asarray(regions), len(self.disc_quads))
        self._add(np.concatenate(nodes), hexes, cell_regions)

    def merged(self):
        """Nodes, hexahedra (positively oriented) and region names, with coincident nodes merged."""
        nodes = np.concatenate(self.nodes)
        hexes = np.concatenate(self.hexes)
        regions = np.concatenate(self.regions)
        pairs = cKDTree(nodes).query_pairs(1e-7 * np.abs(nodes).max(), output_type="ndarray")
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(nodes),) * 2)
        count, label = connected_components(graph, directed=False)
        first = np.zeros(count, dtype=np.int64)
        first[label[::-1]] = np.arange(len(nodes))[::-1]
        nodes, hexes = nodes[first], label[hexes]
        if np.any(np.sort(hexes, axis=1)[:, 1:] == np.sort(hexes, axis=1)[:, :-1]):
            raise RuntimeError("eye: a hexahedron lost a node when coincident nodes were merged")
        det, _ = corner_jacobians(nodes, hexes)
        flip = np.all(det < 0, axis=1)
        hexes[flip] = hexes[flip][:, [4, 5, 6, 7, 0, 1, 2, 3]]
        return nodes, hexes, regions


def assemble_eye(m: Meridian, n_circ: int, sector_deg: float,
                 graded=()) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Assemble the whole eye from the meridian ``m``, revolved over :func:`node_azimuths` (graded
    around the azimuths ``graded``, rad, on the whole eye): nodes, hexahedra, region per hexahedron,
    and the node azimuths."""
    r = m.p["refine"]
    ns, ni = SCLERA_LAYERS * m.wall, len(m.fractions) - 1
    nch = CHOROID_LAYERS * m.wall
    parts = _Assembly(m, n_circ, sector_deg, graded)
    s = m.columns
    mid = 0.5 * (s[1:] + s[:-1])

    # The corneoscleral shell and the inner layers (choroid and retina, then ciliary body).
    shell = np.stack([m.shell_row(s, j) for j in range(ns + 1)], axis=1)
    parts.revolve(shell, np.where(mid < m.s_l, "sclera", "cornea")[:, None].repeat(ns, axis=1))
    spur = m.index["spur"]
    inner = np.stack([m.inner_row(s[:spur + 1], j) for j in range(ni + 1)], axis=1)
    retina_or_choroid = np.where(np.arange(ni) < nch, "choroid", "retina")
    parts.revolve(inner, np.where((mid[:spur] < m.s_ora)[:, None], retina_or_choroid[None, :], "ciliary_body"))

    # The lens beyond its core, and the zonule from the lens rim to the pars plicata.
    nl = LENS_LAYERS * r
    rho = np.linspace(LENS_CORE, m.rho_lens, LENS_COLUMNS * r + 1)
    lens = np.stack([m.lens_row(rho, j) for j in range(nl + 1)], axis=1)
    parts.revolve(lens, np.full((len(rho) - 1, nl), "lens"))
    rim = lens[-1]
    ciliary = inner[m.index["z0"]:m.index["z1"] + 1, -1]
    u = np.linspace(0.0, 1.0, ZONULE_COLUMNS * r + 1)[:, None, None]
    parts.revolve((1 - u) * rim + u * ciliary, np.full((len(u) - 1, nl), "zonule"))

    # Butterfly cores: the posterior pole stack, the corneal apex, the lens centre.
    nerve_layers = NERVE_LAYERS * r
    pole_surfaces = ([lambda q, k=k: m.nerve_row(q, k) for k in range(nerve_layers)]
                     + [lambda q, j=j: m.shell_row(q, j) for j in range(ns)]
                     + [lambda q, j=j: m.inner_row(q, j) for j in range(ni + 1)])
    parts.core(m.s_nerve, pole_surfaces,
               ["optic_nerve"] * nerve_layers + ["sclera"] * ns + list(retina_or_choroid))
    parts.core(CORNEA_CORE, [lambda q, j=j: m.shell_row(m.S - q, j) for j in range(ns + 1)], ["cornea"] * ns)
    parts.core(LENS_CORE, [lambda q, j=j: m.lens_row(q, j) for j in range(nl + 1)], ["lens"] * nl)
    return (*parts.merged(), parts.azimuths)

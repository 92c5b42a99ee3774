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


The azimuths, graded around a radial sponge or not, and the cores' discs are eye_azimuths.py's.
A graded eye's azimuths are graded only between two circles of latitude (``between``: a radial
sponge's ends and its bites, with a margin, buckle_sutures.py); the shell's and the inner layers'
columns outside them take the cores' coarser sets (eye_azimuths.coarser_levels), one level per
column away, and the zonule, the lens and the cornea the coarsest, where it is reached behind the
zonule (else everything in front of the band stays graded). Between two columns a level apart,
each row's sheet has the cores' 1-to-3 templates, swept through the wall: their middle nodes a
fine element's width from the coarse column (at most halfway), so that the templates' corners stay
near square however long the column interval, the same fraction of the way on every row (between
the two columns' lines through the centre, and between their radii), so that they lie on one line
through the centre as a column's nodes do: a detachment moves its nodes along those lines.
"""
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .eye_azimuths import coarser_levels, cos_sin, disc, node_azimuths, template_thirds, transition_quads
from .eye_meridian import (
    CHOROID_LAYERS,
    CORNEA_CORE,
    LENS_COLUMNS,
    LENS_CORE,
    LENS_LAYERS,
    NERVE_LAYERS,
    SCLERA_LAYERS,
    ZONULE_COLUMNS,
    Meridian,
)
from .hexes import corner_jacobians, hex_grid


class _Assembly:
    """Hexahedra of the revolved blocks and the butterfly cores, before their common nodes are merged."""

    def __init__(self, m, n_circ, sector_deg, graded):
        self.full, self.sector_deg, self.radius = sector_deg >= 360.0, sector_deg, m.Ro
        self.n_circ, self.rings, self.graded = n_circ, m.p["refine"], len(graded) > 0
        self.azimuths = node_azimuths(n_circ, sector_deg, graded, m.Ro, self.rings)
        self.levels, self.kept = coarser_levels(self.azimuths, n_circ) if self.graded else ([self.azimuths], [])
        self.discs = {}
        self.nodes, self.hexes, self.regions = [], [], []
        self.count = 0

    def _add(self, nodes, hexes, regions):
        self.nodes.append(nodes)
        self.hexes.append(hexes + self.count)
        self.regions.append(regions)
        self.count += len(nodes)

    def revolve(self, section, regions, levels=None, columns=None):
        """Revolve a structured block: ``section`` (columns, rows, 2) in (rho, z); ``regions`` per cell;
        each column over the azimuths of its level in ``self.levels`` (``levels``, by default the
        first), with a strip of transition templates between two columns one level apart (then
        ``columns``: the columns' meridional parameters s)."""
        levels = np.zeros(len(section), dtype=int) if levels is None else np.asarray(levels)
        changes = np.flatnonzero(np.diff(levels))
        for first, last in zip([0, *(changes + 1)], [*changes, len(section) - 1]):
            if last > first:
                self._revolve(section[first:last + 1], regions[first:last], self.levels[levels[first]])
        for i in changes:
            fine, coarse = (i, i + 1) if levels[i] < levels[i + 1] else (i + 1, i)
            self._strip(section[coarse], section[fine], regions[i], min(levels[i], levels[i + 1]),
                        columns[[coarse, fine]] / self.radius)

    def _revolve(self, section, regions, azimuths):
        rho, z = section[..., 0, None], section[..., 1, None]
        cos, sin = cos_sin(azimuths)
        nodes = np.stack([rho * cos, rho * sin, np.broadcast_to(z, rho.shape[:-1] + cos.shape)], axis=-1)
        ids = np.arange(nodes[..., 0].size).reshape(nodes.shape[:-1])
        if self.full:
            ids = np.concatenate([ids, ids[..., :1]], axis=-1)
        hexes = hex_grid(ids)
        cell_regions = np.broadcast_to(np.asarray(regions)[..., None], hexes.shape[:-1])
        self._add(nodes.reshape(-1, 3), hexes.reshape(-1, 8), cell_regions.ravel())

    def _strip(self, coarse, fine, regions, level, polar):
        """The hexahedra between a column ``fine`` (rows, 2) at the azimuths of ``level`` and the next,
        ``coarse``, at those of level + 1 (``polar``: the two columns' polar angles): on each row's
        sheet the cores' transition templates (eye_azimuths.transition_quads), their middle nodes
        halfway between the azimuth of the fine node each faces and the template's third, and a fine
        element's width from the coarse column toward the fine one (at most halfway: near-square
        corners), the same fraction on every row, so that they lie on one line through the centre
        as a column's nodes do (the detachment moves nodes along those lines); swept through the rows."""
        azimuths, kept = self.levels[level], self.kept[level]
        n, rows = len(azimuths), len(fine)
        templates = kept[np.diff(np.append(kept, n)) == 3]
        thirds = template_thirds(azimuths, templates)
        middle = ((azimuths[templates[:, None] + [1, 2]] + thirds) / 2).ravel()
        widths = np.repeat(thirds[:, 0] - azimuths[templates], 2)  # rad: a fine element's, about
        fraction = np.minimum(0.5, np.sin(polar.mean()) * widths / abs(polar[1] - polar[0]))[:, None]
        rings = [cos_sin(azimuths[kept]), cos_sin(azimuths), cos_sin(middle)]  # a row's coarse, fine, middle nodes
        nodes = []
        for row in range(rows):
            ends = np.linalg.norm([coarse[row], fine[row]], axis=1)
            direction = (1 - fraction) * coarse[row] / ends[0] + fraction * fine[row] / ends[1]
            between = direction / np.linalg.norm(direction, axis=1)[:, None] * ((1 - fraction) * ends[0]
                                                                                 + fraction * ends[1])
            for (rho, z), (cos, sin) in zip((coarse[row], fine[row], between.T), rings):
                nodes.append(np.column_stack([rho * cos, rho * sin, np.broadcast_to(z, cos.shape)]))
        per_row = len(kept) + n + len(middle)
        quads = transition_quads(kept, n, np.arange(len(kept)), len(kept) + np.arange(n),
                                 len(kept) + n + np.arange(len(middle)).reshape(-1, 2))
        hexes = np.concatenate([np.hstack([quads + row * per_row, quads + (row + 1) * per_row])
                                for row in range(rows - 1)])
        self._add(np.concatenate(nodes), hexes, np.repeat(np.asarray(regions), len(quads)))

    def _disc(self, level):
        """The cores' disc at the azimuths of ``level`` (eye_azimuths.disc), cut to the model's sector."""
        if level not in self.discs:
            points, quads = disc(self.n_circ, self.rings, self.levels[level] if self.graded else None)
            if not self.full:  # keep the cells of the wedge 0 <= azimuth <= sector
                centre = points[quads].mean(axis=1)
                azimuth = np.mod(np.arctan2(centre[:, 1], centre[:, 0]), 2 * np.pi)
                quads = quads[azimuth < np.radians(self.sector_deg)]
            used = np.unique(quads)
            renumber = np.full(len(points), -1)
            renumber[used] = np.arange(len(used))
            self.discs[level] = points[used], renumber[quads]
        return self.discs[level]

    def core(self, radius, surfaces, regions, level=0):
        """A butterfly core of meridional radius ``radius`` at the azimuths of ``level``: ``surfaces``
        are functions q -> (rho, z) of its node surfaces, from the first to the last; ``regions``
        names its layers."""
        disc_points, disc_quads = self._disc(level)
        q = radius * np.linalg.norm(disc_points, axis=1)
        direction = np.divide(disc_points, q[:, None] / radius, out=np.zeros_like(disc_points), where=q[:, None] > 0)
        nodes = []
        for surface in surfaces:
            section = surface(q)
            nodes.append(np.column_stack([section[:, :1] * direction, section[:, 1]]))
        size = len(q)
        hexes = np.concatenate([np.hstack([disc_quads + k * size, disc_quads + (k + 1) * size])
                                for k in range(len(regions))])
        cell_regions = np.repeat(np.asarray(regions), len(disc_quads))
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


def _column_levels(m: Meridian, parts: _Assembly, between) -> np.ndarray:
    """The level of each shell column's azimuths (``parts.levels``): the graded ones (0) between the
    circles ``between`` (mm behind the limbus; none: everywhere), one coarser per column away, up to
    the coarsest; but graded in front too where the coarsest is not reached behind the zonule (the
    zonule, lens and cornea take one set)."""
    columns, coarsest = m.columns, len(parts.levels) - 1
    if not len(between) or not coarsest:
        return np.zeros(len(columns), dtype=int)
    back, front = np.sort(m.s_l - np.asarray(between, dtype=float))
    inside = np.flatnonzero((columns >= back) & (columns <= front))
    if not len(inside):
        inside = [np.argmin(np.abs(columns - (back + front) / 2))]
    index, first, last = np.arange(len(columns)), inside[0], inside[-1]
    levels = np.minimum(coarsest, np.maximum(first - index, 0) + np.maximum(index - last, 0))
    if np.any(levels[m.index["z0"]:] < coarsest):  # graded from the band to the cornea, then
        levels = np.minimum(coarsest, np.maximum(min(first, m.index["z0"]) - index, 0))
    return levels


def assemble_eye(m: Meridian, n_circ: int, sector_deg: float, graded=(),
                 between=()) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Assemble the whole eye from the meridian ``m``, revolved over :func:`node_azimuths` (graded
    around the azimuths ``graded``, rad, on the whole eye): nodes, hexahedra, region per hexahedron,
    and the node azimuths."""
    r = m.p["refine"]
    ns, ni = SCLERA_LAYERS * m.wall, len(m.fractions) - 1
    nch = CHOROID_LAYERS * m.wall
    parts = _Assembly(m, n_circ, sector_deg, graded)
    s = m.columns
    mid = 0.5 * (s[1:] + s[:-1])
    levels = _column_levels(m, parts, between)
    front = levels[-1]  # the zonule's, the lens's and the cornea's

    # The corneoscleral shell and the inner layers (choroid and retina, then ciliary body).
    shell = np.stack([m.shell_row(s, j) for j in range(ns + 1)], axis=1)
    parts.revolve(shell, np.where(mid < m.s_l, "sclera", "cornea")[:, None].repeat(ns, axis=1), levels, s)
    spur = m.index["spur"]
    inner = np.stack([m.inner_row(s[:spur + 1], j) for j in range(ni + 1)], axis=1)
    retina_or_choroid = np.where(np.arange(ni) < nch, "choroid", "retina")
    parts.revolve(inner, np.where((mid[:spur] < m.s_ora)[:, None], retina_or_choroid[None, :], "ciliary_body"),
                  levels[:spur + 1], s[:spur + 1])

    # The lens beyond its core, and the zonule from the lens rim to the pars plicata.
    nl = LENS_LAYERS * r
    rho = np.linspace(LENS_CORE, m.rho_lens, LENS_COLUMNS * r + 1)
    lens = np.stack([m.lens_row(rho, j) for j in range(nl + 1)], axis=1)
    parts.revolve(lens, np.full((len(rho) - 1, nl), "lens"), np.full(len(rho), front))
    rim = lens[-1]
    ciliary = inner[m.index["z0"]:m.index["z1"] + 1, -1]
    u = np.linspace(0.0, 1.0, ZONULE_COLUMNS * r + 1)[:, None, None]
    parts.revolve((1 - u) * rim + u * ciliary, np.full((len(u) - 1, nl), "zonule"), np.full(len(u), front))

    # Butterfly cores: the posterior pole stack, the corneal apex, the lens centre.
    nerve_layers = NERVE_LAYERS * r
    pole_surfaces = ([lambda q, k=k: m.nerve_row(q, k) for k in range(nerve_layers)]
                     + [lambda q, j=j: m.shell_row(q, j) for j in range(ns)]
                     + [lambda q, j=j: m.inner_row(q, j) for j in range(ni + 1)])
    parts.core(m.s_nerve, pole_surfaces,
               ["optic_nerve"] * nerve_layers + ["sclera"] * ns + list(retina_or_choroid), levels[0])
    parts.core(CORNEA_CORE, [lambda q, j=j: m.shell_row(m.S - q, j) for j in range(ns + 1)], ["cornea"] * ns, front)
    parts.core(LENS_CORE, [lambda q, j=j: m.lens_row(q, j) for j in range(nl + 1)], ["lens"] * nl, front)
    return (*parts.merged(), parts.azimuths)

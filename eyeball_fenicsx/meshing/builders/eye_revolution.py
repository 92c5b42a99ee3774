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
"""
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .eye_meridian import (
    CHOROID_LAYERS,
    CORE_SQUARE,
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


def _disc(n_circ, rings):
    """Butterfly mesh of the unit disc: a square of (n_circ / 4)^2 quadrilaterals inside ``rings``
    rings of n_circ quadrilaterals, whose outer nodes are at angles 2 pi k / n_circ.

    Returns:
        ``(points, quads)``: coordinates, shape ``(N, 2)``, and counter-clockwise quadrilaterals.
    """
    m = n_circ // 4
    ticks = CORE_SQUARE * np.linspace(-1.0, 1.0, m + 1)
    grid = np.arange((m + 1) ** 2).reshape(m + 1, m + 1)  # grid[i, j] at (ticks[i], ticks[j])
    points = [np.stack(np.meshgrid(ticks, ticks, indexing="ij"), axis=-1).reshape(-1, 2)]
    quads = [np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=-1).reshape(-1, 4)]
    # The square's boundary counter-clockwise from (CORE_SQUARE, 0), the point of angle 0.
    half = m // 2
    boundary = np.concatenate([grid[m, half:], grid[m - 1::-1, m], grid[0, m - 1::-1], grid[1:, 0],
                               grid[m, 1:half]])
    square = points[0][boundary]
    angles = 2 * np.pi * np.arange(n_circ) / n_circ
    circle = np.stack([np.cos(angles), np.sin(angles)], axis=-1)
    previous = boundary
    for ring in range(1, rings + 1):
        t = ring / rings
        ids = (m + 1) ** 2 + (ring - 1) * n_circ + np.arange(n_circ)
        points.append((1 - t) * square + t * circle)
        quads.append(np.stack([previous, ids, np.roll(ids, -1), np.roll(previous, -1)], axis=-1))
        previous = ids
    points = np.concatenate(points)
    points[np.abs(points) < 1e-15] = 0.0
    return points, np.concatenate(quads)


def node_azimuths(n_circ: int, sector_deg: float) -> np.ndarray:
    """The eye's node azimuths (rad): 2 pi k / n_circ over the model's sector (with both ends in a wedge)."""
    sectors = round(n_circ * sector_deg / 360.0)
    return 2 * np.pi * np.arange(sectors + (0 if sector_deg >= 360.0 else 1)) / n_circ


def cos_sin(azimuths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cosines and sines of azimuths, with those below 1e-15 in magnitude set to 0 (so that nodes on
    the planes x = 0 and y = 0 are exactly on them)."""
    cos, sin = np.cos(azimuths), np.sin(azimuths)
    cos[np.abs(cos) < 1e-15] = 0.0
    sin[np.abs(sin) < 1e-15] = 0.0
    return cos, sin


class _Assembly:
    """Hexahedra of the revolved blocks and the butterfly cores, before their common nodes are merged."""

    def __init__(self, n_circ, sector_deg, refine):
        self.full = sector_deg >= 360.0
        self.cos, self.sin = cos_sin(node_azimuths(n_circ, sector_deg))
        points, quads = _disc(n_circ, refine)
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


def assemble_eye(m: Meridian, n_circ: int, sector_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Assemble the whole eye from the meridian ``m``: nodes, hexahedra and region per hexahedron."""
    r = m.p["refine"]
    ns, ni = SCLERA_LAYERS * m.wall, len(m.fractions) - 1
    nch = CHOROID_LAYERS * m.wall
    parts = _Assembly(n_circ, sector_deg, r)
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
    return parts.merged()

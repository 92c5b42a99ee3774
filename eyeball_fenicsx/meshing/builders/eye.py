"""Hexahedral mesh of a human eye, axisymmetric about the optic axis, for scleral-buckling simulations.

The optic axis is the z axis: the corneal apex is at +z, the posterior pole at -z, and the origin
is the centre of the spherical sclera, so the equator is the plane z = 0. Only the solid tissues
are meshed, with 8-node hexahedra; the vitreous and the aqueous are liquid cavities, and an
optional retinal detachment is an empty subretinal gap.

**Meridional section.** The section rho >= 0 of the eye is a few structured quadrilateral blocks:

* the corneoscleral shell: sclera from the posterior pole to the limbus, then cornea to the apex,
  with its nodes on lines C(s) + d n(s), where C(s) is the outer surface by arc length s from the
  posterior pole, n(s) the inward normal and d the depth (the two normals are blended over
  0.8 mm at the limbus, where the surface has a kink);
* the inner layers on the same lines: choroid and retina from the pole to the ora serrata, then
  the ciliary body to the scleral spur, thickening from the pars plana to the pars plicata; the
  retina ends at the ora serrata, the ciliary body's front face is the iris root (no iris);
* the zonule, a fan-shaped ring from the pars plicata to the lens equator;
* the lens, between two spherical surfaces and a short equatorial rim;
* the optic nerve, a cylinder behind the posterior pole (on the axis, as in an axisymmetric model).

**Revolution.** Each block is revolved in ``n_circ`` sectors of the full circle. A block cannot be
revolved down to the axis (its first column would collapse into wedges), so every part that
crosses the axis -- the cornea, the lens and the posterior pole stack optic nerve / sclera /
choroid / retina -- has a butterfly core instead: a disc of radius q_1 meshed as a square of
(n_circ / 4)^2 quadrilaterals inside one ring of quadrilaterals, mapped onto each of the part's
node surfaces by its meridional arc length q and azimuth. Its outer circle has the n_circ nodes of
the revolved column q = q_1, so the core and the revolved mesh conform. Nodes that the parts have
in common are merged: bonded tissues share nodes.

**Retinal detachment.** Over a spherical cap of the retina-choroid interface the retina gets its
own nodes, moved by ``gap`` toward the centre of the eye with the whole retinal thickness, so that
the gap between "retina_outer" and "choroid_inner" is constant. On the rim of the cap the retina
and the choroid keep their shared nodes: the gap closes over one ring of elements, whose
hexahedra are sheared by gap / element size, not collapsed (a gap tapering to zero over the whole
cap, as in a real bullous detachment, would degenerate the elements at the rim). The vitreous wall
stays the inner surface of the retina, closed. A cap centred on the posterior pole is whole rings
of faces, and its rim is moved onto the cap's circle; any other cap is the set of faces nearest to
its centre whose solid angle, seen from the centre of the eye, is the cap's: its outline is a
staircase of element edges, its area that of the cap within about one element.

Physical groups: the volumes "cornea", "sclera", "ciliary_body", "choroid", "retina",
"optic_nerve", "lens", "zonule"; the surfaces "sclera_outer", "cornea_outer", "optic_nerve_side",
"optic_nerve_end", "vitreous_wall", "anterior_chamber_wall" (the aqueous cavity: anterior and
posterior chamber, there is no iris), with a detachment "retina_outer" and "choroid_inner", and in
a wedge model "cut_0" (plane azimuth 0) and "cut_1" (plane azimuth ``sector_deg``).

Usage: ``/usr/bin/python3 -m eyeball_fenicsx.meshing.builders.eye --out eye.msh [--sector-deg 180] [--detachment 60 0 30 0.1]``
"""
import argparse
import dataclasses
import inspect
import math
import numbers
import time

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from eyeball_fenicsx.errors import SceneError

from .hexes import HEX_FACES, add_hex_model, check, corner_jacobians, hex_grid, run_cli, write_msh

# --- anatomy (mm) -----------------------------------------------------------------------------
# Le Grand full theoretical eye, in Atchison & Smith, Optics of the Human Eye (2000), appendix A:
# anterior corneal radius 7.8, aqueous depth 3.05, lens 4.0 thick with radii 10.2 and -6.0,
# cornea to retina 24.2 (24.0 in Navarro's eye).
CORNEA_RADIUS = 7.8
ANTERIOR_CHAMBER_DEPTH = 3.05  # posterior cornea to anterior lens, on the axis
LENS_THICKNESS = 4.0
LENS_ANTERIOR_RADIUS = 10.2
LENS_POSTERIOR_RADIUS = 6.0
# Lens equatorial diameter 8.7-9.9 mm in adults (Rosen et al., Vision Res. 46:1002, 2006).
LENS_DIAMETER = 9.2
# Corneal (white-to-white) diameter 11.71 +- 0.42 mm (Rüfer et al., Cornea 24:259, 2005).
LIMBUS_DIAMETER = 11.8
# Ora serrata 6-7 mm behind the limbus; ciliary body ~6 mm long: pars plana ~4 mm, pars plicata
# ~2 mm, from the ora to the scleral spur ~1 mm behind the limbus (Hogan, Alvarado & Weddell,
# Histology of the Human Eye, 1971).
ORA_TO_LIMBUS = 6.5
SPUR_TO_LIMBUS = 1.0
# In section the ciliary body is a right triangle ~6 mm long, its pars plicata ~2 mm long with
# processes 0.8-1 mm high on the ciliary muscle (Borges-Giampani & Giampani, in Glaucoma - Basic
# and Clinical Aspects, InTech 2013): here 1.2 mm thick at the pars plicata, where the zonule
# leaves it (3.0 to 1.4 mm behind the limbus) for the lens equator.
CILIARY_THICKNESS = 1.2
ZONULE_POSTERIOR_TO_LIMBUS = 3.0
ZONULE_ANTERIOR_TO_LIMBUS = 1.4
LIMBUS_BLEND = 0.8  # half-width over which the shell's lines turn from the scleral to the corneal normal

# --- mesh sizes at refine = 1 ---------------------------------------------------------------
SPACING = 0.8       # meridional element size along the shell (mm)
CORNEA_CORE = 1.3   # radius (arc length) of the corneal butterfly core (mm)
LENS_CORE = 1.2     # radius of the lens butterfly core (mm)
CORE_SQUARE = 0.5   # half-side of the core square / core radius
SCLERA_LAYERS, CHOROID_LAYERS, RETINA_LAYERS = 2, 1, 1
LENS_LAYERS, ZONULE_COLUMNS, LENS_COLUMNS, NERVE_LAYERS = 4, 3, 4, 3
N_CIRC = 40         # sectors of the full circle at refine = 1

MIN_SCALED_JACOBIAN = 0.2  # the builder refuses a mesh with a worse corner
_SECTORS = (90.0, 180.0, 360.0)
_TOLERANCE = 1e-9  # mm: nodes closer than this to a plane are on it (they are placed on it exactly)
_DETACHMENT_KEYS = ("polar_deg", "azimuth_deg", "extent_deg", "gap")


@dataclasses.dataclass
class EyeMesh:
    """The eye mesh as arrays (0-based node indices, gmsh order).

    Attributes:
        nodes: coordinates, shape ``(num_nodes, 3)``.
        regions: tissue name -> hexahedra, shape ``(count, 8)``.
        surfaces: surface name -> outward quadrilaterals, shape ``(count, 4)``.
        info: statistics: counts, worst scaled Jacobian, cavity volumes (mm^3, whole eye),
            measured axial length, globe radius, build time (s).
    """

    nodes: np.ndarray
    regions: dict
    surfaces: dict
    info: dict


def _smoothstep(x):
    """0 for x <= 0, 1 for x >= 1, sin^2(pi x / 2) between: C1 with zero slope at both ends."""
    return np.sin(np.pi / 2 * np.clip(x, 0.0, 1.0)) ** 2


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class _Meridian:
    """The meridional section (rho, z) of the eye: curves, layer depths and column positions."""

    def __init__(self, p):
        self.p = p
        rho_l = LIMBUS_DIAMETER / 2
        self.rho_l, self.Rc = rho_l, CORNEA_RADIUS
        corneal_sag = CORNEA_RADIUS - math.sqrt(CORNEA_RADIUS**2 - rho_l**2)
        pole_wall = p["sclera_thickness_pole"] + p["choroid_thickness"] + p["retina_thickness"]
        # Corneal apex to the vitreoretinal interface on the axis: Ro + sqrt(Ro^2 - rho_l^2) = a.
        a = p["axial_length"] - corneal_sag + pole_wall
        if a <= rho_l:
            raise SceneError(f"eye: axial_length {p['axial_length']} is too short for a limbus of diameter "
                             f"{LIMBUS_DIAMETER} mm")
        self.Ro = (a * a + rho_l**2) / (2 * a)
        z_l = a - self.Ro
        self.theta_l = math.atan2(rho_l, -z_l)
        self.s_l = self.Ro * self.theta_l
        self.z_cc = z_l - math.sqrt(CORNEA_RADIUS**2 - rho_l**2)
        self.z_apex = self.z_cc + CORNEA_RADIUS
        self.phi_l = math.asin(rho_l / CORNEA_RADIUS)
        self.S = self.s_l + CORNEA_RADIUS * self.phi_l
        self.n_limbus = _unit(np.array([-math.sin(self.theta_l), math.cos(self.theta_l)])
                              + np.array([-math.sin(self.phi_l), -math.cos(self.phi_l)]))
        self.s_ora = self.s_l - ORA_TO_LIMBUS
        self.s_z0 = self.s_l - ZONULE_POSTERIOR_TO_LIMBUS
        self.s_z1 = self.s_l - ZONULE_ANTERIOR_TO_LIMBUS
        self.s_spur = self.s_l - SPUR_TO_LIMBUS
        self.nerve_radius = p["optic_nerve_diameter"] / 2
        if not self.nerve_radius < 0.5 * self.Ro:
            raise SceneError(f"eye: optic_nerve_diameter {p['optic_nerve_diameter']} is too large")
        self.s_nerve = self.Ro * math.asin(self.nerve_radius / self.Ro)
        self.z_nerve_end = -self.Ro - p["optic_nerve_length"]
        # Lens (Le Grand): anterior pole at the aqueous depth behind the posterior cornea.
        self.z_lens_front = self.z_apex - p["cornea_thickness"] - ANTERIOR_CHAMBER_DEPTH
        self.z_lens_back = self.z_lens_front - LENS_THICKNESS
        self.rho_lens = LENS_DIAMETER / 2
        r = self.p["refine"]
        self.fractions = np.concatenate([
            np.linspace(0.0, p["choroid_thickness"], CHOROID_LAYERS * r + 1),
            np.linspace(p["choroid_thickness"], p["choroid_thickness"] + p["retina_thickness"],
                        RETINA_LAYERS * r + 1)[1:]]) / (p["choroid_thickness"] + p["retina_thickness"])
        self.columns = self._columns()

    def outer(self, s):
        """The outer surface C(s) and the unit vector n(s) of the shell's line, by arc length s from
        the posterior pole: shape (..., 2) each, in (rho, z)."""
        s = np.asarray(s, dtype=float)
        theta = np.minimum(s, self.s_l) / self.Ro
        phi = np.maximum(self.S - s, 0.0) / self.Rc
        on_sclera = (s <= self.s_l)[..., None]
        point = np.where(on_sclera, np.stack([self.Ro * np.sin(theta), -self.Ro * np.cos(theta)], axis=-1),
                         np.stack([self.Rc * np.sin(phi), self.z_cc + self.Rc * np.cos(phi)], axis=-1))
        normal = np.where(on_sclera, np.stack([-np.sin(theta), np.cos(theta)], axis=-1),
                          np.stack([-np.sin(phi), -np.cos(phi)], axis=-1))
        weight = _smoothstep(1.0 - np.abs(s - self.s_l) / LIMBUS_BLEND)[..., None]
        return point, _unit((1 - weight) * normal + weight * self.n_limbus)

    def shell_thickness(self, s):
        """Sclera (s <= s_l) or cornea (s > s_l) thickness."""
        p = self.p
        s = np.asarray(s, dtype=float)
        theta = np.minimum(s, self.s_l) / self.Ro
        posterior = p["sclera_thickness_equator"] + (p["sclera_thickness_pole"] - p["sclera_thickness_equator"]) \
            * np.cos(np.minimum(theta, np.pi / 2)) ** 2
        anterior = p["sclera_thickness_equator"] + (p["sclera_thickness_limbus"] - p["sclera_thickness_equator"]) \
            * _smoothstep((theta - np.pi / 2) / (self.theta_l - np.pi / 2))
        phi = np.maximum(self.S - s, 0.0) / self.Rc
        cornea = p["cornea_thickness"] \
            + (p["sclera_thickness_limbus"] - p["cornea_thickness"]) * (phi / self.phi_l) ** 2
        return np.where(s > self.s_l, cornea, np.where(theta <= np.pi / 2, posterior, anterior))

    def inner_thickness(self, s):
        """Choroid + retina up to the ora serrata, then the ciliary body thickening to the pars plicata."""
        base = self.p["choroid_thickness"] + self.p["retina_thickness"]
        return base + (CILIARY_THICKNESS - base) * _smoothstep((np.asarray(s) - self.s_ora) / (self.s_z0 - self.s_ora))

    def shell_row(self, s, j):
        point, normal = self.outer(s)
        layers = SCLERA_LAYERS * self.p["refine"]
        return point + (j / layers * self.shell_thickness(s))[..., None] * normal

    def inner_row(self, s, j):
        point, normal = self.outer(s)
        depth = self.shell_thickness(s) + self.fractions[j] * self.inner_thickness(s)
        return point + depth[..., None] * normal

    def nerve_row(self, s, k):
        point, _ = self.outer(s)
        layers = NERVE_LAYERS * self.p["refine"]
        z = self.z_nerve_end + k / layers * (point[..., 1] - self.z_nerve_end)
        return np.stack([point[..., 0], z], axis=-1)

    def lens_row(self, rho, j):
        rho = np.asarray(rho, dtype=float)
        front = self.z_lens_front - (LENS_ANTERIOR_RADIUS - np.sqrt(LENS_ANTERIOR_RADIUS**2 - rho**2))
        back = self.z_lens_back + (LENS_POSTERIOR_RADIUS - np.sqrt(LENS_POSTERIOR_RADIUS**2 - rho**2))
        return np.stack([rho, back + j / (LENS_LAYERS * self.p["refine"]) * (front - back)], axis=-1)

    def _columns(self):
        """Arc lengths of the revolved columns of the shell, from the nerve core to the corneal core."""
        r = self.p["refine"]
        stops = [(self.s_nerve, None), (self.s_ora, None), (self.s_z0, None),
                 (self.s_z1, LENS_LAYERS * r), (self.s_spur, None), (self.s_l, None), (self.S - CORNEA_CORE, None)]
        columns = [np.array([self.s_nerve])]
        self.index = {}
        for (start, _), (stop, count) in zip(stops, stops[1:]):
            if stop <= start + 0.1:
                raise SceneError("eye: the anatomy does not fit: check axial_length and the thicknesses")
            count = count or max(1, round((stop - start) / SPACING)) * r
            columns.append(np.linspace(start, stop, count + 1)[1:])
        columns = np.concatenate(columns)
        for name, value in (("z0", self.s_z0), ("z1", self.s_z1), ("spur", self.s_spur)):
            self.index[name] = int(np.argmin(np.abs(columns - value)))
        return columns


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


class _Assembly:
    """Hexahedra of the revolved blocks and the butterfly cores, before their common nodes are merged."""

    def __init__(self, n_circ, sector_deg, refine):
        self.full = sector_deg >= 360.0
        sectors = round(n_circ * sector_deg / 360.0)
        angles = 2 * np.pi * np.arange(sectors + (0 if self.full else 1)) / n_circ
        self.cos, self.sin = np.cos(angles), np.sin(angles)
        self.cos[np.abs(self.cos) < 1e-15] = 0.0
        self.sin[np.abs(self.sin) < 1e-15] = 0.0
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


def _build_arrays(m, n_circ, sector_deg):
    """Assemble the whole eye from the meridian ``m``: nodes, hexahedra and region per hexahedron."""
    r = m.p["refine"]
    ns, ni = SCLERA_LAYERS * r, len(m.fractions) - 1
    nch = CHOROID_LAYERS * r
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


def _faces(hexes):
    """All hexahedron faces, outward and counter-clockwise: ``(quads, face_id)`` with
    quads shape ``(6 num_hexes, 4)``, row 6 h + f the face f of hexahedron h, and face_id the
    same number for the two sides of an interior face."""
    quads = hexes[:, list(HEX_FACES.values())].reshape(-1, 4)
    _, face_id = np.unique(np.sort(quads, axis=1), axis=0, return_inverse=True)
    return quads, face_id.ravel()


def _detach(nodes, hexes, regions, m, detachment, sector_deg):
    """Open the subretinal gap (see the module docstring); returns the new nodes and hexahedra."""
    quads, face_id = _faces(hexes)
    owner = np.repeat(regions, 6)
    retina_side = np.flatnonzero(owner == "retina")
    choroid_faces = set(face_id[owner == "choroid"].tolist())
    interface = quads[retina_side[np.fromiter((f in choroid_faces for f in face_id[retina_side]), bool,
                                              len(retina_side))]]
    polar, azimuth = np.radians(detachment["polar_deg"]), np.radians(detachment["azimuth_deg"])
    centre = np.array([math.sin(polar) * math.cos(azimuth), math.sin(polar) * math.sin(azimuth), -math.cos(polar)])
    face_centres = nodes[interface].mean(axis=1)
    angle = np.arccos(np.clip(_unit(face_centres) @ centre, -1.0, 1.0))
    extent = math.radians(detachment["extent_deg"])
    on_axis = detachment["polar_deg"] == 0.0 and extent * m.Ro > 1.01 * m.s_nerve

    def split(faces):
        """Rim and interior nodes of a set of detached faces, and the faces that really open (those
        with an interior node; a face with all its nodes on the rim stays bonded)."""
        rim_edges = _open_edges(faces)
        if sector_deg < 360.0:  # the cuts by the symmetry planes are not rim
            rim_edges = rim_edges[~np.all(_on_cut_planes(nodes[rim_edges], sector_deg), axis=1)]
        rim = np.unique(rim_edges)
        return rim, np.setdiff1d(np.unique(faces), rim), faces[~np.all(np.isin(faces, rim), axis=1)]

    if on_axis:
        # Whole rings of faces about the axis, beyond the butterfly core; their rim is moved onto
        # the cone of the cap below.
        rim, interior, _ = split(interface[angle < extent])
    else:
        # The faces nearest to the centre whose solid angle (seen from the centre of the eye) is that
        # of the cap: a staircase of element edges cannot be moved onto the cap's circle without
        # collapsing the edges that cross it, so the cap keeps its area, not its exact outline.
        inside = 1.0 if sector_deg == 360.0 else 0.5  # a wedge cuts the cap through its centre
        cap = 2 * np.pi * (1 - math.cos(extent)) * inside
        order = np.argsort(angle)
        solid = _areas(nodes, interface[order]) / np.sum(face_centres[order] ** 2, axis=1)
        guess = int(np.argmin(np.abs(np.cumsum(solid) - cap))) + 1
        best = None
        for count in range(max(1, guess - 8), guess + 9):
            rim, interior, opened = split(interface[order[:count]])
            error = abs(np.sum(_areas(nodes, opened) / np.sum(nodes[opened].mean(axis=1) ** 2, axis=1)) - cap)
            if len(interior) and (best is None or error < best[0]):
                best = (error, rim, interior)
        if best is None:
            raise SceneError("eye: the detachment is smaller than one element; increase extent_deg or refine")
        _, rim, interior = best
    if len(interior) == 0:
        raise SceneError("eye: the detachment is smaller than one element; increase extent_deg or refine")
    if on_axis:
        # The wall's nodes lie on lines through the centre of the eye: the lines of the rim's ring
        # turn onto the cone of half-angle extent_deg, which makes the rim the cap's circle.
        wall = np.unique(hexes[np.isin(regions, ("sclera", "choroid", "retina"))])
        lines = cKDTree(_unit(nodes[wall]))
        for direction in _unit(nodes[rim]):
            on_line = wall[lines.query_ball_point(direction, 1e-9)]
            off_axis = _unit(direction - (direction @ centre) * centre)
            nodes[on_line] = np.linalg.norm(nodes[on_line], axis=1)[:, None] * (
                math.cos(extent) * centre + math.sin(extent) * off_axis)
    # The retina's nodes on the lines of the interior nodes move inward by the gap; those on the
    # interface are copied first, the choroid keeps the originals.
    retina_hexes = regions == "retina"
    retina_nodes = np.unique(hexes[retina_hexes])
    directions = cKDTree(_unit(nodes[interior]))
    distance, _ = directions.query(_unit(nodes[retina_nodes]), distance_upper_bound=1e-9)
    moving = retina_nodes[np.isfinite(distance)]
    copy = np.full(len(nodes), -1)
    copy[interior] = len(nodes) + np.arange(len(interior))
    nodes = np.concatenate([nodes, nodes[interior]])
    retina = hexes[retina_hexes]
    hexes[retina_hexes] = np.where(copy[retina] >= 0, copy[retina], retina)
    moving = np.concatenate([np.setdiff1d(moving, interior), copy[interior]])
    nodes[moving] -= detachment["gap"] * _unit(nodes[moving])
    return nodes, hexes


_GAUSS = (0.5 - 0.5 / math.sqrt(3), 0.5 + 0.5 / math.sqrt(3))


def _bilinear(nodes, quads):
    """Yield (weight, point, x_u x x_v) at the 2 x 2 Gauss points of bilinear quadrilaterals."""
    x = nodes[quads]  # corners 0, 1, 2, 3 at (u, v) = (0, 0), (1, 0), (1, 1), (0, 1)
    for u in _GAUSS:
        for v in _GAUSS:
            point = x[:, 0] * (1 - u) * (1 - v) + x[:, 1] * u * (1 - v) + x[:, 2] * u * v + x[:, 3] * (1 - u) * v
            du = (x[:, 1] - x[:, 0]) * (1 - v) + (x[:, 2] - x[:, 3]) * v
            dv = (x[:, 3] - x[:, 0]) * (1 - u) + (x[:, 2] - x[:, 1]) * u
            yield 0.25, point, np.cross(du, dv)


def _areas(nodes, quads):
    """Areas of bilinear quadrilaterals."""
    return sum(w * np.linalg.norm(normal, axis=1) for w, _, normal in _bilinear(nodes, quads))


def _signed_volume(nodes, quads):
    """-(1/3) integral of x . n over bilinear quadrilaterals, n their outward normal (2 x 2 Gauss: exact)."""
    return -sum(w * np.sum(point * normal) for w, point, normal in _bilinear(nodes, quads)) / 3


def _open_edges(quads):
    """Edges (node pairs) used by one quadrilateral of ``quads`` only."""
    edges = np.sort(np.concatenate([quads[:, [k, (k + 1) % 4]] for k in range(4)]), axis=1)
    unique_edges, counts = np.unique(edges, axis=0, return_counts=True)
    return unique_edges[counts == 1]


def _on_plane(points, azimuth):
    """Whether points (shape (..., 3)) lie on the half-plane through the z axis at ``azimuth`` (rad)."""
    normal = np.array([-math.sin(azimuth), math.cos(azimuth), 0.0])
    along = np.array([math.cos(azimuth), math.sin(azimuth), 0.0])
    return (np.abs(points @ normal) < _TOLERANCE) & (points @ along > -_TOLERANCE)


def _on_cut_planes(points, sector_deg):
    return _on_plane(points, 0.0) | _on_plane(points, math.radians(sector_deg))


def _surfaces(nodes, hexes, regions, m, sector_deg):
    """Named boundary surfaces: cut planes first, then the edge-connected pieces of the rest of the
    boundary, named by the tissues they touch and the sign of the volume they enclose."""
    quads, face_id = _faces(hexes)
    owner = np.repeat(regions, 6)
    boundary = np.flatnonzero(np.bincount(face_id)[face_id] == 1)
    surfaces = {}
    if sector_deg < 360.0:
        for name, azimuth in (("cut_0", 0.0), ("cut_1", math.radians(sector_deg))):
            on = np.all(_on_plane(nodes[quads[boundary]], azimuth), axis=1)
            surfaces[name] = quads[boundary[on]]
            boundary = boundary[~on]
    edges = np.sort(np.concatenate([quads[boundary][:, [k, (k + 1) % 4]] for k in range(4)]), axis=1)
    _, edge_id = np.unique(edges, axis=0, return_inverse=True)
    edge_id = edge_id.ravel()
    face_of_edge = np.tile(np.arange(len(boundary)), 4)
    size = len(boundary) + edge_id.max() + 1
    graph = coo_matrix((np.ones(len(edge_id)), (face_of_edge, len(boundary) + edge_id)), shape=(size, size))
    _, piece = connected_components(graph, directed=False)
    piece = piece[:len(boundary)]
    for label in np.unique(piece):
        faces = boundary[piece == label]
        tissues = set(owner[faces].tolist())
        volume = _signed_volume(nodes, quads[faces])
        if volume < 0:  # the outside of the eye
            for tissue, name in (("sclera", "sclera_outer"), ("cornea", "cornea_outer")):
                surfaces[name] = quads[faces[owner[faces] == tissue]]
            nerve = quads[faces[owner[faces] == "optic_nerve"]]
            end = np.all(np.abs(nodes[nerve][..., 2] - m.z_nerve_end) < _TOLERANCE, axis=1)
            surfaces["optic_nerve_end"], surfaces["optic_nerve_side"] = nerve[end], nerve[~end]
        elif "choroid" in tissues:
            surfaces["retina_outer"] = quads[faces[owner[faces] == "retina"]]
            surfaces["choroid_inner"] = quads[faces[owner[faces] == "choroid"]]
        elif "cornea" in tissues:
            surfaces["anterior_chamber_wall"] = quads[faces]
        elif "retina" in tissues:
            surfaces["vitreous_wall"] = quads[faces]
        else:
            raise RuntimeError(f"eye: unexpected piece of boundary touching {sorted(tissues)}")
    order = ["sclera_outer", "cornea_outer", "optic_nerve_side", "optic_nerve_end", "vitreous_wall",
             "anterior_chamber_wall", "retina_outer", "choroid_inner", "cut_0", "cut_1"]
    return {name: surfaces[name] for name in order if name in surfaces}


def _check_parameters(p):
    for name in ("axial_length", "sclera_thickness_limbus", "sclera_thickness_equator", "sclera_thickness_pole",
                 "cornea_thickness", "choroid_thickness", "retina_thickness", "optic_nerve_diameter",
                 "optic_nerve_length"):
        check("eye", name, p[name], "positive number")
    check("eye", "refine", p["refine"], "positive integer")
    check("eye", "n_circ", p["n_circ"], "positive integer")
    if p["sector_deg"] not in _SECTORS:
        raise SceneError(f"eye: sector_deg must be one of {_SECTORS}, got {p['sector_deg']!r}")
    # The butterfly core's square has n_circ / 4 quadrilaterals a side, and its boundary must have a node
    # at azimuth 0 (and, in a wedge, on the cut planes): an even number of them.
    if p["n_circ"] % 8:
        raise SceneError(f"eye: n_circ must be a multiple of 8 (the butterfly cores have n_circ / 4 quadrilaterals "
                         f"a side, an even number), got {p['n_circ']}")
    inner = p["choroid_thickness"] + p["retina_thickness"]
    if not inner < CILIARY_THICKNESS:
        raise SceneError(f"eye: choroid_thickness + retina_thickness ({inner}) must be below the ciliary body "
                         f"thickness {CILIARY_THICKNESS} mm")
    if max(p["sclera_thickness_limbus"], p["sclera_thickness_equator"], p["sclera_thickness_pole"],
           p["cornea_thickness"]) > 2.0:
        raise SceneError("eye: the sclera and the cornea must be thinner than 2 mm")


def _check_detachment(detachment, m, sector_deg):
    if not isinstance(detachment, dict) or set(detachment) - set(_DETACHMENT_KEYS) \
            or not {"polar_deg", "extent_deg", "gap"} <= set(detachment):
        raise SceneError(f"eye: detachment must be None or a table with {', '.join(_DETACHMENT_KEYS)} "
                         f"(azimuth_deg optional), got {detachment!r}")
    detachment = {"azimuth_deg": 0.0, **detachment}
    for key in _DETACHMENT_KEYS:
        value = detachment[key]
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            raise SceneError(f"eye: detachment {key} must be a number, got {value!r}")
    check("eye", "detachment gap", detachment["gap"], "positive number")
    check("eye", "detachment extent_deg", detachment["extent_deg"], "positive number")
    if detachment["gap"] > 0.5:
        raise SceneError(f"eye: detachment gap must be at most 0.5 mm, got {detachment['gap']}")
    ora_deg = math.degrees(m.s_ora / m.Ro)
    if not (0.0 <= detachment["polar_deg"] and detachment["polar_deg"] + detachment["extent_deg"] < ora_deg - 2.0):
        raise SceneError(f"eye: the detachment must lie in the retina: polar_deg + extent_deg below the ora "
                         f"serrata at {ora_deg - 2.0:.0f} deg from the posterior pole, got "
                         f"{detachment['polar_deg']} + {detachment['extent_deg']}")
    azimuth = detachment["azimuth_deg"] % 360.0
    symmetric = (detachment["polar_deg"] == 0.0 or sector_deg == 360.0
                 or (sector_deg == 180.0 and azimuth in (0.0, 180.0)))
    if not symmetric:
        raise SceneError("eye: a wedge model is mirrored across its cut planes, so its detachment must be too: "
                         "centre on the axis (polar_deg = 0) or, in a half model, azimuth_deg 0 or 180")
    return {key: float(detachment[key]) for key in _DETACHMENT_KEYS}


def eye_geometry(axial_length=24.0, sclera_thickness_limbus=0.5, sclera_thickness_equator=0.4,
                 sclera_thickness_pole=1.0, cornea_thickness=0.53, choroid_thickness=0.25, retina_thickness=0.25,
                 optic_nerve_diameter=3.5, optic_nerve_length=3.0, detachment=None, refine=1, n_circ=None,
                 sector_deg=360.0):
    """The eye mesh as numpy arrays (see :func:`build_eye` for the parameters).

    Returns:
        An :class:`EyeMesh`.

    Raises:
        SceneError: if a parameter is invalid or the mesh would have a corner with a scaled
            Jacobian below ``MIN_SCALED_JACOBIAN``.
    """
    start = time.perf_counter()
    p = dict(locals())
    del p["start"]
    if p["n_circ"] is None and isinstance(refine, numbers.Integral):
        p["n_circ"] = N_CIRC * refine
    if isinstance(sector_deg, numbers.Real) and not isinstance(sector_deg, bool):
        p["sector_deg"] = float(sector_deg)
    _check_parameters(p)
    m = _Meridian(p)
    if detachment is not None:
        detachment = _check_detachment(detachment, m, p["sector_deg"])
    nodes, hexes, regions = _build_arrays(m, p["n_circ"], p["sector_deg"])
    if detachment is not None:
        nodes, hexes = _detach(nodes, hexes, regions, m, detachment, p["sector_deg"])
    _, scaled = corner_jacobians(nodes, hexes)
    if scaled.min() < MIN_SCALED_JACOBIAN:
        raise SceneError(f"eye: the mesh has a corner with scaled Jacobian {scaled.min():.3f} < {MIN_SCALED_JACOBIAN} "
                         "(a detachment gap too large for the elements?)")
    surfaces = _surfaces(nodes, hexes, regions, m, p["sector_deg"])
    # The cavities and the subretinal gap must be closed, but for their cuts by the symmetry planes.
    cavities = {"vitreous_wall": surfaces["vitreous_wall"], "anterior_chamber_wall": surfaces["anterior_chamber_wall"]}
    if detachment is not None:
        cavities["subretinal gap"] = np.concatenate([surfaces["retina_outer"], surfaces["choroid_inner"]])
    for name, quads in cavities.items():
        if not np.all(_on_cut_planes(nodes[_open_edges(quads)], p["sector_deg"])):
            raise RuntimeError(f"eye: the {name} is not closed")
    whole = 360.0 / p["sector_deg"]
    wall = np.unique(surfaces["vitreous_wall"])
    on_axis = wall[np.linalg.norm(nodes[wall, :2], axis=1) < _TOLERANCE]
    info = {
        "hexahedra": len(hexes), "nodes": len(nodes),
        "per_region": {name: int(np.sum(regions == name)) for name in np.unique(regions)},
        "min_scaled_jacobian": float(scaled.min()),
        "vitreous_volume": whole * _signed_volume(nodes, surfaces["vitreous_wall"]),
        "anterior_chamber_volume": whole * _signed_volume(nodes, surfaces["anterior_chamber_wall"]),
        "axial_length": m.z_apex - nodes[on_axis, 2].min(),
        "globe_radius": m.Ro, "corneal_apex_z": m.z_apex,
        "limbus": (m.rho_l, float(m.outer(m.s_l)[0][1])),
        "ora_serrata_deg": math.degrees(m.s_ora / m.Ro),
        "optic_nerve_end_z": m.z_nerve_end, "n_circ": p["n_circ"],
    }
    if detachment is not None:
        info["detachment"] = detachment
    order = ["cornea", "sclera", "ciliary_body", "choroid", "retina", "optic_nerve", "lens", "zonule"]
    info["build_seconds"] = time.perf_counter() - start
    return EyeMesh(nodes, {name: hexes[regions == name] for name in order}, surfaces, info)


def scleral_wall(samples=60, **parameters):
    """The wall around the vitreous as the mesh builds it, direction by direction from the centre
    of the sclera, for estimates that treat each direction as a piece of a layered sphere.

    On the sclera the shell's lines are radial (but within ``LIMBUS_BLEND`` of the limbus), so at
    polar angle theta (from the posterior pole) the wall is concentric spherical layers: retina,
    choroid and sclera up to the ora serrata, the ciliary body and the sclera from there to the
    scleral spur, where the ciliary body ends. The sclera in front of the spur and the cornea are
    left out (they bound the aqueous, a cavity of its own).

    Args:
        samples: number of polar angles, equally spaced from the pole to the scleral spur.
        parameters: as :func:`eye_geometry` (defaults the same).

    Returns:
        (theta, layers): the polar angles (radians), and for each the layers inside out,
        ``[(inner radius, outer radius, tissue), ...]`` in mm.
    """
    p = {name: value.default for name, value in inspect.signature(eye_geometry).parameters.items()}
    p.update(parameters)
    m = _Meridian(p)
    inner = p["choroid_thickness"] + p["retina_thickness"]
    theta, layers = np.linspace(0.0, m.s_spur / m.Ro, samples), []
    for s in m.Ro * theta:
        scleral = m.Ro - float(m.shell_thickness(s))
        below = scleral - float(m.inner_thickness(s))
        if s < m.s_ora:
            choroid = scleral - p["choroid_thickness"] / inner * (scleral - below)
            layers.append([(below, choroid, "retina"), (choroid, scleral, "choroid"), (scleral, m.Ro, "sclera")])
        else:
            layers.append([(below, scleral, "ciliary_body"), (scleral, m.Ro, "sclera")])
    return theta, layers


def build_eye(**parameters):
    """Add the gmsh model "eye": a human eye in 8-node hexahedra (see the module docstring).

    Call on the rank that owns gmsh, with gmsh initialized.

    Args:
        axial_length: corneal apex to the vitreoretinal interface on the axis (mm), 24 (Atchison
            & Smith's schematic eyes); the sclera is a sphere whose radius follows from it.
        sclera_thickness_limbus, sclera_thickness_equator, sclera_thickness_pole: 0.5, 0.4 and 1.0 mm
            (Olsen et al., Am. J. Ophthalmol. 125:237, 1998: 0.53, 0.39, 0.9-1.0; Norman et al.,
            Exp. Eye Res. 90:277, 2010).
        cornea_thickness: central, 0.53 mm (Doughty & Zaman, Surv. Ophthalmol. 44:367, 2000); it
            blends into the limbal sclera.
        choroid_thickness: 0.25 mm (subfoveal 0.29 mm: Margolis & Spaide, Am. J. Ophthalmol.
            147:811, 2009).
        retina_thickness: 0.25 mm (~0.25 mm posteriorly, thinner toward the ora: Hogan et al. 1971).
        optic_nerve_diameter: with its sheaths, 3.5 mm (3-4 mm); optic_nerve_length: 3 mm of it.
        detachment: None, or {"polar_deg": angle of the centre from the posterior pole,
            "azimuth_deg": its azimuth from the x axis (default 0), "extent_deg": angular radius of
            the detached cap, "gap": subretinal gap in mm (0.05-0.2)}; angles seen from the centre
            of the eye.
        refine: 1 gives 9,820 hexahedra (the seed's eye had 9,862); 2 doubles the elements in every
            direction (78,560).
        n_circ: sectors of the full circle (default 40 * refine), a multiple of 8.
        sector_deg: 360 (whole eye), 180 or 90 (a wedge with the cut planes "cut_0" at azimuth 0
            and "cut_1" at ``sector_deg``, for models symmetric about them).

    Returns:
        The mesh statistics (:attr:`EyeMesh.info`).

    Raises:
        SceneError: if a parameter is invalid, or the mesh would have a corner with a scaled
            Jacobian below ``MIN_SCALED_JACOBIAN`` (a detachment gap too large for its elements).
    """
    known = inspect.signature(eye_geometry).parameters
    unknown = sorted(set(parameters) - set(known))
    if unknown:
        raise SceneError(f"eye: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(known)}")
    eye = eye_geometry(**parameters)
    add_hex_model("eye", eye.nodes, None, None, eye.surfaces, regions=eye.regions)
    return eye.info


def write(path, **parameters):
    """Write the eye as an MSH 4.1 file in a private gmsh session (serial).

    Args:
        path: the .msh file to write.
        **parameters: keyword arguments of :func:`build_eye`.
    """
    write_msh(path, build_eye, **parameters)


def _build_from_cli(detachment=None, **parameters):
    if detachment is not None:
        detachment = dict(zip(("polar_deg", "azimuth_deg", "extent_deg", "gap"), detachment))
    info = build_eye(detachment=detachment, **parameters)
    print(f"eye: {info['hexahedra']} hexahedra, {info['nodes']} nodes, worst scaled Jacobian "
          f"{info['min_scaled_jacobian']:.3f}, vitreous {info['vitreous_volume'] / 1000:.2f} mL, anterior chamber "
          f"{info['anterior_chamber_volume'] / 1000:.3f} mL, axial length {info['axial_length']:.2f} mm, "
          f"built in {info['build_seconds']:.2f} s")


def add_eye_arguments(parser):
    """The eye's dimensions and resolution as command-line options (all but the detachment)."""
    parser.add_argument("--axial-length", dest="axial_length", type=float, default=24.0)
    parser.add_argument("--sclera-thickness-limbus", dest="sclera_thickness_limbus", type=float, default=0.5)
    parser.add_argument("--sclera-thickness-equator", dest="sclera_thickness_equator", type=float, default=0.4)
    parser.add_argument("--sclera-thickness-pole", dest="sclera_thickness_pole", type=float, default=1.0)
    parser.add_argument("--cornea-thickness", dest="cornea_thickness", type=float, default=0.53)
    parser.add_argument("--choroid-thickness", dest="choroid_thickness", type=float, default=0.25)
    parser.add_argument("--retina-thickness", dest="retina_thickness", type=float, default=0.25)
    parser.add_argument("--optic-nerve-diameter", dest="optic_nerve_diameter", type=float, default=3.5)
    parser.add_argument("--optic-nerve-length", dest="optic_nerve_length", type=float, default=3.0)
    parser.add_argument("--refine", type=int, default=1, help="2 doubles the elements in every direction")
    parser.add_argument("--n-circ", dest="n_circ", type=int, default=None, help="sectors of the full circle")
    parser.add_argument("--sector-deg", dest="sector_deg", type=float, default=360.0, choices=_SECTORS)


def main(argv=None):
    """Command-line entry point: write an eye mesh (on rank 0 when run under MPI)."""
    parser = argparse.ArgumentParser(prog="python3 -m eyeball_fenicsx.meshing.builders.eye", description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="the .msh file to write")
    add_eye_arguments(parser)
    parser.add_argument("--detachment", type=float, nargs=4,
                        metavar=("POLAR_DEG", "AZIMUTH_DEG", "EXTENT_DEG", "GAP"),
                        help="detached cap: centre (degrees from the posterior pole, azimuth), angular radius, gap (mm)")
    run_cli(parser, _build_from_cli, argv)


if __name__ == "__main__":
    main()

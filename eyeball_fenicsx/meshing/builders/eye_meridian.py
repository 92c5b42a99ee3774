"""The meridional section of the eye (eyeball_fenicsx/meshing/builders/eye.py): anatomy, tissue boundaries, node rows.

The optic axis is the z axis, the corneal apex at +z and the origin the centre of the spherical
sclera; a point of the section is (rho, z), rho >= 0 its distance from the axis. The section is
a few structured quadrilateral blocks, whose rows of nodes :class:`Meridian` places:

* the corneoscleral shell: sclera from the posterior pole to the limbus, then cornea to the apex,
  with its nodes on lines C(s) + d n(s), where C(s) is the outer surface by arc length s from the
  posterior pole, n(s) the inward normal and d the depth (the two normals are blended over
  0.8 mm at the limbus, where the surface has a kink);
* the inner layers on the same lines: choroid and retina from the pole to the ora serrata, then
  the ciliary body to the scleral spur, thickening from the pars plana to the pars plicata; the
  retina ends at the ora serrata, the ciliary body's front face is the iris root (no iris);
* the zonule, a fan-shaped ring from the pars plicata to the lens equator;
* the lens, between two spherical surfaces and a short equatorial rim: Le Grand's, its anterior pole
  ``anterior_chamber_depth`` behind the cornea. With a chamber shallower than the reference eye's
  with respect to the limbus (where the ciliary body and the zonule are) the lens is thicker, its
  posterior surface and equator where they are, its anterior surface steeper through the anterior
  pole and the rim: as the lens thickens with age, the distance from the cornea to its posterior
  surface unchanged, and the chamber shallows (Cook et al., Vision Res. 34:2945, 1994); a deeper
  chamber moves the whole lens back;
* the optic nerve, a cylinder behind the posterior pole (on the axis, as in an axisymmetric model).

The outer surface is the sclera and the cornea, a sphere of radius ``corneal_radius`` (7.8 mm),
meeting at the limbus, of radius rho_l. In front of the equator (z >= 0) the sclera is a sphere of
radius R_o about the origin; behind it, at polar angle theta from the posterior pole, its radius is

    r(theta) = R_o + e cos^2(theta),

which is R_o at the equator (with zero slope: the surface is C1 there) and R_o + e at the posterior
pole: to first order in e / R_o the half spheroid of semi-axes R_o (equatorial) and R_o + e (polar).
The eye of the reference axial length 24 mm (Atchison & Smith's schematic eyes) is the sphere
(e = 0): R_o + sqrt(R_o^2 - rho_l^2) = a, a the axial length (corneal apex to the vitreoretinal
interface on the axis) less the corneal sagitta plus the wall at the pole. Another axial length L
keeps the anterior segment and changes the equatorial diameter by ``EQUATOR_PER_AXIAL`` (L - 24),
the rest of the change going into the posterior segment, e: myopic eyes are larger in all three
dimensions, but more in length (0.35 mm/D) than in height (0.19 mm/D) and width (0.10 mm/D)
(Atchison et al., IOVS 45:3380, 2004, MRI of 88 eyes from emmetropia to -12 D); a short
(hyperopic) eye is assumed to follow the same rates the other way (their eyes were not hyperopic).
A long eye's posterior segment is prolate (e > 0), a short one's oblate (e < 0).

A point of the shell is on the line through the origin at polar angle theta = s / R_o, s the
parameter of the meridian (the arc length from the posterior pole on the sphere of radius R_o:
the arc length of the sclera itself in front of the equator), at a depth measured across the
shell (the line's direction is scaled by 1 / cos alpha, alpha = atan(r' / r) the angle between the
line and the normal of r(theta)); so the shell's lines meet at the origin, as in the sphere. The
sclera thins from the pole to the equator as cos^2 of the polar angle and thickens again to the
limbus; the cornea thickens quadratically in its own polar angle from its central thickness to the
limbal sclera's. Blends are ``smoothstep`` = sin^2(pi x / 2), C1 with zero slope at both ends.

Along the meridian the shell's columns of nodes are ``SPACING`` apart (over ``refine``), but around
the circles of latitude ``graded_at`` (mm behind the limbus along the sclera, as a buckle's
position), each on a column (or within ``FINE_SPACING`` / 2 of one, where two circles, or a circle
and a tissue's edge, are closer): there the spacing is ``FINE_SPACING``, and longer by ``GRADING``
per mm away from the nearest such circle (the elements either side of a circle are about 0.13 mm
long). A buckle's edge and its sutures' bites,
1 mm apart, bend the sclera between them (buckle_sutures.py says how much this matters).

Sources of the anatomy (beside each constant): the Le Grand full theoretical eye (Atchison &
Smith, Optics of the Human Eye, 2000, appendix A); Rosen et al., Vision Res. 46:1002, 2006 (the
lens diameter); Rüfer et al., Cornea 24:259, 2005 (the limbus); Hogan, Alvarado & Weddell,
Histology of the Human Eye, 1971 (ora serrata, ciliary body); Borges-Giampani & Giampani, in
Glaucoma - Basic and Clinical Aspects, InTech 2013 (the ciliary body's section).
"""
import math

import numpy as np

from ...checks import is_number
from ...errors import SceneError

# --- anatomy (mm) -----------------------------------------------------------------------------
# Le Grand full theoretical eye, in Atchison & Smith, Optics of the Human Eye (2000), appendix A:
# anterior corneal radius 7.8, aqueous depth 3.05, lens 4.0 thick with radii 10.2 and -6.0,
# cornea to retina 24.2 (24.0 in Navarro's eye).
CORNEA_RADIUS = 7.8
ANTERIOR_CHAMBER_DEPTH = 3.05  # posterior cornea to anterior lens, on the axis
REFERENCE_AXIAL_LENGTH = 24.0  # the spherical eye
# Myopic eyes grow 0.35 mm/D in length, 0.19 mm/D in height and 0.10 mm/D in width (Atchison et al.,
# "Eye shape in emmetropia and myopia", IOVS 45:3380, 2004): an axisymmetric eye's equatorial
# diameter grows by the mean of height and width per mm of axial length.
EQUATOR_PER_AXIAL = (0.19 + 0.10) / 2 / 0.35
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
FINE_SPACING = 0.1  # ... at a graded line (mm)
GRADING = 0.5       # growth of the meridional element size per mm away from a graded line
CORNEA_CORE = 1.3   # radius (arc length) of the corneal butterfly core (mm)
LENS_CORE = 1.2     # radius of the lens butterfly core (mm)
CORE_SQUARE = 0.5   # half-side of the core square / core radius
SCLERA_LAYERS, CHOROID_LAYERS, RETINA_LAYERS = 2, 1, 1
LENS_LAYERS, ZONULE_COLUMNS, LENS_COLUMNS, NERVE_LAYERS = 4, 3, 4, 3
N_CIRC = 40         # sectors of the full circle at refine = 1


def graded_spacing(distance: np.ndarray, coarse: float) -> np.ndarray:
    """The element length (mm, at refine = 1) at ``distance`` mm from the nearest graded line:
    ``FINE_SPACING`` there, longer by ``GRADING`` per mm away, up to ``coarse``."""
    return np.minimum(coarse, FINE_SPACING + GRADING * distance)


def integrated(a: float, b: float, density) -> tuple[np.ndarray, np.ndarray]:
    """401 points x of [a, b] and the integral of ``density`` from a to each (trapezoidal rule)."""
    x = np.linspace(a, b, 401)
    d = density(x)
    return x, np.concatenate([[0.0], np.cumsum((d[1:] + d[:-1]) / 2 * np.diff(x))])


def divided(x: np.ndarray, integral: np.ndarray, count: int) -> np.ndarray:
    """The count + 1 points of x (ends included) where ``count`` equal steps of the integral fall."""
    return np.interp(np.linspace(0.0, integral[-1], count + 1), integral, x)


def smoothstep(x: np.ndarray) -> np.ndarray:
    """0 for x <= 0, 1 for x >= 1, sin^2(pi x / 2) between: C1 with zero slope at both ends."""
    return np.sin(np.pi / 2 * np.clip(x, 0.0, 1.0)) ** 2


def unit(v: np.ndarray) -> np.ndarray:
    """v divided by its length, along its last axis."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class Meridian:
    """The meridional section (rho, z) of the eye: curves, layer depths and column positions."""

    def __init__(self, p: dict):
        self.p = p
        rho_l, Rc = LIMBUS_DIAMETER / 2, p["corneal_radius"]
        self.rho_l, self.Rc = rho_l, Rc
        corneal_sag = Rc - math.sqrt(Rc**2 - rho_l**2)
        pole_wall = p["sclera_thickness_pole"] + p["choroid_thickness"] + p["retina_thickness"]
        # The outer posterior pole to the limbus' plane: a = R_o + e + sqrt(R_o^2 - rho_l^2).
        a = p["axial_length"] - corneal_sag + pole_wall
        reference = REFERENCE_AXIAL_LENGTH - corneal_sag + pole_wall
        sphere = (reference * reference + rho_l**2) / (2 * reference)  # the reference eye's radius
        change = p["axial_length"] - REFERENCE_AXIAL_LENGTH
        self.Ro = sphere + EQUATOR_PER_AXIAL / 2 * change
        # e from a - reference = change, written as differences so that e = 0 exactly at the reference.
        self.elongation = change - (self.Ro - sphere) - (math.sqrt(self.Ro**2 - rho_l**2)
                                                          - math.sqrt(sphere**2 - rho_l**2))
        z_l = a - (self.Ro + self.elongation)
        self.theta_l = math.atan2(rho_l, -z_l)
        self.s_l = self.Ro * self.theta_l
        self.z_cc = z_l - math.sqrt(Rc**2 - rho_l**2)
        self.z_apex = self.z_cc + Rc
        self.phi_l = math.asin(rho_l / Rc)
        self.S = self.s_l + Rc * self.phi_l
        self.n_limbus = unit(np.array([-math.sin(self.theta_l), math.cos(self.theta_l)])
                             + np.array([-math.sin(self.phi_l), -math.cos(self.phi_l)]))
        self.s_ora = self.s_l - ORA_TO_LIMBUS
        self.s_z0 = self.s_l - ZONULE_POSTERIOR_TO_LIMBUS
        self.s_z1 = self.s_l - ZONULE_ANTERIOR_TO_LIMBUS
        self.s_spur = self.s_l - SPUR_TO_LIMBUS
        self.nerve_radius = p["optic_nerve_diameter"] / 2
        if not self.nerve_radius < 0.5 * self.Ro:
            raise SceneError(f"eye: optic_nerve_diameter {p['optic_nerve_diameter']} is too large")
        theta = math.asin(self.nerve_radius / self.Ro)
        for _ in range(50):  # r(theta) sin(theta) = the nerve's radius, by fixed point (a contraction)
            theta, previous = math.asin(self.nerve_radius / float(self.radius(theta))), theta
            if theta == previous:
                break
        self.s_nerve = self.Ro * theta
        self.z_nerve_end = -(self.Ro + self.elongation) - p["optic_nerve_length"]
        self._place_lens(corneal_sag)
        self.rho_lens = LENS_DIAMETER / 2
        self.wall = r = self.p["refine"] * self.p["wall_layers"]  # multiplies the layers through the wall
        self.fractions = np.concatenate([
            np.linspace(0.0, p["choroid_thickness"], CHOROID_LAYERS * r + 1),
            np.linspace(p["choroid_thickness"], p["choroid_thickness"] + p["retina_thickness"],
                        RETINA_LAYERS * r + 1)[1:]]) / (p["choroid_thickness"] + p["retina_thickness"])
        self.graded = self._graded_lines(p["graded_at"])
        self.columns = self._columns()

    def _graded_lines(self, graded_at):
        """The meridian's parameters s of the circles of latitude ``graded_at`` (mm behind the limbus
        along the sclera), sorted and checked to lie on the sclera."""
        if not (isinstance(graded_at, (list, tuple, np.ndarray)) and all(is_number(x) for x in graded_at)):
            raise SceneError(f"eye: graded_at must be a list of distances behind the limbus (mm), got {graded_at!r}")
        for behind in graded_at:
            if not ZONULE_POSTERIOR_TO_LIMBUS < behind < self.s_l - self.s_nerve:
                raise SceneError(f"eye: graded_at {behind} mm behind the limbus is off the sclera that can be graded "
                                 f"({ZONULE_POSTERIOR_TO_LIMBUS:g} to {self.s_l - self.s_nerve:.1f} mm: from where the "
                                 "zonule meets the ciliary body to the optic nerve's edge)")
        return np.sort(self.s_l - np.asarray(graded_at, dtype=float))

    def _place_lens(self, corneal_sag):
        """The lens's poles and anterior radius (Le Grand's lens): its anterior pole at the aqueous depth
        behind the posterior cornea. A chamber shallower than the reference eye's with respect to the
        limbus (a shallower depth, or a steeper cornea's deeper sagitta) thickens the lens forward,
        its posterior surface and equator staying (module docstring)."""
        p, rho_l = self.p, self.rho_l
        self.z_lens_front = self.z_apex - p["cornea_thickness"] - p["anterior_chamber_depth"]
        shallower = (corneal_sag - (CORNEA_RADIUS - math.sqrt(CORNEA_RADIUS**2 - rho_l**2))) \
            + (ANTERIOR_CHAMBER_DEPTH - p["anterior_chamber_depth"])
        self.lens_anterior_radius = LENS_ANTERIOR_RADIUS
        self.z_lens_back = self.z_lens_front - LENS_THICKNESS
        if shallower > 0:
            rim = LENS_DIAMETER / 2
            sag = LENS_ANTERIOR_RADIUS - math.sqrt(LENS_ANTERIOR_RADIUS**2 - rim**2) + shallower
            self.lens_anterior_radius = (sag * sag + rim * rim) / (2 * sag)
            self.z_lens_back -= shallower

    def radius(self, theta):
        """The sclera's outer radius r(theta) at polar angle theta (rad) from the posterior pole
        (as far as the limbus): R_o + e cos^2(theta) behind the equator, R_o in front of it."""
        theta = np.asarray(theta, dtype=float)
        return self.Ro + self.elongation * np.where(theta < np.pi / 2, np.cos(theta) ** 2, 0.0)

    def outer(self, s):
        """The outer surface C(s) and the direction n(s) of the shell's line, by the meridian's
        parameter s from the posterior pole: shape (..., 2) each, in (rho, z). A unit vector but
        behind the equator of an elongated eye, where it is the inward radial direction over
        cos alpha (module docstring)."""
        s = np.asarray(s, dtype=float)
        theta = np.minimum(s, self.s_l) / self.Ro
        phi = np.maximum(self.S - s, 0.0) / self.Rc
        on_sclera = (s <= self.s_l)[..., None]
        r = self.radius(theta)
        point = np.where(on_sclera, np.stack([r * np.sin(theta), -r * np.cos(theta)], axis=-1),
                         np.stack([self.Rc * np.sin(phi), self.z_cc + self.Rc * np.cos(phi)], axis=-1))
        normal = np.where(on_sclera, np.stack([-np.sin(theta), np.cos(theta)], axis=-1),
                          np.stack([-np.sin(phi), -np.cos(phi)], axis=-1))
        weight = smoothstep(1.0 - np.abs(s - self.s_l) / LIMBUS_BLEND)[..., None]
        slope = -self.elongation * np.where(theta < np.pi / 2, np.sin(2 * theta), 0.0) / r  # r' / r = tan(alpha)
        stretch = np.where(on_sclera[..., 0], np.sqrt(1.0 + slope**2), 1.0)[..., None]
        return point, unit((1 - weight) * normal + weight * self.n_limbus) * stretch

    def shell_thickness(self, s):
        """Sclera (s <= s_l) or cornea (s > s_l) thickness."""
        p = self.p
        s = np.asarray(s, dtype=float)
        theta = np.minimum(s, self.s_l) / self.Ro
        posterior = p["sclera_thickness_equator"] + (p["sclera_thickness_pole"] - p["sclera_thickness_equator"]) \
            * np.cos(np.minimum(theta, np.pi / 2)) ** 2
        anterior = p["sclera_thickness_equator"] + (p["sclera_thickness_limbus"] - p["sclera_thickness_equator"]) \
            * smoothstep((theta - np.pi / 2) / (self.theta_l - np.pi / 2))
        phi = np.maximum(self.S - s, 0.0) / self.Rc
        cornea = p["cornea_thickness"] \
            + (p["sclera_thickness_limbus"] - p["cornea_thickness"]) * (phi / self.phi_l) ** 2
        return np.where(s > self.s_l, cornea, np.where(theta <= np.pi / 2, posterior, anterior))

    def inner_thickness(self, s):
        """Choroid + retina up to the ora serrata, then the ciliary body thickening to the pars plicata."""
        base = self.p["choroid_thickness"] + self.p["retina_thickness"]
        return base + (CILIARY_THICKNESS - base) * smoothstep((np.asarray(s) - self.s_ora) / (self.s_z0 - self.s_ora))

    def shell_row(self, s, j):
        point, normal = self.outer(s)
        layers = SCLERA_LAYERS * self.wall
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
        radius = self.lens_anterior_radius
        front = self.z_lens_front - (radius - np.sqrt(radius**2 - rho**2))
        back = self.z_lens_back + (LENS_POSTERIOR_RADIUS - np.sqrt(LENS_POSTERIOR_RADIUS**2 - rho**2))
        return np.stack([rho, back + j / (LENS_LAYERS * self.p["refine"]) * (front - back)], axis=-1)

    def _stretch(self, s):
        """The outer surface's length per unit of the parameter s: 1 but behind the equator of an
        elongated eye, where the length element is sqrt(r^2 + r'^2) dtheta."""
        theta = np.minimum(s, self.s_l) / self.Ro
        r = self.radius(theta)
        slope = -self.elongation * np.where(theta < np.pi / 2, np.sin(2 * theta), 0.0)
        return np.where(s <= self.s_l, np.sqrt(r**2 + slope**2) / self.Ro, 1.0)

    def _length(self, start, stop):
        """Length of the outer surface between the parameters start and stop (by the trapezoidal rule
        on 200 intervals)."""
        s = np.linspace(start, stop, 201)
        factor = self._stretch(s)
        return float(np.sum((factor[1:] + factor[:-1]) / 2 * np.diff(s)))

    def spacing(self, s):
        """The element length along the meridian at s, at refine = 1: ``SPACING``, but ``FINE_SPACING``
        at a graded line, growing by ``GRADING`` per mm away from the nearest."""
        s = np.asarray(s, dtype=float)
        if not len(self.graded):
            return np.full_like(s, SPACING)
        return graded_spacing(np.min(np.abs(s[..., None] - self.graded), axis=-1), SPACING)

    def _graded_columns(self, start, stop):
        """The columns of (start, stop], about ``spacing`` (over ``refine``) apart: the graded lines
        inside are columns (but one within FINE_SPACING / 2 of the last or of ``stop``), and each
        piece between them is divided where equal steps of the integral of stretch / spacing fall."""
        ends = []
        for line in self.graded:
            if (ends[-1] if ends else start) + FINE_SPACING / 2 < line < stop - FINE_SPACING / 2:
                ends.append(line)
        columns = []
        for a, b in zip([start, *ends], [*ends, stop]):
            s, integral = integrated(a, b, lambda s: self._stretch(s) / self.spacing(s))
            columns.append(divided(s, integral, max(1, round(integral[-1])) * self.p["refine"])[1:])
        return np.concatenate(columns)

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
            if count is None and np.min(self.spacing(np.linspace(start, stop, 401))) < SPACING:
                columns.append(self._graded_columns(start, stop))
                continue
            count = count or max(1, round(self._length(start, stop) / SPACING)) * r
            columns.append(np.linspace(start, stop, count + 1)[1:])
        columns = np.concatenate(columns)
        for name, value in (("z0", self.s_z0), ("z1", self.s_z1), ("spur", self.s_spur)):
            self.index[name] = int(np.argmin(np.abs(columns - value)))
        return columns

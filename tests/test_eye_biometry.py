"""The eye built from biometry (eyeball_fenicsx/meshing/builders/eye.py, eye_meridian.py): axial length,
corneal radius and anterior chamber depth measured on the mesh's nodes, a myopic eye's shape against
the MRI rates of Atchison et al. (IOVS 45:3380, 2004), and the buckle on long and short eyes.

The builders are numpy only (no gmsh, no DOLFINx): each rank builds the coarse eye (n_circ = 16, a
quarter eye) in a fraction of a second, and every check is on its own nodes.
"""
import math

import numpy as np
import pytest

from eyeball_fenicsx.errors import SceneError
from eyeball_fenicsx.meshing.builders import buckled_eye, eye

COARSE = {"n_circ": 16, "sector_deg": 90.0}
# The nodes of an axisymmetric surface on the axis are placed on it exactly (the butterfly cores'
# centres), and every node of a spherical surface on its sphere: the mesh holds the biometry to
# round-off. 1e-9 mm is that round-off with a wide margin.
EXACT = 1e-9
# Atchison et al. 2004 (MRI, 88 eyes, emmetropia to -12 D): per dioptre of myopia the eye grows 0.35 mm
# in length (internal: cornea to retina), 0.19 mm in height and 0.10 mm in width (retina to retina).
LENGTH_PER_D, HEIGHT_PER_D, WIDTH_PER_D = 0.35, 0.19, 0.10


def _nodes(mesh, surface):
    return mesh.nodes[np.unique(mesh.surfaces[surface])]


def _on_axis(points):
    return points[np.linalg.norm(points[:, :2], axis=1) < EXACT]


@pytest.mark.parametrize("axial_length", [21.0, 22.0, 28.0, 30.0])
def test_axial_length_is_the_biometry(axial_length):
    mesh = eye.eye_geometry(axial_length=axial_length, **COARSE)
    # Corneal apex (the highest node of the cornea) to the vitreoretinal interface on the axis.
    apex = _nodes(mesh, "cornea_outer")[:, 2].max()
    retina = _on_axis(_nodes(mesh, "vitreous_wall"))[:, 2].min()
    assert apex - retina == pytest.approx(axial_length, abs=EXACT)
    assert mesh.info["axial_length"] == pytest.approx(axial_length, abs=EXACT)
    # Elements as good as the default eye's (0.50 at this resolution) within 0.05.
    assert mesh.info["min_scaled_jacobian"] > 0.45


@pytest.mark.parametrize("corneal_radius, depth", [(7.2, 2.8), (7.8, 3.05), (8.4, 3.6)])
def test_corneal_radius_and_chamber_depth_are_the_biometry(corneal_radius, depth):
    mesh = eye.eye_geometry(corneal_radius=corneal_radius, anterior_chamber_depth=depth, axial_length=26.0,
                            **COARSE)
    # The sphere through the nodes of the cornea's outer surface, by linear least squares:
    # |x|^2 = 2 c . x + (R^2 - |c|^2).
    x = _nodes(mesh, "cornea_outer")
    solution = np.linalg.lstsq(np.column_stack([2 * x, np.ones(len(x))]), np.sum(x**2, axis=1), rcond=None)[0]
    centre = solution[:3]
    radius = math.sqrt(solution[3] + centre @ centre)
    assert radius == pytest.approx(corneal_radius, abs=1e-7)
    assert np.linalg.norm(centre[:2]) < 1e-7  # on the optic axis
    # Anterior chamber depth: on the axis, the chamber's wall is the posterior cornea (top) and the
    # lens's anterior pole (bottom); the cornea between its two surfaces is cornea_thickness thick.
    wall = _on_axis(_nodes(mesh, "anterior_chamber_wall"))[:, 2]
    assert wall.max() - wall.min() == pytest.approx(depth, abs=EXACT)
    assert x[:, 2].max() - wall.max() == pytest.approx(0.53, abs=EXACT)  # the default central thickness


def test_shallow_chamber_thickens_the_lens_forward():
    # Cook et al. (Vision Res. 34:2945, 1994): as the lens thickens with age, the distance from the cornea
    # to its posterior surface stays and the chamber shallows; a deeper chamber moves the lens back.
    # On the axis the vitreous wall's highest node is the lens's posterior pole, the chamber wall's
    # lowest its anterior pole.
    def poles(depth):
        mesh = eye.eye_geometry(anterior_chamber_depth=depth, **COARSE)
        back = _on_axis(_nodes(mesh, "vitreous_wall"))[:, 2].max()
        return back, _on_axis(_nodes(mesh, "anterior_chamber_wall"))[:, 2].min()
    reference, shallow, deep = poles(3.05), poles(2.05), poles(4.05)
    assert shallow[0] == pytest.approx(reference[0], abs=EXACT)
    assert shallow[1] - shallow[0] == pytest.approx(4.0 + 1.0, abs=EXACT)  # Le Grand's 4.0 mm lens, thicker by 1
    assert deep[1] - deep[0] == pytest.approx(4.0, abs=EXACT)
    assert reference[0] - deep[0] == pytest.approx(1.0, abs=EXACT)


@pytest.mark.parametrize("axial_length", [21.0, 30.0])
@pytest.mark.parametrize("corneal_radius", [6.5, 9.5])
@pytest.mark.parametrize("depth", [1.5, 4.5])
def test_every_corner_of_the_biometry_builds(axial_length, corneal_radius, depth):
    mesh = eye.eye_geometry(axial_length=axial_length, corneal_radius=corneal_radius, anterior_chamber_depth=depth,
                            **COARSE)
    assert mesh.info["min_scaled_jacobian"] > 0.4  # the default eye's 0.50, less 0.1


def _shape(axial_length):
    """Internal equatorial diameter (retina to retina, the widest ring of the vitreous wall) and the
    vitreous wall's posterior semi-axis (its depth behind the equator's plane) of a coarse eye."""
    wall = _nodes(eye.eye_geometry(axial_length=axial_length, **COARSE), "vitreous_wall")
    rho = np.linalg.norm(wall[:, :2], axis=1)
    equator = wall[np.argmax(rho)]
    return 2 * rho.max(), equator[2] - wall[:, 2].min()


def test_myopic_eye_is_prolate_as_atchison_measured():
    short, default, myopic = (_shape(length) for length in (22.0, 24.0, 28.0))
    # The equator grows by the mean of height and width per dioptre for each 0.35 mm of length:
    # 0.41 mm per mm. The widest node ring is within one element (0.8 mm, 0.033 rad) of the
    # equator, where the diameter is lower by at most R (0.033 / 2)^2 = 0.004 mm.
    per_mm = (HEIGHT_PER_D + WIDTH_PER_D) / 2 / LENGTH_PER_D
    assert (myopic[0] - default[0]) / 4.0 == pytest.approx(per_mm, abs=0.005)
    assert (default[0] - short[0]) / 2.0 == pytest.approx(per_mm, abs=0.005)
    # So the rest of the length goes behind the equator: the 28 mm eye is longer than it is wide,
    # by more than the default eye, and its posterior segment is prolate (deeper than its radius);
    # the short eye's is oblate. (The default's is slightly oblate on the inside, its wall
    # thicker at the pole, 1.5 mm, than at the equator, 0.9 mm.)
    assert 28.0 - myopic[0] > 24.0 - default[0] + 1.0
    assert myopic[1] / (myopic[0] / 2) > 1.1
    assert short[1] / (short[0] / 2) < default[1] / (default[0] / 2) < 1.0


def test_scleral_thickness_is_kept_in_a_long_eye():
    # Behind the equator the shell's lines run through the centre, not along the normal, and are
    # lengthened so that the shell keeps its thickness across: at the posterior pole (on the axis, the
    # normal) the sclera, choroid and retina are sclera_thickness_pole + 0.25 + 0.25 thick.
    mesh = eye.eye_geometry(axial_length=30.0, sclera_thickness_pole=0.7, **COARSE)
    nerve_end = _on_axis(_nodes(mesh, "optic_nerve_end"))[:, 2].max()
    retina = _on_axis(_nodes(mesh, "vitreous_wall"))[:, 2].min()
    assert retina - nerve_end == pytest.approx(3.0 + 0.7 + 0.5, abs=EXACT)  # optic_nerve_length 3 mm


@pytest.mark.parametrize("axial_length", [22.0, 28.0])
def test_encircling_band_on_long_and_short_eyes(axial_length):
    mesh, layout = buckled_eye.buckled_eye_geometry(axial_length=axial_length, **COARSE)
    sclera = _nodes(mesh, "sclera_outer")
    band = _nodes(mesh, "band_inner")
    polar = np.arccos(-sclera[:, 2] / np.linalg.norm(sclera, axis=1))
    band_polar = np.arccos(-band[:, 2] / np.linalg.norm(band, axis=1))
    # band_position is measured along the sclera from the limbus (the most anterior node of the sclera's
    # outer surface) to the band's centre line: along the polyline of the sclera's nodes at azimuth 0,
    # whose chords are shorter than the arc by h^3 / 24 R^2 each (h <= 0.8 mm): < 0.01 mm in all.
    meridian = sclera[np.abs(sclera[:, 1]) < EXACT]
    meridian = meridian[np.argsort(-meridian[:, 2])]
    centre = 0.5 * (band_polar.min() + band_polar.max())
    meridian_polar = np.arccos(-meridian[:, 2] / np.linalg.norm(meridian, axis=1))
    front = meridian[meridian_polar >= centre]
    length = np.sum(np.linalg.norm(np.diff(front, axis=0), axis=1))
    last = front[-1]
    length += np.linalg.norm(last) * (np.arccos(-last[2] / np.linalg.norm(last)) - centre)  # to the centre line
    assert length == pytest.approx(buckled_eye.BAND_POSITION, abs=0.01)
    # The band clears the sclera under it by the builder's gap: the sclera in front of the equator is
    # the sphere under the band; a short eye's sclera behind the equator lies inside it.
    under = (polar >= band_polar.min() - EXACT) & (polar <= band_polar.max() + EXACT)
    clearance = np.linalg.norm(band, axis=1).min() - np.linalg.norm(sclera[under], axis=1)
    assert clearance.min() == pytest.approx(buckled_eye.GAP, abs=EXACT)
    assert clearance.max() < buckled_eye.GAP + (0.05 if axial_length < 24.0 else EXACT)


def test_buckle_behind_the_equator_of_a_long_eye_is_refused():
    # 28 mm: the equator is 14.3 mm behind the limbus, and the sclera behind it bulges out of the sphere.
    with pytest.raises(SceneError, match="would cut into the sclera behind the equator of this 28.0 mm eye"):
        buckled_eye.buckle_layout(axial_length=28.0, band_position=15.5, **COARSE)
    buckled_eye.buckle_layout(axial_length=24.0, band_position=15.5, **COARSE)  # the sphere: it fits


@pytest.mark.parametrize("options, fragment", [
    ({"axial_length": 20.5}, "axial_length must be between 21 and 30 mm, got 20.5"),
    ({"axial_length": 31.0}, "axial_length must be between 21 and 30 mm"),
    ({"axial_length": "24"}, "axial_length must be a positive number"),
    ({"corneal_radius": 5.5}, "corneal_radius must be between 6.5 and 9.5 mm"),
    ({"corneal_radius": float("nan")}, "corneal_radius must be a positive number"),
    ({"anterior_chamber_depth": 6.0}, "anterior_chamber_depth must be between 1.5 and 4.5 mm"),
    ({"anterior_chamber_depth": -3.0}, "anterior_chamber_depth must be a positive number"),
])
def test_rejects_bad_biometry(options, fragment):
    with pytest.raises(SceneError, match=fragment):
        eye.eye_geometry(**COARSE, **options)


def _filled_quarter_eye(axial_length):
    """The scene of a coarse quarter eye on the seed's tissues, held by its nerve and its cut planes,
    both cavities filled to 15 mmHg in one step."""
    supports = [("optic_nerve_end", "x = 0.0\ny = 0.0\nz = 0.0"), ("cut_0", "y = 0.0"), ("cut_1", "x = 0.0")]
    cavities = [("vitreous", "vitreous_wall"), ("aqueous", "anterior_chamber_wall")]
    return (f'tissues = "seed"\n[mesh]\nbuilder = "eye"\naxial_length = {axial_length}\n'
            + "".join(f"{key} = {value}\n" for key, value in COARSE.items())
            + '[[step]]\nname = "fill"\n'
            + "".join(f'[[dirichlet]]\nsurface = "{surface}"\n{fixed}\n' for surface, fixed in supports)
            + "".join(f'[[cavity]]\nname = "{name}"\nsurface = "{wall}"\nbulk_modulus = 2083.3\n'
                      'initial_pressure = 0.002\npressurize = true\nsymmetry = ["x", "y"]\n' for name, wall in cavities)
            + '[eye]\nvitreous = "vitreous"\n')


def test_myopic_eye_filled_to_15_mmHg(tmp_path):
    from mpi4py import MPI

    from eyeball_fenicsx.analytic import wall_volume_change
    from eyeball_fenicsx.meshing.builders.eye import scleral_wall
    from eyeball_fenicsx.output.measures import MMHG_PER_MPA
    from eyeball_fenicsx.scene.loader import load_scene

    comm = MPI.COMM_WORLD
    path = comm.bcast(str(tmp_path / "filled.toml"), root=0)
    if comm.rank == 0:
        with open(path, "w") as f:
            f.write(_filled_quarter_eye(28.0))
    comm.barrier()
    scene = load_scene(path, comm)
    step = scene.run()["steps"][-1]
    vitreous, eye_measures = step["cavities"]["vitreous"], step["eye"]
    # The quarter of the 28 mm eye, on the seed's tissues, filled to 15 mmHg: the vitreous takes the
    # volume of its wall, direction by direction a thick neo-Hookean sphere of its layers (Laplace's
    # law, as tests/test_eye.py for the 24 mm eye), within 10 %: behind the equator the prolate wall
    # is not a sphere about the centre (measured +1.2 %; the 24 mm eye -3.8 %, the 22 mm -5.4 %).
    materials = {tissue: law.c for tissue, law in scene.materials.items() if hasattr(law, "c")}
    angles, layers = scleral_wall(**scene.mesh.parameters)
    estimate = wall_volume_change(0.0, eye_measures["iop_mmHg"] / MMHG_PER_MPA, angles, layers, materials)
    assert 4 * (vitreous["volume"] - vitreous["initial_volume"]) == pytest.approx(estimate, rel=0.10)
    # The filled eye is the requested one lengthened by the filling, by a strain of the order of the
    # wall's hoop strain that the volume above implies (dV / 3V of the 7.4 mL cavity: 3.3 %).
    assert 28.0 < eye_measures["axial_length_mm"] < 28.0 * 1.05


def test_refraction_change_is_gullstrands_eye_lengthened():
    """The refraction rule's constants are Gullstrand's exact eye (Atchison & Smith 2000, table
    A1): its power, 58.636 D, focuses at 24.387 mm behind the corneal apex. Lengthened by 1 mm
    from there, the eye is a myope whose far point lies where the vergence n'/L' - P says, and
    the slope is the textbook -2.5 to -3 D per mm; a 28 mm eye's is smaller, a 22 mm eye's larger."""
    from eyeball_fenicsx.output.measures import SECOND_PRINCIPAL_POINT_MM, VITREOUS_INDEX, refraction_change

    focus = 24.387
    assert 1000 * VITREOUS_INDEX / (focus - SECOND_PRINCIPAL_POINT_MM) == pytest.approx(58.636, rel=1e-3)
    assert refraction_change(focus, focus + 1.0) == pytest.approx(1336 / 23.785 - 58.636, rel=2e-3)
    slopes = {length: refraction_change(length, length + 1e-3) / 1e-3 for length in (22.0, 24.0, 28.0)}
    assert -3.0 < slopes[24.0] < -2.5
    assert slopes[22.0] < slopes[24.0] < slopes[28.0] < 0

"""The surgeon's measures (eyeball_fenicsx/output/measures.py) on states whose answers are known, and the
pictures a scene with an [eye] table draws.

The displacements are prescribed (interpolated into the solid's state), not solved for: the
measures must read them back. Runs in serial and under ``mpirun -n 2``.
"""
import io
import math
import os

import dolfinx
import numpy as np
import pytest
from mpi4py import MPI
from scipy.spatial import cKDTree
from test_scenes import read_summary, scene_file

from eyeball_fenicsx.errors import OutputError, SceneError
from eyeball_fenicsx.mechanics.materials import NeoHooke
from eyeball_fenicsx.mechanics.solid import MixedSolid
from eyeball_fenicsx.meshing.builders import buckled_eye, eye
from eyeball_fenicsx.meshing.load import built_mesh
from eyeball_fenicsx.output import eye_pictures
from eyeball_fenicsx.output.eye_pictures import EyePictures, eye_measures_png
from eyeball_fenicsx.output.files import plot_curves, png_bytes
from eyeball_fenicsx.output.measures import DETACHED_GAP, PENETRATION_TOLERANCE, EyeMeasures
from eyeball_fenicsx.scene.loader import load_scene

COMM = MPI.COMM_WORLD
# A detachment centred on the posterior pole: whole rings of faces, its rim on the cap's circle.
N_CIRC, DETACHMENT = 24, {"polar_deg": 0.0, "extent_deg": 25.0, "gap": 0.1}
BUCKLED = {"sector_deg": 180.0, "n_circ": 16, "detachment": {"extent_deg": 20.0, "gap": 0.1}}
REGIONS = ("cornea", "sclera", "ciliary_body", "choroid", "retina", "optic_nerve", "lens", "zonule", "band")
SCENE = ('name = "buckle-at-rest"\n[mesh]\nbuilder = "buckled_eye"\nsector_deg = 180.0\nn_circ = 16\n'
         'detachment = { extent_deg = 20.0, gap = 0.1 }\n'
         + "".join(f'[materials.{region}]\nmodel = "neo-hooke"\nc10 = 0.05\n' for region in REGIONS)
         + '[[step]]\nname = "at rest"\n[[step]]\nname = "inflate"\n'
         + "".join(f'[[dirichlet]]\nsurface = "{surface}"\n{components}\n' for surface, components in
                   (("optic_nerve_end", "x = 0.0\ny = 0.0\nz = 0.0"), ("band_outer", "x = 0.0\ny = 0.0\nz = 0.0"),
                    ("cut_0", "y = 0.0"), ("cut_1", "y = 0.0")))
         + '[[pressure]]\nsurface = "vitreous_wall"\nvalue = 0.0005\nstep = "inflate"\n'
         + '[eye]\nbuckle = "band_inner"\nretina = "retina_outer"\nchoroid = "choroid_inner"\n'
         + '[solver]\nincrements = 1\n')


def prescribe(solid, displacement):
    """Set the solid's state to the displacement field ``displacement(X)`` (X shape (N, 3)), p = 0."""
    solid.w.x.array[:] = 0.0
    solid.w.sub(0).interpolate(lambda x: displacement(x.T).T)
    solid.w.x.scatter_forward()


def polar(X):
    """Polar angle from the posterior pole, seen from the centre of the eye."""
    return np.arccos(np.clip(-X[:, 2] / np.linalg.norm(X, axis=1), -1.0, 1.0))


@pytest.fixture(scope="module")
def detached():
    """The half eye with a pole-centred detachment, and its retina and choroid measures."""
    data = built_mesh(eye.build_eye, COMM, sector_deg=180.0, n_circ=N_CIRC, detachment=DETACHMENT)
    solid = MixedSolid(data, {region: NeoHooke(0.05) for region in data.regions})
    measures = EyeMeasures([0.0, 0.0, 1e3], [0.0, 0.0, -1e3], "cornea_outer", "vitreous_wall",
                           retina="retina_outer", choroid="choroid_inner")
    measures.setup(solid)
    return solid, measures


@pytest.fixture(scope="module")
def buckled(tmp_path_factory):
    """The half buckled eye of SCENE, run (pictures in its output folder), then its scene."""
    folder = COMM.bcast(str(tmp_path_factory.mktemp("buckled")) if COMM.rank == 0 else None, root=0)
    scene = load_scene(scene_file(folder, SCENE), COMM)
    out = os.path.join(folder, "out")
    scene.run(out)
    return scene, next(o for o in scene.observers if isinstance(o, EyeMeasures)), out


def test_detachment_at_rest_and_moved(detached):
    solid, measures = detached
    gap = DETACHMENT["gap"]
    at_rest = measures.report()
    # The retina is cut free and moved in by the gap along the lines through the centre; the gap is
    # measured along the choroid's nodal normal, which on a wedge's cut plane sees the facets of one
    # side only and tilts by half a sector: the gap reads between gap cos(pi / n_circ) and gap.
    assert gap * math.cos(math.pi / N_CIRC) - 1e-12 <= at_rest["retina_gap_max_mm"] <= gap + 1e-12
    # Detached area: the spherical cap 2 pi r^2 (1 - cos extent), half of it in the half model; r the
    # radius of the retina's outer surface, which varies by 1 % over the cap (the sclera thins away
    # from the pole): its nodes' mean stands for it. The faceted rings lose 1 - sin(t)/t of the
    # area (t = 2 pi / n_circ: 1.1 %).
    msh = solid.mesh_data.mesh
    nodes = dolfinx.cpp.mesh.entities_to_geometry(msh._mesh, 2, solid.mesh_data.facets("retina_outer"), False)
    radius = np.linalg.norm(msh.geometry.x[np.unique(nodes)], axis=1)
    radius = COMM.allreduce(radius.sum(), op=MPI.SUM) / COMM.allreduce(len(radius), op=MPI.SUM)
    cap = math.pi * radius**2 * (1 - math.cos(math.radians(DETACHMENT["extent_deg"])))
    area = at_rest["detached_area_mm2"]
    assert area == pytest.approx(cap, rel=0.03)
    # ... and of the faces of retina_outer, only the ring at the rim, where the gap closes linearly to
    # zero, is detached in part: more than 1 - DETACHED_GAP / gap of it.
    ds = solid.ds(solid.mesh_data.surfaces["retina_outer"])
    whole = COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(1.0 * ds)), op=MPI.SUM)
    assert (1 - DETACHED_GAP / gap) * whole < area <= whole * (1 + 1e-12)

    # A uniform expansion by 1 + e, with a rigid translation, scales every gap by 1 + e and leaves
    # the reference area alone.
    e, shift = 0.05, np.array([0.3, 0.0, -0.2])
    prescribe(solid, lambda X: e * X + shift)
    moved = measures.report()
    assert moved["retina_gap_max_mm"] == pytest.approx((1 + e) * at_rest["retina_gap_max_mm"], rel=1e-9)
    assert moved["detached_area_mm2"] == pytest.approx(area, rel=1e-12)
    # Shrunk 20-fold, the gap is 0.005 mm, under DETACHED_GAP: nothing counts as detached.
    prescribe(solid, lambda X: -0.95 * X)
    shrunk = measures.report()
    assert shrunk["retina_gap_max_mm"] == pytest.approx(0.05 * at_rest["retina_gap_max_mm"], rel=1e-9)
    assert shrunk["detached_area_mm2"] == 0.0


def test_penetration_is_not_attachment(detached):
    """The detached retina pushed out along the lines through the centre onto the choroid and on
    through it by a depth d: it reads a penetration of d less the tolerance, and the area it
    crossed counts as penetrated, not as attached (nor as detached)."""
    solid, measures = detached
    gathered = [np.concatenate(part) for part in zip(*COMM.allgather(
        (measures.X[measures.retina_nodes], measures.X[measures.choroid_nodes])))]
    retina, choroid = (np.unique(nodes, axis=0) for nodes in gathered)
    free = retina[cKDTree(choroid).query(retina)[0] > 1e-9]  # the rim's nodes are the choroid's
    # each free retina node lies on the ray of one choroid node, 0.1 mm further in (the mesh's gap)
    facing = choroid[cKDTree(choroid / np.linalg.norm(choroid, axis=1)[:, None]).query(
        free / np.linalg.norm(free, axis=1)[:, None])[1]]
    tree = cKDTree(free)

    def through(depth):
        def displacement(X):
            distance, index = tree.query(X, distance_upper_bound=1e-9)
            hit = np.isfinite(distance)
            u = np.zeros_like(X)
            target = facing[index[hit]]
            u[hit] = target * (1 + depth / np.linalg.norm(target, axis=1))[:, None] - X[hit]
            return u
        return displacement

    prescribe(solid, lambda X: np.zeros_like(X))
    at_rest = measures.report()
    assert at_rest["retina_penetration_max_mm"] == 0.0 and at_rest["penetrated_area_mm2"] == 0.0
    # Through by d: the gap along the choroid's normal is -d (n . e_r), between -d and -d cos(pi /
    # n_circ) (the tilt on the cut plane: test_detachment_at_rest_and_moved); the deepest, -d.
    d = 0.05
    prescribe(solid, through(d))
    crossed = measures.report()
    assert (d * math.cos(math.pi / N_CIRC) - PENETRATION_TOLERANCE - 1e-12 <= crossed["retina_penetration_max_mm"]
            <= d - PENETRATION_TOLERANCE + 1e-12)
    # Every free node is deeper than the tolerance, the rim's at 0: nothing is detached, and of the
    # faces of retina_outer only the rim ring, where the gap goes linearly from 0 to at most -d cos(pi /
    # n_circ), is not penetrated in part: more than 1 - tolerance / (d cos(pi / n_circ)) is.
    assert crossed["detached_area_mm2"] == 0.0
    ds = solid.ds(solid.mesh_data.surfaces["retina_outer"])
    whole = COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(1.0 * ds)), op=MPI.SUM)
    assert (1 - PENETRATION_TOLERANCE / (d * math.cos(math.pi / N_CIRC))) * whole < crossed["penetrated_area_mm2"]
    assert crossed["penetrated_area_mm2"] <= whole * (1 + 1e-12)
    # Through by less than the tolerance: within what contact may leave, no penetration reported.
    prescribe(solid, through(0.5 * PENETRATION_TOLERANCE))
    within = measures.report()
    assert within["retina_penetration_max_mm"] == 0.0 and within["penetrated_area_mm2"] == 0.0
    assert within["detached_area_mm2"] == 0.0


def test_buckle_height(buckled):
    scene, measures, _ = buckled
    solid = scene.solid
    layout = buckled_eye.buckle_layout(**BUCKLED)
    back, front = layout.bodies["band"].theta
    centre = 0.5 * (back + front)
    prescribe(solid, lambda X: np.zeros_like(X))
    assert measures.report()["buckle_height_mm"] == 0.0  # the reference state
    # The globe inflated uniformly: no indentation.
    e = 0.02
    prescribe(solid, lambda X: e * X)
    assert abs(measures.report()["buckle_height_mm"]) < 1e-12
    # ... and pushed in by d under the middle half of the band (nodes between the band's back and
    # front faces, seen from the centre): the indentation is d.
    d = 0.4
    prescribe(solid, lambda X: e * X - d * (np.abs(polar(X) - centre) < (front - back) / 4)[:, None]
              * X / np.linalg.norm(X, axis=1)[:, None])
    assert measures.report()["buckle_height_mm"] == pytest.approx(d, rel=1e-9)


def test_scene_writes_measures_and_pictures(buckled):
    scene, _, out = buckled
    summary = read_summary(out)
    assert [s["name"] for s in summary["steps"]] == ["at rest", "inflate"]
    rest, inflated = (s["eye"] for s in summary["steps"])
    # Nothing moves in the first step: the buckle's footprint is not indented, the detachment under
    # the band has its gap (read on the cut plane: see test_detachment_at_rest_and_moved) and area.
    assert rest["buckle_height_mm"] == 0.0
    assert 0.1 * math.cos(math.pi / 16) < rest["retina_gap_max_mm"] <= 0.1 + 1e-12
    assert rest["detached_area_mm2"] > 0.0
    # In the second the vitreous pressure pushes the detached retina out onto the choroid (and, with
    # no contact, on through it): the largest gap and the detached area shrink.
    assert inflated["retina_gap_max_mm"] < rest["retina_gap_max_mm"]
    assert inflated["detached_area_mm2"] < rest["detached_area_mm2"]
    assert np.isfinite(inflated["buckle_height_mm"])
    if COMM.rank == 0:
        pictures = {name for name in os.listdir(out) if name.endswith(".png")}
        assert pictures == {"section_at_rest.png", "section_inflate.png", "eye_measures.png", "retina_gap_at_rest.png",
                            "retina_gap_inflate.png", "surface_at_rest.png", "surface_inflate.png"}
        assert all(os.path.getsize(os.path.join(out, name)) > 10_000 for name in pictures)


def test_the_measures_picture_drawn_by_every_rank_is_the_one_rank_picture(buckled, tmp_path):
    """The run's eye_measures.png, its cells drawn by the ranks apart (``plot_curves``), has the
    pixels of the same picture drawn whole on one rank (with half-pixel margins it did not: 4088
    pixels of the top row's frame differed on 2 ranks)."""
    _, _, out = buckled
    if COMM.rank == 0:
        from PIL import Image
        eye_measures_png(read_summary(out)["steps"], str(tmp_path / "one_rank.png"))
        together, alone = (np.asarray(Image.open(path)) for path in (os.path.join(out, "eye_measures.png"),
                                                                     tmp_path / "one_rank.png"))
        assert together.shape == alone.shape == (330 * 7, 3 * 440, 3)  # its measures fill 7 rows of 3
        assert np.array_equal(together, alone)


def test_each_small_plot_is_drawn_as_if_alone(tmp_path_factory):
    """``plot_curves`` draws its plots in turn on one axes, and the ranks each their share: every
    plot must come out as it does drawn alone, whatever came before it on that axes (a title that
    must rise over its axis' offset or multiplier, a curve with no finite value, a band and its
    legend), and whichever rank draws it."""
    from PIL import Image
    nan = float("nan")
    curves = {"a plain curve first, with a title long enough to meet an offset (mm)": [10.0, 20.0, 30.0],
              "a multiplier over its y axis, with a title long enough to meet it (mm)": [1e-7, 3e-7, 2e-7],
              "no finite value": [nan, nan, nan],
              "an offset over its y axis, with a title long enough to meet it too (mm)": [23.41, 23.4102, 23.4101],
              "banded": [1.0, 2.0, 3.0], "constant": [5.0, 5.0, 5.0], "plain again": [3.0, 1.0, 2.0]}
    bands = {"banded": ([0.0, 1.0, 2.0], [2.0, 3.0, 6.0]), "no finite value": ([nan] * 3, [nan] * 3)}
    x, labels = [22.0, 24.0, 28.0], ["first", "second", "third"]
    folder = COMM.bcast(str(tmp_path_factory.mktemp("cells")) if COMM.rank == 0 else None, root=0)
    plot_curves(os.path.join(folder, "all.png"), x, curves, "step", labels, bands, "band", comm=COMM)
    if COMM.rank == 0:
        with Image.open(os.path.join(folder, "all.png")) as picture:
            together = np.asarray(picture)
        for k, name in enumerate(curves):
            plot_curves(os.path.join(folder, "one.png"), x, {name: curves[name]}, "step", labels, bands, "band")
            with Image.open(os.path.join(folder, "one.png")) as picture:
                alone = np.asarray(picture)
            row, column = divmod(k, 3)
            cell = together[row * alone.shape[0]: (row + 1) * alone.shape[0],
                            column * alone.shape[1]: (column + 1) * alone.shape[1]]
            assert np.array_equal(cell, alone), name


def test_the_pictures_png_files_decode_to_their_pixels(buckled):
    """``png_bytes`` writes PNG itself (unfiltered rows, one zlib stream): another decoder, Pillow's,
    reads back every pixel, of random colours of odd sizes and of the run's measures picture."""
    from PIL import Image
    _, _, out = buckled
    rng = np.random.default_rng(COMM.rank)
    with Image.open(os.path.join(out, "eye_measures.png")) as picture:
        drawn = np.asarray(picture)
    for pixels in (rng.integers(0, 256, (1, 1, 3), dtype=np.uint8), rng.integers(0, 256, (7, 13, 3), dtype=np.uint8),
                   drawn):
        with Image.open(io.BytesIO(png_bytes(pixels))) as read:
            assert read.mode == "RGB"
            assert np.array_equal(np.asarray(read), pixels)


def test_a_failure_of_a_picture_the_ranks_draw_together_is_an_error_on_every_rank(tmp_path_factory):
    """``plot_curves`` with a communicator: a picture rank 0 cannot write, or cells one rank cannot
    draw (here the last rank's: a curve one value short), is an OutputError on every rank, not a
    rank left waiting for the others in a collective."""
    curves = {f"measure {k}": [0.0, 1.0] for k in range(5)}
    with pytest.raises(OutputError, match="could not write"):
        plot_curves(os.path.join("/no such folder", "eye_measures.png"), [1, 2], curves, "step", comm=COMM)
    curves["the last row's, one value short"] = [0.0]
    folder = COMM.bcast(str(tmp_path_factory.mktemp("pictures")) if COMM.rank == 0 else None, root=0)
    with pytest.raises(OutputError, match="could not draw"):
        plot_curves(os.path.join(folder, "eye_measures.png"), [1, 2], curves, "step", comm=COMM)


def test_a_picture_one_rank_cannot_draw_after_a_step_is_an_error_on_every_rank(buckled, tmp_path_factory,
                                                                               monkeypatch):
    """After a step each rank draws a picture of its own (``EyePictures.after_step``): one that
    fails on the last rank alone (the retina's gap map, drawn there) is an OutputError on every
    rank that names it, not the other ranks left waiting for that one."""
    scene, _, _ = buckled
    pictures = next(o for o in scene.observers if isinstance(o, EyePictures))
    folder = COMM.bcast(str(tmp_path_factory.mktemp("failed_pictures")) if COMM.rank == 0 else None, root=0)
    pictures.start(scene.name, folder)

    def unable(*args, **kwargs):
        raise ValueError("no colour for the gap")
    monkeypatch.setattr(eye_pictures, "retina_gap_png", unable)
    with pytest.raises(OutputError, match="could not draw .*retina_gap_inflate.png .ValueError: no colour"):
        pictures.after_step("inflate", 1, {}, True)


@pytest.mark.parametrize("keys, fragment", [
    ('retina = "retina_outer"', "give both retina and choroid"),
    ('sclera = "sclera_outer"', "give buckle too"),
    ('buckle = "tire_inner"', "surface 'tire_inner' is not a surface group"),
    ('buckle = 3', "buckle must be a non-empty string"),
])
def test_eye_keys_are_checked(keys, fragment, tmp_path_factory):
    folder = COMM.bcast(str(tmp_path_factory.mktemp("invalid")) if COMM.rank == 0 else None, root=0)
    text = SCENE[: SCENE.index("[eye]")] + f"[eye]\n{keys}\n"
    with pytest.raises(SceneError, match=fragment) as error:
        load_scene(scene_file(folder, text), COMM)
    assert "[eye]" in str(error.value)


@pytest.mark.parametrize("buckle", [{"tire": {"width": 4.0, "height": 1.0, "arc_deg": 60.0, "azimuth_deg": 45.0}},
                                    {"sponge": {"azimuth_deg": 45.0}}], ids=["tire", "sponge"])
def test_indentation_under_and_opposite(buckle):
    """A segmental buckle at 45 degrees on the whole eye: a dent prescribed under it reads d under
    it and nothing opposite; the same dent turned by 180 degrees reads d opposite and nothing under
    (the footprints are geometry: the buckle's polar and azimuthal range, turned about the axis)."""
    parameters = {"sector_deg": 360.0, "n_circ": 16, **buckle}
    data = built_mesh(buckled_eye.build_buckled_eye, COMM, **parameters)
    solid = MixedSolid(data, {region: NeoHooke(0.05) for region in data.regions})
    name = next(iter(buckle))
    measures = EyeMeasures([0.0, 0.0, 1e3], [0.0, 0.0, -1e3], "cornea_outer", "vitreous_wall", buckle=f"{name}_inner")
    measures.setup(solid)
    body = buckled_eye.buckle_layout(**parameters).bodies[name]
    middle_polar, middle = 0.5 * sum(body.theta), math.radians(body.azimuth_deg)
    half_polar = 0.5 * (body.theta[1] - body.theta[0])
    half_azimuth = 0.5 * (body.azimuths[-1] - body.azimuths[0])

    def dent(at, d=0.3):
        """The globe inflated by 2 %, and pushed in by d over the middle half of the footprint at ``at``."""
        def displacement(X):
            azimuth = np.angle(np.exp(1j * (np.arctan2(X[:, 1], X[:, 0]) - at)))
            inside = (np.abs(polar(X) - middle_polar) < half_polar / 2) & (np.abs(azimuth) < half_azimuth / 2)
            return 0.02 * X - d * inside[:, None] * X / np.linalg.norm(X, axis=1)[:, None]
        return displacement

    prescribe(solid, dent(middle))
    under = measures.report()
    assert under["buckle_height_mm"] == pytest.approx(0.3, rel=1e-9)
    assert abs(under["opposite_indentation_mm"]) < 1e-12
    prescribe(solid, dent(middle + math.pi))
    opposite = measures.report()
    assert opposite["opposite_indentation_mm"] == pytest.approx(0.3, rel=1e-9)
    assert abs(opposite["buckle_height_mm"]) < 1e-12

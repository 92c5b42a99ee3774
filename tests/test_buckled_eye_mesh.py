"""The buckled eye (eyeball_fenicsx/meshing/builders/buckled_eye.py): the eye plus an encircling
band and/or a silicone tire.

Runs in serial and under ``mpirun -n 2``: the meshes are built on rank 0 and distributed, every check
is collective, and nodes are gathered on rank 0 (by their global input numbers) to compare bodies.
A coarse eye (n_circ = 16) keeps it fast.
"""
import math
import pathlib

import dolfinx
import numpy as np
import pytest
import ufl
from conftest import on_rank0
from mpi4py import MPI
from scipy.spatial import cKDTree

from eyeball_fenicsx.errors import SceneError
from eyeball_fenicsx.meshing.builders import buckled_eye, eye
from eyeball_fenicsx.meshing.builders.buckle_sutures import BITE_LENGTH, BITE_SPACING
from eyeball_fenicsx.meshing.builders.eye_azimuths import _butterfly, coarser_levels, disc, node_azimuths
from eyeball_fenicsx.meshing.builders.eye_meridian import SPACING
from eyeball_fenicsx.meshing.builders.hexes import HEX_FACES, corner_jacobians
from eyeball_fenicsx.meshing.load import built_mesh, load_mesh
from eyeball_fenicsx.scene.loader import load_scene

COMM = MPI.COMM_WORLD
N_CIRC = 16
TISSUES = {"cornea", "sclera", "ciliary_body", "choroid", "retina", "optic_nerve", "lens", "zonule"}
EYE_SURFACES = {"sclera_outer", "cornea_outer", "optic_nerve_side", "optic_nerve_end", "vitreous_wall",
                "anterior_chamber_wall"}
BAND_SURFACES = {"band_inner", "band_outer", "band_front", "band_back"}
TIRE_SURFACES = {"tire_inner", "tire_outer", "tire_front", "tire_back"}
GAP = buckled_eye.GAP
# The three scenes: an encircling band alone (whole eye); a tire ring under the band in a half eye with
# a retinal detachment under the buckle; a segmental tire (90 degrees) without band.
ENCIRCLED = {"n_circ": N_CIRC}
TIRED = {"n_circ": N_CIRC, "sector_deg": 180, "tire": {"width": 4.0, "height": 1.0},
         "detachment": {"extent_deg": 15.0, "gap": 0.1}}
SEGMENTAL = {"n_circ": N_CIRC, "tire": {"width": 4.0, "height": 1.0, "arc_deg": 90.0, "azimuth_deg": 30.0}}


@pytest.fixture(scope="module")
def encircled():
    return built_mesh(buckled_eye.build_buckled_eye, COMM, **ENCIRCLED)


@pytest.fixture(scope="module")
def tired():
    return built_mesh(buckled_eye.build_buckled_eye, COMM, **TIRED)


@pytest.fixture(scope="module")
def segmental():
    return built_mesh(buckled_eye.build_buckled_eye, COMM, **SEGMENTAL)


def _gather(ids, coordinates):
    """On rank 0: the rows of (ids, coordinates) of all ranks, each id once; None elsewhere."""
    gathered = COMM.gather((ids, coordinates), root=0)
    if COMM.rank != 0:
        return None, None
    ids = np.concatenate([g[0] for g in gathered])
    coordinates = np.concatenate([g[1] for g in gathered])
    key = np.sort(ids, axis=1) if ids.ndim == 2 else ids
    _, first = np.unique(key, axis=0, return_index=True)  # ghosts come twice
    return ids[first], coordinates[first]


def _region_nodes(data, region):
    """On rank 0: global input numbers and coordinates of the nodes of a region's cells."""
    msh = data.mesh
    dofs = msh.geometry.dofmap.array.reshape(-1, 8)[data.cells(region)].ravel()
    return _gather(np.asarray(msh.geometry.input_global_indices)[dofs], msh.geometry.x[dofs])


def _surface_facets(data, surface):
    """On rank 0: the corners of a surface's facets, global numbers (count, 4) and coordinates (count, 4, 3),
    in DOLFINx order (vertices 0, 1, 3, 2 go round the quadrilateral)."""
    msh = data.mesh
    msh.topology.create_connectivity(2, 3)
    nodes = dolfinx.cpp.mesh.entities_to_geometry(msh._mesh, 2, data.facets(surface), False)
    return _gather(np.asarray(msh.geometry.input_global_indices)[nodes], msh.geometry.x[nodes])


def _surface_nodes(data, surface):
    """On rank 0: the coordinates of a surface's nodes, each once."""
    ids, corners = _surface_facets(data, surface)
    if ids is None:
        return None
    _, first = np.unique(ids.ravel(), return_index=True)
    return corners.reshape(-1, 3)[first]


def _volume(data, region):
    dx = ufl.dx(domain=data.mesh, subdomain_data=data.cell_tags, subdomain_id=data.regions[region])
    return COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(1.0 * dx)), op=MPI.SUM)


def _polar(points):
    """Polar angle from the posterior pole (-z) and azimuth of points."""
    return np.arctan2(np.linalg.norm(points[:, :2], axis=1), -points[:, 2]), np.arctan2(points[:, 1], points[:, 0])


def _globe(data):
    """The radius of the sclera's outer surface and the polar angle of the limbus, measured on the mesh (the
    limbus is the front ring of "sclera_outer"); on every rank."""
    nodes = _surface_nodes(data, "sclera_outer")
    radii = on_rank0(lambda: np.linalg.norm(nodes, axis=1))
    assert np.ptp(radii) < 1e-9  # the sclera's outer surface is a sphere
    return radii.mean(), on_rank0(lambda: _polar(nodes)[0].max())


def test_regions_and_surfaces(encircled, tired, segmental):
    assert set(encircled.regions) == TISSUES | {"band"}
    assert set(encircled.surfaces) == EYE_SURFACES | BAND_SURFACES
    assert set(tired.regions) == TISSUES | {"tire", "band"}
    assert set(tired.surfaces) == (EYE_SURFACES | BAND_SURFACES | TIRE_SURFACES
                                   | {"retina_outer", "choroid_inner", "cut_0", "cut_1"})
    # A segmental tire: no band unless asked, and the tire's two ends.
    assert set(segmental.regions) == TISSUES | {"tire"}
    assert set(segmental.surfaces) == EYE_SURFACES | TIRE_SURFACES | {"tire_end_0", "tire_end_1"}
    for data in (encircled, tired, segmental):
        for name in data.regions:
            assert COMM.allreduce(len(data.cells(name)), op=MPI.SUM) > 0, name
        for name in data.surfaces:
            assert COMM.allreduce(len(data.facets(name)), op=MPI.SUM) > 0, name
    # The band: 4 x 2 elements in the meridian, n_circ around; the whole tire ring of the half eye
    # 6 x 3 (elements of about the band's size) over 8 sectors; the segmental tire 15 + 3 x 22.5 + 7.5 degrees.
    eye_cells = eye.eye_geometry(n_circ=N_CIRC).info["hexahedra"]  # the eye, unchanged
    assert encircled.mesh.topology.index_map(3).size_global == eye_cells + 4 * 2 * N_CIRC
    assert tired.mesh.topology.index_map(3).size_global == eye_cells // 2 + 6 * 3 * 8 + 4 * 2 * 8
    assert segmental.mesh.topology.index_map(3).size_global == eye_cells + 6 * 3 * 5


@pytest.mark.parametrize("model", ["encircled", "tired", "segmental"])
def test_elements_are_well_shaped(model, request):
    data = request.getfixturevalue(model)
    msh = data.mesh
    cells = msh.geometry.dofmap.array.reshape(-1, 8)[:, [0, 1, 3, 2, 4, 5, 7, 6]]  # to gmsh order
    det, scaled = corner_jacobians(msh.geometry.x, cells)
    assert COMM.allreduce(det.min(), op=MPI.MIN) > 0.0
    assert COMM.allreduce(scaled.min(), op=MPI.MIN) > 0.45  # the eye's zonule, ~0.5
    for body in ("band", "tire"):
        if body in data.regions:
            worst = scaled[data.cells(body)].min(initial=1.0)
            assert COMM.allreduce(worst, op=MPI.MIN) > 0.95, body  # nearly right-angled


def _to_polyline(points, line):
    """Distances from 2D points to a polyline (shape (k, 2))."""
    start, step = line[:-1], line[1:] - line[:-1]
    t = np.clip(np.einsum("psk,sk->ps", points[:, None] - start, step) / np.sum(step**2, axis=1), 0.0, 1.0)
    return np.linalg.norm(points[:, None] - (start + t[..., None] * step), axis=2).min(axis=1)


def _clearance(data, inner, outer):
    """Distances from the nodes of surface ``inner`` to surface ``outer``, in the meridional planes of the
    node azimuths both have (the nodes of the two surfaces are on the same azimuths, so the nearest point is
    on the meridional edges there): (smallest, largest) over the nodes, and the smallest distance between
    the two surfaces' nodes; on every rank."""
    nodes = _surface_nodes(data, inner)
    outer_nodes = _surface_nodes(data, outer)

    def distances():
        theta, phi = _polar(nodes)
        outer_theta, outer_phi = _polar(outer_nodes)
        result = []
        for azimuth in np.unique(np.round(phi, 9)):
            here = np.abs(phi - azimuth) < 1e-9
            line = np.abs(outer_phi - azimuth) < 1e-9
            if line.sum() < 2:
                continue  # e.g. the ends of a segmental tire, between the eye's azimuths
            order = np.argsort(outer_theta[line])
            section = np.column_stack([np.linalg.norm(outer_nodes[line][:, :2], axis=1), outer_nodes[line][:, 2]])
            points = np.column_stack([np.linalg.norm(nodes[here][:, :2], axis=1), nodes[here][:, 2]])
            result.append(_to_polyline(points, section[order]))
        result = np.concatenate(result)
        to_nodes, _ = cKDTree(outer_nodes).query(nodes)
        return result.min(), result.max(), to_nodes.min()
    return on_rank0(distances)


@pytest.mark.parametrize("model, pairs", [
    ("encircled", [("band", "sclera_outer")]),
    ("tired", [("band", "tire_outer"), ("tire", "sclera_outer")]),
    ("segmental", [("tire", "sclera_outer")]),
])
def test_buckle_shares_no_node_with_the_eye(model, pairs, request):
    data = request.getfixturevalue(model)
    eye_nodes = [_region_nodes(data, tissue)[0] for tissue in TISSUES]
    for body, under in pairs:
        body_nodes, _ = _region_nodes(data, body)
        assert on_rank0(lambda: not np.intersect1d(body_nodes, np.concatenate(eye_nodes)).size)
        # The body's inner surface is `gap` clear of the surface under it: its nodes are that far from the
        # facets under them, plus the sag of the facets' meridional chords (< 0.8^2 / 8 R = 0.007 mm), and no
        # node of the other surface is nearer.
        nearest, farthest, node_to_node = _clearance(data, f"{body}_inner", under)
        assert GAP - 1e-9 < nearest and farthest < GAP + 0.007
        assert GAP - 1e-9 < node_to_node < math.hypot(GAP, 0.5)  # meridional offset < half an element
    if model == "tired":
        band, _ = _region_nodes(data, "band")
        tire, _ = _region_nodes(data, "tire")
        assert on_rank0(lambda: not np.intersect1d(band, tire).size)


def test_band_volume_is_the_spherical_zone(encircled, tired):
    """The band is the shell zone R1 <= r <= R2, theta1 <= theta <= theta2 (polar angle from the posterior
    pole), whose volume is the integral of r^2 sin(theta) over it:

        V = (2 pi / 3) (R2^3 - R1^3) (cos theta1 - cos theta2),

    the difference of spherical sectors (2 pi / 3) r^3 (1 - cos theta) (CRC Standard Mathematical Tables,
    "spherical sector"); with latitudes phi = theta - pi / 2 it is the (sin phi2 - sin phi1) form. The mesh
    replaces arcs by chords: a ring of n chords has the volume of the smooth ring times sin(d)/d, d = 2 pi / n
    (each hexahedron between azimuths a and a + d has the volume sin(d) times the integral of rho over its
    section, exactly), and the meridional chords of angle e add a relative error of about e^2 / 6."""
    for data, parameters, fraction in ((encircled, ENCIRCLED, 1.0), (tired, TIRED, 0.5)):
        layout = buckled_eye.buckle_layout(**parameters)
        band = layout.bodies["band"]
        R1, R2 = band.inner_radius, band.outer_radius
        theta1, theta2 = band.theta
        exact = 2 * math.pi / 3 * (R2**3 - R1**3) * (math.cos(theta1) - math.cos(theta2)) * fraction
        assert band.volume() == pytest.approx(exact, rel=1e-12)  # the wedge holds its part of the ring
        # R1 and R2 are the sclera's measured radius + gap (+ tire height + gap) and + thickness
        radius, _ = _globe(data)
        below = GAP if "tire" not in parameters else 2 * GAP + parameters["tire"]["height"]
        assert R1 == pytest.approx(radius + below, abs=1e-9)
        assert R2 - R1 == pytest.approx(buckled_eye.BAND_THICKNESS, abs=1e-12)
        d, e = 2 * math.pi / N_CIRC, (theta2 - theta1) / 4
        volume = _volume(data, "band")
        assert volume / (exact * math.sin(d) / d) == pytest.approx(1.0, abs=e**2 / 6 * 1.5)
        assert volume == pytest.approx(exact, rel=(d**2 + e**2) / 6 * 1.05)  # 2.6 % at n_circ = 16


@pytest.mark.parametrize("model", ["encircled", "tired"])
def test_band_position_and_width(model, request):
    data = request.getfixturevalue(model)
    radius, limbus = _globe(data)
    nodes = _surface_nodes(data, "band_inner")
    measured = on_rank0(lambda: _polar(nodes)[0])
    centre = 0.5 * (measured.min() + measured.max())
    inner_radius = radius + (GAP if model == "encircled" else 2 * GAP + 1.0)
    # Behind the limbus by band_position, measured along the sclera's outer surface, within half an element
    # of the band (exact by construction); its width measured on its inner surface.
    position = radius * (limbus - centre)
    half_element = 0.5 * buckled_eye.BAND_WIDTH / 4
    assert position == pytest.approx(buckled_eye.BAND_POSITION, abs=half_element)
    assert position == pytest.approx(buckled_eye.BAND_POSITION, abs=1e-9)
    assert inner_radius * (measured.max() - measured.min()) == pytest.approx(buckled_eye.BAND_WIDTH, abs=1e-9)
    # The default sits at about the equator (12.95 mm behind the limbus in this eye), 11.25-13.75 mm behind it.
    assert abs(centre - math.pi / 2) < math.radians(3.0)


def test_segmental_tire_extent(segmental):
    nodes = _surface_nodes(segmental, "tire_outer")
    azimuths = on_rank0(lambda: np.degrees(_polar(nodes)[1]))
    assert azimuths.min() == pytest.approx(30.0 - 45.0, abs=1e-9)
    assert azimuths.max() == pytest.approx(30.0 + 45.0, abs=1e-9)
    area = COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(1.0 * ufl.ds(
        domain=segmental.mesh, subdomain_data=segmental.facet_tags,
        subdomain_id=segmental.surfaces["tire_end_0"]))), op=MPI.SUM)
    # The end face: a sector of an annulus, the tire's section, in 6 meridional chords.
    tire = buckled_eye.buckle_layout(**SEGMENTAL).bodies["tire"]
    angle = (tire.theta[1] - tire.theta[0]) / 6
    assert area == pytest.approx(0.5 * (tire.outer_radius**2 - tire.inner_radius**2) * 6 * math.sin(angle), rel=1e-9)


@pytest.mark.parametrize("model, parameters, body, count", [
    ("encircled", ENCIRCLED, "band", 8), ("tired", TIRED, "tire", 4), ("segmental", SEGMENTAL, "tire", 8)])
def test_suture_points_lie_on_their_surfaces(model, parameters, body, count, request):
    data = request.getfixturevalue(model)
    sutures = buckled_eye.suture_points(parameters)
    assert len(sutures) == count  # 4 azimuths over the whole eye, 2 of them in the half eye; 2 sutures each
    layout = buckled_eye.buckle_layout(**parameters)
    widest = max(layout.globe_radius * (b.theta[1] - b.theta[0]) for b in layout.bodies.values())
    radius, _ = _globe(data)
    sclera = _surface_nodes(data, "sclera_outer")
    outer = _surface_nodes(data, f"{body}_outer")
    sides = {side: _surface_nodes(data, f"{body}_{side}") for side in ("front", "back")}
    inner = _surface_nodes(data, f"{body}_inner")
    for suture in sutures:
        assert suture["sclera_surface"] == "sclera_outer" and suture["buckle_surface"] == f"{body}_outer"
        assert suture["hold_surface"] == f"{body}_inner"
        bite, knot, hold = (np.array(suture[key]) for key in ("sclera", "buckle", "hold"))
        assert np.linalg.norm(bite) == pytest.approx(radius, abs=1e-9)  # on the sclera's outer surface

        def distances():
            return (cKDTree(sclera).query(bite)[0], cKDTree(outer).query(knot)[0],
                    cKDTree(sides[suture["side"]]).query(knot)[0], cKDTree(inner).query(hold)[0])
        # among the surfaces' nodes (the Suture ties the nearest point of each surface's elements):
        # within an element, whose side is at most the sclera's azimuthal spacing 2 pi R / n_circ
        assert max(on_rank0(distances)) < 2 * math.pi * radius / N_CIRC
        # the knot on the body's top edge on the suture's side, the loop's hold on its base under it
        sutured = layout.bodies[body]
        edge = sutured.theta[1 if suture["side"] == "front" else 0]
        assert np.linalg.norm(knot) == pytest.approx(sutured.outer_radius, rel=1e-12)
        assert _polar(knot[None])[0][0] == pytest.approx(edge, abs=1e-12)
        assert hold == pytest.approx(sutured.inner_radius * knot / np.linalg.norm(knot), abs=1e-12)
        # The bite is suture_width / 2 from the centre line along the meridian, outside the buckle.
        theta, phi = _polar(bite[None])
        arc = radius * (theta[0] - layout.centre_theta)
        assert abs(arc) == pytest.approx(widest / 2 + buckled_eye.SUTURE_MARGIN, abs=1e-9)
        assert (arc > 0) == (suture["side"] == "front")
        assert _polar(knot[None])[1][0] == pytest.approx(phi[0], abs=1e-12)
        # The bite: points on the bite's circle of latitude, evenly spaced at most BITE_SPACING apart over
        # BITE_LENGTH (less only where the sutures' azimuths are closer: the tire's are 15 degrees apart,
        # 3.1 mm on the bites' latitudes), centred on the suture's azimuth; the knot's end over the same
        # azimuths of the body's top edge.
        spread, over = np.array(suture["sclera_bite"]), np.array(suture["buckle_bite"])
        assert np.linalg.norm(spread, axis=1) == pytest.approx(radius, abs=1e-9)
        assert _polar(spread)[0] == pytest.approx(theta[0], abs=1e-12)
        assert _polar(over)[0] == pytest.approx(edge, abs=1e-12)
        azimuths = _polar(spread)[1]
        assert _polar(over)[1] == pytest.approx(azimuths, abs=1e-12)
        step = np.diff(azimuths)
        assert step == pytest.approx(step[0], rel=1e-9)
        assert step[0] * radius * math.sin(theta[0]) <= BITE_SPACING * (1 + 1e-9)
        length = (azimuths[-1] - azimuths[0] + step[0]) * radius * math.sin(theta[0])  # on its own latitude
        assert length == pytest.approx(BITE_LENGTH, rel=1e-9)
        assert azimuths.mean() == pytest.approx(phi[0], abs=1e-12)
    wider = buckled_eye.suture_points(parameters, count=2, suture_width=8.0)
    # Two azimuths (90 and 270 degrees for the ring; 7.5 and 52.5 on the segmental tire), of which the
    # half eye holds one.
    assert len(wider) == (2 if model == "tired" else 4)
    assert all(abs(abs(radius * (_polar(np.array([s["sclera"]]))[0][0] - layout.centre_theta)) - 4.0) < 1e-9
               for s in wider)


def test_cavity_walls_are_closed(encircled, tired):
    for surface in ("vitreous_wall", "anterior_chamber_wall"):
        for data, whole in ((encircled, True), (tired, False)):
            ids, corners = _surface_facets(data, surface)

            def check():
                pairs = [(0, 1), (1, 3), (3, 2), (2, 0)]
                edges = np.concatenate([np.sort(ids[:, list(p)], axis=1) for p in pairs])
                middles = np.concatenate([corners[:, list(p)].mean(axis=1) for p in pairs])
                _, first, counts = np.unique(edges, axis=0, return_index=True, return_counts=True)
                open_ = counts == 1
                if whole:
                    return bool(np.all(counts == 2))
                return bool(np.all(counts[~open_] == 2) and np.all(np.abs(middles[first][open_][:, 1]) < 1e-9))
            assert on_rank0(check), surface


@pytest.mark.parametrize("options, fragment", [
    ({"band_position": 30.0}, "must rest on the sclera"),
    ({"band_position": 0.5}, "must rest on the sclera"),
    ({"tire": {"width": 2.0}}, "must not be wider than the tire"),
    ({"tire": {"arc_deg": 90.0, "azimuth_deg": 45.0}, "sector_deg": 180, "n_circ": 16}, "centred on one"),
    ({"tire": {"arc_deg": 400.0}}, "arc_deg must be at most 360"),
    ({"tire": {"depth": 1.0}}, "tire must be None or a table"),
    ({"band": False}, "there must be a tire"),
    ({"gap": 0.0}, "gap must be a positive number"),
    ({"n_band_width": 2.5}, "n_band_width must be a positive integer"),
    ({"iop": 15}, "unknown parameter"),
    ({"n_circ": 18}, "n_circ must be a multiple of 8"),
])
def test_rejects_bad_parameters(options, fragment):
    with pytest.raises(SceneError, match=fragment):
        buckled_eye.buckle_layout(**options)


def test_rejects_bad_sutures_and_reports_on_every_rank():
    with pytest.raises(SceneError, match="must exceed the buckle's footprint"):
        buckled_eye.suture_points({}, suture_width=2.0)
    with pytest.raises(SceneError, match="must rest on the sclera"):
        built_mesh(buckled_eye.build_buckled_eye, COMM, n_circ=N_CIRC, band_position=40.0)


def test_cli(tmp_path):
    folder = pathlib.Path(COMM.bcast(str(tmp_path), root=0))
    path = folder / "buckled.msh"
    buckled_eye.main(["--out", str(path), "--n-circ", "16", "--sector-deg", "180", "--tire", "4", "1", "90", "180",
                      "--band", "--detachment", "15", "0.1"])
    data = load_mesh(path)
    assert set(data.regions) == TISSUES | {"tire", "band"}
    assert set(data.surfaces) == (EYE_SURFACES | BAND_SURFACES | TIRE_SURFACES
                                  | {"tire_end_0", "retina_outer", "choroid_inner", "cut_0", "cut_1"})


def test_suture_on_a_cut_plane_is_kept_at_half_share():
    """In a half eye, a suture on a cut plane (azimuth 0) is kept, half of it in the wedge (its mirror
    image holds the other half), and one in the mirror image (-22.5 degrees) is left out; the suture at
    7.5 degrees, between the coarse eye's nodes (11.25 degrees apart), stays where it was put."""
    tire = {"width": 4.0, "height": 1.0, "arc_deg": 60.0, "azimuth_deg": 0.0}
    sutures = buckled_eye.suture_points({"n_circ": 16, "sector_deg": 180.0, "tire": tire},
                                        azimuth_deg=[-22.5, 0.0, 7.5])
    shares = sorted((s["azimuth_deg"], s["side"], s["share"]) for s in sutures)
    assert shares == [(0.0, "back", 0.5), (0.0, "front", 0.5), (7.5, "back", 1.0), (7.5, "front", 1.0)]


def test_a_bite_stays_on_its_tire():
    """A bite is cut at the ends of its tire: a suture at the tire's end (azimuth -30 degrees, given a
    hair outside it) keeps its bite on the tire, from -30 degrees into it, half of BITE_LENGTH long on
    its latitude; one at 7.5 degrees keeps the whole of it."""
    tire = {"width": 4.0, "height": 1.0, "arc_deg": 60.0, "azimuth_deg": 0.0}
    end, inside = buckled_eye.suture_points({"n_circ": 16, "sector_deg": 360.0, "tire": tire},
                                            azimuth_deg=[-30.00000001, 7.5])[::2]
    for suture, length in ((end, BITE_LENGTH / 2), (inside, BITE_LENGTH)):
        theta, phi = _polar(np.array(suture["sclera_bite"]))
        arc = (np.ptp(np.unwrap(phi)) * len(phi) / (len(phi) - 1)) * np.linalg.norm(suture["sclera"]) * np.sin(theta[0])
        assert arc == pytest.approx(length, rel=1e-6)  # the end's 1e-8 degrees outside: 2e-9 mm
        assert np.all(np.abs(np.degrees(np.angle(np.exp(1j * phi)))) <= 30.0 + 1e-9)


def test_radial_sponge_and_its_sutures():
    """A radial sponge at 45 degrees: a shell zone along the meridian, its length and width on its
    inner surface as asked, and its sutures across it in pairs symmetric about its middle azimuth,
    their bites on the sclera half the suture width from it along the circle of latitude."""
    sponge = {"width": 5.0, "height": 2.0, "length": 10.0, "azimuth_deg": 45.0}
    parameters = {"n_circ": N_CIRC, "sector_deg": 360.0, "sponge": sponge}
    mesh, layout = buckled_eye.buckled_eye_geometry(**parameters)
    body = layout.bodies["sponge"]
    assert body.inner_radius * (body.theta[1] - body.theta[0]) == pytest.approx(10.0, rel=1e-12)
    middle = 0.5 * sum(body.theta)
    assert middle == pytest.approx(layout.centre_theta, rel=1e-12)  # centred on the band's centre line
    width = body.inner_radius * math.sin(middle) * (body.azimuths[-1] - body.azimuths[0])
    assert width == pytest.approx(5.0, rel=1e-12)
    assert 0.5 * (body.azimuths[0] + body.azimuths[-1]) == pytest.approx(math.radians(45.0), rel=1e-12)
    # the mesh volume against the smooth zone: the facets inscribed in it lose about a^2 / 6 in each
    # curved direction, a = 0.051 rad the element's angle (16 elements over 47 degrees, 8 over 23.5):
    # 9e-4 in all, below 2e-3
    info = mesh.info["sponge"]
    assert info["volume"] == pytest.approx(info["smooth_volume"], rel=2e-3)
    assert {"sponge_inner", "sponge_outer", "sponge_side_0", "sponge_side_1"} <= set(mesh.surfaces)
    sutures = buckled_eye.suture_points(parameters, count=2)
    assert len(sutures) == 4
    for first, second in zip(sutures[::2], sutures[1::2]):
        bites = [np.array(s["sclera"]) for s in (first, second)]
        assert [np.linalg.norm(b) for b in bites] == pytest.approx([layout.globe_radius] * 2, rel=1e-12)
        azimuths = [math.atan2(b[1], b[0]) for b in bites]
        assert 0.5 * sum(azimuths) == pytest.approx(math.radians(45.0), rel=1e-12)
        rho = math.hypot(*bites[0][:2])
        footprint = 5.0 * layout.globe_radius / body.inner_radius  # its width seen on the sclera, at the centre line
        expected = footprint + 2 * buckled_eye.SUTURE_MARGIN
        assert rho * abs(azimuths[1] - azimuths[0]) == pytest.approx(expected, rel=1e-12)
    with pytest.raises(SceneError, match="needs the whole eye"):
        buckled_eye.buckle_layout(n_circ=N_CIRC, sector_deg=180.0, sponge=sponge)


def test_sutures_spread_symmetrically_over_a_tire():
    """Four suture azimuths over a 60-degree tire at 45 degrees on the default eye lie where they are
    spread, 7.5 and 22.5 degrees either side of its middle, though the eye's nodes are 9 degrees apart
    (22.5 and 67.5 fall halfway between two of them): the sutures are symmetric about 45 degrees."""
    tire = {"width": 4.0, "height": 1.0, "arc_deg": 60.0, "azimuth_deg": 45.0}
    sutures = buckled_eye.suture_points({"n_circ": 40, "sector_deg": 360.0, "tire": tire}, count=4)
    azimuths = sorted({s["azimuth_deg"] for s in sutures})
    assert azimuths == pytest.approx([22.5, 37.5, 52.5, 67.5], abs=1e-9)


def test_the_eye_is_graded_around_a_tires_sutures():
    """A segmental tire held in by its sutures alone: the eye is graded at the tire's edges (4 mm
    wide on its inner surface, radius R_o + gap: 2 R_o / (R_o + gap) mm either side of the centre
    line, 12.5 mm behind the limbus, on the sclera) and at the sutures' bites, SUTURE_MARGIN beyond
    them. Each is on a column of nodes, the elements either side of it 0.10-0.15 mm long (the
    README's "about 0.13": the spacing 0.1 mm at the circle, 0.5 mm longer per mm away), each
    element near them as long as the meridian's spacing at its middle to 15 % and at most 1.7 times
    its neighbour; refine 2 halves every element. An encircling band (its tightening pushes the
    buckle in) is not graded unless asked."""
    lines = buckled_eye.suture_grading(SEGMENTAL)["graded_at"]
    layout = buckled_eye.buckle_layout(**SEGMENTAL)
    ro, margin = layout.globe_radius, buckled_eye.SUTURE_MARGIN
    half = 2.0 * ro / (ro + GAP)
    assert lines == pytest.approx([12.5 - half - margin, 12.5 - half, 12.5 + half, 12.5 + half + margin], abs=1e-12)
    columns = {}
    for refine in (1, 2):
        _, meridian = eye.checked_parameters({**layout.eye, "graded_at": lines, "refine": refine})
        behind = meridian.s_l - meridian.columns
        columns[refine] = behind
        length = -np.diff(behind)
        for line in lines:
            at = int(np.argmin(np.abs(behind - line)))
            assert abs(behind[at] - line) < 1e-9
            assert np.all((0.10 / refine <= length[at - 1:at + 1]) & (length[at - 1:at + 1] <= 0.15 / refine))
        spacing = meridian.spacing(meridian.s_l - 0.5 * (behind[1:] + behind[:-1])) / refine
        near = np.flatnonzero(spacing < SPACING / refine)
        assert np.all(np.abs(length[near] / spacing[near] - 1.0) < 0.15)
        ratio = length[near[0]:near[-1] + 1][1:] / length[near[0]:near[-1] + 1][:-1]
        assert np.all((1 / 1.7 < ratio) & (ratio < 1.7))
    assert all(np.min(np.abs(columns[2] - column)) < 1e-9 for column in columns[1])
    assert len(columns[2]) - 1 == 2 * (len(columns[1]) - 1)
    mesh, _ = buckled_eye.buckled_eye_geometry(**SEGMENTAL, graded_at=list(lines))
    assert mesh.info["min_scaled_jacobian"] > eye.MIN_SCALED_JACOBIAN
    assert buckled_eye.suture_grading(ENCIRCLED) == buckled_eye.suture_grading(TIRED) == {}
    assert len(buckled_eye.suture_grading(TIRED, graded=True)["graded_at"]) == 4


def test_the_eye_is_graded_around_a_radial_sponges_sutures():
    """A radial sponge (5 mm wide on its inner surface, radius R_o + gap, at 45 degrees) tied by two
    sutures across it: the eye is graded across the meridians at the sponge's sides and at the
    bites' meridians, suture_width / 2 = 2.5 R_o / (R_o + gap) + SUTURE_MARGIN mm along each
    suture's circle of latitude from the middle. Each is a node azimuth (the two bites of one side,
    at two latitudes, are 0.054 mm apart on this eye: lines closer than 0.05 mm share a node, as two
    lines 0.04 mm apart do and two 0.06 mm apart do not); along the equator the elements either side
    of a line are 0.10-0.15 mm long, but one from a line to the next, and neighbours differ by at most 1.8 times
    (1.5 by the growth, more where a piece's count is rounded), but beside an element between two lines;
    there are nodes at 0 and 180 degrees (the section pictures), a multiple of 8 in all; and the
    cores, which take fewer azimuths inside and turn the even azimuths of their square onto those,
    keep every corner's scaled Jacobian above the builder's bound. A tire or a band is refused on a graded eye."""
    sponge = {"n_circ": N_CIRC, "sector_deg": 360.0, "sponge": {"azimuth_deg": 45.0}}
    sutures = buckled_eye.suture_points(sponge, count=2)
    lines = buckled_eye.suture_grading(sponge, sutures)["graded_azimuths"]
    layout = buckled_eye.buckle_layout(**sponge)
    ro, theta_c = layout.globe_radius, layout.centre_theta
    side = math.degrees(2.5 / ((ro + GAP) * math.sin(theta_c)))
    half_width = 2.5 * ro / (ro + GAP) + buckled_eye.SUTURE_MARGIN  # mm along the circle of latitude
    bites = [math.degrees(half_width / (ro * math.sin(math.radians(s["polar_deg"])))) for s in sutures[::2]]
    expected = sorted([45 - side, 45 + side, *(45 + sign * bite for bite in bites for sign in (-1, 1))])
    assert lines == pytest.approx(expected, abs=1e-8)
    azimuths = np.degrees(node_azimuths(N_CIRC, 360.0, np.radians(lines), ro))
    assert len(azimuths) % 8 == 0 and azimuths[0] == 0.0 and np.min(np.abs(azimuths - 180.0)) < 1e-12
    length = np.radians(np.diff(np.append(azimuths, 360.0))) * ro  # along the equator
    assert all(np.min(np.abs(azimuths - line)) < 1e-9 for line in lines)  # 0.054 mm apart at the least
    on_line = np.min(np.abs(azimuths[:, None] - np.array(lines)), axis=1) < 1e-9
    short = on_line & np.roll(on_line, -1)  # an element from one line to the next
    for at in np.flatnonzero(on_line):
        for element in (at - 1, at):
            assert (length[element] >= 0.10 or short[element]) and length[element] <= 0.15
    ratio = length / np.roll(length, 1)
    assert np.all(((1 / 1.8 < ratio) & (ratio < 1.8))[~(short | np.roll(short, 1))])
    fine = 0.1 / ro  # rad: FINE_SPACING along the equator
    for apart, nodes in ((0.4, 1), (0.6, 2)):  # lines closer than half of it share a node
        pair = np.radians(90.0) + np.array([0.0, apart * fine])
        assert np.sum(np.min(np.abs(node_azimuths(N_CIRC, 360.0, pair, ro)[:, None] - pair), axis=0) < 1e-12) == nodes
    mesh, _ = buckled_eye.buckled_eye_geometry(**sponge, graded_azimuths=lines)
    assert mesh.info["min_scaled_jacobian"] > eye.MIN_SCALED_JACOBIAN
    assert mesh.info["azimuths"] == len(azimuths)
    with pytest.raises(SceneError, match="a tire or a band lies on the eye's even azimuths"):
        buckled_eye.buckle_layout(**SEGMENTAL, graded_azimuths=[45.0])


@pytest.mark.parametrize("width, azimuth", [(8.0, 45.0), (8.0, 225.0), (5.0, 35.0), (5.0, 145.0), (3.0, 0.0),
                                            (3.0, 180.0)])
def test_graded_cores_keep_their_shape_wherever_the_sponge_lies(width, azimuth):
    """On the coarse eye, whose even azimuths are 22.5 degrees apart, the graded azimuths crowd
    around the sponge and the cores turn their square's boundary furthest: sponges that once left a
    core's corner at a scaled Jacobian of 0.19 (a second reading of the change) and sponges on the
    azimuths that stay nodes build with every corner above the builder's bound."""
    sponge = {"n_circ": N_CIRC, "sector_deg": 360.0, "sponge": {"width": width, "azimuth_deg": azimuth}}
    grading = buckled_eye.suture_grading(sponge, buckled_eye.suture_points(sponge, count=2))
    mesh, _ = buckled_eye.buckled_eye_geometry(**sponge, **grading)
    assert mesh.info["min_scaled_jacobian"] > eye.MIN_SCALED_JACOBIAN


def test_a_sponge_grades_the_eye_between_two_circles_only():
    """A radial sponge's grading holds from GRADED_MARGIN in front of the sponge (whose bites lie
    on it) to as far behind it; beyond, the shell's columns take the cores' coarser azimuths a
    level per column, to the coarsest (eye_azimuths.coarser_levels). On the coarse eye the sclera
    has a node at every graded azimuth on the circle through the sponge's middle and only the
    coarsest near the limbus and the optic nerve; the transition strips keep every corner above the
    builder's bound and the surfaces closed (the builder checks both); the eye has at most 0.75 of
    the hexahedra of the eye graded all along its meridians, and the same cavity volumes to 1e-3
    (measured 5e-4: the anterior segment faceted by the coarsest azimuths, 24 against 48 here)."""
    sponge = {"n_circ": N_CIRC, "sector_deg": 360.0, "sponge": {"azimuth_deg": 45.0}}
    grading = buckled_eye.suture_grading(sponge, buckled_eye.suture_points(sponge, count=2))
    layout = buckled_eye.buckle_layout(**sponge)
    ends = layout.limbus_arc - layout.globe_radius * np.array(layout.bodies[layout.sutured].theta)
    margin = buckled_eye.GRADED_MARGIN
    assert grading["graded_between"] == pytest.approx([ends.min() - margin, ends.max() + margin], abs=1e-9)
    banded, _ = buckled_eye.buckled_eye_geometry(**sponge, **grading)
    everywhere, _ = buckled_eye.buckled_eye_geometry(**sponge, graded_azimuths=grading["graded_azimuths"])
    assert banded.info["hexahedra"] <= 0.75 * everywhere.info["hexahedra"]
    assert banded.info["min_scaled_jacobian"] > eye.MIN_SCALED_JACOBIAN
    for volume in ("vitreous_volume", "anterior_chamber_volume"):
        assert banded.info[volume] == pytest.approx(everywhere.info[volume], rel=1e-3)
    nodes = banded.nodes[np.unique(banded.surfaces["sclera_outer"])]
    behind = layout.limbus_arc - layout.globe_radius * np.arccos(-nodes[:, 2] / np.linalg.norm(nodes, axis=1))
    azimuths = np.round(np.mod(np.arctan2(nodes[:, 1], nodes[:, 0]), 2 * np.pi), 9)
    graded = node_azimuths(N_CIRC, 360.0, np.radians(grading["graded_azimuths"]), layout.globe_radius)
    coarsest = len(coarser_levels(graded, N_CIRC)[0][-1])
    assert coarsest < len(graded)
    for low, high, count in ((ends.mean() - 0.5, ends.mean() + 0.5, len(graded)), (0.5, 2.5, coarsest),
                             (25.0, 27.0, coarsest)):
        assert len(np.unique(azimuths[(low < behind) & (behind < high)])) == count


def test_strips_of_the_band_keep_a_detachment_and_the_zonule_whole():
    """Two ways a band's strips once broke the eye (a second reading of the change): a detachment
    whose edge crosses a strip moves its nodes along the lines through the centre, so the strips'
    middle nodes must lie on one such line through the wall (they did not, by 5e-7 mm, and the
    retina inverted: a scaled Jacobian of -1 for a 0.3 mm gap); and a band in front of the zonule's
    attachment must not leave the zonule on coarser azimuths than the ciliary body it is bonded to
    (its faces lay on the ciliary body's unshared). Now the detached eye keeps its corners above
    0.4 (measured 0.48; 0.50 graded everywhere), and no boundary face of the zonule lies on one of
    the ciliary body."""
    sponge = {"n_circ": N_CIRC, "sector_deg": 360.0, "sponge": {"azimuth_deg": 45.0},
              "detachment": {"polar_deg": 60.0, "azimuth_deg": 45.0, "extent_deg": 40.0, "gap": 0.3}}
    grading = buckled_eye.suture_grading(sponge, buckled_eye.suture_points(sponge, count=2))
    detached, _ = buckled_eye.buckled_eye_geometry(**sponge, **grading)
    assert detached.info["min_scaled_jacobian"] > 0.4
    front = eye.eye_geometry(n_circ=N_CIRC, graded_azimuths=[45.0], graded_between=[0.5, 1.5])
    hexes = np.concatenate(list(front.regions.values()))
    faces = np.sort(hexes[:, list(HEX_FACES.values())].reshape(-1, 4), axis=1)
    unique, count = np.unique(faces, axis=0, return_counts=True)
    outside = {tuple(face) for face in unique[count == 1]}

    def boundary(region):
        quads = front.regions[region][:, list(HEX_FACES.values())].reshape(-1, 4)
        return quads[[tuple(sorted(quad)) in outside for quad in quads]]

    ciliary = front.nodes[boundary("ciliary_body")]
    samples = np.concatenate([(1 - u) * (1 - v) * ciliary[:, 0] + u * (1 - v) * ciliary[:, 1] + u * v * ciliary[:, 2]
                              + (1 - u) * v * ciliary[:, 3] for u in (0.25, 0.5, 0.75) for v in (0.25, 0.5, 0.75)])
    distance, _ = cKDTree(samples).query(front.nodes[boundary("zonule")].mean(axis=1))
    assert distance.min() > 0.03


@pytest.mark.parametrize("n_circ", [N_CIRC, 40])
def test_graded_cores_take_fewer_azimuths_inside(n_circ):
    """A graded core's disc (before it is swept through the core's layers): inside transition rings
    of 1-to-3 templates it has fewer azimuths than the graded circle, so at most 0.7 times the
    quadrilaterals of a butterfly disc turned onto the graded circle's N azimuths directly (a square
    of N / 4 a side, the construction before; 0.52 and 0.63 here). It still tiles the
    polygon of the graded azimuths on the unit circle (its area, 1/2 sum sin(d phi), to round-off:
    no overlap, no gap), every quadrilateral counter-clockwise and well shaped, its boundary exactly
    the polygon's N edges and every other edge shared by two quadrilaterals (no hanging node)."""
    sponge = {"n_circ": n_circ, "sector_deg": 360.0, "sponge": {"azimuth_deg": 45.0}}
    lines = buckled_eye.suture_grading(sponge, buckled_eye.suture_points(sponge, count=2))["graded_azimuths"]
    azimuths = node_azimuths(n_circ, 360.0, np.radians(lines), buckled_eye.buckle_layout(**sponge).globe_radius)
    points, quads = disc(n_circ, 1, azimuths)
    n = len(azimuths)
    assert len(quads) < 0.7 * len(_butterfly(n, 1, azimuths)[1])
    corners = points[quads]
    x, y = corners[..., 0], corners[..., 1]
    area = 0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    assert np.all(area > 0)
    assert area.sum() == pytest.approx(0.5 * np.sum(np.sin(np.diff(np.append(azimuths, 2 * np.pi)))), rel=1e-12)
    sides = np.roll(corners, -1, axis=1) - corners
    cross = sides[..., 0] * np.roll(sides, 1, axis=1)[..., 1] - sides[..., 1] * np.roll(sides, 1, axis=1)[..., 0]
    scaled = -cross / (np.linalg.norm(sides, axis=-1) * np.linalg.norm(np.roll(sides, 1, axis=1), axis=-1))
    assert scaled.min() > 0.3
    edges, uses = np.unique(np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=-1).reshape(-1, 2), axis=1),
                            axis=0, return_counts=True)
    assert set(uses) == {1, 2}
    boundary = points[edges[uses == 1]]
    assert np.allclose(np.linalg.norm(boundary, axis=-1), 1.0)
    assert sorted(np.round(np.mod(np.arctan2(boundary[..., 1], boundary[..., 0]), 2 * np.pi), 12).ravel()) == \
        pytest.approx(np.sort(np.repeat(azimuths, 2)), abs=1e-11)


def test_circles_closer_than_the_fine_spacing_share_a_column():
    """Two circles on one another, or 0.02 mm apart (a suture width just above the tire's
    footprint), give one column, not an element of no length: the eye builds, its worst corner
    as the single circle's."""
    single, _ = buckled_eye.buckled_eye_geometry(**SEGMENTAL, graded_at=[12.5])
    for close in ([12.5, 12.5], [12.5, 12.52]):
        mesh, _ = buckled_eye.buckled_eye_geometry(**SEGMENTAL, graded_at=close)
        assert mesh.info["hexahedra"] == single.info["hexahedra"]
        assert mesh.info["min_scaled_jacobian"] == pytest.approx(single.info["min_scaled_jacobian"], abs=0.05)


@pytest.mark.parametrize("buckle", ["tire", "sponge"])
def test_a_scene_grades_the_eye_of_its_sutured_buckle(tmp_path, buckle):
    """Read from a scene: a segmental tire or a radial sponge with [buckle_sutures] builds the eye
    graded at the lines of suture_grading (by default: circles of latitude for the tire, meridians
    between two circles for the sponge), uniform with ``[mesh] graded = false``; a sponge's scene may
    give its own span (``graded_between``), which replaces the sutures'."""
    body = {"tire": {"width": 4.0, "height": 1.0, "arc_deg": 90.0, "azimuth_deg": 30.0},
            "sponge": {"width": 5.0, "height": 2.0, "length": 10.0, "azimuth_deg": 45.0}}[buckle]
    parameters = {"n_circ": N_CIRC, "sector_deg": 360.0, buckle: body}
    grading = buckled_eye.suture_grading(parameters, buckled_eye.suture_points(parameters, count=2))
    inline = ", ".join(f"{k} = {v}" for k, v in body.items())
    scene = (f'name = "graded"\ntissues = "seed"\n[mesh]\nbuilder = "buckled_eye"\nn_circ = {N_CIRC}\n'
             f'sector_deg = 360.0\n{buckle} = {{ {inline} }}\n{{graded}}[materials.{buckle}]\nmodel = "neo-hooke"\n'
             'c10 = 0.41\n[[step]]\nname = "suture"\n[buckle_sutures]\ncount = 2\ntension = 0.01\n')
    cases = [("", grading), ("graded = false\n", {key: None for key in grading})]
    if buckle == "sponge":  # a scene's own span replaces the sutures' ([]: graded all along the meridians)
        cases += [(f"graded_between = {span}\n", {**grading, "graded_between": span}) for span in ([4.0, 21.0], [])]
    for graded, expected in cases:
        path = tmp_path / f"scene{COMM.rank}{len(graded)}.toml"
        path.write_text(scene.replace("{graded}", graded))
        built = load_scene(str(path)).mesh.parameters
        for key, lines in expected.items():
            assert built.get(key) == (pytest.approx(lines, abs=1e-12) if lines is not None else None)

"""The eye mesh (eyeball_fenicsx/meshing/builders/eye.py): tissues, surfaces, quality, closed
cavities and anatomical sizes.

Runs in serial and under ``mpirun -n 2``: the meshes are built on rank 0 and distributed, every
check is collective, and lists of facets are gathered on rank 0 to count edge incidences.
"""
import math
import pathlib

import dolfinx
import numpy as np
import pytest
import ufl
from conftest import on_rank0
from mpi4py import MPI

from eyeball_fenicsx.errors import SceneError
from eyeball_fenicsx.meshing.builders import eye
from eyeball_fenicsx.meshing.builders.hexes import corner_jacobians
from eyeball_fenicsx.meshing.load import built_mesh, load_mesh
from eyeball_fenicsx.output.eye_pictures import eye_section_png

COMM = MPI.COMM_WORLD
TISSUES = {"cornea", "sclera", "ciliary_body", "choroid", "retina", "optic_nerve", "lens", "zonule"}
SURFACES = {"sclera_outer", "cornea_outer", "optic_nerve_side", "optic_nerve_end", "vitreous_wall",
            "anterior_chamber_wall"}
# A superotemporal-like detachment centred in the cut plane of the half model.
DETACHMENT = {"polar_deg": 60.0, "azimuth_deg": 0.0, "extent_deg": 30.0, "gap": 0.1}


@pytest.fixture(scope="module")
def whole_eye():
    return built_mesh(eye.build_eye, COMM)


@pytest.fixture(scope="module")
def half_eye():
    return built_mesh(eye.build_eye, COMM, sector_deg=180, detachment=DETACHMENT)


def _integrate(data, integrand, surface):
    ds = ufl.ds(domain=data.mesh, subdomain_data=data.facet_tags, subdomain_id=data.surfaces[surface],
                metadata={"quadrature_degree": 4})
    return COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(integrand * ds)), op=MPI.SUM)


def _enclosed_volume(data, surface, shift=(0.0, 0.0, 0.0)):
    """-(1/3) integral of x . n over a surface, n the solid's outward normal, the mesh moved by ``shift``."""
    x = ufl.SpatialCoordinate(data.mesh) + ufl.as_vector(shift)
    return _integrate(data, -ufl.dot(x, ufl.FacetNormal(data.mesh)) / 3, surface)


def _surface_nodes(data, surface):
    """On rank 0: the global input numbers and coordinates of the corners of a surface's facets,
    shape (count, 4) and (count, 4, 3), each facet once; None elsewhere."""
    msh = data.mesh
    msh.topology.create_connectivity(2, 3)
    nodes = dolfinx.cpp.mesh.entities_to_geometry(msh._mesh, 2, data.facets(surface), False)
    ids = np.asarray(msh.geometry.input_global_indices)[nodes]
    gathered = COMM.gather((ids, msh.geometry.x[nodes]), root=0)
    if COMM.rank != 0:
        return None, None
    ids = np.concatenate([g[0] for g in gathered])
    coordinates = np.concatenate([g[1] for g in gathered])
    _, first = np.unique(np.sort(ids, axis=1), axis=0, return_index=True)  # ghost facets come twice
    return ids[first], coordinates[first]


def _edge_incidences(data, surface):
    """On rank 0: for each edge of a surface, its midpoint and the number of the surface's facets on it."""
    ids, coordinates = _surface_nodes(data, surface)
    if ids is None:
        return None, None
    pairs = [(0, 1), (1, 3), (3, 2), (2, 0)]  # DOLFINx quadrilateral: vertices 0, 1, 3, 2 go round it
    edges = np.concatenate([np.sort(ids[:, list(p)], axis=1) for p in pairs])
    middles = np.concatenate([coordinates[:, list(p)].mean(axis=1) for p in pairs])
    _, first, counts = np.unique(edges, axis=0, return_index=True, return_counts=True)
    return middles[first], counts


def test_tissues_and_surfaces(whole_eye, half_eye):
    assert set(whole_eye.regions) == TISSUES
    assert set(whole_eye.surfaces) == SURFACES
    assert set(half_eye.regions) == TISSUES
    assert set(half_eye.surfaces) == SURFACES | {"retina_outer", "choroid_inner", "cut_0", "cut_1"}
    for data in (whole_eye, half_eye):
        for name in data.regions:
            assert COMM.allreduce(len(data.cells(name)), op=MPI.SUM) > 0, name
        for name in data.surfaces:
            assert COMM.allreduce(len(data.facets(name)), op=MPI.SUM) > 0, name
    # About the seed's 9862 hexahedra; the half model has half of them.
    cells = whole_eye.mesh.topology.index_map(3).size_global
    assert 9000 <= cells <= 11000
    assert 2 * half_eye.mesh.topology.index_map(3).size_global == cells


@pytest.mark.parametrize("model", ["whole_eye", "half_eye"])
def test_no_inverted_or_badly_shaped_hexahedron(model, request):
    msh = request.getfixturevalue(model).mesh
    # DOLFINx numbers hexahedron nodes as a tensor product; gmsh order goes round each face.
    cells = msh.geometry.dofmap.array.reshape(-1, 8)[:, [0, 1, 3, 2, 4, 5, 7, 6]]
    det, scaled = corner_jacobians(msh.geometry.x, cells)
    assert COMM.allreduce(det.min(), op=MPI.MIN) > 0.0
    # The worst corners, ~0.51, are in the zonule's fan from the lens rim to the ciliary body; the
    # butterfly cores' corners are 135 degree angles (sin = 0.71).
    assert COMM.allreduce(scaled.min(), op=MPI.MIN) > 0.45


def test_cavity_walls_are_closed(whole_eye, half_eye):
    for surface in ("vitreous_wall", "anterior_chamber_wall"):
        # Whole eye: every edge of a cavity wall is shared by exactly two of its facets.
        _, counts = _edge_incidences(whole_eye, surface)
        assert on_rank0(lambda: bool(np.all(counts == 2))), surface
        # Hence -(1/3) integral of x . n is the enclosed volume, whatever the origin: moving the
        # mesh changes it by -(1/3) t . integral of n, and n integrates to zero on a closed surface.
        volume = _enclosed_volume(whole_eye, surface)
        assert _enclosed_volume(whole_eye, surface, shift=(3.0, -2.0, 5.0)) == pytest.approx(volume, rel=1e-10)
        # Half eye: the walls are open only where the symmetry plane y = 0 cuts them.
        middles, counts = _edge_incidences(half_eye, surface)
        assert on_rank0(lambda: bool(np.all((counts == 2) | ((counts == 1) & (np.abs(middles[:, 1]) < 1e-9)))))
        assert on_rank0(lambda: bool(np.any(counts == 1)))


def test_cavity_volumes_and_axial_length(whole_eye, half_eye):
    vitreous = _enclosed_volume(whole_eye, "vitreous_wall")
    aqueous = _enclosed_volume(whole_eye, "anterior_chamber_wall")
    # Vitreous: 5.28 mL for the default 24 mm eye. In vivo, MRI gives 5.41 +- 0.32 mL in emmetropic
    # eyes (Feng et al., Chin. J. Exp. Ophthalmol. 29:155, 2011); the textbook value is ~4 mL.
    assert 4.0e3 < vitreous < 6.0e3
    # Aqueous: anterior chamber 0.154 +- 0.032 mL by SS-OCT (Zong et al., J. Ophthalmol. 2017:6762047)
    # plus the posterior chamber ~0.06 mL and the space of the iris, which the model has not:
    # 0.28 mL here.
    assert 0.15e3 < aqueous < 0.35e3
    # The half model is half of it: the symmetry plane passes through the origin, x . n = 0 on it.
    assert 2 * _enclosed_volume(half_eye, "vitreous_wall") == pytest.approx(vitreous, rel=5e-3)
    # Axial length: corneal apex (on the axis, the highest point) to the vitreous wall on the axis.
    x = whole_eye.mesh.geometry.x
    apex = COMM.allreduce(x[:, 2].max(), op=MPI.MAX)
    _, wall = _surface_nodes(whole_eye, "vitreous_wall")
    posterior = on_rank0(lambda: float(wall[np.linalg.norm(wall[..., :2], axis=-1) < 1e-9][:, 2].min()))
    assert apex - posterior == pytest.approx(24.0, abs=0.1)


def test_detachment(half_eye):
    # The detached faces are the faces nearest the centre of the cap whose solid angle is the cap's,
    # 2 pi (1 - cos extent); the half model holds half of the cap.
    cap = math.pi * (1 - math.cos(math.radians(DETACHMENT["extent_deg"])))
    areas = {}
    for surface in ("retina_outer", "choroid_inner"):
        _, corners = _surface_nodes(half_eye, surface)
        radius = on_rank0(lambda: float(np.linalg.norm(corners, axis=-1).mean()))
        areas[surface] = _integrate(half_eye, 1.0, surface)
        assert areas[surface] == pytest.approx(cap * radius**2, rel=0.03), surface
    # The subretinal gap encloses area x gap, less what the ring of elements at the rim loses as the
    # gap closes over it: about half of rim length (17 mm) x element width (0.8 to 1.9 mm) x gap.
    gap = _enclosed_volume(half_eye, "retina_outer") + _enclosed_volume(half_eye, "choroid_inner")
    assert 0.65 < gap / (areas["choroid_inner"] * DETACHMENT["gap"]) < 0.9
    # Elsewhere retina and choroid share nodes: the detached retina is bonded along its rim, and the
    # vitreous wall stays closed (test_cavity_walls_are_closed).


def test_finer_and_wedge_meshes_keep_their_quality():
    # Numpy only (no gmsh, no DOLFINx): refine = 2 doubles the elements in every direction.
    coarse = eye.eye_geometry(sector_deg=90)
    fine = eye.eye_geometry(sector_deg=90, refine=2)
    assert fine.info["hexahedra"] == 8 * coarse.info["hexahedra"]
    assert fine.info["min_scaled_jacobian"] > 0.45
    # The bilinear walls converge to the curved ones: the volumes move by less than 1 %.
    assert fine.info["vitreous_volume"] == pytest.approx(coarse.info["vitreous_volume"], rel=0.01)
    assert fine.info["axial_length"] == pytest.approx(24.0, abs=1e-9)
    # A detachment centred on the posterior pole is a ring-aligned cap whose rim is put on the circle.
    pole = eye.eye_geometry(sector_deg=90, detachment={"polar_deg": 0.0, "extent_deg": 20.0, "gap": 0.2})
    assert pole.info["min_scaled_jacobian"] > 0.45
    assert pole.info["axial_length"] == pytest.approx(24.0 - 0.2, abs=1e-9)


def test_wall_layers_refine_through_the_wall_only():
    # Numpy only: wall_layers = 2 doubles every layer of the wall (sclera and cornea, choroid and
    # retina, and the ciliary body revolved with them) and leaves the rest of the mesh; the layers
    # divide the same thickness, so the cavities' walls do not move.
    coarse = eye.eye_geometry(sector_deg=90, n_circ=16)
    layered = eye.eye_geometry(sector_deg=90, n_circ=16, wall_layers=2)
    before, after = coarse.info["per_region"], layered.info["per_region"]
    for region in ("sclera", "cornea", "choroid", "retina", "ciliary_body"):
        assert after[region] == 2 * before[region], region
    for region in ("lens", "zonule", "optic_nerve"):
        assert after[region] == before[region], region
    assert layered.info["vitreous_volume"] == pytest.approx(coarse.info["vitreous_volume"], rel=1e-12)
    assert layered.info["min_scaled_jacobian"] > 0.45


@pytest.mark.parametrize("options, fragment", [
    ({"refine": 0}, "refine must be a positive integer"),
    ({"wall_layers": 0}, "wall_layers must be a positive integer"),
    ({"sector_deg": 120}, "sector_deg must be one of"),
    ({"sector_deg": 180, "n_circ": 20}, "n_circ must be a multiple of 8"),
    ({"axial_length": -24.0}, "axial_length must be a positive number"),
    ({"detachment": {"polar_deg": 100.0, "extent_deg": 30.0, "gap": 0.1}}, "must lie in the retina"),
    ({"detachment": {"polar_deg": 60.0, "extent_deg": 30.0}}, "detachment must be None or a table"),
    ({"detachment": {"polar_deg": 60.0, "extent_deg": 30.0, "gap": 1.0}}, "gap must be at most"),
    ({"sector_deg": 180, "detachment": {"polar_deg": 60.0, "azimuth_deg": 90.0, "extent_deg": 20.0, "gap": 0.1}},
     "mirrored across its cut planes"),
])
def test_rejects_bad_parameters(options, fragment):
    with pytest.raises(SceneError, match=fragment):
        eye.eye_geometry(**options)


def test_cli_and_section_picture(tmp_path):
    folder = pathlib.Path(COMM.bcast(str(tmp_path), root=0))
    path = folder / "eye.msh"
    eye.main(["--out", str(path), "--sector-deg", "90", "--n-circ", "16", "--detachment", "0", "0", "25", "0.1",
              "--graded-at", "12.5", "16.0"])
    data = load_mesh(path)
    assert set(data.regions) == TISSUES
    detachment = {"polar_deg": 0.0, "azimuth_deg": 0.0, "extent_deg": 25.0, "gap": 0.1}
    graded = eye.eye_geometry(sector_deg=90, n_circ=16, detachment=detachment, graded_at=[12.5, 16.0]).info
    assert data.mesh.topology.index_map(3).size_global == graded["hexahedra"] > 904  # 904 ungraded
    assert {"retina_outer", "choroid_inner", "cut_0", "cut_1"} <= set(data.surfaces)
    picture = folder / "section.png"
    eye_section_png(data, picture)
    assert on_rank0(lambda: picture.stat().st_size > 10_000)

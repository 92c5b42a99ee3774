"""Tests of the mesh builders and the distributed mesh loader, in serial and under ``mpirun -n 2``.

gmsh lives on rank 0 only: models are built there, files are written there into rank 0's
``tmp_path`` (broadcast to all ranks) and every check below is collective.
"""
import math
import pathlib

import dolfinx
import gmsh
import numpy as np
import pytest
import ufl
from mpi4py import MPI

from eyeball_fenicsx.errors import SceneError
from eyeball_fenicsx.meshing.builders import block, sphere_octant
from eyeball_fenicsx.meshing.load import built_mesh, load_mesh, mesh_from_gmsh_model

COMM = MPI.COMM_WORLD


def _build(builder, **options):
    """Build a gmsh model on rank 0 with ``builder`` and distribute it."""
    return built_mesh(builder, COMM, **options)


def _shared_dir(tmp_path):
    """Rank 0's temporary directory, on every rank."""
    return pathlib.Path(COMM.bcast(str(tmp_path), root=0))


def _on_rank0_with_gmsh(action):
    """Run ``action()`` in a gmsh session on rank 0 only, then synchronize."""
    if COMM.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        try:
            action()
        finally:
            gmsh.finalize()
    COMM.barrier()


def _integrate(data, measure):
    return COMM.allreduce(dolfinx.fem.assemble_scalar(dolfinx.fem.form(1.0 * measure)), op=MPI.SUM)


def _volume(data):
    return _integrate(data, ufl.dx(domain=data.mesh))


def _area(data, name):
    ds = ufl.ds(domain=data.mesh, subdomain_data=data.facet_tags, subdomain_id=data.surfaces[name])
    return _integrate(data, ds)


def _num_cells(data):
    return data.mesh.topology.index_map(3).size_global


def _min_scaled_jacobian(mesh):
    """Minimum over all hexahedra and their 8 corners of det(J) / (|J_1| |J_2| |J_3|).

    At a corner of a trilinear hexahedron the columns of J are its three edge vectors along the
    reference directions a, b, c, so this is the standard corner scaled Jacobian: > 0 at every
    corner means a valid, positively oriented hexahedron; 1 is a right-angled corner.
    """
    # DOLFINx numbers hexahedron nodes as a tensor product: node a + 2 b + 4 c at (a, b, c).
    x = mesh.geometry.x[mesh.geometry.dofmap.array.reshape(-1, 8)].reshape(-1, 2, 2, 2, 3)
    x = np.moveaxis(x, [1, 2, 3], [3, 2, 1])  # axes (cell, a, b, c, xyz)
    edges = [np.diff(x, axis=axis) for axis in (1, 2, 3)]  # edge vectors along a, b and c
    local = np.inf
    for a in (0, 1):
        for b in (0, 1):
            for c in (0, 1):
                columns = np.stack([edges[0][:, 0, b, c], edges[1][:, a, 0, c], edges[2][:, a, b, 0]], axis=-1)
                det = np.linalg.det(columns)
                scale = np.prod(np.linalg.norm(columns, axis=-2), axis=-1)
                local = min(local, np.min(det / scale, initial=np.inf))
    return COMM.allreduce(local, op=MPI.MIN)


# --- block ---------------------------------------------------------------------------------------

LENGTHS, DIVISIONS = (1.5, 2.0, 0.5), (3, 4, 2)


def _check_block(data):
    lx, ly, lz = LENGTHS
    assert data.regions == {"solid": 1}
    assert set(data.surfaces) == {"x0", "x1", "y0", "y1", "z0", "z1"}
    assert _num_cells(data) == math.prod(DIVISIONS)
    # A box's volume and face areas are products of its edge lengths; the mesh is exact.
    assert _volume(data) == pytest.approx(lx * ly * lz, rel=1e-12)
    areas = {"x0": ly * lz, "x1": ly * lz, "y0": lx * lz, "y1": lx * lz, "z0": lx * ly, "z1": lx * ly}
    for name, area in areas.items():
        assert _area(data, name) == pytest.approx(area, rel=1e-12)


def test_block_in_memory():
    if COMM.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
        block.build_block(lengths=LENGTHS, divisions=DIVISIONS)
    try:
        data = mesh_from_gmsh_model(gmsh.model, COMM, "the block")
    finally:
        if COMM.rank == 0:
            gmsh.finalize()
    assert data.source == "the block"
    _check_block(data)
    assert _min_scaled_jacobian(data.mesh) == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("version", [4.1, 2.2])
def test_block_file_round_trip(tmp_path, version):
    path = _shared_dir(tmp_path) / f"block-{version}.msh"

    def write():
        block.build_block(lengths=LENGTHS, divisions=DIVISIONS)
        gmsh.option.setNumber("Mesh.MshFileVersion", version)
        gmsh.write(str(path))

    _on_rank0_with_gmsh(write)
    data = load_mesh(path)
    assert data.source == str(path)
    _check_block(data)


def test_block_cli(tmp_path):
    path = _shared_dir(tmp_path) / "cli.msh"
    block.main(["--out", str(path), "--lengths", *map(str, LENGTHS), "--divisions", *map(str, DIVISIONS)])
    _check_block(load_mesh(path))


def test_named_facets_and_cells():
    data = _build(block.build_block, lengths=LENGTHS, divisions=DIVISIONS)
    for axis, name in enumerate(["x0", "y0", "z0"]):
        midpoints = dolfinx.mesh.compute_midpoints(data.mesh, 2, data.facets(name))
        assert np.all(np.abs(midpoints[:, axis]) < 1e-14)
    owned = data.cells("solid")
    owned = owned[owned < data.mesh.topology.index_map(3).size_local]
    assert COMM.allreduce(len(owned), op=MPI.SUM) == math.prod(DIVISIONS)
    with pytest.raises(SceneError, match=r"no surface named 'top'.*'x0', 'x1'"):
        data.facets("top")
    with pytest.raises(SceneError, match=r"no region named 'sclera'; available: 'solid'"):
        data.cells("sclera")


@pytest.mark.parametrize("options", [{"divisions": (4, 0, 4)}, {"lengths": (1.0, -1.0, 1.0)},
                                     {"divisions": (4, 4.0, 4)}, {"lengths": (1.0, 1.0)}])
def test_block_rejects_bad_parameters(options):
    with pytest.raises(SceneError, match="^block: "):
        block.build_block(**options)


def test_without_surface_groups():
    def build():
        block.build_block(lengths=LENGTHS, divisions=DIVISIONS)
        gmsh.model.removePhysicalGroups(gmsh.model.getPhysicalGroups(2))

    data = _build(build)
    assert data.surfaces == {}
    assert len(data.facet_tags.indices) == 0
    assert _volume(data) == pytest.approx(math.prod(LENGTHS), rel=1e-12)
    with pytest.raises(SceneError, match="no surface named 'x0'; available: none"):
        data.facets("x0")


def test_tetrahedra_with_point_and_curve_groups():
    def build():
        gmsh.model.add("tetrahedra")
        gmsh.model.occ.addBox(0, 0, 0, *LENGTHS)
        gmsh.model.occ.synchronize()
        gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, [1]), "solid")
        bottom = next(s for _, s in gmsh.model.getEntities(2) if gmsh.model.occ.getCenterOfMass(2, s)[2] == 0.0)
        gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, [bottom]), "z0")
        gmsh.model.setPhysicalName(1, gmsh.model.addPhysicalGroup(1, [1]), "an edge")  # ignored
        gmsh.model.setPhysicalName(0, gmsh.model.addPhysicalGroup(0, [1]), "a corner")  # ignored
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.4)
        gmsh.model.mesh.generate(3)

    data = _build(build)
    assert data.mesh.topology.cell_type == dolfinx.mesh.CellType.tetrahedron
    assert data.regions == {"solid": 1} and data.surfaces == {"z0": 2}
    # Planar faces: a tetrahedral mesh of the box is exact.
    assert _volume(data) == pytest.approx(math.prod(LENGTHS), rel=1e-12)
    assert _area(data, "z0") == pytest.approx(LENGTHS[0] * LENGTHS[1], rel=1e-12)


# --- sphere octant -------------------------------------------------------------------------------

A, B = 1.0, 2.0


def _surface_nodes(data, name):
    """Coordinates of the geometry nodes of the local facets of a named surface."""
    nodes = dolfinx.cpp.mesh.entities_to_geometry(data.mesh._mesh, 2, data.facets(name), False)
    return data.mesh.geometry.x[nodes.ravel()]


def test_sphere_octant_topology_and_exact_nodes():
    n, layers = 16, 8
    data = _build(sphere_octant.build_sphere_octant, inner_radius=A, outer_radius=B, n=n, layers=layers)
    assert data.regions == {"wall": 1}
    assert set(data.surfaces) == {"inner", "outer", "sym_x", "sym_y", "sym_z"}
    # Three patches of n x n quadrilaterals, each extruded in `layers` hexahedra.
    assert _num_cells(data) == 3 * n * n * layers == 6144
    # Conforming: 3 patches of (n + 1)^2 nodes share 3 arcs of n + 1 nodes and the corner
    # (inclusion-exclusion: 3 (n + 1)^2 - 3 (n + 1) + 1), on each of the layers + 1 spheres.
    assert data.mesh.topology.index_map(0).size_global == (3 * (n + 1) ** 2 - 3 * (n + 1) + 1) * (layers + 1)
    for name, radius in (("inner", A), ("outer", B)):
        assert np.allclose(np.linalg.norm(_surface_nodes(data, name), axis=1), radius, rtol=1e-14, atol=0)
    for axis, name in enumerate(("sym_x", "sym_y", "sym_z")):
        assert np.all(_surface_nodes(data, name)[:, axis] == 0.0)
    assert np.all(data.mesh.geometry.x >= 0.0)
    # The worst corners are where the three patches meet, at 120 degrees: sin(120 deg) = 0.866.
    assert _min_scaled_jacobian(data.mesh) > 0.85


def test_sphere_octant_converges_at_second_order():
    # Octant of the shell: volume (1/8)(4/3) pi (b^3 - a^3), spherical faces (1/8) 4 pi r^2, and each
    # symmetry plane a quarter annulus (pi/4)(b^2 - a^2). Bilinear faces inscribed in the sphere
    # and straight chords of the arcs err by O(h^2), h ~ 1/n.
    exact = {"volume": math.pi / 6 * (B**3 - A**3), "inner": math.pi / 2 * A**2, "outer": math.pi / 2 * B**2,
             "sym_x": math.pi / 4 * (B**2 - A**2)}
    errors = []
    for n in (4, 8, 16):
        data = _build(sphere_octant.build_sphere_octant, inner_radius=A, outer_radius=B, n=n, layers=2)
        measured = {"volume": _volume(data), **{name: _area(data, name) for name in ("inner", "outer", "sym_x")}}
        errors.append({name: abs(measured[name] - value) / value for name, value in exact.items()})
    for coarse, fine in zip(errors, errors[1:]):
        for name in exact:
            assert math.log2(coarse[name] / fine[name]) == pytest.approx(2.0, abs=0.1), name
    assert max(errors[-1].values()) < 2e-3


def test_sphere_octant_grading():
    radii = sphere_octant.layer_radii(1.0, 2.0, 4, 2.0)
    # Thicknesses h, 2h, 4h, 8h fill b - a = 1: h = 1/15.
    assert np.allclose(radii, [1.0, 1 + 1 / 15, 1 + 3 / 15, 1 + 7 / 15, 2.0], rtol=1e-15)
    graded = _build(sphere_octant.build_sphere_octant, n=6, layers=5, grading=1.5)
    assert _min_scaled_jacobian(graded.mesh) > 0.85
    # With x = rho(zeta) d(xi, eta) in each hexahedron, det J = rho^2 rho' d . (d_xi x d_eta): the
    # radial integral telescopes to (b^3 - a^3) / 3, so the volume does not depend on the layers.
    single = _build(sphere_octant.build_sphere_octant, n=6, layers=1)
    assert _volume(graded) == pytest.approx(_volume(single), rel=1e-12)


def test_sphere_octant_cli(tmp_path):
    path = _shared_dir(tmp_path) / "octant.msh"
    sphere_octant.main(["--out", str(path), "--n", "3", "--layers", "2", "--region", "sclera"])
    data = load_mesh(path)
    assert data.regions == {"sclera": 1}
    assert _num_cells(data) == 3 * 3 * 3 * 2


@pytest.mark.parametrize("options", [{"n": 0}, {"layers": 2.5}, {"inner_radius": 2.0, "outer_radius": 1.0},
                                     {"grading": 0.0}, {"inner_radius": float("nan")}])
def test_sphere_octant_rejects_bad_parameters(options):
    with pytest.raises(SceneError, match="^sphere_octant: "):
        sphere_octant.build_sphere_octant(**options)


# --- loader errors -------------------------------------------------------------------------------

def _raises_everywhere(call, *fragments):
    """Assert ``call()`` raises SceneError on every rank, with one message containing ``fragments``."""
    with pytest.raises(SceneError) as caught:
        call()
    messages = COMM.allgather(str(caught.value))
    assert len(set(messages)) == 1
    assert "\n" not in messages[0]
    for fragment in fragments:
        assert fragment in messages[0]


def _write_text(path, text):
    if COMM.rank == 0:
        path.write_text(text)
    COMM.barrier()


def _write_block(path, edit):
    """Write a small block mesh on rank 0 after ``edit()`` changes the gmsh model."""
    def write():
        block.build_block(divisions=(1, 1, 1))
        edit()
        gmsh.write(str(path))

    _on_rank0_with_gmsh(write)


def test_load_missing_file(tmp_path):
    path = _shared_dir(tmp_path) / "missing.msh"
    _raises_everywhere(lambda: load_mesh(path), str(path), "no such file")


def test_load_not_msh(tmp_path):
    path = _shared_dir(tmp_path) / "mesh.xdmf"
    _write_text(path, "<Xdmf/>")
    _raises_everywhere(lambda: load_mesh(path), str(path), "not a .msh file")


@pytest.mark.parametrize("text", ["this is not a mesh\n", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 3\n", ""])
def test_load_garbage(tmp_path, text):
    path = _shared_dir(tmp_path) / "garbage.msh"
    _write_text(path, text)
    _raises_everywhere(lambda: load_mesh(path), str(path), "gmsh cannot read it")


def test_load_no_volume_group(tmp_path):
    path = _shared_dir(tmp_path) / "surfaces.msh"
    _write_block(path, lambda: gmsh.model.removePhysicalGroups([(3, 1)]))
    _raises_everywhere(lambda: load_mesh(path), str(path), "no volume physical group")


def test_load_unnamed_volume_group(tmp_path):
    path = _shared_dir(tmp_path) / "unnamed.msh"
    _write_block(path, lambda: gmsh.model.removePhysicalName("solid"))
    _raises_everywhere(lambda: load_mesh(path), str(path), "volume physical group 1 has no name")


def test_load_duplicate_names(tmp_path):
    path = _shared_dir(tmp_path) / "duplicate.msh"
    _write_block(path, lambda: None)
    if COMM.rank == 0:
        path.write_text(path.read_text().replace('"x1"', '"x0"'))
    COMM.barrier()
    _raises_everywhere(lambda: load_mesh(path), str(path), "both named 'x0'")


def _add_volume(element_type, nodes, group=None):
    """Add a discrete volume holding one element on the block's nodes, optionally in a new group."""
    gmsh.model.addDiscreteEntity(3, 2)
    gmsh.model.mesh.addElementsByType(2, element_type, [1000], nodes)
    if group:
        _add_group(3, [2], group)


def _add_surface(element_type, nodes, group):
    """Add a discrete surface holding one element on the block's nodes, in a new group."""
    gmsh.model.addDiscreteEntity(2, 20)
    gmsh.model.mesh.addElementsByType(20, element_type, [1000], nodes)
    _add_group(2, [20], group)


def _add_group(dim, entities, name):
    gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, entities), name)


# Node tags of the 1 x 1 x 1 block: 1 + 4 i + 2 j + k at (i, j, k); its volume entity is 1 and the
# surface entities x0, x1, y0, y1, z0, z1 are 2 .. 7.
CORRUPTIONS = {
    "unsupported": (lambda: _add_volume(6, [1, 5, 7, 2, 6, 8], "extra"), "unsupported volume elements 'Prism 6'"),
    "mixed": (lambda: _add_volume(4, [1, 5, 7, 2], "extra"), "mixed volume elements"),
    "untagged": (lambda: _add_volume(5, [1, 5, 7, 3, 2, 6, 8, 4]), "volume entity 2 has elements in no physical group"),
    "empty": (lambda: _add_group(3, [gmsh.model.addDiscreteEntity(3)], "empty"),
              "volume physical group 'empty' has no elements"),
    "two volume groups": (lambda: _add_group(3, [1], "again"),
                          "volume entity 1 is in physical groups 'solid' and 'again'"),
    "two surface groups": (lambda: _add_group(2, [2], "x0 again"),
                           "surface entity 2 is in physical groups 'x0' and 'x0 again'"),
    "face tagged twice": (lambda: _add_surface(3, [1, 3, 4, 2], "left"), "some faces are in several surface physical"),
    "not a face": (lambda: _add_surface(3, [1, 5, 8, 4], "diagonal"),
                   "surface physical group 'diagonal' has elements that are not faces"),
    "triangle facets": (lambda: _add_surface(2, [1, 5, 7], "triangle"),
                        "must hold the faces of the 8-node hexahedra only"),
}


@pytest.mark.parametrize("corruption", CORRUPTIONS)
def test_model_errors(corruption):
    edit, fragment = CORRUPTIONS[corruption]

    def build_corrupted():
        block.build_block(divisions=(1, 1, 1))
        edit()

    _raises_everywhere(lambda: _build(build_corrupted), "build_corrupted: ", fragment)


def test_builder_error_raised_on_every_rank():
    _raises_everywhere(lambda: _build(sphere_octant.build_sphere_octant, n=0), "sphere_octant: n must be a positive")


def test_sparse_node_tags_and_unused_nodes():
    def build():
        gmsh.model.add("sparse")
        gmsh.model.addDiscreteEntity(3, 1)
        corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
        # Node tags 80, 70, ..., 10 in gmsh hexahedron order, and an unused node 5 far away.
        gmsh.model.mesh.addNodes(3, 1, [80, 70, 60, 50, 40, 30, 20, 10, 5], np.ravel(corners + [(9, 9, 9)]))
        gmsh.model.mesh.addElementsByType(1, 5, [1], [80, 70, 60, 50, 40, 30, 20, 10])
        _add_group(3, [1], "cube")

    data = _build(build)
    assert data.mesh.geometry.index_map().size_global == 8
    assert _volume(data) == pytest.approx(1.0, rel=1e-14)

"""Distributed meshes with named regions and surfaces, from gmsh models and .msh files.

Only rank 0 touches gmsh. It checks the model, extracts the cells of the volume physical groups
and the facets of the surface physical groups (groups of dimension 0 and 1 are ignored), and
DOLFINx distributes them. Every check is decided on rank 0 and its verdict broadcast, so that all
ranks raise the same :class:`SceneError` together and none is left waiting.

This does the work of ``dolfinx.io.gmshio.model_to_mesh`` with the same DOLFINx calls, but it
does not assume what that function assumes: node tags need not be contiguous, a volume must lie
in exactly one physical group, and lower-dimensional groups or untagged elements cannot slip in.
"""
import dataclasses
import os
from collections.abc import Callable

import dolfinx
import gmsh
import numpy as np
from dolfinx import cpp as _cpp
from dolfinx.io import gmshio
from mpi4py import MPI

from ..errors import SceneError

# Supported gmsh volume element types -> (name, gmsh type of their facets, local nodes of each face).
_VOLUME_TYPES = {
    4: ("4-node tetrahedra", 2, [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)]),
    5: ("8-node hexahedra", 3, [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (0, 4, 7, 3)]),
}


@dataclasses.dataclass
class MeshData:
    """A distributed mesh with its physical groups.

    Attributes:
        mesh: the DOLFINx mesh.
        cell_tags: cell markers; values are gmsh volume physical-group tags.
        facet_tags: facet markers; values are gmsh surface physical-group tags.
        regions: volume physical-group name -> tag (same on every rank).
        surfaces: surface physical-group name -> tag (same on every rank).
        source: file path or builder name, for error messages.
        parameters: the builder's parameters, as given (empty for a mesh file): what an
            estimate of the geometry needs (``eyeball_fenicsx.meshing.builders.eye.scleral_wall``).
    """

    mesh: dolfinx.mesh.Mesh
    cell_tags: _cpp.mesh.MeshTags_int32
    facet_tags: _cpp.mesh.MeshTags_int32
    regions: dict[str, int]
    surfaces: dict[str, int]
    source: str
    parameters: dict = dataclasses.field(default_factory=dict)

    def facets(self, name: str) -> np.ndarray:
        """Local indices of the facets of a named surface (ghosts included).

        Raises:
            SceneError: if there is no surface of that name.
        """
        return self.facet_tags.find(_lookup(self.surfaces, name, "surface", self.source))

    def cells(self, name: str) -> np.ndarray:
        """Local indices of the cells of a named region (ghosts included).

        Raises:
            SceneError: if there is no region of that name.
        """
        return self.cell_tags.find(_lookup(self.regions, name, "region", self.source))


def load_mesh(path: str | os.PathLike, comm: MPI.Comm = MPI.COMM_WORLD) -> MeshData:
    """Read a gmsh .msh file (MSH 4.1 or 2.2) on rank 0 and distribute it over ``comm``.

    Collective. Rank 0 opens and closes its own gmsh session, so it must not be called while
    gmsh is initialized on rank 0.

    Args:
        path: the .msh file.
        comm: MPI communicator of the mesh.

    Returns:
        The distributed mesh with its physical groups.

    Raises:
        SceneError: on every rank, if the file is missing, unreadable or not a valid mesh.
    """
    source = os.fspath(path)

    def read():
        if not source.endswith(".msh"):
            raise SceneError(f"{source}: not a .msh file; export the mesh from gmsh in MSH format (4.1 or 2.2)")
        if not os.path.isfile(source):
            raise SceneError(f"{source}: no such file; check the mesh path")
        if not os.access(source, os.R_OK):
            raise SceneError(f"{source}: file is not readable; check its permissions")
        gmsh.initialize()
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            try:
                gmsh.merge(source)
            except Exception as error:
                raise SceneError(f"{source}: gmsh cannot read it ({error}); "
                                 "write it again with gmsh in MSH 4.1 or 2.2 format") from None
            return _extract(gmsh.model, source)
        finally:
            gmsh.finalize()

    return _distribute(comm, _on_rank0(comm, read, source), source)


def mesh_from_gmsh_model(model, comm: MPI.Comm, source: str) -> MeshData:
    """Distribute a gmsh model that exists on rank 0 over ``comm``.

    Collective; ``model`` (normally the ``gmsh.model`` module) is only used on rank 0 and is not
    modified.

    Args:
        model: the gmsh model (current model of the gmsh session on rank 0).
        comm: MPI communicator of the mesh.
        source: name of the model for error messages, e.g. a builder name.

    Returns:
        The distributed mesh with its physical groups.

    Raises:
        SceneError: on every rank, if the model is not a valid mesh.
    """
    return _distribute(comm, _on_rank0(comm, lambda: _extract(model, source), source), source)


@dataclasses.dataclass
class _Extracted:
    """What rank 0 reads from a gmsh model: 0-based node numbers, cells and facets in gmsh order."""

    x: np.ndarray
    cell_type: int
    cells: np.ndarray
    cell_values: np.ndarray
    facets: np.ndarray
    facet_values: np.ndarray
    regions: dict
    surfaces: dict


def _on_rank0(comm, task, source):
    """Run ``task`` on rank 0 and raise its SceneError on every rank.

    Any other exception is re-raised on rank 0 and reported as a RuntimeError on the others.

    Returns:
        The result of ``task`` on rank 0, None elsewhere.
    """
    result, failure = None, None
    if comm.rank == 0:
        try:
            result = task()
        except SceneError as error:
            failure = (SceneError, str(error))
        except Exception as error:
            comm.bcast((RuntimeError, f"{source}: rank 0 failed to read the mesh: {error!r}"), root=0)
            raise
    failure = comm.bcast(failure, root=0)
    if failure is not None:
        raise failure[0](failure[1])
    return result


def _lookup(names, name, kind, source):
    """Tag of a named physical group, or SceneError listing the available names."""
    if name not in names:
        available = ", ".join(f"'{n}'" for n in names) or "none"
        raise SceneError(f"{source}: no {kind} named '{name}'; available: {available}")
    return names[name]


def _named_groups(model, dim, source):
    """Physical groups of one dimension: name -> tag, checking that names are present and unique."""
    kind = "volume" if dim == 3 else "surface"
    groups = {}
    for _, tag in model.getPhysicalGroups(dim):
        name = model.getPhysicalName(dim, tag)
        if not name:
            raise SceneError(f"{source}: {kind} physical group {tag} has no name; name every physical group "
                             f"(gmsh: Physical {kind.capitalize()}(\"name\") = {{...}};)")
        if name in groups:
            raise SceneError(f"{source}: {kind} physical groups {groups[name]} and {tag} are both named '{name}'; "
                             "give each physical group its own name")
        groups[name] = tag
    return groups


def _group_elements(model, dim, groups, source):
    """Elements of the physical groups of one dimension, checking that no entity is in two groups.

    Returns:
        ``(types, node_tags, values)``: per element, its gmsh type and physical-group tag, and the
        flat array of the node tags of all elements.
    """
    kind = "volume" if dim == 3 else "surface"
    owner = {}
    types, node_tags, values = [np.empty(0, np.int64)], [np.empty(0, np.int64)], []
    for name, tag in groups.items():
        count = 0
        for entity in model.getEntitiesForPhysicalGroup(dim, tag):
            if entity in owner:
                raise SceneError(f"{source}: {kind} entity {entity} is in physical groups '{owner[entity]}' and "
                                 f"'{name}'; put each {kind} in one physical group only")
            owner[entity] = name
            for element_type, tags, nodes in zip(*model.mesh.getElements(dim, entity)):
                types.append(np.full(len(tags), element_type, dtype=np.int64))
                node_tags.append(nodes.astype(np.int64))
                count += len(tags)
        if count == 0:
            raise SceneError(f"{source}: {kind} physical group '{name}' has no elements; generate the mesh "
                             "before saving it, or remove the empty group")
        values.append(np.full(count, tag, dtype=np.int32))
    if dim == 3:
        for _, entity in model.getEntities(3):
            if entity not in owner and any(len(tags) for tags in model.mesh.getElements(3, entity)[1]):
                raise SceneError(f"{source}: volume entity {entity} has elements in no physical group; add it to a "
                                 "named volume physical group")
    return np.concatenate(types), np.concatenate(node_tags), np.concatenate([np.empty(0, np.int32), *values])


def _extract(model, source):
    """Check a gmsh model and extract its tagged cells and facets (rank 0 only)."""
    regions = _named_groups(model, 3, source)
    if not regions:
        raise SceneError(f"{source}: no volume physical group; a mesh needs at least one named volume "
                         "physical group of 3D elements (gmsh: Physical Volume(\"name\") = {...};)")
    surfaces = _named_groups(model, 2, source)

    types, cell_nodes, cell_values = _group_elements(model, 3, regions, source)
    present = [int(t) for t in np.unique(types)]
    for element_type in present:
        if element_type not in _VOLUME_TYPES:
            name = model.mesh.getElementProperties(element_type)[0]
            raise SceneError(f"{source}: unsupported volume elements '{name}' (gmsh type {element_type}); "
                             "use 8-node hexahedra or 4-node tetrahedra (first-order mesh)")
    if len(present) > 1:
        raise SceneError(f"{source}: mixed volume elements (both tetrahedra and hexahedra); "
                         "use a single type: all 8-node hexahedra or all 4-node tetrahedra")
    cell_type = present[0]
    type_name, facet_type, faces = _VOLUME_TYPES[cell_type]

    facet_types, facet_nodes, facet_values = _group_elements(model, 2, surfaces, source)
    if np.any(facet_types != facet_type):
        raise SceneError(f"{source}: the surface physical groups must hold the faces of the {type_name} only "
                         f"({'quadrangles' if facet_type == 3 else 'triangles'}), found other elements")

    node_tags, coordinates, _ = model.mesh.getNodes()
    order = np.argsort(node_tags)
    node_tags, coordinates = node_tags[order], coordinates.reshape(-1, 3)[order]
    # Number the nodes of the cells 0, 1, ... in tag order; other nodes get -1.
    cells = np.searchsorted(node_tags, cell_nodes).reshape(len(types), -1)
    used = np.unique(cells)
    numbers = np.full(len(node_tags), -1, dtype=np.int64)
    numbers[used] = np.arange(len(used))
    cells = numbers[cells]
    facets = numbers[np.searchsorted(node_tags, facet_nodes)].reshape(len(facet_types), len(faces[0]))
    _check_facets(cells, faces, facets, facet_values, surfaces, source)
    return _Extracted(x=coordinates[used], cell_type=cell_type, cells=cells, cell_values=cell_values,
                      facets=facets, facet_values=facet_values, regions=regions, surfaces=surfaces)


def _check_facets(cells, faces, facets, facet_values, surfaces, source):
    """SceneError unless every tagged facet is a face of a cell and is tagged once only."""
    if len(facets) == 0:
        return
    cell_faces = cells[:, faces].reshape(-1, len(faces[0]))
    index = _same_vertex_ids(np.concatenate([cell_faces, facets]))
    is_face = np.zeros(index.max() + 1, dtype=bool)
    is_face[index[:len(cell_faces)]] = True
    facet_index = index[len(cell_faces):]
    not_face = ~is_face[facet_index] | np.any(facets < 0, axis=1)
    if np.any(not_face):
        tag = facet_values[not_face][0]
        name = next(name for name, value in surfaces.items() if value == tag)
        raise SceneError(f"{source}: surface physical group '{name}' has elements that are not faces of the volume "
                         "cells; mesh the surfaces and volumes together so that they share nodes")
    if len(np.unique(facet_index)) < len(facet_index):
        raise SceneError(f"{source}: some faces are in several surface physical groups (or twice in one); "
                         "a face can carry one surface tag only")


def _same_vertex_ids(rows):
    """Number the rows so that rows with the same set of vertices get the same number.

    Equivalent to ``np.unique(np.sort(rows, axis=1), axis=0, return_inverse=True)[1]``, faster.
    """
    rows = np.sort(rows, axis=1)
    order = np.lexsort(rows.T[::-1])
    ordered = rows[order]
    ids = np.empty(len(rows), dtype=np.int64)
    ids[order] = np.cumsum(np.concatenate([[False], np.any(ordered[1:] != ordered[:-1], axis=1)]))
    return ids


def _distribute(comm, extracted, source):
    """Create the distributed mesh and its tags from what rank 0 extracted (collective)."""
    header = (extracted.cell_type, extracted.regions, extracted.surfaces) if comm.rank == 0 else None
    cell_type, regions, surfaces = comm.bcast(header, root=0)
    domain = gmshio.ufl_mesh(cell_type, 3)
    dolfinx_cell = dolfinx.mesh.to_type(str(domain.ufl_cell()))
    num_nodes = _cpp.mesh.cell_num_vertices(dolfinx_cell)
    facet_cell = _cpp.mesh.cell_entity_type(dolfinx_cell, 2, 0)
    num_facet_nodes = _cpp.mesh.cell_num_vertices(facet_cell)
    if comm.rank == 0:
        cells = extracted.cells[:, gmshio.cell_perm_array(dolfinx_cell, num_nodes)]
        facets = extracted.facets[:, gmshio.cell_perm_array(facet_cell, num_facet_nodes)]
        x, cell_values, facet_values = extracted.x, extracted.cell_values, extracted.facet_values
    else:
        cells, facets = np.empty((0, num_nodes), np.int64), np.empty((0, num_facet_nodes), np.int64)
        x, cell_values, facet_values = np.empty((0, 3)), np.empty(0, np.int32), np.empty(0, np.int32)
    mesh = dolfinx.mesh.create_mesh(comm, cells, x, domain)
    return MeshData(mesh=mesh, cell_tags=_tags(mesh, 3, cells, cell_values),
                    facet_tags=_tags(mesh, 2, facets, facet_values),
                    regions=regions, surfaces=surfaces, source=source)


def _tags(mesh, dim, entities, values):
    """MeshTags of entities given by their global input node numbers, held on rank 0 (collective)."""
    local_entities, local_values = _cpp.io.distribute_entity_data(mesh._mesh, dim, entities.astype(np.int64),
                                                                  values.astype(np.int32))
    mesh.topology.create_connectivity(dim, 0)
    mesh.topology.create_connectivity(dim, 3)
    tags = dolfinx.mesh.meshtags_from_entities(mesh, dim, _cpp.graph.AdjacencyList_int32(local_entities),
                                               local_values.astype(np.int32))
    tags.name = "Cell tags" if dim == 3 else "Facet tags"
    return tags


def built_mesh(build: Callable, comm: MPI.Comm = MPI.COMM_WORLD, **options) -> MeshData:
    """Run a gmsh builder (``eyeball_fenicsx.meshing.builders.*.build_*``) on rank 0 and distribute its mesh."""
    source = f"builder {build.__name__}"
    if comm.rank == 0:
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)
    try:
        message = None
        if comm.rank == 0:
            try:
                build(**options)
            except (TypeError, ValueError) as error:
                message = f"{source}: {error}"
        message = comm.bcast(message, root=0)
        if message:
            raise SceneError(message)
        data = mesh_from_gmsh_model(gmsh.model, comm, source)
        data.parameters = dict(options)
        return data
    finally:
        if comm.rank == 0:
            gmsh.finalize()

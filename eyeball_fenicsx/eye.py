"""Pictures of the eye model: its meridional section with the tissues coloured."""
import numpy as np

from dolfinx import cpp

# Tissue colours of the section (matplotlib names); regions not listed are grey.
TISSUE_COLOURS = {"cornea": "lightskyblue", "sclera": "gainsboro", "ciliary_body": "sienna", "choroid": "firebrick",
                  "retina": "hotpink", "optic_nerve": "gold", "lens": "steelblue", "zonule": "seagreen"}


def meridional_section(mesh_data, tolerance=1e-9):
    """Faces of the mesh in the plane y = 0 (the section through the optic axis at azimuth 0 and 180).

    Collective.

    Args:
        mesh_data: a :class:`~eyeball_fenicsx.mesh.MeshData` of hexahedra whose nodes lie exactly on
            y = 0 where the section cuts them (true of ``meshes.eye``).
        tolerance: distance (mesh units) under which a node is on the plane.

    Returns:
        On rank 0, ``(polygons, regions)``: the faces' corners in the (x, z) plane in cyclic order,
        shape ``(count, 4, 2)``, and the region name of each face; ``(None, None)`` elsewhere.
    """
    msh = mesh_data.mesh
    tdim = msh.topology.dim
    msh.topology.create_connectivity(tdim - 1, tdim)
    num_facets = msh.topology.index_map(tdim - 1).size_local
    facets = np.arange(num_facets, dtype=np.int32)
    # DOLFINx numbers a quadrilateral's vertices as a tensor product: 0, 1, 3, 2 goes round it.
    nodes = cpp.mesh.entities_to_geometry(msh._mesh, tdim - 1, facets, False)[:, [0, 1, 3, 2]]
    x = msh.geometry.x[nodes]
    in_plane = np.all(np.abs(x[..., 1]) < tolerance, axis=1)
    facet_cells = msh.topology.connectivity(tdim - 1, tdim)
    cells = np.array([facet_cells.links(f)[0] for f in facets[in_plane]], dtype=np.int32)
    names = {tag: name for name, tag in mesh_data.regions.items()}
    tag_of_cell = np.zeros(msh.topology.index_map(tdim).size_local + msh.topology.index_map(tdim).num_ghosts,
                           dtype=np.int32)
    tag_of_cell[mesh_data.cell_tags.indices] = mesh_data.cell_tags.values
    regions = [names.get(tag, "") for tag in tag_of_cell[cells]]
    gathered = msh.comm.gather((x[in_plane][..., [0, 2]], regions), root=0)
    if msh.comm.rank != 0:
        return None, None
    return (np.concatenate([g[0] for g in gathered]).reshape(-1, 4, 2),
            [name for g in gathered for name in g[1]])


def eye_section_png(mesh_data, path, title=None):
    """Draw the meridional section of an eye mesh with its tissues coloured, as a PNG (matplotlib Agg).

    Collective; rank 0 writes the file.

    Args:
        mesh_data: the eye mesh (:func:`meshes.eye.build_eye` through ``built_mesh``).
        path: the .png file to write.
        title: optional title of the figure.
    """
    polygons, regions = meridional_section(mesh_data)
    if polygons is None:  # not rank 0
        return
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    from matplotlib.patches import Patch

    figure, axes = plt.subplots(figsize=(7, 8))
    colours = [TISSUE_COLOURS.get(name, "grey") for name in regions]
    axes.add_collection(PolyCollection(polygons, facecolors=colours, edgecolors="black", linewidths=0.15))
    axes.autoscale_view()
    axes.set_aspect("equal")
    axes.set_xlabel("x (mm)")
    axes.set_ylabel("z: optic axis (mm)")
    present = [name for name in TISSUE_COLOURS if name in set(regions)]
    axes.legend(handles=[Patch(facecolor=TISSUE_COLOURS[name], edgecolor="black", label=name.replace("_", " "))
                         for name in present], loc="center", fontsize=8, frameon=False)
    if title:
        axes.set_title(title)
    figure.tight_layout()
    figure.savefig(path, dpi=150)
    plt.close(figure)

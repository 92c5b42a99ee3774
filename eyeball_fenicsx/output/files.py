"""What a run writes: probes, field output (XDMF for ParaView), summary.json and pictures.

Every file appears atomically: summary.json and the PNG pictures are written to a temporary
name and renamed; the XDMF/HDF5 pair is written in a hidden folder and moved into place when
closed.
"""
import json
import os
import shutil

import numpy as np
from dolfinx import fem, geometry, io
from mpi4py import MPI


class Probes:
    """Displacement at material points given by their reference coordinates."""

    def __init__(self, solid, points: dict):
        self.solid = solid
        msh = solid.mesh_data.mesh
        tree = geometry.BoundingBoxTree(msh, msh.topology.dim)
        num_owned_cells = msh.topology.index_map(msh.topology.dim).size_local
        self.cells = {}
        for name, point in points.items():
            x = np.asarray(point, dtype=float).reshape(1, 3)
            candidates = geometry.compute_collisions(tree, x)
            cells = geometry.compute_colliding_cells(msh, candidates, x).links(0)
            cells = cells[cells < num_owned_cells]
            # the lowest rank that holds the point evaluates it
            owner = solid.comm.allreduce(solid.comm.rank if len(cells) else solid.comm.size, op=MPI.MIN)
            if owner == solid.comm.size:
                from ..errors import SceneError
                raise SceneError(f"probe {name!r}: point {list(point)} is not inside the mesh {solid.mesh_data.source}")
            self.cells[name] = (x, cells[0] if solid.comm.rank == owner else None, owner)

    def displacements(self):
        u = self.solid.w.sub(0)
        result = {}
        for name, (x, cell, owner) in self.cells.items():
            value = u.eval(x, [cell])[:3] if cell is not None else None
            result[name] = [float(v) for v in self.solid.comm.bcast(value, root=owner)]
        return result


class FieldOutput:
    """Displacement, pressure, von Mises stress and region tags per step, in XDMF."""

    def __init__(self, solid, out_dir, name="fields"):
        self.solid, self.comm = solid, solid.comm
        self.final = [os.path.join(out_dir, name + ext) for ext in (".xdmf", ".h5")]
        self.hidden = os.path.join(out_dir, f".{name}.partial")
        if self.comm.rank == 0:
            os.makedirs(self.hidden, exist_ok=True)
        self.comm.barrier()
        msh = solid.mesh_data.mesh
        self.file = io.XDMFFile(self.comm, os.path.join(self.hidden, name + ".xdmf"), "w")
        self.file.write_mesh(msh)
        solid.mesh_data.cell_tags.name = "region"
        self.file.write_meshtags(solid.mesh_data.cell_tags)
        self.displacement = fem.Function(fem.VectorFunctionSpace(msh, ("Lagrange", 1)), name="displacement")
        self.pressure = fem.Function(fem.FunctionSpace(msh, ("DG", 0)), name="pressure")
        self.mises = fem.Function(self.pressure.function_space, name="von_mises")
        points = self.pressure.function_space.element.interpolation_points()
        self._mises_expr = fem.Expression(solid.mises_expression(), points)
        self._u_expr = fem.Expression(solid.u, self.displacement.function_space.element.interpolation_points())
        self._p_expr = fem.Expression(solid.p, points)

    def write(self, time):
        self.displacement.interpolate(self._u_expr)
        self.pressure.interpolate(self._p_expr)
        self.mises.interpolate(self._mises_expr)
        for f in (self.displacement, self.pressure, self.mises):
            self.file.write_function(f, time)
        return self.mises

    def close(self):
        self.file.close()
        self.comm.barrier()
        if self.comm.rank == 0:
            for final in self.final:
                os.replace(os.path.join(self.hidden, os.path.basename(final)), final)
            shutil.rmtree(self.hidden, ignore_errors=True)
        self.comm.barrier()


def write_text_atomic(path, text, comm=MPI.COMM_WORLD):
    """Write a text file on rank 0 to a temporary name, then rename it into place."""
    if comm.rank == 0:
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        tmp = f"{path}.tmp{os.getpid()}"
        with open(tmp, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    comm.barrier()


def write_json_atomic(path, data, comm=MPI.COMM_WORLD):
    """Write JSON atomically (see ``write_text_atomic``); NaN is refused, never written."""
    write_text_atomic(path, json.dumps(data, indent=1, allow_nan=False) if comm.rank == 0 else "", comm)


def save_figure_atomic(figure, path, dpi=150):
    """Save a matplotlib figure as a PNG under a temporary name, then rename it into place
    (call on the one rank that draws)."""
    tmp = f"{path}.tmp{os.getpid()}.png"
    figure.savefig(tmp, dpi=dpi)
    os.replace(tmp, path)


def plot_curves(path, x, curves, xlabel, xticklabels=None):
    """A PNG of small plots, one curve each, against the same x (matplotlib Agg; call on one rank).

    Args:
        curves: {title: y values}.
        xticklabels: labels of the x values (step names), or None for numbers.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    columns = min(3, len(curves))
    lines = -(-len(curves) // columns)
    figure, axes = plt.subplots(lines, columns, figsize=(4 * columns, 3 * lines), squeeze=False)
    for ax, (name, y) in zip(axes.ravel(), curves.items()):
        ax.plot(x, y, "o-")
        ax.set_xlabel(xlabel)
        ax.set_title(name, fontsize=9)
        if xticklabels is not None:
            ax.set_xticks(x, xticklabels, rotation=30, fontsize=8)
    for ax in axes.ravel()[len(curves):]:
        ax.axis("off")
    figure.tight_layout()
    save_figure_atomic(figure, path, dpi=110)
    plt.close(figure)


def flatten(entries, prefix=""):
    """{"a": 1, "b": {"c": 2}, "d": [3, 4]} -> {"a": 1, "b.c": 2, "d.0": 3, "d.1": 4}."""
    flat = {}
    for key, value in entries.items():
        if isinstance(value, list):
            value = dict(enumerate(value))
        if isinstance(value, dict):
            flat.update(flatten(value, f"{prefix}{key}."))
        else:
            flat[f"{prefix}{key}"] = value
    return flat

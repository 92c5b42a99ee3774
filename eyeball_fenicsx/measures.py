"""What a surgeon asks of the eye after each step, written under "eye" in summary.json.

* ``axial_length_mm``: corneal apex to the posterior pole along the optic axis (the
  anterior corneal surface to the retina's inner surface, as optical biometry measures);
  ``axial_length_change_mm`` from the reference state;
* ``refraction_change_D``: the refractive change of that length change at -2.7 D per mm
  (a 1 mm longer eye is about 2.7 D more myopic: Atchison & Smith, Optics of the Human
  Eye, 2000, ch. 17; schematic-eye values range from -2.5 to -3 D/mm);
* ``iop_mmHg``: the vitreous pressure (1 MPa = 7500.62 mmHg);
* ``max_mises_MPa``: the largest von Mises stress (element midpoints) per tissue.
"""
import numpy as np
from mpi4py import MPI

from dolfinx import fem

from .feature import Feature
from .formulation import MaterialNode

MMHG_PER_MPA = 7500.62
DIOPTRES_PER_MM = -2.7


class EyeMeasures(Feature):
    """Eye measures of the current state (no contribution to the equations).

    Args:
        anterior, posterior: reference points near the corneal apex and the posterior pole
            (the nearest nodes of ``anterior_surface`` / ``posterior_surface`` are used).
        vitreous: the cavity feature whose pressure is the IOP (or None).
    """

    section = "eye"
    name = None  # the report is the section itself

    def __init__(self, anterior, posterior, anterior_surface=None, posterior_surface=None, vitreous=None):
        self.points = (anterior, posterior)
        self.surfaces = (anterior_surface, posterior_surface)
        self.vitreous = vitreous
        self.extra = []  # functions adding measures (buckle height, retina gap, ...)

    def setup(self, solid):
        self.solid = solid
        self.ends = [MaterialNode(solid, p, s) for p, s in zip(self.points, self.surfaces)]
        self.initial_length = np.linalg.norm(self.ends[0].reference - self.ends[1].reference)
        msh = solid.mesh_data.mesh
        self.mises = fem.Function(fem.FunctionSpace(msh, ("DG", 0)))
        self._mises_expr = None  # built on first use: the materials may still change in setup
        self.num_cells = msh.topology.index_map(msh.topology.dim).size_local

    def report(self):
        length = float(np.linalg.norm(self.ends[0].position() - self.ends[1].position()))
        change = length - self.initial_length
        result = {"axial_length_mm": length, "axial_length_change_mm": change,
                  "refraction_change_D": DIOPTRES_PER_MM * change}
        if self.vitreous is not None:
            result["iop_mmHg"] = self.vitreous.report()["pressure"] * MMHG_PER_MPA
        if self._mises_expr is None:
            self._mises_expr = fem.Expression(self.solid.mises_expression(),
                                              self.mises.function_space.element.interpolation_points())
        self.mises.interpolate(self._mises_expr)
        values = self.mises.x.array
        comm = self.solid.comm
        result["max_mises_MPa"] = {}
        for region in sorted(self.solid.materials):
            cells = self.solid.mesh_data.cells(region)
            cells = cells[cells < self.num_cells]
            local = values[cells].max() if len(cells) else -np.inf
            result["max_mises_MPa"][region] = float(comm.allreduce(local, op=MPI.MAX))
        for measure in self.extra:
            result.update(measure())
        return result

"""The encircling band, tightened by the surgeon.

The surgeon shortens the band by a length Delta (the circumference reduction, in mm). We
give the band's region a rest state shortened along its circumference: the prescribed
deformation F_g = I + (lambda - 1) e_theta e_theta, lambda = 1 - Delta / C with C the
band's mean circumference, about an axis (the optic axis). Free, the band would shrink to
C - Delta; on the eye it squeezes the sclera through contact, and its tension follows.
The solid owns the rest state: the band asks it for the prestretch of its region
(``MixedSolid.prestretch``, the law ``materials.Prestretched``).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from .. import checks
from ..errors import SceneError
from ..mechanics.solid import MixedSolid
from .base import Feature


class BandTightening(Feature):
    """Shorten the rest length of a band region by ``reduction`` around an axis.

    Args:
        region: the band's volume group.
        reduction: circumference reduction (same length unit as the mesh), ramped.
        axis: direction of the axis through ``center`` (default: z through the origin).
    """

    section = "bands"

    def __init__(self, region: str, reduction: float, center: Sequence[float] = (0.0, 0.0, 0.0),
                 axis: Sequence[float] = (0.0, 0.0, 1.0), step: int = 0):
        reduction = checks.number(reduction, f"band {region!r}: reduction")
        if reduction < 0:
            raise SceneError(f"band {region!r}: reduction is how much the band's circumference is shortened; it must "
                             f"not be negative, got {reduction!r}")
        axis = np.array(checks.nonzero_vector(axis, f"band {region!r}: axis"))
        self.name = self.region = region
        self.reduction, self.step = reduction, step
        self.center = np.array(checks.vector(center, f"band {region!r}: center"))
        self.axis = axis / np.linalg.norm(axis)

    def setup(self, solid: MixedSolid) -> None:
        if self.region not in solid.materials:
            raise SceneError(f"band {self.region!r} is not a region of mesh {solid.mesh_data.source} "
                             f"(its regions: {sorted(solid.materials)})")
        msh = solid.mesh_data.mesh
        dx = solid.dx(solid.mesh_data.regions[self.region])
        axis = ufl.as_vector(self.axis)
        relative = solid.X - ufl.as_vector(self.center)
        radial = relative - ufl.dot(relative, axis) * axis
        radius = ufl.sqrt(ufl.dot(radial, radial))
        e_theta = ufl.cross(axis, radial) / radius
        volume = msh.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * dx)), op=MPI.SUM)
        mean_radius = msh.comm.allreduce(fem.assemble_scalar(fem.form(radius * dx)), op=MPI.SUM) / volume
        self.circumference = 2 * np.pi * mean_radius
        if not self.reduction < self.circumference:
            raise SceneError(f"band {self.region!r}: reduction {self.reduction} is not less than its "
                             f"circumference {self.circumference:.4g}")
        self.stretch = fem.Constant(msh, 1.0)
        F_g = ufl.Identity(3) + (self.stretch - 1) * ufl.outer(e_theta, e_theta)
        solid.prestretch(self.region, F_g)
        # current mean circumference and the band tension (1/2pi) integral of sigma_tt / r dv
        x = solid.X + solid.u
        current = x - ufl.as_vector(self.center)
        current_radial = current - ufl.dot(current, axis) * axis
        current_radius = ufl.sqrt(ufl.dot(current_radial, current_radial))
        self._radius_form = fem.form(current_radius * dx)
        self._volume = volume
        self._solid = solid

    def set_load_factor(self, factor: float) -> None:
        self.stretch.value = 1 - factor * self.reduction / self.circumference

    def report(self) -> dict:
        comm = self._solid.comm
        mean_radius = comm.allreduce(fem.assemble_scalar(self._radius_form), op=MPI.SUM) / self._volume
        return {"reduction": self.reduction, "rest_stretch": float(self.stretch.value),
                "circumference": 2 * np.pi * mean_radius, "initial_circumference": self.circumference}

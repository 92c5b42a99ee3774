"""What a surgeon asks of the eye after each step, written under "eye" in summary.json.

* ``axial_length_mm``: corneal apex to the posterior pole along the optic axis (the
  anterior corneal surface to the retina's inner surface, as optical biometry measures);
  ``axial_length_change_mm`` from the pre-operative eye, as the surgeon means it: the state
  after the step in which the vitreous is brought to its pressure (``pressurize``), so 0 after
  that step; before it (no pre-operative eye yet), from the unloaded mesh. The change from the
  mesh is always there too, ``axial_length_change_from_mesh_mm`` (the inflation included);
* ``refraction_change_D`` (and ``refraction_change_from_mesh_D``): the refractive change of
  that length change, the eye's optics unchanged (axial ametropia): an eye of refracting power
  P whose retina lies L' behind its second principal point sees sharply at the vergence
  R = n'/L' - P, so a length change from L_0 to L_1 changes the refraction by
  n' (1 / (L_1 - H') - 1 / (L_0 - H')), with n' = 1.336 (vitreous) and H' = 1.602 mm behind
  the corneal apex (Gullstrand's exact schematic eye: Atchison & Smith, Optics of the Human
  Eye, 2000, appendix 3). About -2.6 D per mm at 24 mm (1 mm longer: 2.5 to 3 D more myopic,
  ch. 17 there), -3.3 at 22 mm and -1.9 at 28: a long eye's change reads less per mm;
* ``iop_mmHg``: the vitreous pressure (1 MPa = 7500.62 mmHg);
* ``max_mises_MPa``: the largest von Mises stress (element midpoints) per tissue.

With a buckle (the name of its inner surface: "band_inner", "tire_inner" or "sponge_inner"):

* ``buckle_height_mm``: how deep the buckle indents the sclera. Over the nodes of the sclera's
  outer surface ("sclera_outer": in eyeball_fenicsx/meshing/builders/eye.py all of it is on the
  sphere about the origin, from the optic nerve to the limbus, so no node needs leaving out) the
  radial displacement u_r = |x| - |X| (outward positive); the height is the mean u_r of the nodes
  *around* the buckle minus the least u_r of the nodes *under* it. Seen from the origin, the
  buckle's inner surface covers a *footprint*: a range of polar angles, and a range of azimuths
  about its middle (all of them for an encircling band; the azimuths of its nodes, about the
  direction of their summed horizontal unit vectors). Under: the sclera's nodes in the footprint
  (reference positions); around: the sclera beside it, more than one buckle width away across the
  buckle and over the buckle's extent along it: in polar angle at the buckle's azimuths for a band
  or a circumferential tire (a footprint longer in azimuth than in the meridian), in azimuth
  within its polar range for a radial sponge (longer in the meridian; out to 90 degrees from its
  middle, and taken ring by ring: the sponge's footprint spans some 47 degrees of polar angle,
  over which the inflated globe's radius varies, so each node under it is compared with the sclera
  beside it at its own polar angle). The largest depth is the deepest point of the indentation,
  for any buckle; the mean beside it takes out what moves that part of the globe (its inflation by
  the IOP, its elongation). Zero in the reference state and under any uniform expansion of the
  globe. A globe that inflates unevenly reads a few hundredths of a mm without any indentation
  (-0.02 to -0.07 mm for the buckled eye's sclera at 15 mmHg: the thin equator bulges most), far
  below the 0.5 to 1.5 mm of a buckle (docs/published_figures.md, section 4).
* ``opposite_indentation_mm``, for a buckle over less than half of the azimuths (a segmental
  tire, a radial sponge): the same measure, footprint and sclera beside it turned by 180 degrees
  about the optic axis, diametrically opposite the buckle. A buckle indents the sclera under
  itself only, so the change of this measure over an operation stays a small fraction of that
  of ``buckle_height_mm``; the uneven inflation is in both. In a wedge model it reads the part
  of the turned footprint that the model holds (for a tire centred on a cut plane, the other cut
  plane's meridian: the middle of the turned footprint).

With a detachment (the retina's outer surface "retina_outer" and the choroid's inner surface
"choroid_inner", the two faces of the subretinal gap of eyeball_fenicsx/meshing/builders/eye.py):

* ``retina_gap_max_mm``: the largest gap, in the current configuration. The gap at a node of
  the retina is its distance from the tangent plane of the choroid at the choroid's nearest
  node, (x_retina - x_choroid) . n (n the choroid's outward unit normal there, the
  area-weighted mean of its facets' current normals; negative where the retina has passed
  the choroid). Unlike the distance between the two nodes it does not grow when the retina
  slides along the choroid; on the curved wall it errs by s^2 / 2R for a slide s (7e-3 mm
  for s = 0.4 mm, R = 11.5 mm). Nodes the two surfaces share (the detachment's rim) have
  gap 0. The choroid's nodes are gathered on every rank (a surface, not the mesh).
* ``detached_area_mm2``: the reference area of "retina_outer" where the gap, interpolated
  bilinearly from the nodes, exceeds ``DETACHED_GAP`` (integrated at 7 x 7 Gauss points per
  facet). It is the area *of the model*: a half model (a wedge) reports half of the eye's.
* ``retina_penetration_max_mm``: how far the retina has passed through the choroid beyond
  ``PENETRATION_TOLERANCE``: max(0, -min gap - PENETRATION_TOLERANCE) over the retina's nodes.
  Contact with the choroid keeps the gap at zero to far less than that (the augmented
  Lagrangian stops when its updates move no node by more than AUGMENT_DEPTH = 1e-3 of its
  element's thickness), so anything above 0 is a failure to report (contact that did not
  act, or a mesh too coarse for it), not attachment.
* ``penetrated_area_mm2``: the reference area of "retina_outer" where the gap is below
  ``-PENETRATION_TOLERANCE`` (as ``detached_area_mm2``). A retina through the choroid is not
  attached: the attached area is the detachment's area less the detached and the penetrated.
* ``reattached_fraction``: that attached area as a fraction of the initially detached area
  (the reference area of "retina_outer"), 1 - (detached + penetrated) / initial.
* ``subretinal_volume_mm3``: the volume between the two faces, -(1/3) integral of x . n over
  both in the current configuration (n their outward normals; a cut plane through the origin
  adds nothing, so a half model reports half of the eye's).

Data path: ``EyeMeasures`` observes the runs of a scene (output/observer.py): when the scene
is built it finds the measured nodes and builds its forms; after each step (the failed one too)
it measures the state into the step's entry of summary.json, under "eye", and keeps the von
Mises stress (``mises``) and the retina's gap (``retina_gap_map``) it measured, which the eye's
pictures then draw (``EyePictures``, output/eye_pictures.py).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import ufl
from dolfinx import fem, la
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc
from scipy.spatial import cKDTree

from ..errors import SceneError
from ..mechanics.solid import MaterialNode
from .observer import Observer

if TYPE_CHECKING:
    from ..features.cavity import LiquidCavity
    from ..mechanics.solid import MixedSolid
    from ..system.problem import Problem

MMHG_PER_MPA = 7500.62
VITREOUS_INDEX = 1.336  # n' of the reduced eye's image space
SECOND_PRINCIPAL_POINT_MM = 1.602  # H' behind the corneal apex (Gullstrand's exact eye)


def refraction_change(length_before: float, length_after: float) -> float:
    """The refraction change (D) of an axial length change (mm) at fixed optics (module docstring)."""
    return 1000.0 * VITREOUS_INDEX * (1.0 / (length_after - SECOND_PRINCIPAL_POINT_MM)
                                      - 1.0 / (length_before - SECOND_PRINCIPAL_POINT_MM))
# A retina more than this from the choroid is detached: a tenth of the 0.1 mm gaps of the
# detachments we model (a retina in contact with the choroid has a gap <= 0: the penetration).
DETACHED_GAP = 0.01
# A retina more than this through the choroid has penetrated it: the same resolution as
# DETACHED_GAP (the gap read in the choroid's tangent plane errs by s^2 / 2R, 7e-3 mm for a
# slide s = 0.4 mm), far above what contact leaves (see retina_penetration_max_mm).
PENETRATION_TOLERANCE = DETACHED_GAP


def ocular_rigidity(injected: list[float], iop: list[float], low: float = 15.0, high: float = 35.0) -> float:
    """Friedenwald's ocular rigidity K in ln(P2/P1) = K (V2 - V1): the least-squares slope of
    ln(IOP) against the injected volume over the states with ``low <= IOP <= high`` (mmHg), as
    Pallikaris et al. fitted living eyes over 10-35 mmHg (IOVS 2005;46:409). Natural logarithm;
    divide by ln 10 for Friedenwald's decimal one."""
    injected, iop = np.asarray(injected, dtype=float), np.asarray(iop, dtype=float)
    fitted = (iop >= low - 1e-6) & (iop <= high)
    if fitted.sum() < 2:
        raise ValueError(f"ocular rigidity: {fitted.sum()} state(s) between {low} and {high} mmHg, need two")
    return float(np.polyfit(injected[fitted], np.log(iop[fitted]), 1)[0])


def _turn(angle):
    """Angles (rad) brought to [-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(angle)))


def polar_angle(X: np.ndarray) -> np.ndarray:
    """Polar angle (rad) of points seen from the origin, from the posterior pole (-z)."""
    return np.arccos(np.clip(-X[:, 2] / np.linalg.norm(X, axis=1), -1.0, 1.0))


class EyeMeasures(Observer):
    """Eye measures of the current state.

    Args:
        anterior, posterior: reference points near the corneal apex and the posterior pole
            (the nearest nodes of ``anterior_surface`` / ``posterior_surface`` are used).
        vitreous: the cavity feature whose pressure is the IOP (or None).
        buckle: the buckle's inner surface, for ``buckle_height_mm`` on ``sclera`` (or None).
        retina, choroid: the two faces of a detachment's subretinal gap, for
            ``retina_gap_max_mm`` and ``detached_area_mm2`` (both or neither).
    """

    def __init__(self, anterior: list[float], posterior: list[float], anterior_surface: str | None = None,
                 posterior_surface: str | None = None, vitreous: LiquidCavity | None = None,
                 buckle: str | None = None, sclera: str = "sclera_outer", retina: str | None = None,
                 choroid: str | None = None) -> None:
        self.points = (anterior, posterior)
        self.surfaces = (anterior_surface, posterior_surface)
        self.vitreous = vitreous
        if (retina is None) != (choroid is None):
            raise SceneError("give both retina and choroid (the faces of the subretinal gap), or neither")
        self.buckle, self.sclera, self.retina, self.choroid = buckle, sclera, retina, choroid
        self.extra: list[Callable[[], dict]] = []  # functions adding measures
        if buckle is not None:
            self.extra.append(self._buckle_height)
        if retina is not None:
            self.extra.append(self._detachment)

    def setup(self, solid: MixedSolid, problem: Problem | None = None) -> None:
        """Find the measured nodes of ``solid`` and build the measures' forms (collective); the
        measures read the solid only (and the ``vitreous``), not ``problem``."""
        self.solid = solid
        self.ends = [MaterialNode(solid, p, s) for p, s in zip(self.points, self.surfaces)]
        self.initial_length = np.linalg.norm(self.ends[0].reference - self.ends[1].reference)
        if self.initial_length == 0.0:
            raise SceneError(f"[eye]: anterior {list(self.points[0])} and posterior {list(self.points[1])} pick "
                             f"the same node {list(self.ends[0].reference)}, so the axial length would be 0: give "
                             "points near the corneal apex and the posterior pole")
        self.preoperative_length = None  # the length after the vitreous' pressurize step
        filled = self.vitreous is not None and self.vitreous.pressurize
        self.preoperative_step = self.vitreous.step if filled else None
        self.step_index = -1
        self.retina_gap = None  # the gap at the retina's owned nodes, as last measured
        msh = solid.mesh_data.mesh
        self.mises = fem.Function(fem.FunctionSpace(msh, ("DG", 0)))
        points = self.mises.function_space.element.interpolation_points()
        self._mises_expr = fem.Expression(solid.mises_expression(), points)
        self.num_cells = msh.topology.index_map(msh.topology.dim).size_local
        if self.buckle is not None or self.retina is not None:
            self._setup_nodal(solid)

    def _setup_nodal(self, solid):
        """Nodal displacements (a P1 interpolant of u) and the surfaces' nodes."""
        md = solid.mesh_data
        self.V = fem.VectorFunctionSpace(md.mesh, ("Lagrange", 1))
        self.owned = self.V.dofmap.index_map.size_local
        self.displacement = fem.Function(self.V)
        self._u_expr = fem.Expression(solid.u, self.V.element.interpolation_points())
        self.X = self.V.tabulate_dof_coordinates()[: self.owned]
        comm = solid.comm
        if self.buckle is not None:
            self._setup_footprint(comm)
        if self.retina is not None:
            self.retina_nodes = self._surface_nodes(self.retina)
            self.choroid_nodes = self._surface_nodes(self.choroid)
            v = ufl.TestFunction(self.V)
            self._normals = fem.form(ufl.inner(solid.current_normal_area(), v) * solid.ds(md.surfaces[self.choroid]))
            self.gap = fem.Function(self.V)  # its x component: the gap at the retina's nodes
            ds = ufl.Measure("ds", domain=md.mesh, subdomain_data=md.facet_tags,
                             subdomain_id=md.surfaces[self.retina], metadata={"quadrature_degree": 12})
            self._detached = fem.form(ufl.conditional(ufl.gt(self.gap[0], DETACHED_GAP), 1.0, 0.0) * ds)
            self._penetrated = fem.form(ufl.conditional(ufl.lt(self.gap[0], -PENETRATION_TOLERANCE), 1.0, 0.0) * ds)
            x = solid.X + solid.u
            faces = solid.ds((md.surfaces[self.retina], md.surfaces[self.choroid]))
            self._subretinal_volume = fem.form(-ufl.inner(x, solid.current_normal_area()) / 3 * faces)
            self.detachment_area = solid.comm.allreduce(fem.assemble_scalar(fem.form(1.0 * ds)), op=MPI.SUM)

    def _surface_nodes(self, surface):
        """The owned nodes (blocks of V) of a surface, wherever its facets are (collective)."""
        tdim = self.solid.mesh_data.mesh.topology.dim
        marker = fem.Function(self.V)
        nodes = fem.locate_dofs_topological(self.V, tdim - 1, self.solid.mesh_data.facets(surface))
        marker.x.array.reshape(-1, 3)[nodes, 0] = 1.0
        marker.x.scatter_reverse(la.ScatterMode.add)  # a ghost facet's nodes reach their owners
        return np.flatnonzero(marker.x.array.reshape(-1, 3)[: self.owned, 0] > 0)

    def _positions(self):
        """Current positions of the owned nodes."""
        self.displacement.interpolate(self._u_expr)
        return self.X + self.displacement.x.array.reshape(-1, 3)[: self.owned]

    def _setup_footprint(self, comm):
        """The sclera's nodes under the buckle, around it and opposite it (module docstring)."""
        buckle = self.X[self._surface_nodes(self.buckle)]
        polar = polar_angle(buckle)
        lo = comm.allreduce(polar.min() if len(polar) else np.inf, op=MPI.MIN)
        hi = comm.allreduce(polar.max() if len(polar) else -np.inf, op=MPI.MAX)
        horizontal = buckle[:, :2] / np.linalg.norm(buckle[:, :2], axis=1)[:, None]
        summed = comm.allreduce(horizontal.sum(axis=0), op=MPI.SUM)
        count = comm.allreduce(len(buckle), op=MPI.SUM)
        middle = math.atan2(summed[1], summed[0])
        half = comm.allreduce(np.abs(_turn(np.arctan2(buckle[:, 1], buckle[:, 0]) - middle)).max(initial=0.0),
                              op=MPI.MAX)
        if np.linalg.norm(summed) < 1e-6 * count:  # a whole ring
            half = math.pi
        self.sclera_nodes = self._surface_nodes(self.sclera)
        X = self.X[self.sclera_nodes]
        polar, azimuth = polar_angle(X), np.arctan2(X[:, 1], X[:, 0])
        in_polar = (polar >= lo - 1e-9) & (polar <= hi + 1e-9)
        along_meridian = 2 * half * math.sin(0.5 * (lo + hi)) < hi - lo  # a radial sponge

        def footprint(at):
            """The sclera's nodes under the footprint turned to the azimuth ``at``, and around it. A
            node on a bound (the mesh puts nodes exactly 90 degrees from a buckle at a node azimuth)
            is in or out by 1e-9 rad, not by the round-off of ``at``, which the partition decides."""
            away = np.abs(_turn(azimuth - at))
            if along_meridian:  # beside it, a width away in azimuth, on its side of the eye
                return (in_polar & (away <= half + 1e-9),
                        in_polar & (away > 3 * half + 1e-9) & (away < 0.5 * math.pi - 1e-9))
            # a width away in the meridian, at its azimuths
            beside = (polar < 2 * lo - hi - 1e-9) | (polar > 2 * hi - lo + 1e-9)
            return in_polar & (away <= half + 1e-9), beside & (away <= half + 1e-9)

        # the sclera beside a sponge is compared ring by ring (its footprint spans some 47 degrees of
        # polar angle, over which the inflated globe's radius varies); beside a band or tire, as one
        rings = np.round(polar, 6) if along_meridian else np.zeros(len(polar))
        keys = np.unique(np.concatenate(comm.allgather(np.unique(rings))))
        self.rings, self.num_rings = np.searchsorted(keys, rings), len(keys)
        self.footprints = {"buckle_height_mm": footprint(middle)}
        under, around = (comm.allreduce(int(m.sum()), op=MPI.SUM) for m in self.footprints["buckle_height_mm"])
        if not under or not around:
            raise SceneError(f"[eye]: {self.sclera!r} has {under} node(s) under the buckle {self.buckle!r} "
                             f"(polar angles {np.degrees(lo):.1f} to {np.degrees(hi):.1f} deg from the "
                             f"posterior pole) and {around} around it: is the buckle on that surface?")
        if half < 0.5 * math.pi - 1e-9:
            opposite = footprint(middle + math.pi)
            if all(comm.allreduce(int(m.sum()), op=MPI.SUM) for m in opposite):  # not in a wedge that lacks it
                self.footprints["opposite_indentation_mm"] = opposite

    def _buckle_height(self):
        X = self.X[self.sclera_nodes]
        radial = np.linalg.norm(self._positions()[self.sclera_nodes], axis=1) - np.linalg.norm(X, axis=1)
        comm = self.solid.comm
        result = {}
        for key, (under, around) in self.footprints.items():
            sums = np.zeros((2, self.num_rings))
            np.add.at(sums[0], self.rings[around], radial[around])
            np.add.at(sums[1], self.rings[around], 1.0)
            sums = comm.allreduce(sums, op=MPI.SUM)
            beside = sums[0] / np.maximum(sums[1], 1.0)  # the mean u_r beside the buckle, per ring
            depth = (beside[self.rings] - radial)[under & (sums[1][self.rings] > 0)]
            result[key] = float(comm.allreduce(depth.max() if len(depth) else -np.inf, op=MPI.MAX))
        return result

    def _detachment(self):
        x = self._positions()
        b = assemble_vector(self._normals)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        normals = b.array_r.reshape(-1, 3)[self.choroid_nodes]
        b.destroy()
        comm = self.solid.comm
        choroid = comm.allgather((x[self.choroid_nodes], normals / np.linalg.norm(normals, axis=1)[:, None]))
        xc, nc = (np.concatenate([c[k] for c in choroid]) for k in (0, 1))
        xr = x[self.retina_nodes]
        _, nearest = cKDTree(xc).query(xr)
        gap = np.einsum("ij,ij->i", xr - xc[nearest], nc[nearest])
        self.gap.x.array[:] = 0.0
        self.gap.x.array.reshape(-1, 3)[self.retina_nodes, 0] = gap
        self.gap.x.scatter_forward()
        self.retina_gap = gap
        depth = comm.allreduce(-gap.min() if len(gap) else -np.inf, op=MPI.MAX)
        detached = comm.allreduce(fem.assemble_scalar(self._detached), op=MPI.SUM)
        penetrated = comm.allreduce(fem.assemble_scalar(self._penetrated), op=MPI.SUM)
        result = {"retina_gap_max_mm": float(comm.allreduce(gap.max() if len(gap) else -np.inf, op=MPI.MAX)),
                  "detached_area_mm2": float(detached),
                  "retina_penetration_max_mm": float(max(depth - PENETRATION_TOLERANCE, 0.0)),
                  "penetrated_area_mm2": float(penetrated)}
        result["reattached_fraction"] = float(1 - (detached + penetrated) / self.detachment_area)
        subretinal = comm.allreduce(fem.assemble_scalar(self._subretinal_volume), op=MPI.SUM)
        result["subretinal_volume_mm3"] = float(subretinal)
        return result

    def retina_gap_map(self, root: int = 0) -> tuple:
        """Collective. On rank ``root``, (reference positions, gap) of the retina's nodes as last
        measured; (None, None) elsewhere or without a detachment."""
        if self.retina_gap is None:
            return None, None
        gathered = self.solid.comm.gather((self.X[self.retina_nodes], self.retina_gap), root=root)
        if self.solid.comm.rank != root:
            return None, None
        return np.concatenate([g[0] for g in gathered]), np.concatenate([g[1] for g in gathered])

    def report(self) -> dict:
        """Collective: the eye measures of the current state (``step_index`` the step it ends)."""
        length = float(np.linalg.norm(self.ends[0].position() - self.ends[1].position()))
        if self.step_index == self.preoperative_step:
            self.preoperative_length = length
        before = self.initial_length if self.preoperative_length is None else self.preoperative_length
        result = {"axial_length_mm": length, "axial_length_change_mm": length - before,
                  "refraction_change_D": refraction_change(before, length),
                  "axial_length_change_from_mesh_mm": length - self.initial_length,
                  "refraction_change_from_mesh_D": refraction_change(self.initial_length, length)}
        if self.vitreous is not None:
            result["iop_mmHg"] = self.vitreous.report()["pressure"] * MMHG_PER_MPA
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

    # -- a checkpoint (output/checkpoint.py) ---------------------------------------------------
    def checkpoint_state(self) -> dict:
        """The pre-operative length (None until its step is done) and the last step measured."""
        return {"preoperative_length": self.preoperative_length, "step_index": self.step_index}

    def restore_state(self, state: dict) -> None:
        self.preoperative_length, self.step_index = state["preoperative_length"], state["step_index"]

    # -- observing the runs (output/observer.py) ----------------------------------------------
    def after_step(self, step: str, index: int, entry: dict, converged: bool) -> None:
        self.step_index = index
        entry["eye"] = self.report()

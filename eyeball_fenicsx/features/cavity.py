"""Static liquid in a closed cavity: the seed's solid-liquid coupling.

The liquid's law is p = p_ini - K (V - V_ini - dV_inj) / V_ini, with the enclosed volume

    V(u) = -(1/3) integral over the wetted surface of x . n da   (n: the solid's outward normal)

in the current configuration. Both p_ini and the injected volume dV_inj ramp with the load
factor in the cavity's step, so the reference mesh is stress-free and the first step brings
the eye to its pressure. The liquid loads its walls by -p V' (a UFL term).

The seed's *new algorithm* (default, ``BorderedCavity``): p is one extra global unknown. Its
equation comes with the solid from one potential

    Pi(u, p) = Pi_solid(u) - p (V(u) - V_ini - dV_inj) - V_ini (p - p_ini)^2 / (2 K),

so the Newton matrix is the symmetric bordered one [[K - p V'', -V'], [-V'^T, -V_ini/K]]: one
sparse column and row over the wetted dofs, and it stays regular as K -> infinity (a volume
constraint) and through a pressure maximum under volume control.

The seed's *previous algorithm* (``algorithm="previous"``, ``CondensedCavity``, for comparison
only): p = p(u) is eliminated, and the tangent gains the dense block (K / V_ini) V' V'^T over
all wetted dofs.

A retinal break (``break_into``): the subretinal space is a cavity of its own that
communicates with the vitreous through the break until the buckle closes it. While the break
is open the two are one liquid: the vitreous' pressure acts on both, and its law holds for the
sum of their volumes (its border row and column take the subretinal wall's V' too); the
subretinal unknown is idle (its row is p_s = 0). When the break closes, at the start of step
``break_closes``, each keeps the liquid it holds: both laws restart from the current state
(p_base = p, V_ref = V), the subretinal one with its own pressure unknown.

Liquid added or removed in a later step is the cavity's to account for: it takes an
``Injection`` or a ``Drainage`` by ``add_injection`` or ``add_drainage`` and reads their ramps.
A drainage removes a fraction of the liquid a cavity holds when its step starts, by volume:
under the vitreous' pressure the floating retina has almost no stiffness of its own (a pressure
drop of about 0.02 mmHg would carry it across a 0.3 mm gap), so lowering the subretinal pressure
would snap it onto the choroid, while taking the liquid out moves it there smoothly. All of it
cannot go: with the retina on the choroid everywhere the volume and the contact would fix the
same motion.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem.petsc import assemble_vector
from mpi4py import MPI
from petsc4py import PETSc

from .. import checks
from ..errors import SceneError
from ..mechanics.solid import MixedSolid
from .base import AXES, Feature
from .closed_surface import check_closed


class LiquidCavity(Feature):
    """A closed cavity of static liquid wetting ``surface``: what both algorithms share.

    Args:
        name: the cavity's name in summary.json.
        surface: the solid's wetted surface: a surface group name, or a list of them (a
            vitreous that communicates through a retinal break with the subretinal space
            wets ["vitreous_wall", "retina_outer", "choroid_inner"]).
        bulk_modulus: K of the liquid (> 0; ``math.inf`` makes it incompressible).
        initial_pressure: p_ini, the pressure in the reference state.
        injected_volume: liquid volume added in the cavity's step (negative: removed).
        symmetry: names of the planes x=0, y=0, z=0 that close an open surface.
        algorithm: "new" (bordered, one global unknown: ``BorderedCavity``) or "previous"
            (dense tangent: ``CondensedCavity``); ``LiquidCavity(...)`` makes the one named.
        pressurize: bring the cavity to ``initial_pressure`` in its step by filling it (the
            pressure is prescribed, the liquid fills what it takes); the liquid law then holds
            about the filled state. For a stress-free mesh of an eye that is at its IOP.

    ``connect_break(host, closes)`` makes it a subretinal space that communicates with
    ``host`` until step ``closes`` (None: open throughout).
    """

    section = "cavities"
    # The bordered system is symmetric (one potential), but MUMPS's LDL^T fills it in about
    # twice as much as the solid alone (benchmarks/liquid_coupling.py), while LU pays +1%:
    # it stays on LU.
    symmetric_tangent = False
    algorithm: str | None = None  # the seed's name of a subclass's algorithm

    def __new__(cls, *args, algorithm: str = "new", **kwargs):
        if cls is LiquidCavity:  # the algorithm named; an unknown name stays here, and __init__ says so
            cls = ALGORITHMS.get(algorithm, cls)
        return super().__new__(cls)

    def __init__(self, name: str, surface: str | Sequence[str], bulk_modulus: float, initial_pressure: float = 0.0,
                 injected_volume: float = 0.0, symmetry: Sequence[str] = (), step: int = 0, *,
                 algorithm: str | None = None, pressurize: bool = False):
        what = f"cavity {name!r}: "
        K = bulk_modulus if bulk_modulus == math.inf else checks.number(bulk_modulus, what + "bulk_modulus", "positive")
        p_ini = checks.number(initial_pressure, what + "initial_pressure")
        dV_inj = checks.number(injected_volume, what + "injected_volume")
        unknown = sorted(set(symmetry) - set(AXES))
        if unknown:
            raise SceneError(f"{what}symmetry planes must be among 'x', 'y', 'z', got {unknown}")
        if self.algorithm is None:
            raise SceneError(f"{what}algorithm must be one of {sorted(ALGORITHMS)}, got {algorithm!r}")
        if algorithm not in (None, self.algorithm):
            raise SceneError(f"{what}{type(self).__name__} is the {self.algorithm!r} algorithm, got {algorithm!r}")
        if pressurize and injected_volume:
            raise SceneError(f"{what}pressurize fills the cavity to its initial_pressure; give no injected_volume "
                             "with it (use an injection in a later step)")
        surfaces = [surface] if isinstance(surface, str) else list(surface)
        if not surfaces or not all(isinstance(s, str) and s for s in surfaces):
            raise SceneError(f"{what}surface must be a surface group name or a non-empty list of them, got {surface!r}")
        if len(set(surfaces)) < len(surfaces):
            raise SceneError(f"{what}surface lists a surface group twice: {surfaces}")
        self.name, self.step = name, step
        self.surfaces = surfaces
        self.surface = surface
        self.pressurize, self.filling = pressurize, False
        self.K, self.p_ini, self.dV_inj = float(K), p_ini, dV_inj
        self.symmetry = [AXES[s] for s in symmetry]
        self.factor = 0.0
        self.injections = []  # the Injections it took (add_injection)
        self.drainage, self.drainage_volume = None, 0.0  # the Drainage it took, and its change (set in its step)
        self.host, self.guests, self.break_closes = None, [], None  # a retinal break, see connect_break
        self.break_open = False
        self.step_index = -1
        self.p_base = None  # the pressure the liquid law restarts from (None: factor * p_ini)
        self.injected_base = 0.0
        self.filled_volume = 0.0

    # -- what the scene connects ---------------------------------------------------------
    def connect_break(self, host: LiquidCavity, closes: int | None = None) -> None:
        """Communicate with ``host`` (the vitreous) through a break until step ``closes``."""
        if host is self or host.host is not None or self.guests:
            raise SceneError(f"cavity {self.name!r}: break_into must name another cavity that has no break itself")
        if "previous" in (self.algorithm, host.algorithm):
            raise SceneError(f"cavity {self.name!r}: a break joins two cavities of the new algorithm (one pressure "
                             "unknown each)")
        if self.pressurize or self.dV_inj or self.p_ini:
            raise SceneError(f"cavity {self.name!r}: with break_into it fills with {host.name!r}; give it no "
                             "initial_pressure, injected_volume or pressurize")
        if closes is not None and closes <= host.step:
            raise SceneError(f"cavity {self.name!r}: break_closes must be a step after {host.name!r}'s (the break "
                             "closes once the eye is at its pressure)")
        self.host, self.break_closes, self.break_open = host, closes, True
        host.guests.append(self)

    def break_open_in(self, step_index: int) -> bool:
        """The break (if any) is open in step ``step_index``: the liquid is the host's."""
        return self.host is not None and (self.break_closes is None or step_index < self.break_closes)

    def add_injection(self, injection) -> int:
        """Take an ``Injection`` (its ``volume`` ramps with its ``factor`` in its ``step``) into the
        liquid law; returns its number among this cavity's injections."""
        if self.break_open_in(injection.step):
            raise SceneError(f"injection into {self.name!r}: its break is open in that step; inject into "
                             f"{self.host.name!r}, or after the break closes")
        self.injections.append(injection)
        return len(self.injections)

    def add_drainage(self, drainage) -> None:
        """Take a ``Drainage``: when its step starts, its ``fraction`` of the liquid this cavity
        holds then is to leave, ramped with its ``factor``."""
        if self.break_open_in(drainage.step):
            raise SceneError(f"drainage of {self.name!r}: its break is still open in that step (draining it "
                             f"would drain {self.host.name!r} too); close the break first (break_closes)")
        if self.drainage is not None or drainage.step == 0 or (self.pressurize and drainage.step <= self.step):
            raise SceneError(f"drainage of {self.name!r}: drain a cavity once, in a step after it is filled "
                             "(not the first)")
        self.drainage = drainage

    # -- the liquid ----------------------------------------------------------------------
    def setup(self, solid: MixedSolid) -> None:
        self.solid = solid
        msh = solid.mesh_data.mesh
        missing = [s for s in self.surfaces if s not in solid.mesh_data.surfaces]
        if missing:
            raise SceneError(f"cavity {self.name!r}: surface {missing[0]!r} is not a surface group of mesh "
                             f"{solid.mesh_data.source} (its surfaces: {sorted(solid.mesh_data.surfaces)})")
        check_closed(solid, self.surfaces, self.symmetry, self.name)
        x = solid.X + solid.u
        tags = tuple(solid.mesh_data.surfaces[s] for s in self.surfaces)
        volume = -ufl.inner(x, solid.current_normal_area()) / 3 * solid.ds(tags)
        self.volume_form = fem.form(volume)
        self._dV = ufl.derivative(volume, solid.w, ufl.TestFunction(solid.W))
        self.dV_form = fem.form(self._dV)
        self.pressure = fem.Constant(msh, 0.0)
        self.V_ini = self.V_ref = self.volume()
        if not self.V_ini > 0:
            raise SceneError(f"cavity {self.name!r}: the volume enclosed by {self.surface!r} is {self.V_ini:.4g}, "
                             "not positive: check the symmetry planes and that the surface faces the liquid")
        owned = solid.num_owned
        self.wetted = np.unique(np.concatenate([d[d < owned] for s in self.surfaces for d in solid.surface_dofs(s)]))
        self.dV = fem.petsc.create_vector(self.dV_form)

    def residual(self, solid: MixedSolid) -> ufl.Form:
        """The liquid's load -p V'; through an open break, the host's pressure."""
        if self.host is None:
            return -self.pressure * self._dV
        self.open = fem.Constant(solid.mesh_data.mesh, 1.0)  # 1 while the break is open
        return -(self.open * self.host.pressure + (1 - self.open) * self.pressure) * self._dV

    def set_load_factor(self, factor: float) -> None:
        self.factor = factor

    def begin_step(self, step_index: int) -> None:
        if self.step_index < 0:  # the first step: the liquid law covers the guests' walls too
            self.V_ref = self.initial_liquid = self.V_ini + sum(g.V_ini for g in self.guests)
        self.step_index = step_index
        if self.pressurize and step_index == self.step:
            self.filling = True
        elif self.filling and step_index > self.step:  # filled: the liquid law from here on
            self.filling = False
            self.V_ref = self.liquid_volume()
            self.filled_volume = self.V_ref - self.initial_liquid
        if self.drainage is not None and step_index == self.drainage.step:
            self.drainage_volume = -self.drainage.fraction * self.liquid_volume()

    def _restart_law(self, pressure: float) -> None:
        """The liquid law from the current state on: p = pressure at the liquid it holds now."""
        self.p_base, self.injected_base = pressure, self.injected()
        self.V_ref = self.liquid_volume()

    def liquid_volume(self) -> float:
        """The volume the liquid law sees: this cavity's, and its guests' through open breaks."""
        return self.current_volume + sum(g.current_volume for g in self.guests if g.break_open)

    def volume(self) -> float:
        return self.solid.comm.allreduce(fem.assemble_scalar(self.volume_form), op=MPI.SUM)

    def injected(self) -> float:
        """Liquid volume added so far: this cavity's own, ramped in its step, and that of its
        later injections and drainage."""
        drained = self.drainage.factor * self.drainage_volume if self.drainage is not None else 0.0
        return self.factor * self.dV_inj + sum(i.factor * i.volume for i in self.injections) + drained

    def law(self, V: float) -> float:
        """Liquid pressure at volume V (at the current load factor); while filling or behind
        an open break, the prescribed pressure."""
        if self.filling:
            return self.factor * self.p_ini
        if self.break_open:
            return 0.0  # idle: the host's pressure acts on the walls
        base = self.factor * self.p_ini if self.p_base is None else self.p_base
        return base - self.K * (V - self.V_ref - self.injected() + self.injected_base) / self.V_ref

    def liquid_pressure(self) -> float:
        """The pressure of the liquid at the current state (each algorithm has its own)."""
        raise NotImplementedError

    def state_changed(self) -> None:
        self.current_volume = self.volume()
        self.pressure.value = self.liquid_pressure()

    def _volume_gradient(self) -> np.ndarray:
        """V' on the owned wetted dofs."""
        with self.dV.localForm() as local:
            local.set(0.0)
        assemble_vector(self.dV, self.dV_form)
        self.dV.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        return self.dV.array_r[self.wetted]

    def report(self) -> dict:
        p = self.host.liquid_pressure() if self.break_open else self.liquid_pressure()
        filled = self.liquid_volume() - self.initial_liquid if self.filling else self.filled_volume
        result = {"pressure": float(p), "volume": float(self.current_volume), "initial_volume": float(self.V_ini)}
        if self.host is None:
            result["injected_volume"] = float(filled + self.injected())
        else:
            result["break"] = "open" if self.break_open else "closed"
        if self.drainage is not None and self.step_index >= self.drainage.step:
            result["drained_volume"] = float(-self.drainage.factor * self.drainage_volume)
        return result

    # what the liquid law carries from step to step; a checkpoint's (output/checkpoint.py), with
    # the pressure unknown that the checkpoint keeps with the solution
    _carried = ("filling", "V_ref", "initial_liquid", "filled_volume", "p_base", "injected_base", "drainage_volume",
                "break_open", "step_index")

    def checkpoint_state(self) -> dict:
        return {name: getattr(self, name) for name in self._carried}

    def restore_state(self, state: dict) -> None:
        vars(self).update({name: state[name] for name in self._carried})
        if self.host is not None:  # the break's switch in the forms
            self.open.value = float(self.break_open)


class BorderedCavity(LiquidCavity):
    """The seed's new algorithm: the liquid's pressure is a global unknown that borders the
    Newton matrix (see the module docstring)."""

    algorithm = "new"
    num_unknowns = 1

    def setup(self, solid: MixedSolid) -> None:
        super().setup(solid)
        self.unknowns = np.zeros(1)

    def begin_step(self, step_index: int) -> None:
        super().begin_step(step_index)
        for guest in self.guests:  # the host decides, so that both restart from the same state
            if guest.break_open and not guest.break_open_in(step_index):
                guest.close_break(self.unknowns[0])
                self._restart_law(self.unknowns[0])

    def close_break(self, pressure: float) -> None:
        """The host closes the break: from here on this cavity keeps the liquid it holds, at
        ``pressure`` (the host's)."""
        self.break_open = False
        self.open.value = 0.0
        self.unknowns[0] = pressure
        self._restart_law(pressure)

    def liquid_pressure(self) -> float:
        return self.unknowns[0]

    def unknown_residuals(self) -> list[float]:
        """dPi/dp = -(V - V_ref - dV_inj) - V_ref (p - p_ini) / K (scaled alike while filling),
        V the volume of the liquid (with the guests' behind open breaks); behind an open break
        the idle row -V_ref p / K."""
        p = self.unknowns[0]
        return [(self.law(self.liquid_volume()) - p) * self.V_ref / self.K]

    def border(self) -> list[tuple]:
        """(owned wetted dofs, column dR_u/dp, row dR_p/du, dR_p/dp): through open breaks,
        the guests' walls too (a dof on both walls appears twice; the entries add)."""
        if self.break_open:  # idle: p_s = 0, and the host's pressure loads the walls
            return [(self.wetted, np.zeros(len(self.wetted)), np.zeros(len(self.wetted)), -self.V_ref / self.K)]
        walls = [self] + [g for g in self.guests if g.break_open]
        dofs = np.concatenate([c.wetted for c in walls])
        gradient = -np.concatenate([c._volume_gradient() for c in walls])
        row = np.zeros_like(gradient) if self.filling else gradient
        return [(dofs, gradient, row, -self.V_ref / self.K)]


class CondensedCavity(LiquidCavity):
    """The seed's previous algorithm: the pressure follows the liquid law p(V(u)), and the
    tangent gains the dense block (K / V_ref) V' V'^T over the wetted dofs."""

    algorithm = "previous"

    def liquid_pressure(self) -> float:
        return self.law(self.current_volume)

    def coupling(self) -> tuple[np.ndarray, np.ndarray]:
        rows = np.asarray(self._problem_globals(self.wetted))
        cols = np.concatenate(self.solid.comm.allgather(rows))
        return np.repeat(rows, len(cols)), np.tile(cols, len(rows))

    def add_to_jacobian(self, A: PETSc.Mat) -> None:
        if self.filling:  # the pressure is prescribed: no dependence on the volume
            return
        rows = self._problem_globals(self.wetted)
        gradient = self._volume_gradient()
        cols = np.concatenate(self.solid.comm.allgather(rows))
        all_gradient = np.concatenate(self.solid.comm.allgather(gradient))
        A.setValues(rows, cols, (self.K / self.V_ref) * np.outer(gradient, all_gradient),
                    addv=PETSc.InsertMode.ADD_VALUES)

    def _problem_globals(self, local: np.ndarray) -> np.ndarray:
        index_map = self.solid.W.dofmap.index_map
        return index_map.local_to_global(np.asarray(local, dtype=np.int32)).astype(PETSc.IntType)


ALGORITHMS = {c.algorithm: c for c in (BorderedCavity, CondensedCavity)}  # the seed's names


class Drainage(Feature):
    """The surgeon drains a cavity (the subretinal fluid, through a sclerotomy): over ``step``
    the liquid it holds when the step starts leaves it, all but ``1 - fraction`` of it."""

    def __init__(self, cavity: LiquidCavity, step: int, fraction: float = 0.98):
        what = f"drainage of {cavity.name!r}: drain_fraction"
        if not 0 < checks.number(fraction, what) < 1:
            raise SceneError(f"{what} must be a number in (0, 1) (the share of the liquid removed; all of it cannot "
                             f"go), got {fraction!r}")
        self.name = f"{cavity.name} drainage"
        self.step, self.factor, self.fraction = step, 0.0, float(fraction)
        cavity.add_drainage(self)

    def set_load_factor(self, factor: float) -> None:
        self.factor = factor


class Injection(Feature):
    """Liquid added to (negative: removed from) a cavity in a step of its own: a
    paracentesis, or volume-controlled inflation in stages."""

    def __init__(self, cavity: LiquidCavity, volume: float, step: int):
        self.volume = checks.number(volume, f"injection into {cavity.name!r}: volume")
        self.step, self.factor = step, 0.0
        self.name = f"{cavity.name} injection {cavity.add_injection(self)}"

    def set_load_factor(self, factor: float) -> None:
        self.factor = factor

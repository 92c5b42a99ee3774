"""Scene TOML files (the format fixed in the scene contract, plus our extensions).

Every problem with the file is a ``SceneError`` that says what is wrong, where (file and
table) and how to fix it; nothing is built before the whole file has been checked. Each
top-level key is read by one parser of the registry ``TABLES`` (solid_tables.py,
operation_tables.py), in the registry's order, which decides which error a file with several
reports; the mesh, the last, is built once the other tables have been checked, and the
surfaces and regions the tables name are then checked against it.

Extensions beyond the contract (documented in README.md):

* ``[mesh] builder = "block" | "sphere_octant"`` with the builder's parameters, instead of
  ``file``: the mesh is built in memory;
* ``[[step]]`` tables (``name``, ``increments``) and a ``step = "<name>"`` key on every load,
  cavity and contact: it ramps in that step and is held after it (default: the first step);
* ``[solver]``: ``increments``, ``max_cutbacks``, ``growth``, ``predictor``, ``element``, ``linear``;
* ``[[force]]`` with ``point`` instead of ``surface`` (the node nearest to the point);
* ``[[cavity]] algorithm = "new" | "previous"``, ``pressurize = true`` (fill the cavity to
  its ``initial_pressure`` in its step: the eye brought to its IOP) and ``surface`` as a list
  of surface groups (a liquid wetting several surfaces);
* ``[[cavity]] break_into = "<cavity>"``, ``break_closes = "<step>"``: a subretinal space
  that communicates with the vitreous through a retinal break until that step (one liquid,
  one pressure; then each its own); ``drain = "<step>"``: the surgeon drains the cavity in
  that step, removing ``drain_fraction`` (default 0.98) of the liquid it then holds;
* ``[[injection]]`` (``cavity``, ``volume``, ``step``): liquid added or removed in a step;
* ``tissues = "seed" | "calibrated"``: the eye's materials from a tissue set
  (eyeball_fenicsx/tissues/), which the scene's own ``[materials.<region>]`` tables override
  (an override of ``materials.<region>...`` reaches the set's table);
* ``[[contact]] smoothing`` (mm): the penalty law smoothed over that length (contact/law.py);
  ``symmetry`` (axes): the model's symmetry planes, where the master's normals lie in the plane;
  ``adjust`` (mm): a clearance in the mesh closed at the start (contact/pair.py);
* ``[[suture]]`` (``name``, ``first``, ``second``, ``tension`` or ``shortening``,
  ``stiffness``, ``first_surface``, ``second_surface``, ``anchored``, ``step``): an end given
  with its surface is the nearest point of that surface's elements (interpolated in the element
  there), one without the nearest mesh node;
* ``[[band]]`` (``region``, ``reduction``, ``center``, ``axis``, ``step``): band tightening;
* ``[eye]`` (``vitreous``, ``anterior``, ``posterior``, ``anterior_surface``,
  ``posterior_surface``): the eye measures written under "eye" in summary.json
  (eyeball_fenicsx/output/measures.py), and the pictures ``surface_<step>.png``,
  ``section_<step>.png`` and ``eye_measures.png`` in the output folder; optional measures, each only when its keys are
  given: ``buckle`` (the buckle's inner surface, "band_inner" or "tire_inner") with
  ``sclera`` (default "sclera_outer") for ``buckle_height_mm``, and ``retina`` and ``choroid``
  (the faces of the subretinal gap, "retina_outer" and "choroid_inner") for
  ``retina_gap_max_mm``, ``detached_area_mm2``, ``retina_penetration_max_mm`` and
  ``penetrated_area_mm2``;
* ``[mesh] builder = "eye" | "band" | "buckled_eye"`` (eyeball_fenicsx/meshing/builders/eye.py,
  band.py, buckled_eye.py);
* ``[buckle_sutures]`` (``count``, ``width``, ``azimuths``, ``bite``, ``tension`` or ``shortening``,
  ``stiffness``, ``step``): sutures generated from the buckled eye's geometry, each tying a
  sclera bite ``width / 2`` from the buckle's centre line, ``bite`` mm long, to the buckle's top
  edge; they are tied around the buckle, so they hold it both ways (``Suture(bilateral=True)``),
  and a loop tied by ``tension`` holds it at rest until its step (``stiffness``: the string's).
"""
import dataclasses
import os
import tomllib
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from mpi4py import MPI

from ..errors import SceneError
from ..output.report import RunReport
from . import operation_tables as operation
from . import solid_tables as solid
from .overrides import set_parameter
from .scene import Scene
from .tables import Reading, Table
from .tissues import tables_for

# every top-level key of a scene file and its parser, in the order they are read
TABLES: dict[str, Callable[[Reading], None]] = {
    "name": solid.read_name, "step": solid.read_step, "tissues": solid.read_tissues,
    "materials": solid.read_materials, "dirichlet": solid.read_dirichlet, "pressure": solid.read_pressure,
    "force": solid.read_force, "cavity": operation.read_cavity, "injection": operation.read_injection,
    "suture": operation.read_suture, "band": operation.read_band, "buckle_sutures": operation.read_buckle_sutures,
    "eye": operation.read_eye, "contact": operation.read_contact, "probe": solid.read_probe,
    "solver": solid.read_solver, "mesh": solid.read_mesh}


def load_scene(path: str, comm: MPI.Comm = MPI.COMM_WORLD, overrides: Mapping[str, Any] | None = None,
               linear: str | None = None) -> Scene:
    """Read and check a scene TOML file, load its mesh and return the Scene.

    Args:
        overrides: {dotted path: value} replacing entries of the file (``"mesh.n_circ"``),
            as a sweep does (overrides.py).
        linear: the linear solver (``[solver] linear``) instead of the file's, if given: the
            command line's ``--linear-solver``.
    """
    data = parsed_scene(path, overrides or {})
    for key, value in (overrides or {}).items():
        set_parameter(data, key, value)
    reading = Reading(path, data, comm, top=Table(data, path, TABLES))
    for read in TABLES.values():
        read(reading)
    _check_against_mesh(reading)
    if linear is not None:
        reading.settings = dataclasses.replace(reading.settings, linear=linear)
    return Scene(reading.name, reading.mesh, reading.materials, reading.features, reading.probes, reading.steps,
                 reading.settings, reading.element, observers=[*reading.observers, RunReport()])


def parsed_scene(path: str, parameters: Iterable[str] = ()) -> dict:
    """The scene file's TOML as a dict, where each of the dotted ``parameters`` can be found.

    A parameter ``materials.<region>....`` of a region the file leaves to its tissue set
    (``tissues = "calibrated"``) gets the set's table copied into the file's ``[materials]``,
    so that an override reaches the set's constants (tissues.tables_for).
    """
    if not os.path.isfile(path):
        raise SceneError(f"scene file {path} does not exist")
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise SceneError(f"{path}: not valid TOML: {error}") from None
    tables_for(data, parameters, path)
    return data


def _check_against_mesh(reading: Reading) -> None:
    """Every surface the tables name is a surface group of the mesh, every [materials.<region>]
    a volume group, and every volume group has a material."""
    mesh = reading.mesh
    for surface, where in reading.surfaces:
        if surface not in mesh.surfaces:
            raise SceneError(f"{where}: surface {surface!r} is not a surface group of mesh {mesh.source} "
                             f"(its surfaces: {sorted(mesh.surfaces)})")
    for region, (_, where) in reading.material_tables.items():
        if region not in mesh.regions:
            raise SceneError(f"{where}: {region!r} is not a volume group of mesh "
                             f"{mesh.source} (its regions: {sorted(mesh.regions)})")
    missing = sorted(set(mesh.regions) - set(reading.materials))
    if missing:
        raise SceneError(f"{reading.path}: no [materials.<region>] table for region(s) {missing} of mesh "
                         f"{mesh.source}: give every volume group of the mesh a material")

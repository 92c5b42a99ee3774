"""The parsers of a scene file's tables for the solid and its load path: the scene's name, the
``[[step]]`` tables, the materials (a tissue set and ``[materials.<region>]``), the supports and
loads (``[[dirichlet]]``, ``[[pressure]]``, ``[[force]]``), the ``[[probe]]`` points, the
``[solver]`` settings and the ``[mesh]``. Each reads its key of the file into the ``Reading``
(tables.py); the registry of loader.py calls them in the order of the file format.
"""
import os
from typing import Any

from mpi4py import MPI

from ..errors import SceneError
from ..features.loads import Dirichlet, NodalForce, Pressure
from ..mechanics.materials import FibreReinforced, LinearElastic, MooneyRivlin, NeoHooke
from ..mechanics.solid import ELEMENTS
from ..meshing.builders import band, block, buckled_eye, eye, sphere_octant
from ..meshing.load import MeshData, built_mesh, load_mesh
from ..system.settings import SolverSettings
from .scene import Step
from .tables import Reading, Table
from .tissues import tissue_set

BUILDERS = {"block": block.build_block, "sphere_octant": sphere_octant.build_sphere_octant,
            "eye": eye.build_eye, "band": band.build_band, "buckled_eye": buckled_eye.build_buckled_eye}
CELLS = {"Q": "hexahedra", "P": "tetrahedra"}  # the cells of an element, by its name's first letter


def read_name(reading: Reading) -> None:
    """``name``: the scene's name (default: the file's, without .toml)."""
    reading.name = reading.top.get("name", "string", default=os.path.splitext(os.path.basename(reading.path))[0])


def read_step(reading: Reading) -> None:
    """``[[step]]`` (``name``, ``increments``): the load path (default: one step "load")."""
    if reading.data.get("step") == []:
        raise SceneError(f"{reading.path}: step = [] gives no step: give [[step]] tables, or none for one step "
                         "'load'")
    reading.steps = [Step(t.get("name", "string", required=True), t.get("increments", "integer"))
                     for t in reading.array("step", {"name", "increments"})] or [Step("load")]
    names = [step.name for step in reading.steps]
    if len(set(names)) != len(names):
        raise SceneError(f"{reading.path}: [[step]] names must be unique, got {names}")


def read_tissues(reading: Reading) -> None:
    """``tissues = "<set>"``: the materials of a tissue set (tissues.py)."""
    reading.material_tables = tissue_set(reading.top.get("tissues", "string"), reading.path)


def read_materials(reading: Reading) -> None:
    """``[materials.<region>]``: a material law per volume group, over the tissue set's."""
    given = reading.data.get("materials", {})
    if not isinstance(given, dict):
        raise SceneError(f"{reading.path}: materials must be tables [materials.<region>]")
    tables = reading.material_tables
    tables.update({region: (t, f"{reading.path}: [materials.{region}]") for region, t in given.items()})
    if not tables:
        raise SceneError(f"{reading.path}: no [materials.<region>] table: give one per volume group of the mesh")
    reading.materials = {region: material_table(Table(t, where, t if isinstance(t, dict) else ()))
                         for region, (t, where) in tables.items()}  # keys are checked per model


def material_table(table: Table) -> MooneyRivlin | LinearElastic | FibreReinforced:
    """A [materials.<region>] table -> its material law."""
    model = table.get("model", "string", required=True)
    if model == "neo-hooke":
        Table(table.data, table.where, {"model", "c10"})
        law, arguments = NeoHooke, [table.get("c10", "positive", required=True)]
    elif model == "mooney-rivlin":
        Table(table.data, table.where, {"model", "c"})
        law, arguments = MooneyRivlin, [_coefficients(table)]
    elif model == "linear-elastic":
        Table(table.data, table.where, {"model", "E", "nu"})
        law, arguments = LinearElastic, [table.get("E", "positive", required=True),
                                         table.get("nu", "number", required=True)]
    elif model == "fibre-reinforced":
        Table(table.data, table.where, {"model", "c10", "k1", "k2", "fibre_angles_deg", "axis", "centre"})
        law = FibreReinforced
        arguments = [table.get(key, "positive", required=True) for key in ("c10", "k1", "k2")]
        arguments += [tuple(table.get("fibre_angles_deg", "numbers", [0.0, 90.0])),
                      tuple(table.get("axis", "vector", [0.0, 0.0, 1.0])),
                      tuple(table.get("centre", "vector", [0.0, 0.0, 0.0]))]
    else:
        raise table.error(f"unknown model {model!r}: choose neo-hooke, mooney-rivlin, linear-elastic or "
                          "fibre-reinforced")
    with table.located():  # the law's own checks: nu < 0.5, c10 + c01 > 0, ...
        return law(*arguments)


def _coefficients(table: Table) -> dict[tuple[int, int], Any]:
    """A Mooney-Rivlin table's ``c = { "rs" = c_rs }`` -> {(r, s): c_rs}."""
    c = table.get("c", None, required=True)
    if not isinstance(c, dict) or not c:
        raise table.error('c must be a table of coefficients, e.g. c = { "10" = 0.4, "01" = 0.1 }')
    coefficients = {}
    for key, value in c.items():
        if len(key) != 2 or not key.isdigit():
            raise table.error(f'coefficient names are two digits "rs" for (I1bar-3)^r (I2bar-3)^s, got {key!r}')
        coefficients[(int(key[0]), int(key[1]))] = value
    return coefficients


def read_dirichlet(reading: Reading) -> None:
    """``[[dirichlet]]`` (``surface``, ``x``, ``y``, ``z``, ``step``): prescribed displacements."""
    for t in reading.array("dirichlet", {"surface", "x", "y", "z", "step"}):
        surface = t.get("surface", "string", required=True)
        components = {c: t.get(c, "number") for c in "xyz" if t.has(c)}
        if not components:
            raise t.error("constrain at least one of x, y, z")
        reading.add(t, Dirichlet, surface, components, step=reading.step_of(t))
        reading.use(t, [surface])


def read_pressure(reading: Reading) -> None:
    """``[[pressure]]`` (``surface``, ``value``, ``step``): a follower pressure."""
    for t in reading.array("pressure", {"surface", "value", "step"}):
        surface = t.get("surface", "string", required=True)
        reading.add(t, Pressure, surface, t.get("value", "number", required=True), step=reading.step_of(t))
        reading.use(t, [surface])


def read_force(reading: Reading) -> None:
    """``[[force]]`` (``surface`` or ``point``, ``value``, ``step``): a force on nodes."""
    for t in reading.array("force", {"surface", "point", "value", "step"}):
        if t.has("surface") == t.has("point"):
            raise t.error("give exactly one of surface or point")
        surface = t.get("surface", "string")
        reading.add(t, NodalForce, t.get("value", "vector", required=True), surface=surface,
                    point=t.get("point", "vector"), step=reading.step_of(t))
        reading.use(t, [surface])


def read_probe(reading: Reading) -> None:
    """``[[probe]]`` (``name``, ``point``): displacements reported at points."""
    for t in reading.array("probe", {"name", "point"}):
        name = t.unique_name("probe", reading.probes)
        reading.probes[name] = t.get("point", "vector", required=True)


def read_solver(reading: Reading) -> None:
    """``[solver]``: ``increments``, ``max_cutbacks``, ``growth``, ``predictor``, ``element``, ``linear``."""
    t = reading.table("solver", {"increments", "max_cutbacks", "growth", "predictor", "element", "linear"})
    given = {key: t.get(key, kind) for key, kind in
             (("increments", "integer"), ("max_cutbacks", "integer"), ("growth", "positive"), ("predictor", "flag"),
              ("linear", "string"))}
    with t.located():  # the settings' own checks: growth >= 1, a known linear solver
        reading.settings = SolverSettings(**{key: value for key, value in given.items() if value is not None})
    reading.element = t.get("element", "string")
    if reading.element is not None and reading.element not in ELEMENTS:
        raise t.error(f"unknown element {reading.element!r}: choose one of {sorted(ELEMENTS)}")


def read_mesh(reading: Reading) -> None:
    """``[mesh]``: ``file`` (relative to the scene file), or ``builder`` and its parameters. The
    mesh is built here, the last table read: once every other table has been checked."""
    mesh = reading.data.get("mesh")
    if not isinstance(mesh, dict) or not mesh:
        given = "no [mesh] table" if mesh is None else "[mesh] is empty" if mesh == {} else \
            f"mesh = {mesh!r} is not a table"
        raise SceneError(f"{reading.path}: {given}: give [mesh] file = \"<mesh>.msh\" (relative to the scene file) "
                         "or [mesh] builder = ...")
    if "graded" in mesh:  # the sutures' grading (read by [buckle_sutures]), not the builder's
        if reading.graded is None:
            raise SceneError(f"{reading.path}: [mesh]: graded refines the eye around the sutures' bites: it needs "
                             "[buckle_sutures]")
        mesh = {k: v for k, v in mesh.items() if k != "graded"}
    for key, lines in (reading.graded or {}).items():  # with the scene's own lines, if it gives them
        given = mesh.get(key, [])  # (the span of graded_between, the scene's if it gives one, [] too)
        merged = [*given, *lines] if key != "graded_between" else given if key in mesh else lines
        mesh = {**mesh, key: merged if isinstance(given, list) else given}
    table = Table(mesh, f"{reading.path}: [mesh]", set(mesh))  # keys are checked per mesh source
    reading.mesh = mesh_table(table, os.path.dirname(os.path.abspath(reading.path)), reading.comm)
    cells = {"hexahedron": "hexahedra", "tetrahedron": "tetrahedra"}[reading.mesh.mesh.ufl_cell().cellname()]
    if reading.element is not None and CELLS[reading.element[0]] != cells:
        suited = sorted(name for name in ELEMENTS if CELLS[name[0]] == cells)
        raise SceneError(f"{reading.path}: [solver]: element {reading.element!r} is for {CELLS[reading.element[0]]}, "
                         f"but mesh {reading.mesh.source} has {cells}: choose one of {suited}")


def mesh_table(table: Table, directory: str, comm: MPI.Comm) -> MeshData:
    """A [mesh] table -> the mesh, read from its file or built by its builder."""
    if table.has("file"):
        Table(table.data, table.where, {"file"})
        given = table.get("file", "string")
        path = os.path.join(directory, given)
        if not os.path.isfile(path):
            raise table.error(f"file = {given!r}: {path} does not exist (the path is relative to the scene file)")
        with table.located():  # the mesh's own checks: gmsh reads it, named groups, supported elements
            return load_mesh(path, comm)
    builder = table.get("builder", "string", required=False)
    if builder not in BUILDERS:
        raise table.error(f"give file = \"<mesh>.msh\" or builder = one of {sorted(BUILDERS)}")
    options = {k: v for k, v in table.data.items() if k != "builder"}
    with table.located():  # the builder's own checks of its parameters
        return built_mesh(BUILDERS[builder], comm, **options)

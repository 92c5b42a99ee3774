"""Scene TOML files (the format fixed in the scene contract, plus our extensions).

Every problem with the file is a ``SceneError`` that says what is wrong, where (file and
table) and how to fix it; nothing is built before the whole file has been checked.

Extensions beyond the contract (documented in README.md):

* ``[mesh] builder = "block" | "sphere_octant"`` with the builder's parameters, instead of
  ``file``: the mesh is built in memory;
* ``[[step]]`` tables (``name``, ``increments``) and a ``step = "<name>"`` key on every load,
  cavity and contact: it ramps in that step and is held after it (default: the first step);
* ``[solver]``: ``increments``, ``max_cutbacks``, ``growth``, ``predictor``, ``element``;
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
  (eyeball_fenicsx/tissues/), which the scene's own ``[materials.<region>]`` tables override;
* ``[[contact]] smoothing`` (mm): the penalty law smoothed over that length (contact/law.py);
  ``symmetry`` (axes): the model's symmetry planes, where the master's normals lie in the plane;
* ``[[suture]]`` (``name``, ``first``, ``second``, ``tension`` or ``shortening``,
  ``stiffness``, ``first_surface``, ``second_surface``, ``anchored``, ``step``);
* ``[[band]]`` (``region``, ``reduction``, ``center``, ``axis``, ``step``): band tightening;
* ``[eye]`` (``vitreous``, ``anterior``, ``posterior``, ``anterior_surface``,
  ``posterior_surface``): the eye measures written under "eye" in summary.json
  (eyeball_fenicsx/measures.py), and the pictures ``section_<step>.png`` and
  ``eye_measures.png`` in the output folder; optional measures, each only when its keys are
  given: ``buckle`` (the buckle's inner surface, "band_inner" or "tire_inner") with
  ``sclera`` (default "sclera_outer") for ``buckle_height_mm``, and ``retina`` and ``choroid``
  (the faces of the subretinal gap, "retina_outer" and "choroid_inner") for
  ``retina_gap_max_mm``, ``detached_area_mm2``, ``retina_penetration_max_mm`` and
  ``penetrated_area_mm2``;
* ``[mesh] builder = "eye" | "band" | "buckled_eye"`` (eyeball_fenicsx/meshing/builders/eye.py, band.py, buckled_eye.py);
* ``[buckle_sutures]`` (``count``, ``width``, ``azimuths``, ``tension`` or ``shortening``,
  ``stiffness``, ``step``): sutures generated from the buckled eye's geometry, each tying a
  sclera bite ``width / 2`` from the buckle's centre line to the buckle's top edge; they are
  tied around the buckle, so they hold it both ways (``Suture(bilateral=True)``).
"""
import os
import tomllib

from mpi4py import MPI

from ..errors import SceneError
from ..features.band import BandTightening
from ..features.cavity import Drainage, Injection, LiquidCavity
from ..features.loads import Dirichlet, NodalForce, Pressure
from ..features.sutures import Suture
from ..output.measures import EyeMeasures
from ..system.stepping import SolverSettings
from .scene import Scene, Step
from .tables import Table, contact_table, material_table, mesh_table, table_array

TOP_LEVEL = {"name", "mesh", "materials", "dirichlet", "pressure", "force", "cavity", "contact", "probe",
             "solver", "step", "injection", "suture", "band", "eye", "buckle_sutures", "tissues"}
TISSUE_SETS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tissues")


def tissue_set(name, path):
    """The [materials.<region>] tables of the tissue set ``name`` (``tissues = "<name>"``:
    eyeball_fenicsx/tissues/<name>.toml, each constant with its source), as {region: (table,
    where)}; the scene's own [materials.<region>] tables replace or add to them."""
    if name is None:
        return {}
    sets = sorted(f[:-5] for f in os.listdir(TISSUE_SETS) if f.endswith(".toml"))
    if name not in sets:
        raise SceneError(f"{path}: tissues = {name!r} is not a tissue set (sets: {sets})")
    source = os.path.join(TISSUE_SETS, name + ".toml")
    with open(source, "rb") as f:
        materials = tomllib.load(f)["materials"]
    return {region: (t, f"{path}: tissues = {name!r} ({source}): [materials.{region}]")
            for region, t in materials.items()}


def load_scene(path, comm=MPI.COMM_WORLD, overrides=None) -> Scene:
    """Read and check a scene TOML file, load its mesh and return the Scene.

    Args:
        overrides: {dotted path: value} replacing entries of the file (``"mesh.n_circ"``),
            as a sweep does.
    """
    if not os.path.isfile(path):
        raise SceneError(f"scene file {path} does not exist")
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise SceneError(f"{path}: not valid TOML: {error}") from None
    from .sweep import set_parameter
    for key, value in (overrides or {}).items():
        set_parameter(data, key, value)
    top = Table(data, path, TOP_LEVEL)
    name = top.get("name", "string", default=os.path.splitext(os.path.basename(path))[0])

    steps = []
    for t, where in table_array(data, "step", path):
        t = Table(t, where, {"name", "increments"})
        steps.append(Step(t.get("name", "string", required=True), t.get("increments", "integer")))
    steps = steps or [Step("load")]
    step_index = {s.name: i for i, s in enumerate(steps)}
    if len(step_index) != len(steps):
        raise SceneError(f"{path}: [[step]] names must be unique, got {[s.name for s in steps]}")

    def step_of(t, key="step"):
        name = t.get(key, "string", default=steps[0].name)
        if name not in step_index:
            raise t.error(f"{key} {name!r} is not a [[step]] of the scene (steps: {list(step_index)})")
        return step_index[name]

    tables = tissue_set(top.get("tissues", "string"), path)
    if not isinstance(data.get("materials", {}), dict):
        raise SceneError(f"{path}: materials must be tables [materials.<region>]")
    tables.update({region: (t, f"{path}: [materials.{region}]") for region, t in data.get("materials", {}).items()})
    if not tables:
        raise SceneError(f"{path}: no [materials.<region>] table: give one per volume group of the mesh")
    materials = {region: material_table(Table(t, where, t if isinstance(t, dict) else ()))
                 for region, (t, where) in tables.items()}  # keys are checked per model

    features, surfaces_used = [], []
    for t, where in table_array(data, "dirichlet", path):
        t = Table(t, where, {"surface", "x", "y", "z", "step"})
        surface = t.get("surface", "string", required=True)
        components = {c: t.get(c, "number") for c in "xyz" if t.has(c)}
        if not components:
            raise t.error("constrain at least one of x, y, z")
        features.append(Dirichlet(surface, components, step=step_of(t)))
        surfaces_used.append((surface, where))
    for t, where in table_array(data, "pressure", path):
        t = Table(t, where, {"surface", "value", "step"})
        surface = t.get("surface", "string", required=True)
        features.append(Pressure(surface, t.get("value", "number", required=True), step=step_of(t)))
        surfaces_used.append((surface, where))
    for t, where in table_array(data, "force", path):
        t = Table(t, where, {"surface", "point", "value", "step"})
        if t.has("surface") == t.has("point"):
            raise t.error("give exactly one of surface or point")
        surface = t.get("surface", "string")
        features.append(NodalForce(t.get("value", "vector", required=True), surface=surface,
                                   point=t.get("point", "vector"), step=step_of(t)))
        if surface:
            surfaces_used.append((surface, where))
    cavities, cavity_tables = {}, []
    for t, where in table_array(data, "cavity", path):
        t = Table(t, where, {"name", "surface", "bulk_modulus", "initial_pressure", "injected_volume",
                              "symmetry", "step", "algorithm", "pressurize", "break_into", "break_closes", "drain",
                              "drain_fraction"})
        name_ = t.unique_name("cavity", cavities)
        surface = t.get("surface", "strings" if isinstance(t.data.get("surface"), list) else "string", required=True)
        arguments = (name_, surface, t.get("bulk_modulus", "positive", required=True),
                     t.get("initial_pressure", "number", 0.0), t.get("injected_volume", "number", 0.0),
                     t.get("symmetry", "strings", []))
        options = {"step": step_of(t), "algorithm": t.get("algorithm", "string", "new"),
                   "pressurize": t.get("pressurize", "bool", False)}
        try:
            cavities[name_] = LiquidCavity(*arguments, **options)
        except SceneError as error:
            raise t.error(str(error)) from None
        features.append(cavities[name_])
        surfaces_used.extend((name, where) for name in cavities[name_].surfaces)
        cavity_tables.append((t, cavities[name_]))
    for t, cavity in cavity_tables:  # breaks and drainage name other cavities and steps
        host = t.get("break_into", "string")
        if host is not None and host not in cavities:
            raise t.error(f"break_into = {host!r} is not a [[cavity]] of the scene (cavities: {sorted(cavities)})")
        if t.has("break_closes") and host is None:
            raise t.error("break_closes needs break_into (the cavity the break opens into)")
        if t.has("drain_fraction") and not t.has("drain"):
            raise t.error("drain_fraction needs drain (the step in which the cavity is drained)")
        closes = step_of(t, "break_closes") if t.has("break_closes") else None
        try:
            if host is not None:
                cavity.connect_break(cavities[host], closes)
            if t.has("drain"):
                features.append(Drainage(cavity, step_of(t, "drain"), t.get("drain_fraction", "number", 0.98)))
        except SceneError as error:
            raise t.error(str(error)) from None
    for t, where in table_array(data, "injection", path):
        t = Table(t, where, {"cavity", "volume", "step"})
        cavity = t.get("cavity", "string", required=True)
        if cavity not in cavities:
            raise t.error(f"cavity {cavity!r} is not a [[cavity]] of the scene (cavities: {sorted(cavities)})")
        try:
            features.append(Injection(cavities[cavity], t.get("volume", "number", required=True), step=step_of(t)))
        except SceneError as error:  # the injection's own checks: a finite volume, a closed break
            raise t.error(str(error)) from None
    sutures = set()  # names, unique: each is a key of "sutures" in summary.json
    for t, where in table_array(data, "suture", path):
        t = Table(t, where, {"name", "first", "second", "tension", "shortening", "stiffness", "first_surface",
                              "second_surface", "anchored", "step"})
        name_ = t.unique_name("suture", sutures)
        sutures.add(name_)
        ends = {key: t.get(key, "string") for key in ("first_surface", "second_surface")}
        arguments = (name_, t.get("first", "vector", required=True), t.get("second", "vector", required=True))
        options = {"tension": t.get("tension", "nonnegative"), "shortening": t.get("shortening", "nonnegative"),
                   "stiffness": t.get("stiffness", "positive"), "anchored": t.get("anchored", "bool", False),
                   "step": step_of(t), **ends}
        try:
            features.append(Suture(*arguments, **options))
        except SceneError as error:  # the suture's own checks: tension or shortening
            raise t.error(str(error)) from None
        surfaces_used.extend((n, where) for n in ends.values() if n)
    for t, where in table_array(data, "band", path):
        t = Table(t, where, {"region", "reduction", "center", "axis", "step"})
        region = t.get("region", "string", required=True)
        if region not in materials:
            raise t.error(f"region {region!r} has no [materials.{region}] table")
        arguments = (region, t.get("reduction", "number", required=True))
        options = {"center": t.get("center", "vector", [0.0, 0.0, 0.0]),
                   "axis": t.get("axis", "vector", [0.0, 0.0, 1.0]), "step": step_of(t)}
        try:
            features.append(BandTightening(*arguments, **options))
        except SceneError as error:  # the band's own checks: a reduction >= 0, a non-zero axis
            raise t.error(str(error)) from None
    if "buckle_sutures" in data:
        t = Table(data["buckle_sutures"], f"{path}: [buckle_sutures]",
                   {"count", "width", "azimuths", "tension", "shortening", "stiffness", "step"})
        mesh = data.get("mesh") if isinstance(data.get("mesh"), dict) else {}
        if mesh.get("builder") != "buckled_eye":
            raise t.error('needs [mesh] builder = "buckled_eye" (the sutures follow its buckle)')
        if t.has("tension") == t.has("shortening"):
            raise t.error("give exactly one of tension or shortening")
        from ..meshing.builders.buckled_eye import suture_points
        parameters = {k: v for k, v in mesh.items() if k != "builder"}
        where = {"count": t.get("count", "integer", 4), "suture_width": t.get("width", "positive"),
                 "azimuth_deg": t.get("azimuths", "numbers")}
        pull = {"tension": t.get("tension", "nonnegative"), "shortening": t.get("shortening", "nonnegative"),
                "stiffness": t.get("stiffness", "positive"), "bilateral": True, "step": step_of(t)}
        try:
            points = suture_points(parameters, **where)
        except (SceneError, TypeError) as error:  # the buckle's own checks (and those of [mesh])
            raise t.error(str(error)) from None
        for point in points:
            if point["name"] in sutures:
                raise t.error(f"suture name {point['name']!r} is used twice: rename the [[suture]]")
            sutures.add(point["name"])
            ends = {"first_surface": point["sclera_surface"], "second_surface": point["buckle_surface"]}
            features.append(Suture(point["name"], point["sclera"], point["buckle"], share=point["share"], **ends, **pull))
    if "eye" in data:
        t = Table(data["eye"], f"{path}: [eye]", {"vitreous", "anterior", "posterior", "anterior_surface",
                                                   "posterior_surface", "buckle", "sclera", "retina", "choroid"})
        vitreous = t.get("vitreous", "string")
        if vitreous is not None and vitreous not in cavities:
            raise t.error(f"vitreous = {vitreous!r} is not a [[cavity]] of the scene (cavities: {sorted(cavities)})")
        if t.has("sclera") and not t.has("buckle"):
            raise t.error("sclera is the surface under the buckle: give buckle too (its inner surface)")
        ends = {key: t.get(key, "string", default) for key, default in
                (("anterior_surface", "cornea_outer"), ("posterior_surface", "vitreous_wall"))}
        surfaces = {key: t.get(key, "string") for key in ("buckle", "retina", "choroid")}
        if surfaces["buckle"]:
            surfaces["sclera"] = t.get("sclera", "string", "sclera_outer")
        try:
            features.append(EyeMeasures(t.get("anterior", "vector", [0.0, 0.0, 1e3]),
                                        t.get("posterior", "vector", [0.0, 0.0, -1e3]),
                                        vitreous=cavities.get(vitreous), **ends, **surfaces))
        except SceneError as error:  # the measures' own checks: retina and choroid together
            raise t.error(str(error)) from None
        surfaces_used.extend((n, t.where) for n in [*ends.values(), *surfaces.values()] if n)
    contacts = set()
    for t, where in table_array(data, "contact", path):
        t = Table(t, where, {"name", "slave", "master", "rigid", "penalty", "smoothing", "step", "symmetry"})
        name_ = t.unique_name("contact", contacts)
        contacts.add(name_)
        feature, names = contact_table(t, step_of)
        features.append(feature)
        surfaces_used.extend((n, where) for n in names)

    probes = {}
    for t, where in table_array(data, "probe", path):
        t = Table(t, where, {"name", "point"})
        name_ = t.unique_name("probe", probes)
        probes[name_] = t.get("point", "vector", required=True)

    solver_table = Table(data.get("solver", {}), f"{path}: [solver]",
                          {"increments", "max_cutbacks", "growth", "predictor", "element"})
    given = {key: solver_table.get(key, kind) for key, kind in
             (("increments", "integer"), ("max_cutbacks", "integer"), ("growth", "positive"), ("predictor", "bool"))}
    settings = SolverSettings(**{key: value for key, value in given.items() if value is not None})
    element = solver_table.get("element", "string")

    mesh = data.get("mesh")
    if not isinstance(mesh, dict) or not mesh:
        raise SceneError(f"{path}: no [mesh] table: give file = \"<mesh>.msh\" (relative to the scene file)")
    mesh_keys = Table(mesh, f"{path}: [mesh]", set(mesh))  # keys are checked per mesh source
    mesh_data = mesh_table(mesh_keys, os.path.dirname(os.path.abspath(path)), comm)

    for surface, where in surfaces_used:
        if surface not in mesh_data.surfaces:
            raise SceneError(f"{where}: surface {surface!r} is not a surface group of mesh {mesh_data.source} "
                             f"(its surfaces: {sorted(mesh_data.surfaces)})")
    for region in materials:
        if region not in mesh_data.regions:
            raise SceneError(f"{tables[region][1]}: {region!r} is not a volume group of mesh "
                             f"{mesh_data.source} (its regions: {sorted(mesh_data.regions)})")
    missing = sorted(set(mesh_data.regions) - set(materials))
    if missing:
        raise SceneError(f"{path}: no [materials.<region>] table for region(s) {missing} of mesh {mesh_data.source}: "
                         "give every volume group of the mesh a material")
    return Scene(name, mesh_data, materials, features, probes, steps, settings, element)

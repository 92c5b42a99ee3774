"""The parsers of a scene file's tables for the eye's liquids, the operation and what it is
judged by: ``[[cavity]]`` (with its retinal break and drainage) and ``[[injection]]``, the
surgeon's ``[[suture]]``, ``[[band]]`` and ``[buckle_sutures]``, ``[[contact]]``, and the eye
measures of ``[eye]``. Each reads its key of the file into the ``Reading`` (tables.py); the
registry of loader.py calls them in the order of the file format, the cavities before the
tables that name them.
"""
from collections.abc import Callable

from .. import checks
from ..contact import ContactPair, RigidContact
from ..errors import SceneError
from ..features.band import BandTightening
from ..features.cavity import Drainage, Injection, LiquidCavity
from ..features.sutures import Suture
from ..meshing.builders.buckled_eye import suture_grading, suture_points
from ..output.eye_pictures import EyePictures
from ..output.measures import EyeMeasures
from .tables import Reading, Table

CAVITY_KEYS = {"name", "surface", "bulk_modulus", "initial_pressure", "injected_volume", "symmetry", "step",
               "algorithm", "pressurize", "break_into", "break_closes", "drain", "drain_fraction"}
SUTURE_KEYS = {"name", "first", "second", "tension", "shortening", "stiffness", "first_surface", "second_surface",
               "anchored", "step"}
EYE_KEYS = {"vitreous", "anterior", "posterior", "anterior_surface", "posterior_surface", "buckle", "sclera",
            "retina", "choroid"}
RIGID_SHAPES = {"plane": {"point", "normal"}, "sphere": {"center", "radius"},
                "cylinder": {"point", "axis", "radius"}}


def read_cavity(reading: Reading) -> None:
    """``[[cavity]]``: a liquid-filled cavity; then the breaks and drainages, which name other
    cavities and steps."""
    read = []
    for t in reading.array("cavity", CAVITY_KEYS):
        name = t.unique_name("cavity", reading.cavities)
        surface = t.get("surface", "strings" if isinstance(t.data.get("surface"), list) else "string", required=True)
        arguments = (name, surface, t.get("bulk_modulus", "positive", required=True),
                     t.get("initial_pressure", "number", 0.0), t.get("injected_volume", "number", 0.0),
                     t.get("symmetry", "strings", []))
        options = {"step": reading.step_of(t), "algorithm": t.get("algorithm", "string", "new"),
                   "pressurize": t.get("pressurize", "flag", False)}
        reading.cavities[name] = reading.add(t, LiquidCavity, *arguments, **options)
        reading.use(t, reading.cavities[name].surfaces)
        read.append((t, reading.cavities[name]))
    for t, cavity in read:
        _break_and_drainage(reading, t, cavity)


def _break_and_drainage(reading: Reading, t: Table, cavity: LiquidCavity) -> None:
    """A [[cavity]]'s ``break_into`` / ``break_closes`` and ``drain`` / ``drain_fraction``."""
    host = t.get("break_into", "string")
    if host is not None:
        with t.located():
            checks.known(host, reading.cavities, "break_into", "[[cavity]] of the scene", "cavities")
    if t.has("break_closes") and host is None:
        raise t.error("break_closes needs break_into (the cavity the break opens into)")
    if t.has("drain_fraction") and not t.has("drain"):
        raise t.error("drain_fraction needs drain (the step in which the cavity is drained)")
    closes = reading.step_of(t, "break_closes") if t.has("break_closes") else None
    if host is not None:
        with t.located():
            cavity.connect_break(reading.cavities[host], closes)
    if t.has("drain"):
        step, fraction = reading.step_of(t, "drain"), t.get("drain_fraction", "number", 0.98)
        reading.add(t, Drainage, cavity, step, fraction)


def read_injection(reading: Reading) -> None:
    """``[[injection]]`` (``cavity``, ``volume``, ``step``): liquid added or removed in a step."""
    for t in reading.array("injection", {"cavity", "volume", "step"}):
        cavity = t.get("cavity", "string", required=True)
        with t.located():
            checks.known(cavity, reading.cavities, "cavity", "[[cavity]] of the scene", "cavities", assigned=False)
        volume = t.get("volume", "number", required=True)
        # the injection's own checks: a finite volume, a closed break
        reading.add(t, Injection, reading.cavities[cavity], volume, step=reading.step_of(t))


def read_suture(reading: Reading) -> None:
    """``[[suture]]``: a suture between two points (or one anchored), with its tension or shortening."""
    for t in reading.array("suture", SUTURE_KEYS):
        name = t.unique_name("suture", reading.sutures)
        reading.sutures.add(name)
        ends = {key: t.get(key, "string") for key in ("first_surface", "second_surface")}
        arguments = (name, t.get("first", "vector", required=True), t.get("second", "vector", required=True))
        options = {"tension": t.get("tension", "nonnegative"), "shortening": t.get("shortening", "nonnegative"),
                   "stiffness": t.get("stiffness", "positive"), "anchored": t.get("anchored", "flag", False),
                   "step": reading.step_of(t), **ends}
        reading.add(t, Suture, *arguments, **options)  # the suture's own checks: tension or shortening
        reading.use(t, ends.values())


def read_band(reading: Reading) -> None:
    """``[[band]]`` (``region``, ``reduction``, ``center``, ``axis``, ``step``): band tightening."""
    for t in reading.array("band", {"region", "reduction", "center", "axis", "step"}):
        region = t.get("region", "string", required=True)
        if region not in reading.materials:
            raise t.error(f"region {region!r} has no [materials.{region}] table")
        arguments = (region, t.get("reduction", "number", required=True))
        options = {"center": t.get("center", "vector", [0.0, 0.0, 0.0]),
                   "axis": t.get("axis", "vector", [0.0, 0.0, 1.0]), "step": reading.step_of(t)}
        reading.add(t, BandTightening, *arguments, **options)  # its own checks: a reduction >= 0, a non-zero axis


def read_buckle_sutures(reading: Reading) -> None:
    """``[buckle_sutures]``: sutures generated from the buckled eye's geometry, tied around the
    buckle (so they hold it both ways)."""
    if "buckle_sutures" not in reading.data:
        return
    t = reading.table("buckle_sutures", {"count", "width", "azimuths", "bite", "tension", "shortening", "stiffness",
                                         "step"})
    mesh = reading.data.get("mesh") if isinstance(reading.data.get("mesh"), dict) else {}
    if mesh.get("builder") != "buckled_eye":
        raise t.error('needs [mesh] builder = "buckled_eye" (the sutures follow its buckle)')
    if t.has("tension") == t.has("shortening"):
        raise t.error("give exactly one of tension or shortening")
    graded = Table(mesh, f"{reading.path}: [mesh]", set(mesh)).get("graded", "flag")
    # (graded_between, the span of the grading, is the eye's once the sutures' azimuths are added)
    parameters = {k: v for k, v in mesh.items() if k not in ("builder", "graded", "graded_between")}
    where = {"count": t.get("count", "integer", 4), "suture_width": t.get("width", "positive"),
             "azimuth_deg": t.get("azimuths", "numbers")}
    if t.has("bite"):
        where["bite"] = t.get("bite", "nonnegative")
    pull = {"tension": t.get("tension", "nonnegative"), "shortening": t.get("shortening", "nonnegative"),
            "stiffness": t.get("stiffness", "positive"), "bilateral": True, "step": reading.step_of(t)}
    with t.located((SceneError, TypeError)):  # the buckle's own checks (and those of [mesh])
        points = suture_points(parameters, **where)
        reading.graded = suture_grading(parameters, points, graded)
    for point in points:
        if point["name"] in reading.sutures:
            raise t.error(f"suture name {point['name']!r} is used twice: rename the [[suture]]")
        reading.sutures.add(point["name"])
        ends = {"first_surface": point["sclera_surface"], "second_surface": point["buckle_surface"],
                "hold": point["hold"], "hold_surface": point["hold_surface"]}
        reading.add(t, Suture, point["name"], point["sclera_bite"], point["buckle_bite"], share=point["share"], **ends,
                    **pull)


def read_eye(reading: Reading) -> None:
    """``[eye]``: the eye measures and their pictures, observers of the scene
    (output/measures.py, output/eye_pictures.py)."""
    if "eye" not in reading.data:
        return
    t = reading.table("eye", EYE_KEYS)
    vitreous = t.get("vitreous", "string")
    if vitreous is not None:
        with t.located():
            checks.known(vitreous, reading.cavities, "vitreous", "[[cavity]] of the scene", "cavities")
    if t.has("sclera") and not t.has("buckle"):
        raise t.error("sclera is the surface under the buckle: give buckle too (its inner surface)")
    ends = {key: t.get(key, "string", default) for key, default in
            (("anterior_surface", "cornea_outer"), ("posterior_surface", "vitreous_wall"))}
    surfaces = {key: t.get(key, "string") for key in ("buckle", "retina", "choroid")}
    if surfaces["buckle"]:
        surfaces["sclera"] = t.get("sclera", "string", "sclera_outer")
    points = t.get("anterior", "vector", [0.0, 0.0, 1e3]), t.get("posterior", "vector", [0.0, 0.0, -1e3])
    with t.located():  # the measures' own checks: retina and choroid together
        measures = EyeMeasures(*points, vitreous=reading.cavities.get(vitreous), **ends, **surfaces)
    reading.observers += [measures, EyePictures(measures)]
    reading.use(t, [*ends.values(), *surfaces.values()])


def read_contact(reading: Reading) -> None:
    """``[[contact]]``: a deformable pair (``master``) or a rigid body (``rigid``)."""
    names = set()
    for t in reading.array("contact", {"name", "slave", "master", "rigid", "penalty", "smoothing", "step",
                                       "symmetry", "adjust"}):
        names.add(t.unique_name("contact", names))
        feature, surfaces = contact_table(t, reading.step_of)
        reading.features.append(feature)
        reading.use(t, surfaces)


def contact_table(t: Table, step_of: Callable[[Table], int]) -> tuple[ContactPair | RigidContact, list[str]]:
    """A [[contact]] table -> (feature, surfaces it names)."""
    name = t.get("name", "string", required=True)
    slave = t.get("slave", "string", required=True)
    penalty = t.get("penalty", "positive")
    smoothing = t.get("smoothing", "nonnegative", 0.0)
    if t.has("master") == t.has("rigid"):
        raise t.error("give exactly one of master (a surface) or rigid (a rigid body)")
    if t.has("master"):
        master, step, symmetry = t.get("master", "string"), step_of(t), t.get("symmetry", "strings", [])
        adjust = t.get("adjust", "nonnegative", 0.0)
        with t.located():  # the pair's own checks: slave and master differ
            return ContactPair(name, slave, master, penalty=penalty, step=step, smoothing=smoothing,
                               symmetry=symmetry, adjust=adjust), [slave, master]
    if t.has("symmetry"):
        raise t.error("symmetry applies to a master surface (its nodes on the planes); a rigid body has none")
    if t.has("adjust"):
        raise t.error("adjust applies to two meshed surfaces (the clearance between them); a rigid body has none")
    rigid = t.data["rigid"]
    if not isinstance(rigid, dict):
        raise t.error(f'rigid must be a table, e.g. rigid = {{ shape = "plane", point = [0.0, 0.0, 1.0], '
                      f'normal = [0.0, 0.0, -1.0] }}, got {rigid!r}')
    shape = rigid.get("shape")
    if shape not in RIGID_SHAPES:
        raise t.error(f"rigid.shape must be one of {sorted(RIGID_SHAPES)}, got {shape!r}")
    r = Table(rigid, f"{t.where} rigid", RIGID_SHAPES[shape] | {"shape", "displacement", "inside"})
    params = {key: r.get(key, "positive" if key == "radius" else "vector", required=key != "displacement")
              for key in RIGID_SHAPES[shape] | {"displacement"}}
    if shape in ("sphere", "cylinder"):
        params["inside"] = r.get("inside", "flag", False)
    elif r.has("inside"):
        raise r.error("inside applies to sphere and cylinder only")
    step = step_of(t)
    with r.located():  # the shape's own checks: a non-zero normal or axis
        return RigidContact(name, slave, shape, penalty=penalty, step=step, smoothing=smoothing, **params), [slave]

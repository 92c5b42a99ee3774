"""The tables of a scene file, one parser each: a table reader whose every error says where
(file and table) and how to fix it, and the parsers of the [materials.*], [[contact]] and
[mesh] tables. ``scenefile.load_scene`` reads the whole file with them."""
import math
import os

from ..errors import SceneError
from ..mechanics.materials import LinearElastic, MooneyRivlin, NeoHooke
from ..meshing.load import built_mesh, load_mesh


class Table:
    """A TOML table being read: typed getters that raise located SceneErrors."""

    def __init__(self, data, where, allowed):
        if not isinstance(data, dict):
            raise SceneError(f"{where}: expected a table, got {type(data).__name__}")
        unknown = sorted(set(data) - set(allowed))
        if unknown:
            raise SceneError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
        self.data, self.where = data, where

    def error(self, message):
        return SceneError(f"{self.where}: {message}")

    def has(self, key):
        return key in self.data

    def unique_name(self, kind, taken):
        """The table's required ``name``, which must not be in ``taken`` (it keys the summary)."""
        name = self.get("name", "string", required=True)
        if name in taken:
            raise self.error(f"{kind} name {name!r} is used twice")
        return name

    def get(self, key, kind, default=None, required=False):
        if key not in self.data:
            if required:
                raise self.error(f"missing required key {key!r}")
            return default
        value = self.data[key]
        if kind == "string":
            if not isinstance(value, str) or not value:
                raise self.error(f"{key} must be a non-empty string, got {value!r}")
        elif kind in ("number", "positive", "nonnegative"):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise self.error(f"{key} must be a finite number, got {value!r}")
            if kind == "positive" and value <= 0:
                raise self.error(f"{key} must be positive, got {value!r}")
            if kind == "nonnegative" and value < 0:
                raise self.error(f"{key} must not be negative, got {value!r}")
            value = float(value)
        elif kind == "integer":
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise self.error(f"{key} must be a positive integer, got {value!r}")
        elif kind == "vector":
            if (not isinstance(value, list) or len(value) != 3
                    or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                           for v in value)):
                raise self.error(f"{key} must be a list of 3 finite numbers, got {value!r}")
            value = [float(v) for v in value]
        elif kind == "bool":
            if not isinstance(value, bool):
                raise self.error(f"{key} must be true or false, got {value!r}")
        elif kind == "numbers":
            if (not isinstance(value, list) or not value
                    or any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in value)):
                raise self.error(f"{key} must be a list of finite numbers, got {value!r}")
            value = [float(v) for v in value]
        elif kind == "strings":
            if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
                raise self.error(f"{key} must be a list of strings, got {value!r}")
        return value


def table_array(data, key, path):
    tables = data.get(key, [])
    if not isinstance(tables, list):
        raise SceneError(f"{path}: {key} must be an array of tables, written [[{key}]]")
    return [(t, f"{path}: [[{key}]] #{i + 1}") for i, t in enumerate(tables)]


def material_table(table: Table):
    """A [materials.<region>] table -> its material law."""
    model = table.get("model", "string", required=True)
    if model == "neo-hooke":
        Table(table.data, table.where, {"model", "c10"})
        law, arguments = NeoHooke, [table.get("c10", "positive", required=True)]
    elif model == "mooney-rivlin":
        Table(table.data, table.where, {"model", "c"})
        c = table.get("c", None, required=True)
        if not isinstance(c, dict) or not c:
            raise table.error('c must be a table of coefficients, e.g. c = { "10" = 0.4, "01" = 0.1 }')
        coefficients = {}
        for key, value in c.items():
            if len(key) != 2 or not key.isdigit():
                raise table.error(f'coefficient names are two digits "rs" for (I1bar-3)^r (I2bar-3)^s, got {key!r}')
            coefficients[(int(key[0]), int(key[1]))] = value
        law, arguments = MooneyRivlin, [coefficients]
    elif model == "linear-elastic":
        Table(table.data, table.where, {"model", "E", "nu"})
        law, arguments = LinearElastic, [table.get("E", "positive", required=True),
                                         table.get("nu", "number", required=True)]
    else:
        raise table.error(f"unknown model {model!r}: choose neo-hooke, mooney-rivlin or linear-elastic")
    try:
        return law(*arguments)
    except SceneError as error:  # the law's own checks: nu < 0.5, c10 + c01 > 0, ...
        raise table.error(str(error)) from None


RIGID_SHAPES = {"plane": {"point", "normal"}, "sphere": {"center", "radius"},
                "cylinder": {"point", "axis", "radius"}}


def contact_table(t: Table, step_of):
    """A [[contact]] table -> (feature, surfaces it names)."""
    from ..contact import ContactPair, RigidContact
    name = t.get("name", "string", required=True)
    slave = t.get("slave", "string", required=True)
    penalty = t.get("penalty", "positive")
    smoothing = t.get("smoothing", "nonnegative", 0.0)
    if t.has("master") == t.has("rigid"):
        raise t.error("give exactly one of master (a surface) or rigid (a rigid body)")
    if t.has("master"):
        master = t.get("master", "string")
        step = step_of(t)
        try:
            return ContactPair(name, slave, master, penalty=penalty, step=step, smoothing=smoothing,
                               symmetry=t.get("symmetry", "strings", [])), [slave, master]
        except SceneError as error:  # the pair's own checks: slave and master differ
            raise t.error(str(error)) from None
    if t.has("symmetry"):
        raise t.error("symmetry applies to a master surface (its nodes on the planes); a rigid body has none")
    rigid = t.data["rigid"]
    if not isinstance(rigid, dict):
        raise t.error(f'rigid must be a table, e.g. rigid = {{ shape = "plane", point = [0.0, 0.0, 1.0], '
                      f'normal = [0.0, 0.0, -1.0] }}, got {rigid!r}')
    shape = rigid.get("shape")
    if shape not in RIGID_SHAPES:
        raise t.error(f"rigid.shape must be one of {sorted(RIGID_SHAPES)}, got {shape!r}")
    r = Table(rigid, f"{t.where} rigid", RIGID_SHAPES[shape] | {"shape", "displacement", "inside"})
    params = {}
    for key in RIGID_SHAPES[shape] | {"displacement"}:
        params[key] = r.get(key, "positive" if key == "radius" else "vector", required=key != "displacement")
    if shape in ("sphere", "cylinder"):
        params["inside"] = r.get("inside", "bool", False)
    elif r.has("inside"):
        raise r.error("inside applies to sphere and cylinder only")
    step = step_of(t)
    try:
        return RigidContact(name, slave, shape, penalty=penalty, step=step, smoothing=smoothing, **params), [slave]
    except SceneError as error:  # the shape's own checks: a non-zero normal or axis
        raise r.error(str(error)) from None


def mesh_table(table: Table, directory, comm):
    if table.has("file"):
        Table(table.data, table.where, {"file"})
        given = table.get("file", "string")
        path = os.path.join(directory, given)
        if not os.path.isfile(path):
            raise table.error(f"file = {given!r}: {path} does not exist (the path is relative to the scene file)")
        try:
            return load_mesh(path, comm)
        except SceneError as error:  # the mesh's own checks: gmsh reads it, named groups, supported elements
            raise table.error(str(error)) from None
    builder = table.get("builder", "string", required=False)
    from ..meshing.builders import band, block, buckled_eye, eye, sphere_octant
    builders = {"block": block.build_block, "sphere_octant": sphere_octant.build_sphere_octant,
                "eye": eye.build_eye, "band": band.build_band, "buckled_eye": buckled_eye.build_buckled_eye}
    if builder not in builders:
        raise table.error(f"give file = \"<mesh>.msh\" or builder = one of {sorted(builders)}")
    options = {k: v for k, v in table.data.items() if k != "builder"}
    try:
        return built_mesh(builders[builder], comm, **options)
    except SceneError as error:
        raise table.error(str(error)) from None

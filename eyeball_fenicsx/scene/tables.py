"""Reading a scene file's tables: a reader whose every error says where (file and table), and
the ``Reading`` the table parsers share while one file is read.

``Table.get`` checks a value with eyeball_fenicsx/checks.py (the one validation helper) and
prefixes its message with the table's location, ``"<file>: [[cavity]] #2: bulk_modulus must be
positive, got -1.0"``; the parsers of the tables (solid_tables.py, operation_tables.py) put
what they make into the ``Reading``: the steps, the materials, the features in the order the
file gives them (the order they are summed in), the cavities and sutures by name, and the
surfaces named, which are checked against the mesh once it is built.
"""
import contextlib
import dataclasses
import functools
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from mpi4py import MPI

from .. import checks
from ..errors import SceneError
from ..features.base import Feature
from ..features.cavity import LiquidCavity
from ..meshing.load import MeshData
from ..system.settings import SolverSettings
from .scene import Step

# Table.get's kinds of value: each a check of eyeball_fenicsx/checks.py
KINDS: dict[str, Callable[[Any, str], Any]] = {
    "string": checks.string, "strings": checks.strings, "number": checks.number,
    "positive": functools.partial(checks.number, sign="positive"),
    "nonnegative": functools.partial(checks.number, sign="nonnegative"),
    "integer": checks.integer, "numbers": checks.numbers, "vector": checks.vector, "flag": checks.flag}


class Table:
    """A TOML table being read: typed getters that raise located SceneErrors."""

    def __init__(self, data: Any, where: str, allowed: Iterable[str]) -> None:
        if not isinstance(data, dict):
            raise SceneError(f"{where}: expected a table, got {type(data).__name__}")
        unknown = sorted(set(data) - set(allowed))
        if unknown:
            raise SceneError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
        self.data, self.where = data, where

    def error(self, message: str) -> SceneError:
        return SceneError(f"{self.where}: {message}")

    @contextlib.contextmanager
    def located(self, errors: type[Exception] | tuple[type[Exception], ...] = SceneError) -> Iterator[None]:
        """Raise the ``errors`` of the block (a feature's own checks) as errors of this table."""
        try:
            yield
        except errors as error:
            raise self.error(str(error)) from None

    def has(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str, kind: str | None, default: Any = None, required: bool = False) -> Any:
        """The value of ``key`` checked as ``kind`` (a key of KINDS; None: unchecked), or
        ``default`` if the table has no such key and it is not ``required``."""
        if key not in self.data:
            if required:
                raise self.error(f"missing required key {key!r}")
            return default
        if kind is None:
            return self.data[key]
        with self.located():
            return KINDS[kind](self.data[key], key)

    def unique_name(self, kind: str, taken: Iterable[str]) -> str:
        """The table's required ``name``, which must not be in ``taken`` (it keys the summary)."""
        name = self.get("name", "string", required=True)
        if name in taken:
            raise self.error(f"{kind} name {name!r} is used twice")
        return name


def table_array(data: dict, key: str, path: str) -> list[tuple[Any, str]]:
    """The entries of the array of tables ``[[key]]`` with their locations."""
    tables = data.get(key, [])
    if not isinstance(tables, list):
        raise SceneError(f"{path}: {key} must be an array of tables, written [[{key}]]")
    return [(t, f"{path}: [[{key}]] #{i + 1}") for i, t in enumerate(tables)]


@dataclasses.dataclass
class Reading:
    """One scene file being read: the parsed file, and what its tables have made so far."""

    path: str
    data: dict
    comm: MPI.Comm
    top: Table  # the file's top level
    name: str = ""
    steps: list[Step] = dataclasses.field(default_factory=list)
    material_tables: dict[str, tuple[Any, str]] = dataclasses.field(default_factory=dict)  # region: (table, where)
    materials: dict[str, Any] = dataclasses.field(default_factory=dict)
    features: list[Feature] = dataclasses.field(default_factory=list)
    observers: list[Any] = dataclasses.field(default_factory=list)
    cavities: dict[str, LiquidCavity] = dataclasses.field(default_factory=dict)
    sutures: set[str] = dataclasses.field(default_factory=set)  # names, unique: keys of "sutures" in summary.json
    probes: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    surfaces: list[tuple[str, str]] = dataclasses.field(default_factory=list)  # (surface, where), for the mesh
    graded: dict | None = None  # the buckled eye's grading for [buckle_sutures] (eye parameters), if any
    settings: SolverSettings | None = None
    element: str | None = None
    mesh: MeshData | None = None

    def array(self, key: str, allowed: Iterable[str]) -> Iterator[Table]:
        """The tables ``[[key]]`` of the file, each checked for keys ``allowed`` when it is read."""
        for data, where in table_array(self.data, key, self.path):
            yield Table(data, where, allowed)

    def table(self, key: str, allowed: Iterable[str]) -> Table:
        """The table ``[key]`` of the file (empty if the file has none)."""
        return Table(self.data.get(key, {}), f"{self.path}: [{key}]", allowed)

    def step_of(self, t: Table, key: str = "step") -> int:
        """The index of the step that ``key`` of table ``t`` names (default: the first step)."""
        names = [step.name for step in self.steps]
        name = t.get(key, "string", default=names[0])
        with t.located():
            checks.known(name, names, key, "[[step]] of the scene", "steps", assigned=False, in_order=True)
        return names.index(name)

    def add(self, t: Table, feature_type: Callable[..., Feature], *arguments: Any, **options: Any) -> Feature:
        """Make a feature of table ``t`` (its own checks' errors located at ``t``) and add it."""
        with t.located():
            feature = feature_type(*arguments, **options)
        self.features.append(feature)
        return feature

    def use(self, t: Table, surfaces: Iterable[str | None]) -> None:
        """Note the surfaces that table ``t`` names (None: not given), to check against the mesh."""
        self.surfaces.extend((surface, t.where) for surface in surfaces if surface)

"""What a planning sweep runs: a grid of parameter values, and the corners of a box of ranges.

A sweep varies one or more *parameters*, each over a list of values; the grid is every
combination of them (the last parameter varying fastest), one scene variant per grid point. It
may also be given *ranges*, ``(parameter, low, high)``, of uncertain constants (a tissue's
``c10``, say): each grid point is then also run at every corner of the box of the ranges (2^k
variants for k ranges, each range at its low or its high end), and the sweep reports, for each
prediction, its smallest and largest value over the corners. For a prediction that is monotone
in each ranged constant (not necessarily in the same sense) these are its minimum and maximum over
the whole box, since a function monotone in each variable takes its extremes at corners; for one
that is not (a prediction with an optimum inside a range), the band may be too narrow. The ends
one range at a time (2k variants) would be cheaper but miss the corners where two constants act
together, which are the extremes when both raise (or both lower) a prediction.

Parameters and ranges are dotted paths to numbers of the scene file (overrides.py), or of the
tissue set a region's materials come from (``materials.sclera.c.10`` with ``tissues =
"calibrated"``: loader.parsed_scene). Every input is checked before anything runs; a bad one is a
located one-line SceneError.
"""
import hashlib
import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ..checks import is_number
from ..errors import SceneError
from .loader import parsed_scene
from .overrides import entry


@dataclass(frozen=True)
class Variant:
    """One scene the sweep runs: its folder in the sweep's, its grid point, the corner of the
    ranges' box (``"lh"``: the first range at its low end, the second at its high; ``""``: the
    scene's own constants) and the overrides that make it."""
    folder: str
    point: int
    corner: str
    overrides: dict[str, float]


@dataclass(frozen=True)
class Plan:
    """A checked sweep: the scene, its SHA-256, the grid and the ranges."""
    scene: str
    digest: str
    grid: list[tuple[str, list[float]]]
    ranges: list[tuple[str, float, float]] = field(default_factory=list)

    @property
    def parameters(self) -> list[str]:
        return [parameter for parameter, _ in self.grid]

    def points(self) -> list[dict[str, float]]:
        """The grid points, {parameter: value}, the last parameter varying fastest (one point, {},
        without parameters)."""
        return [dict(zip(self.parameters, values)) for values in itertools.product(*(v for _, v in self.grid))]

    def corners(self) -> list[tuple[str, dict[str, float]]]:
        """The corners of the ranges' box: (name, {parameter: end}); none without ranges."""
        if not self.ranges:
            return []
        return [("".join("lh"[end] for end in ends),
                 {parameter: (low, high)[end] for (parameter, low, high), end in zip(self.ranges, ends)})
                for ends in itertools.product((0, 1), repeat=len(self.ranges))]

    def variants(self) -> list[Variant]:
        """Every run: each grid point's own, then its corners."""
        width = max(2, len(str(len(self.points()) - 1)))
        runs = []
        for k, point in enumerate(self.points()):
            runs.append(Variant(f"{k:0{width}d}", k, "", point))
            runs += [Variant(f"{k:0{width}d}-{name}", k, name, {**point, **ends}) for name, ends in self.corners()]
        return runs

    def record(self) -> dict[str, Any]:
        """sweep.json: what was swept, and the overrides of every variant by its folder."""
        return {"scene": self.digest, "parameters": self.parameters, "values": [v for _, v in self.grid],
                "ranges": [list(r) for r in self.ranges],
                "variants": {v.folder: v.overrides for v in self.variants()}}


def plan_sweep(scene_path: str, grid: Sequence[tuple[str, Sequence[Any]]] | Mapping[str, Sequence[Any]],
               ranges: Sequence[tuple[str, Any, Any]] = ()) -> Plan:
    """Check a sweep's inputs: ``grid`` [(parameter, values)] (or {parameter: values}), ``ranges``
    [(parameter, low, high)]; numbers may be given as text (the command line's).

    Raises:
        SceneError: a parameter or range is not a number of the scene, is given twice, a value is
            not a finite number or repeats, a range's low end is not below its high end, or
            there is nothing to sweep.
    """
    pairs = list(grid.items()) if isinstance(grid, Mapping) else list(grid)
    if not pairs and not ranges:
        raise SceneError(f"{scene_path}: sweep: give a parameter and its values (--parameter P --values ...) or "
                         "a range (--range P LOW HIGH)")
    named = [parameter for parameter, *_ in pairs] + [parameter for parameter, *_ in ranges]
    data = parsed_scene(scene_path, [p for p in named if isinstance(p, str)])
    seen: set[str] = set()
    for parameter in named:
        _check_parameter(data, scene_path, parameter, seen)
    checked_grid = [(parameter, _values(f"{scene_path}: sweep of {parameter!r}", values))
                    for parameter, values in pairs]
    with open(scene_path, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    return Plan(scene_path, digest, checked_grid, [_range(scene_path, r) for r in ranges])


def _check_parameter(data: dict, scene_path: str, parameter: Any, seen: set[str]) -> None:
    """A parameter names a number of the scene, once."""
    if not isinstance(parameter, str) or not parameter:
        raise SceneError(f"{scene_path}: sweep: a parameter is a dotted path such as band.0.reduction, "
                         f"got {parameter!r}")
    if parameter in seen:
        raise SceneError(f"{scene_path}: sweep: parameter {parameter!r} is given twice: give each parameter once, "
                         "either with its values or as a range")
    seen.add(parameter)
    try:
        parent, key = entry(data, parameter)
    except SceneError as error:
        raise SceneError(f"{scene_path}: sweep: {error}") from None
    current = parent[key]  # type: ignore[index]
    if not is_number(current):
        raise SceneError(f"{scene_path}: sweep of {parameter!r}: the scene has {parameter} = {current!r}, not a "
                         "number: a sweep varies a number")


def _number(where: str, value: Any) -> float:
    """A finite number, from a number or its text."""
    number = value
    if isinstance(value, str):
        try:
            number = float(value)
        except ValueError:
            pass
    if not is_number(number):
        raise SceneError(f"{where}: the values must be finite numbers, got {value!r}")
    return float(number)


def _values(where: str, values: Any) -> list[float]:
    if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or not values:
        raise SceneError(f"{where}: give one or more values, got {values!r}")
    numbers = [_number(where, value) for value in values]
    repeated = sorted({v for v in numbers if numbers.count(v) > 1})
    if repeated:
        raise SceneError(f"{where}: the value {repeated[0]!r} is given twice: give each value once")
    return numbers


def _range(scene_path: str, given: Any) -> tuple[str, float, float]:
    """(parameter, low, high), low < high."""
    parameter, *ends = given
    where = f"{scene_path}: sweep: range of {parameter!r}"
    if len(ends) != 2:
        raise SceneError(f"{where}: give its low and its high end, got {ends!r}")
    low, high = (_number(where, end) for end in ends)
    if not low < high:
        raise SceneError(f"{where}: the low end {low!r} must be below the high end {high!r}")
    return parameter, low, high

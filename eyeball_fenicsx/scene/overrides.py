"""Overrides: entries of a parsed scene file replaced before it is read, by dotted paths.

A path names table keys and, for arrays (``[[...]]`` tables, lists of numbers), indices from 0:
``"mesh.n_circ"``, ``"band.0.reduction"``, ``"mesh.divisions.0"``. ``load_scene(path,
overrides={path: value})`` applies them (the demos' coarse meshes, the planning sweep's
variants); only a value the file has can be replaced, not a whole table or array. A whole number
given for an integer entry (the command line's 2.0 for ``n = 2``) is taken as that integer.
"""
from numbers import Integral, Real
from typing import Any

from ..errors import SceneError


def entry(data: dict, path: str) -> tuple[dict | list, str | int]:
    """The table or array holding the entry at a dotted path of a parsed scene, and its key or
    index there; raises a SceneError if the file has no such entry or it is a table or array."""
    node: Any = data
    keys = path.split(".")
    for depth, key in enumerate(keys):
        if isinstance(node, list):
            if not key.isdigit() or int(key) >= len(node):
                raise SceneError(f"parameter {path!r} is not in the scene: {'.'.join(keys[:depth]) or 'it'} is an "
                                 f"array of {len(node)}, indexed from 0, not by {key!r}")
            key = int(key)
        elif not isinstance(node, dict) or key not in node:
            there = f"; that table has {sorted(node)}" if isinstance(node, dict) else ""
            raise SceneError(f"parameter {path!r} is not in the scene (no {key!r}){there}")
        parent, node = node, node[key]
    if isinstance(node, (dict, list)):
        kind = "an array" if isinstance(node, list) else "a table"
        raise SceneError(f"parameter {path!r} names {kind}, not a value: name one of its entries")
    return parent, key


def set_parameter(data: dict, path: str, value: Any) -> None:
    """Set the entry at a dotted path (``"band.0.reduction"``) of a parsed scene."""
    parent, key = entry(data, path)
    current = parent[key]  # type: ignore[index]
    if isinstance(current, Integral) and not isinstance(current, bool) and isinstance(value, Real) \
            and not isinstance(value, (bool, Integral)) and float(value).is_integer():
        value = int(value)
    parent[key] = value  # type: ignore[index]

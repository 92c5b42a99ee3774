"""Overrides: entries of a parsed scene file replaced before it is read, by dotted paths.

A path names table keys and, for ``[[...]]`` tables, array indices: ``"mesh.n_circ"``,
``"band.0.reduction"``. ``load_scene(path, overrides={path: value})`` applies them (the demos'
coarse meshes, the planning sweep's variants); only an entry the file has can be replaced.
"""
from typing import Any

from ..errors import SceneError


def set_parameter(data: dict, path: str, value: Any) -> None:
    """Set the entry at a dotted path (``"band.0.reduction"``) of a parsed scene."""
    *parents, last = path.split(".")
    node = data
    for key in parents:
        try:
            node = node[int(key)] if isinstance(node, list) else node[key]
        except (KeyError, IndexError, ValueError):
            raise SceneError(f"parameter {path!r} is not in the scene (no {key!r})") from None
    if isinstance(node, list):
        raise SceneError(f"parameter {path!r} names a whole array, not a value")
    if last not in node:
        raise SceneError(f"parameter {path!r} is not in the scene (no {last!r}); "
                         f"that table has {sorted(node)}")
    node[last] = value

"""A scene's fingerprint: what decides its answer, so that a checkpoint is resumed only by the
scene that wrote it (output/checkpoint.py).

It holds the scene's name and element, the mesh (its source, the builder's parameters, the
numbers of cells and nodes and a checksum of the node coordinates), the materials, the probes,
the names of the steps, and every feature and observer described by its public attributes of
plain values (numbers, strings, flags, small vectors, a longer array by its shape and a checksum;
a feature it refers to by its name; an object such as a rigid shape by its own attributes). It is
taken before the scene is built, from what the user gave. The solver's settings and the steps'
increments are left out: they choose the path to the answer, not the answer, so a step that did
not converge may be resumed with more increments.

Two fingerprints are compared entry by entry, numbers to a relative 1e-12 (the coordinate
checksum is summed over the ranks in another order on another number of ranks); the first entry
that differs is named in the error.
"""
from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from ..features.base import Feature
from .files import flatten

_PLAIN = (bool, int, float, str, type(None))
_SKIP = object()  # a value that describes nothing (a function, a form, a mesh)
_MAX_ARRAY = 64  # longer arrays (a suture's bite, its points) are described by their shape and a checksum


def describe(value: Any, depth: int = 0) -> Any:
    """The plain-value description of a value (module docstring), or ``_SKIP``."""
    if isinstance(value, _PLAIN):
        return value
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Feature):
        return value.name
    if isinstance(value, np.ndarray):
        if value.size <= _MAX_ARRAY:
            return value.tolist()
        numbers = value.astype(float).ravel()
        return {"shape": list(value.shape), "checksum": math.fsum(numbers * np.arange(1, numbers.size + 1))}
    if isinstance(value, (list, tuple)):
        if len(value) > _MAX_ARRAY:
            return _SKIP
        items = [describe(v, depth) for v in value]
        return [v for v in items if v is not _SKIP]
    if isinstance(value, dict):
        items = {str(k): describe(v, depth) for k, v in value.items()}
        return {k: v for k, v in items.items() if v is not _SKIP}
    if callable(value) or depth >= 2 or not hasattr(value, "__dict__"):
        return _SKIP
    return attributes(value, depth + 1)


def attributes(item: Any, depth: int = 0) -> dict:
    """An object's type and the plain-value descriptions of its public attributes."""
    described = {k: describe(v, depth) for k, v in vars(item).items() if not k.startswith("_")}
    return {"type": type(item).__name__, **{k: v for k, v in described.items() if v is not _SKIP}}


def scene_fingerprint(scene) -> dict:
    """The fingerprint of a ``Scene`` not yet built (collective: the mesh's checksum)."""
    md = scene.mesh
    msh = md.mesh
    nodes = msh.geometry.index_map()
    owned = msh.geometry.x[: nodes.size_local]
    checksums = msh.comm.gather(math.fsum((owned * np.array([1.0, 2.0, 3.0])).ravel()), root=0)
    checksum = msh.comm.bcast(math.fsum(checksums) if msh.comm.rank == 0 else None, root=0)
    data = {
        "scene": scene.name, "element": scene.element,
        "mesh": {"source": str(md.source), "parameters": describe(md.parameters),
                 "cells": msh.topology.index_map(msh.topology.dim).size_global, "nodes": nodes.size_global,
                 "coordinate checksum": checksum},
        "materials": describe(scene.materials), "probes": describe(scene.probes),
        "steps": [step.name for step in scene.steps],
        "features": {f"{i} {type(f).__name__} {f.name}": attributes(f) for i, f in enumerate(scene.features)},
        "observers": {f"{i} {type(o).__name__}": attributes(o) for i, o in enumerate(scene.observers)},
    }
    return json.loads(json.dumps(data))  # as it reads back from a checkpoint: tuples as lists, keys as strings


def first_difference(here: dict, there: dict) -> str | None:
    """The first entry in which two fingerprints differ, in words, or None."""
    ours, theirs = flatten(here), flatten(there)
    for key in sorted(set(ours) | set(theirs)):
        a, b = ours.get(key, "(none)"), theirs.get(key, "(none)")
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (a, b))
        if (numbers and not math.isclose(a, b, rel_tol=1e-12)) or (not numbers and a != b):
            return f"{key} is {a!r} in this scene and {b!r} in the checkpoint"
    return None

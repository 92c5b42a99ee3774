"""Tissue sets: the eye's materials as data, chosen by a scene file's ``tissues = "<name>"``.

A set is a TOML file eyeball_fenicsx/tissues/<name>.toml of ``[materials.<region>]`` tables,
each constant with its source in the file's comments ("seed": the seed's constants, Sun &
Makinouchi; "calibrated": living human eyes, the sclera fitted to Pallikaris et al.'s ocular
rigidity, IOVS 2005;46:409). The scene's own ``[materials.<region>]`` tables replace or add
to the set's; a dotted override ``materials.<region>...`` of a region left to the set
reaches the set's table (``tables_for``).
"""
import copy
import os
import tomllib
from collections.abc import Iterable

from ..errors import SceneError

TISSUE_SETS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tissues")


def tissue_set(name: str | None, path: str) -> dict[str, tuple[dict, str]]:
    """The [materials.<region>] tables of the tissue set ``name`` (none if None) as {region:
    (table, where)}, ``where`` naming the scene file ``path`` and the set's file."""
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


def tables_for(data: dict, parameters: Iterable[str], path: str) -> None:
    """Copy into a parsed scene ``data`` the tissue set's ``[materials.<region>]`` table of each
    dotted parameter ``materials.<region>...`` whose region the scene leaves to its set, so that
    the parameter names an entry of ``data`` (the planning sweep's ranges of tissue constants)."""
    materials, name = data.get("materials", {}), data.get("tissues")
    if not isinstance(materials, dict) or not isinstance(name, str):
        return  # no set, or a file the loader refuses with its own message
    for parameter in parameters:
        parts = parameter.split(".")
        if len(parts) > 2 and parts[0] == "materials" and parts[1] not in materials:
            tables = tissue_set(name, path)
            if parts[1] in tables:
                materials[parts[1]] = copy.deepcopy(tables[parts[1]][0])
                data["materials"] = materials

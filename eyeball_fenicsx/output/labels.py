"""Readable names for the figures of summary.json, for plots, tables and reports.

A flattened key (``eye.max_mises_MPa.band``, ``band.0.reduction``) becomes what a surgeon reads
("largest von Mises stress, band (MPa)", "band 1: reduction"; a tissue's constant
``materials.sclera.c.10``: "sclera: c10 (MPa)"). Keys this module does not know
keep their own text, with the dots shown as " / ", so a new measure is never hidden.
"""
from __future__ import annotations

# The eye measures (output/measures.py), each with its unit.
MEASURES = {
    "axial_length_mm": "axial length (mm)",
    "axial_length_change_mm": "axial length change from pre-op (mm)",
    "refraction_change_D": "refraction change from pre-op (D)",
    "axial_length_change_from_mesh_mm": "axial length change from the mesh (mm)",
    "refraction_change_from_mesh_D": "refraction change from the mesh (D)",
    "iop_mmHg": "IOP (mmHg)",
    "buckle_height_mm": "buckle height (mm)",
    "retina_gap_max_mm": "largest retina-choroid gap (mm)",
    "detached_area_mm2": "detached retina (mm\u00b2)",
    "retina_penetration_max_mm": "retina through the choroid (mm)",
    "penetrated_area_mm2": "retina through the choroid, area (mm\u00b2)",
    "reattached_fraction": "reattached fraction of the detachment",
    "subretinal_volume_mm3": "subretinal fluid (mm\u00b3)",
}

# The features' figures in a step's entry: {group: what it is}, {last key: its name and unit}.
FEATURE_GROUPS = {"cavities": "liquid", "contact": "contact", "bands": "band"}
FEATURE_FIGURES = {
    "pressure": "pressure (MPa)",
    "volume": "volume (mm\u00b3)",
    "drained_volume": "drained volume (mm\u00b3)",
    "force": "force (N)",
    "active_points": "points in contact",
    "max_penetration": "largest penetration (mm)",
    "circumference": "circumference (mm)",
    "rest_stretch": "rest length / initial length",
}

# Scene-file parameters a sweep commonly varies (dotted paths with the array index as "0").
PARAMETERS = {
    "reduction": "circumference reduction (mm)",
    "band_width": "band width (mm)",
    "band_position": "band position behind the limbus (mm)",
    "shortening": "suture shortening (mm)",
    "tension": "suture tension (N)",
    "axial_length": "axial length (mm)",
    "c10": "c10 (MPa)",
    "c01": "c01 (MPa)",
    "c20": "c20 (MPa)",
}


def label(key: str) -> str:
    """The readable name of a flattened summary key or a scene parameter path."""
    parts = key.split(".")
    if parts[0] == "eye" and len(parts) >= 2:
        if parts[1] == "max_mises_MPa" and len(parts) == 3:
            return f"largest von Mises stress, {parts[2].replace('_', ' ')} (MPa)"
        if parts[1] in MEASURES and len(parts) == 2:
            return MEASURES[parts[1]]
    if parts[0] == "materials" and len(parts) == 4 and parts[2] == "c":  # a Mooney-Rivlin constant c_rs
        return f"{parts[1].replace('_', ' ')}: c{parts[3]} (MPa)"
    if len(parts) == 3 and parts[0] in FEATURE_GROUPS and parts[2] in FEATURE_FIGURES:
        return f"{FEATURE_GROUPS[parts[0]]} {parts[1]}: {FEATURE_FIGURES[parts[2]]}"
    if parts[-1] in PARAMETERS:
        owner = [p if not p.isdigit() else str(int(p) + 1) for p in parts[:-1]]
        owner = [p.replace("_", " ") for p in owner if p not in ("mesh", "materials")]
        text = PARAMETERS[parts[-1]]
        return f"{' '.join(owner)}: {text}" if owner else text
    return " / ".join(parts)

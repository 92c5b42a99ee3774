"""eyeball-fenicsx: finite-element simulation of scleral buckling surgery on FEniCSx.

The public API is imported on first use (PEP 562), so that the gmsh mesh builders
(``eyeball_fenicsx.meshing.builders``) and the error types import without DOLFINx.
"""
import importlib

_PUBLIC = {
    "ContactPair": "contact", "RigidContact": "contact",
    "ConvergenceError": "errors", "Interrupted": "errors", "SceneError": "errors",
    "Dirichlet": "features.loads", "NodalForce": "features.loads", "Pressure": "features.loads",
    "LiquidCavity": "features.cavity", "Injection": "features.cavity", "Drainage": "features.cavity",
    "Suture": "features.sutures", "BandTightening": "features.band",
    "FibreReinforced": "mechanics.materials", "LinearElastic": "mechanics.materials",
    "MooneyRivlin": "mechanics.materials", "NeoHooke": "mechanics.materials",
    "EyeMeasures": "output.measures", "EyePictures": "output.eye_pictures", "RunReport": "output.report",
    "Scene": "scene.scene", "Step": "scene.scene", "load_scene": "scene.loader",
    "SolverSettings": "system.settings",
    "load_mesh": "meshing.load", "built_mesh": "meshing.load",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'eyeball_fenicsx' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{_PUBLIC[name]}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return __all__

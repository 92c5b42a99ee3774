"""eyeball-fenicsx: finite-element simulation of scleral buckling surgery on FEniCSx."""
from .errors import ConvergenceError, SceneError
from .loads import Dirichlet, NodalForce, Pressure
from .materials import LinearElastic, MooneyRivlin, NeoHooke
from .scene import Scene, Step
from .solver import SolverSettings

__all__ = ["ConvergenceError", "SceneError", "Dirichlet", "NodalForce", "Pressure", "LinearElastic",
           "MooneyRivlin", "NeoHooke", "Scene", "Step", "SolverSettings"]

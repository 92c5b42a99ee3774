"""eyeball-fenicsx: finite-element simulation of scleral buckling surgery on FEniCSx."""
from .contact import ContactPair, RigidContact
from .errors import ConvergenceError, SceneError
from .loads import Dirichlet, NodalForce, Pressure
from .materials import LinearElastic, MooneyRivlin, NeoHooke
from .scene import Scene, Step
from .stepping import SolverSettings

__all__ = ["ContactPair", "RigidContact", "ConvergenceError", "SceneError", "Dirichlet", "NodalForce", "Pressure", "LinearElastic",
           "MooneyRivlin", "NeoHooke", "Scene", "Step", "SolverSettings"]

# A rank that finds another process compiling the same form waits for it; DOLFINx 0.5 gives
# up after 10 s, too short for the eye's forms on a busy two-core machine.
import dolfinx.jit as _jit  # noqa: E402

_jit.DOLFINX_DEFAULT_JIT_PARAMETERS["timeout"] = (600, _jit.DOLFINX_DEFAULT_JIT_PARAMETERS["timeout"][1])

"""warp_sim: physically based animation in NVIDIA Warp kernels, written to USD stages.

The public API: build a Scene, run it with a Simulator, read the State or the USD stage.
"""
from .emitters import Ramp
from .fields import Attractor, Turbulence, Vortex
from .guards import SimulationDiverged
from .integrators import INTEGRATORS, AdaptiveStepFailed
from .model import Model, State
from .scene import Scene
from .shapes import Box, Capsule, Cylinder, MassProperties, MeshShape, PointMasses, Shape, Sphere
from .simulator import Simulator

__version__ = "0.1.0"
__all__ = ["Scene", "Simulator", "Model", "State", "SimulationDiverged", "AdaptiveStepFailed", "INTEGRATORS",
           "Shape", "Sphere", "Box", "Capsule", "Cylinder", "MeshShape", "PointMasses", "MassProperties", "Ramp",
           "Attractor", "Vortex", "Turbulence", "__version__"]

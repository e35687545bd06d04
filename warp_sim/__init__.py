"""warp_sim: physically based animation in NVIDIA Warp kernels, written to USD stages.

The public API: build a Scene, run it with a Simulator, read the State or the USD stage.
"""
from .util import interrupts  # first of all: a Ctrl-C while the libraries load is recorded, never swallowed  # noqa: I001
from .util.verbosity import set_verbose  # then: Warp stays quiet unless asked (ws.set_verbose(True))
from .core import Control, Model, SimulationDiverged, State
from .scene import (
                    Attractor,
                    Box,
                    Capsule,
                    Cylinder,
                    D6,
                    Drive,
                    MassProperties,
                    MeshShape,
                    PointMasses,
                    Ramp,
                    Scene,
                    Shape,
                    Sphere,
                    Turbulence,
                    Vortex,
)
from . import examples as examples  # ws.examples: the shipped stages (a module: api_docs lists no module)
from .simulator import RunInterrupted, Simulator
from .gradients import gradient
from .sweep import SweepResult, sweep
from .solvers import (
                    INTEGRATORS,
                    RK4,
                    RK45,
                    AdaptiveStepFailed,
                    Euler,
                    ImplicitEuler,
                    Integrator,
                    Midpoint,
                    SymplecticEuler,
                    VelocityVerlet,
)
from .util.version import __version__

__all__ = ["Scene", "Simulator", "Model", "State", "Control", "SimulationDiverged", "AdaptiveStepFailed",
           "INTEGRATORS", "Integrator", "Euler", "Midpoint", "RK4", "SymplecticEuler", "VelocityVerlet",
           "ImplicitEuler", "RK45", "Shape", "Sphere", "Box", "Capsule", "Cylinder", "MeshShape", "PointMasses",
           "MassProperties", "Drive", "D6", "Ramp", "Attractor", "Vortex", "Turbulence", "RunInterrupted",
           "set_verbose", "sweep", "SweepResult", "gradient", "__version__"]
interrupts.release()   # the previous handlers back (the command keeps recording until its main)

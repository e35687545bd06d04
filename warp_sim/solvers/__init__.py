"""ODE solvers written once over the flat state: explicit, partitioned, implicit Euler, adaptive rk45; the registry."""
from .adaptive import RK45, AdaptiveStepFailed
from .base import Integrator
from .explicit import RK4, Euler, Midpoint
from .implicit import ImplicitEuler
from .partitioned import Partitioned, SymplecticEuler, VelocityVerlet
from .registry import INTEGRATORS, make_integrator

__all__ = ["Integrator", "Euler", "Midpoint", "RK4", "Partitioned", "SymplecticEuler", "VelocityVerlet",
           "ImplicitEuler", "RK45", "AdaptiveStepFailed", "INTEGRATORS", "make_integrator"]

"""The simulation's core: Model (constants), State (changes every step), Control (what the user sets
while it runs), the component / force-term / pass protocols, the components, Dynamics, guards and
the launcher."""
from .components import Particles, RigidBodies
from .control import Control
from .dynamics import Dynamics
from .guards import Guard, SimulationDiverged
from .model import Model
from .protocols import Component, Forces, ForceTerm, Pass
from .state import State, StateField, StateLayout

__all__ = ["Model", "State", "StateField", "StateLayout", "Control", "Component", "ForceTerm", "Pass", "Forces",
           "Particles", "RigidBodies", "Dynamics", "Guard", "SimulationDiverged"]

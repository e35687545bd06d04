"""The right-hand side of the ODE over the components and force terms a simulation was assembled with.

The ODE solvers see only ``Dynamics``: the full derivative dy/dt, or its velocity and
position parts for the partitioned (symplectic) schemes. Which components and force
terms exist is decided in ``warp_sim.assembly``; nothing here names one.
"""
from __future__ import annotations

from .model import Model
from .protocols import Component, Forces, ForceTerm
from .state import State, StateLayout


class Dynamics:
    """dy/dt of the given components under the given force terms.

    model: the Model; components: the state owners, in layout order; force_terms: what fills
    ``forces`` (the accumulators) before the components turn them into rates.
    particle_force: None, or a force on each particle (vec3) [N] that the particles' accumulator starts from, in a
    differentiable run (the frame's row of a per-frame control, ws.gradient)
    pool: None, or where ``new_state`` takes its states from (gradients.pool.StatePool, in ws.gradient)

    In a differentiable run (``model.differentiable``) every new state has gradients and every evaluation of the
    forces writes fresh accumulators (``Forces.renew``).
    """

    def __init__(self, model: Model, components: list[Component], force_terms: list[ForceTerm], forces: Forces):
        self.model = model
        self.components = list(components)
        self.force_terms = list(force_terms)
        self.forces = forces
        self.layout = StateLayout([field for c in self.components for field in c.fields])
        self.position_rates_need_positions = any(c.position_rates_need_positions for c in self.components)
        self.particle_force = None
        self.pool = None

    def component(self, name: str) -> Component | None:
        """The component called ``name`` ("particles", "bodies"), or None when absent."""
        return next((c for c in self.components if c.name == name), None)

    def new_state(self) -> State:
        """A zeroed state of this system's layout on the model's device (with gradients in a differentiable run),
        taken from ``pool`` where one is set (a differentiable run's frame of scratch states: gradients.pool)."""
        if self.pool is not None:
            return self.pool.take()
        return self.fresh_state()

    def fresh_state(self) -> State:
        """new_state() newly allocated, never from the pool."""
        state = State(self.layout, self.model.scalar, self.model.device, self.model.differentiable)
        for component in self.components:
            component.attach(state)
        return state

    def initial_state(self, scene) -> State:
        """A state holding the scene's initial values."""
        state = self.new_state()
        for component in self.components:
            component.set_initial(state, scene)
        return state

    def accumulate_forces(self, state: State, t: float) -> None:
        """Clear the force accumulators (renew them, in a differentiable run) and add every force term's forces at
        (t, ``state``)."""
        if self.model.differentiable:
            self.forces.renew(self.particle_force)
        else:
            self.forces.clear()
        for term in self.force_terms:
            term.apply(state, t, self.forces)

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        """Accumulate forces at ``state`` and write the velocity-block rates into ``out``."""
        self.accumulate_forces(state, t)
        for component in self.components:
            component.velocity_derivative(state, t, out)

    def position_derivative(self, positions: State, velocities: State, out: State) -> None:
        """Write the position-block rates into ``out`` (see Component.position_derivative)."""
        for component in self.components:
            component.position_derivative(positions, velocities, out)

    def derivative(self, state: State, t: float, out: State) -> None:
        """The full dy/dt at (t, state) into ``out``."""
        self.velocity_derivative(state, t, out)
        self.position_derivative(state, state, out)

    def post_step(self, state: State) -> None:
        """Every component's projection after a step (e.g. unit quaternions)."""
        for component in self.components:
            component.post_step(state)

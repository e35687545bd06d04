"""The right-hand side of the ODE: components (state owners) and force terms.

A component owns state fields and turns forces into derivatives; a force term
adds forces into the components' accumulators. The ODE solvers see only
``Dynamics``: the full derivative dy/dt, or its velocity and position parts for
the partitioned (symplectic) schemes. A new component or force term plugs in
here and needs no change to any solver.
"""
from __future__ import annotations

import warp as wp

from .kernels import integrate
from .kernels import particles as particle_kernels
from .kernels import springs as spring_kernels
from .model import Field, Model, State, StateLayout


class Component:
    """Owner of some state fields. Subclasses set ``name`` and ``fields``."""

    name = "component"
    fields: list[Field] = []

    def set_initial(self, state: State) -> None:
        """Write the scene's initial values into ``state``."""

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        """Write the rates of the velocity-block fields (accelerations, torques) into ``out``."""

    def position_derivative(self, positions: State, velocities: State, out: State) -> None:
        """Write the rates of the position-block fields into ``out``, reading the
        position fields of ``positions`` and the velocity fields of ``velocities``."""

    def post_step(self, state: State) -> None:
        """Project the state after a step (e.g. renormalise orientations)."""

    def guard_arrays(self, state: State):
        """(positions [m], velocities [m/s]) arrays the divergence guard checks."""
        raise NotImplementedError


class Particles(Component):
    """Point masses: x' = v, v' = g + (f + drag (wind - v)) / m; pinned particles have 1/m = 0."""

    name = "particles"

    def __init__(self, model: Model, forces: "Forces"):
        self.model = model
        self.forces = forces
        self.fields = [Field("particle_x", "position", 3, model.particle_count),
                       Field("particle_v", "velocity", 3, model.particle_count)]

    def set_initial(self, state: State) -> None:
        scene = self.model.scene
        state.particle_x.assign(scene.particle_array("position").astype(self.model.numpy_scalar))
        state.particle_v.assign(scene.particle_array("velocity").astype(self.model.numpy_scalar))

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        m = self.model
        m.launch(particle_kernels.particle_acceleration, m.particle_count,
                 [state.particle_v, self.forces.particle_f, m.particle_inv_mass, m.gravity, m.drag, m.wind,
                  out.particle_v])

    def position_derivative(self, positions: State, velocities: State, out: State) -> None:
        self.model.launch(integrate.copy, self.model.particle_count, [velocities.particle_v, out.particle_x])

    def guard_arrays(self, state: State):
        return state.particle_x, state.particle_v


class ForceTerm:
    """Something that adds forces into the accumulators, given a state."""

    def apply(self, state: State, t: float, forces: "Forces") -> None:
        raise NotImplementedError


class Springs(ForceTerm):
    """Damped Hooke springs between particle pairs."""

    def __init__(self, model: Model):
        self.model = model

    def apply(self, state: State, t: float, forces: "Forces") -> None:
        m = self.model
        m.launch(spring_kernels.spring_forces, m.spring_count,
                 [state.particle_x, state.particle_v, m.spring_pairs, m.spring_stiffness, m.spring_damping,
                  m.spring_rest_length, forces.particle_f])


class Forces:
    """Force accumulators, allocated only when some force term writes them (else empty arrays)."""

    def __init__(self, model: Model, needed: bool):
        count = model.particle_count if needed else 0
        self.particle_f = wp.zeros(count, dtype=model.vec3, device=model.device)
        self.arrays = [self.particle_f] if needed else []

    def clear(self) -> None:
        for array in self.arrays:
            array.zero_()


class Dynamics:
    """The scene's ODE right-hand side over the components and force terms that are present.

    extra_force_terms: force terms from elsewhere (e.g. penalty contacts).
    """

    def __init__(self, model: Model, extra_force_terms=()):
        self.model = model
        self.force_terms: list[ForceTerm] = []
        if model.spring_count:
            self.force_terms.append(Springs(model))
        self.force_terms.extend(extra_force_terms)
        self.forces = Forces(model, needed=bool(self.force_terms))
        self.components: list[Component] = []
        if model.particle_count:
            self.components.append(Particles(model, self.forces))
        self.layout = StateLayout([field for c in self.components for field in c.fields])

    def new_state(self) -> State:
        """A zeroed state of this system's layout on the model's device."""
        return State(self.layout, self.model.scalar, self.model.device)

    def initial_state(self) -> State:
        state = self.new_state()
        for component in self.components:
            component.set_initial(state)
        return state

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        """Accumulate forces at ``state`` and write the velocity-block rates into ``out``."""
        self.forces.clear()
        for term in self.force_terms:
            term.apply(state, t, self.forces)
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
        for component in self.components:
            component.post_step(state)

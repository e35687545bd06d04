"""The right-hand side of the ODE: components (state owners) and force terms.

A component owns state fields and turns forces into derivatives; a force term
adds forces into the components' accumulators. The ODE solvers see only
``Dynamics``: the full derivative dy/dt, or its velocity and position parts for
the partitioned (symplectic) schemes. A new component or force term plugs in
here and needs no change to any solver.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from .kernels import guards as guard_kernels
from .kernels import integrate
from .kernels import particles as particle_kernels
from .kernels import rigid as rigid_kernels
from .kernels import springs as spring_kernels
from .model import Field, Model, State, StateLayout


def _show(values, unit: str) -> str:
    return f"{np.array2string(np.asarray(values, dtype=np.float64), precision=4)} {unit}".rstrip()


class Component:
    """Owner of some state fields. Subclasses set ``name`` and ``fields``."""

    name = "component"
    fields: list[Field] = []
    #: whether the position-block rates read the position block too (not only velocities)
    position_rates_need_positions = False

    def set_initial(self, state: State) -> None:
        """Write the scene's initial values into ``state``."""

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        """Write the rates of the velocity-block fields (accelerations, torques) into ``out``."""

    def position_derivative(self, positions: State, velocities: State, out: State) -> None:
        """Write the rates of the position-block fields into ``out``, reading the
        position fields of ``positions`` and the velocity fields of ``velocities``."""

    def post_step(self, state: State) -> None:
        """Project the state after a step (e.g. renormalise orientations)."""

    #: the divergence guard's reason codes (see kernels.guards) in this component's words
    guard_reasons = {0: "non-finite position", 1: "non-finite velocity", 2: "speed above max_speed"}

    def guard_inputs(self, state: State):
        """(guard kernel, its leading inputs): the kernel takes these, then max_speed, step and the records."""
        raise NotImplementedError

    def describe(self, state: State, element: int) -> str:
        """The current values of one element, for error messages."""
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

    def guard_inputs(self, state: State):
        return guard_kernels.check_finite_and_bounded, [state.particle_x, state.particle_v]

    def describe(self, state: State, element: int) -> str:
        return (f"x = {_show(state.particle_x.numpy()[element], 'm')}, "
                f"v = {_show(state.particle_v.numpy()[element], 'm/s')}")


class RigidBodies(Component):
    """Rigid bodies, the lecture's S = [x, R, P, L] with R as a unit quaternion q.

    x' = P / M, q' = 1/2 (omega, 0) q, P' = F, L' = tau with omega = R I_body^-1 R^T L;
    q is renormalised after every step.
    """

    name = "bodies"
    position_rates_need_positions = True     # omega depends on the orientation
    guard_reasons = {0: "non-finite position or orientation", 1: "non-finite momentum",
                     2: "speed above max_speed"}

    def __init__(self, model: Model, forces: "Forces"):
        self.model = model
        self.forces = forces
        count = model.body_count
        self.fields = [Field("body_x", "position", 3, count), Field("body_q", "position", 4, count),
                       Field("body_P", "velocity", 3, count), Field("body_L", "velocity", 3, count)]

    def set_initial(self, state: State) -> None:
        scene, dtype = self.model.scene, self.model.numpy_scalar
        for field, key in (("body_x", "position"), ("body_q", "orientation"), ("body_P", "momentum"),
                           ("body_L", "angular_momentum")):
            getattr(state, field).assign(scene.body_array(key).astype(dtype))

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        m, f = self.model, self.forces
        m.launch(rigid_kernels.body_momentum_rates, m.body_count,
                 [state.body_q, state.body_P, state.body_L, m.body_inv_mass, m.body_inv_inertia, m.body_drag,
                  m.body_angular_drag, m.gravity, m.wind, m.body_user_force, m.body_user_torque, f.body_f,
                  f.body_t, out.body_P, out.body_L])

    def position_derivative(self, positions: State, velocities: State, out: State) -> None:
        m = self.model
        m.launch(rigid_kernels.body_position_rates, m.body_count,
                 [positions.body_q, velocities.body_P, velocities.body_L, m.body_inv_mass, m.body_inv_inertia,
                  out.body_x, out.body_q])

    def post_step(self, state: State) -> None:
        self.model.launch(rigid_kernels.normalize_orientations, self.model.body_count, [state.body_q])

    def velocities(self, state: State, v: wp.array, omega: wp.array) -> None:
        """Write the auxiliaries v = P / M [m/s] and omega [rad/s] of ``state`` into v and omega."""
        m = self.model
        m.launch(rigid_kernels.body_velocities, m.body_count,
                 [state.body_q, state.body_P, state.body_L, m.body_inv_mass, m.body_inv_inertia, v, omega])

    def guard_inputs(self, state: State):
        return guard_kernels.check_bodies, [state.body_x, state.body_q, state.body_P, state.body_L,
                                            self.model.body_inv_mass]

    def describe(self, state: State, element: int) -> str:
        values = {name: getattr(state, name).numpy()[element] for name in ("body_x", "body_q", "body_P", "body_L")}
        return (f"x = {_show(values['body_x'], 'm')}, q = {_show(values['body_q'], '')}, "
                f"P = {_show(values['body_P'], 'kg m/s')}, L = {_show(values['body_L'], 'kg m^2/s')}")


class ForceTerm:
    """Something that adds forces into the accumulators, given a state.

    ``targets``: the components whose accumulators it writes ("particles", "bodies").
    """

    targets = frozenset({"particles"})

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
    """Force accumulators, allocated only for components some force term writes (else empty arrays).

    particle_f [N] per particle; body_f [N] and body_t (torque about the centre of mass) [N m] per body.
    """

    def __init__(self, model: Model, targets: set):
        def accumulator(component: str, count: int):
            return wp.zeros(count if component in targets else 0, dtype=model.vec3, device=model.device)

        self.particle_f = accumulator("particles", model.particle_count)
        self.body_f = accumulator("bodies", model.body_count)
        self.body_t = accumulator("bodies", model.body_count)
        self.arrays = [a for a in (self.particle_f, self.body_f, self.body_t) if a.shape[0] > 0]

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
        if model.scene.fields and model.particle_count:
            from .fields import FieldForces

            self.force_terms.append(FieldForces(model))
        if any(mesh.drag or mesh.lift for mesh in model.scene.meshes):
            from .aerodynamics import AeroForces

            self.force_terms.append(AeroForces(model))
        self.force_terms.extend(extra_force_terms)
        self.forces = Forces(model, set().union(*(term.targets for term in self.force_terms)))
        self.components: list[Component] = []
        if model.particle_count:
            self.components.append(Particles(model, self.forces))
        self.bodies = RigidBodies(model, self.forces) if model.body_count else None
        if self.bodies is not None:
            self.components.append(self.bodies)
        self.layout = StateLayout([field for c in self.components for field in c.fields])
        self.position_rates_need_positions = any(c.position_rates_need_positions for c in self.components)

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

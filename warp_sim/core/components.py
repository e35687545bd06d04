"""The state owners: particles and rigid bodies, each turning forces into the rates of its fields."""
from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import blocks, integrate
from ..kernels import guards as guard_kernels
from ..kernels import particles as particle_kernels
from ..kernels import rigid as rigid_kernels
from .control import Control
from .model import Model
from .protocols import Component, Forces
from .state import State, StateField


def _show(values, unit: str) -> str:
    return f"{np.array2string(np.asarray(values, dtype=np.float64), precision=4)} {unit}".rstrip()


class Particles(Component):
    """Point masses: x' = v, v' = g + (f + drag (wind - v)) / m; pinned particles have 1/m = 0.

    Fields: particle_x [m], particle_v [m/s].
    """

    name = "particles"
    kernels = ("particles", "integrate")

    def __init__(self, model: Model, forces: Forces):
        self.model = model
        self.forces = forces
        self.fields = [StateField("particle_x", "position", 3, model.particle_count),
                       StateField("particle_v", "velocity", 3, model.particle_count)]

    def set_initial(self, state: State, scene) -> None:
        state.particle_x.assign(scene.particle_array("position").astype(self.model.numpy_scalar))
        state.particle_v.assign(scene.particle_array("velocity").astype(self.model.numpy_scalar))

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        m = self.model
        m.launcher.launch_elementwise(particle_kernels.particle_acceleration, m.particle_count,
                                      [state.particle_v, self.forces.particle_f, m.particle_inv_mass, m.gravity,
                                       m.drag, m.wind, out.particle_v])

    def position_derivative(self, positions: State, velocities: State, out: State) -> None:
        self.model.launcher.launch_elementwise(integrate.copy, self.model.particle_count,
                                               [velocities.particle_v, out.particle_x])

    def guard_inputs(self, state: State):
        return guard_kernels.check_finite_and_bounded, self.model.particle_count, [state.particle_x, state.particle_v]

    def locate(self, element: int) -> str:
        """Where global particle ``element`` belongs: its group's name and its index within the group."""
        for name, start, count in self.model.particle_groups:
            if start <= element < start + count:
                return f"particle {element - start} of group {name!r}"
        return f"particle {element}"

    def describe(self, state: State, element: int) -> str:
        return (f"x = {_show(state.particle_x.numpy()[element], 'm')}, "
                f"v = {_show(state.particle_v.numpy()[element], 'm/s')}")


class RigidBodies(Component):
    """Rigid bodies, the lecture's S = [x, R, P, L] with R as a unit quaternion q.

    x' = P / M, q' = 1/2 (omega, 0) q, P' = F, L' = tau with omega = R I_body^-1 R^T L;
    q is renormalised after every step. F and tau include the held inputs of the Control.
    Fields: body_x [m], body_q (x, y, z, w), body_P [kg m/s], body_L [kg m^2/s].
    """

    name = "bodies"
    kernels = ("rigid", "integrate")
    position_rates_need_positions = True     # omega depends on the orientation
    guard_reasons = {0: "non-finite position or orientation", 1: "non-finite momentum",
                     2: "speed above max_speed"}

    def __init__(self, model: Model, forces: Forces, control: Control):
        self.model = model
        self.forces = forces
        self.control = control
        count = model.body_count
        self.fields = [StateField("body_x", "position", 3, count), StateField("body_q", "position", 4, count),
                       StateField("body_P", "velocity", 3, count), StateField("body_L", "velocity", 3, count)]

    def attach(self, state: State) -> None:
        """state.bodies: the body fields as a kernels.blocks Bodies struct."""
        state.bodies = blocks.fill(self.model.blocks.Bodies, x=state.body_x, q=state.body_q, P=state.body_P,
                                   L=state.body_L)

    def set_initial(self, state: State, scene) -> None:
        dtype = self.model.numpy_scalar
        for field, key in (("body_x", "position"), ("body_q", "orientation"), ("body_P", "momentum"),
                           ("body_L", "angular_momentum")):
            getattr(state, field).assign(scene.body_array(key).astype(dtype))

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        m, f, c = self.model, self.forces, self.control
        m.launch(rigid_kernels.body_momentum_rates, m.body_count,
                 [state.bodies, m.body_mass, m.body_drag, m.body_angular_drag, m.gravity, m.wind, c.held,
                  f.body_wrench, out.bodies])

    def position_derivative(self, positions: State, velocities: State, out: State) -> None:
        m = self.model
        m.launch(rigid_kernels.body_position_rates, m.body_count, [positions.bodies, velocities.bodies,
                                                                   m.body_mass, out.bodies])

    def post_step(self, state: State) -> None:
        self.model.launcher.launch_in_place(rigid_kernels.normalize_orientations, self.model.body_count,
                                            [state.body_q], state.body_q)

    def velocities(self, state: State, v: wp.array, omega: wp.array) -> None:
        """Write the auxiliaries v = P / M [m/s] and omega [rad/s] of ``state`` into v and omega."""
        m = self.model
        m.launch(rigid_kernels.body_velocities, m.body_count, [state.bodies, m.body_mass, v, omega])

    def guard_inputs(self, state: State):
        return guard_kernels.check_bodies, self.model.body_count, [state.bodies, self.model.body_mass]

    def locate(self, element: int) -> str:
        """Body ``element`` by its name."""
        return f"body {self.model.body_names[element]!r}"

    def describe(self, state: State, element: int) -> str:
        values = {name: getattr(state, name).numpy()[element] for name in ("body_x", "body_q", "body_P", "body_L")}
        return (f"x = {_show(values['body_x'], 'm')}, q = {_show(values['body_q'], '')}, "
                f"P = {_show(values['body_P'], 'kg m/s')}, L = {_show(values['body_L'], 'kg m^2/s')}")

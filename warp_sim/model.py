"""Model (constants) and State (time-varying), struct-of-arrays Warp arrays on one device.

A State is one flat buffer of scalars: every component's position-like fields
first (the position block), then every velocity-like field (the velocity block).
Each field is also a typed view into that buffer (``state.particle_x`` is a
``wp.array`` of vec3), so the ODE solvers update the whole state with one launch
while components read and write their own named arrays.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from .launcher import Launcher
from .scene import Scene

SCALARS = {"float32": (wp.float32, wp.vec3f, np.float32), "float64": (wp.float64, wp.vec3d, np.float64)}
MATRICES = {wp.float32: wp.mat33f, wp.float64: wp.mat33d}
BLOCKS = ("position", "velocity")
# the canonical Warp vector types of a field, by scalar type and width (vector, quaternion)
ELEMENT_TYPES = {wp.float32: {3: wp.vec3f, 4: wp.quatf}, wp.float64: {3: wp.vec3d, 4: wp.quatd}}


@dataclass(frozen=True)
class Field:
    """One named per-element array of a component's state.

    block: "position" (x-like: integrated from the position derivative) or
    "velocity" (v- or momentum-like: integrated from forces); width: scalars per
    element (3 for a vector, 4 for a quaternion); count: elements.
    """
    name: str
    block: str
    width: int
    count: int


class StateLayout:
    """Where each Field lies in the flat state buffer: position block, then velocity block."""

    def __init__(self, fields: list[Field]):
        self.fields = list(fields)
        self.offsets: dict[str, int] = {}
        offset = 0
        self.block_start = {}
        for block in BLOCKS:
            self.block_start[block] = offset
            for field in self.fields:
                if field.block == block:
                    self.offsets[field.name] = offset
                    offset += field.width * field.count
        self.position_size = self.block_start["velocity"]
        self.size = offset


class State:
    """The time-varying state: ``y`` (flat), ``position`` and ``velocity`` (its two
    blocks) and one typed view per field, e.g. ``particle_x`` [m], ``particle_v`` [m/s]."""

    def __init__(self, layout: StateLayout, scalar, device):
        self.layout = layout
        self.y = wp.zeros(layout.size, dtype=scalar, device=device)
        self.position = self.y[: layout.position_size]
        self.velocity = self.y[layout.position_size:]
        vector_types = ELEMENT_TYPES[scalar]
        for field in layout.fields:
            start = layout.offsets[field.name]
            flat = self.y[start: start + field.width * field.count]
            setattr(self, field.name, flat.reshape((field.count, field.width)).view(vector_types[field.width]))

    def assign(self, other: "State") -> None:
        """Copy every value of another state of the same layout into this one."""
        wp.copy(self.y, other.y)


def _array(values, dtype, device):
    return wp.array(np.ascontiguousarray(values), dtype=dtype, device=device)


class Model:
    """Constants of a scene on a device, struct-of-arrays.

    Arrays of a component the scene lacks are None and never allocated:
    bodies (body_inv_mass [1/kg], body_inv_inertia: I_body^-1 (mat33, body frame)
    [1/(kg m^2)], body_drag [N s/m], body_angular_drag [N m s/rad], body_restitution,
    body_friction; and the user's held inputs body_user_force [N] and
    body_user_torque [N m], world frame, zero until set), particles
    (particle_inv_mass [1/kg], particle_radius [m], particle_restitution,
    particle_friction: empty where no particle has its own value; an emitter's
    pool slots change their inverse mass and radius at births and deaths), springs
    (spring_pairs, spring_stiffness [N/m], spring_damping [N s/m],
    spring_rest_length [m]), planes (plane_normal, plane_offset [m],
    plane_restitution, plane_friction). gravity [m/s^2], drag [N s/m] and wind
    [m/s] are kernel-ready values of the model's precision.
    """

    def __init__(self, scene: Scene, device):
        self.scene = scene
        self.device = wp.get_device(device)
        self.launcher = Launcher(self.device)
        self.launch = self.launcher.launch
        self.scalar, self.vec3, self.numpy_scalar = SCALARS[scene.precision]
        self.gravity = self.vec3(*scene.gravity)
        self.drag = self.scalar(scene.drag)
        self.wind = self.vec3(*scene.wind)
        self.particle_count = scene.particle_count
        self.spring_count = scene.spring_count
        self.plane_count = len(scene.planes)
        self.body_count = scene.body_count
        self.mat33 = MATRICES[self.scalar]
        for name in ("body_inv_mass", "body_inv_inertia", "body_drag", "body_angular_drag", "body_restitution",
                     "body_friction", "body_user_force", "body_user_torque",
                     "particle_inv_mass", "particle_radius", "particle_restitution", "particle_friction",
                     "spring_pairs", "spring_stiffness", "spring_damping", "spring_rest_length",
                     "plane_normal", "plane_offset", "plane_restitution", "plane_friction"):
            setattr(self, name, None)
        if self.particle_count:
            self._build_particles(scene)
        if self.spring_count:
            self._build_springs(scene)
        if self.body_count:
            self._build_bodies(scene)
        if self.plane_count:
            self._build_planes(scene)

    def _build_particles(self, scene: Scene) -> None:
        mass = scene.particle_array("mass")
        inv_mass = np.where(scene.particle_array("pinned"), 0.0, 1.0 / mass)
        self.particle_inv_mass = _array(inv_mass, self.scalar, self.device)
        self.particle_radius = _array(scene.particle_array("radius"), self.scalar, self.device)
        for key in ("restitution", "friction"):
            values = scene.particle_array(key)
            own = values if np.any(values >= 0.0) else np.zeros(0)
            setattr(self, f"particle_{key}", _array(own, self.scalar, self.device))

    def _build_springs(self, scene: Scene) -> None:
        self.spring_pairs = _array(scene.spring_array("pairs").astype(np.int32), wp.vec2i, self.device)
        for key in ("stiffness", "damping", "rest_length"):
            setattr(self, f"spring_{key}", _array(scene.spring_array(key), self.scalar, self.device))

    def _build_bodies(self, scene: Scene) -> None:
        self.body_inv_mass = _array(1.0 / scene.body_array("mass"), self.scalar, self.device)
        self.body_inv_inertia = _array(np.linalg.inv(scene.body_array("inertia")), self.mat33, self.device)
        for key in ("drag", "angular_drag", "restitution", "friction"):
            setattr(self, f"body_{key}", _array(scene.body_array(key), self.scalar, self.device))
        self.body_user_force = wp.zeros(self.body_count, dtype=self.vec3, device=self.device)
        self.body_user_torque = wp.zeros(self.body_count, dtype=self.vec3, device=self.device)

    def _build_planes(self, scene: Scene) -> None:
        planes = scene.planes
        self.plane_normal = _array([p.normal for p in planes], self.vec3, self.device)
        for key in ("offset", "restitution", "friction"):
            setattr(self, f"plane_{key}", _array([getattr(p, key) for p in planes], self.scalar, self.device))

    def empty(self, dtype=None):
        """A zero-length array of this model's scalar (or the given) type, for absent optional inputs."""
        return wp.empty(0, dtype=dtype or self.scalar, device=self.device)

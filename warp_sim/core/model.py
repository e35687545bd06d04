"""Model: the constants of a scene on one device, struct-of-arrays Warp arrays.

Built once from a Scene; nothing at run time reads the Scene again. Arrays of a
component the scene lacks are None and never allocated.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import blocks, precisions
from ..scene import Scene
from .launcher import Launcher
from .tape import TapedLauncher

SCALARS = {"float32": (wp.float32, wp.vec3f, np.float32), "float64": (wp.float64, wp.vec3d, np.float64)}
MATRICES = {wp.float32: wp.mat33f, wp.float64: wp.mat33d}
QUATERNIONS = {wp.float32: wp.quatf, wp.float64: wp.quatd}

_ARRAYS = ("body_inv_mass", "body_inv_inertia", "body_drag", "body_angular_drag", "body_restitution", "body_friction",
           "particle_inv_mass", "particle_radius", "particle_restitution", "particle_friction",
           "spring_pairs", "spring_stiffness", "spring_damping", "spring_rest_length",
           "plane_normal", "plane_offset", "plane_restitution", "plane_friction")


def _array(values, dtype, device):
    return wp.array(np.ascontiguousarray(values), dtype=dtype, device=device)


#: a kinematic body's mass against the heaviest dynamic body's: the response moves it by this share at most
#: (about 1e-6), and its track resets it every step
KINEMATIC_MASS_RATIO = 1.0e6


class Model:
    """Constants of a scene on a device.

    device: the Warp device; launch(kernel, dim, inputs): a recorded launch on it (core.launcher)
    precision: "float32" or "float64"; scalar, vec3, quat, mat33: its Warp types; numpy_scalar: its numpy type
    gravity [m/s^2] (vec3), drag [N s/m] (scalar), wind [m/s] (vec3): kernel-ready values
    gravity_magnitude [m/s^2], drag_value [N s/m]: the same as Python floats
    particle_count, spring_count, plane_count, body_count: element counts (0: absent)
    particle_inv_mass [1/kg] (0: pinned, or a dead emitter slot), particle_radius [m]
    particle_restitution, particle_friction: per-particle values, or empty where no particle has its own
    spring_pairs (vec2i), spring_stiffness [N/m], spring_damping [N s/m], spring_rest_length [m]
    body_inv_mass [1/kg], body_inv_inertia: I_body^-1, body frame [1/(kg m^2)], body_drag [N s/m],
        body_angular_drag [N m s/rad], body_restitution, body_friction
    plane_normal (unit), plane_offset [m], plane_restitution, plane_friction: planes normal . x = offset
    springs, planes, particle_material, body_mass: the same arrays as kernels.blocks structs (None where absent)

    differentiable: whether launches go through wp.launch and the float arrays have gradients
    (``make_differentiable``)

    The blocks capture the arrays: nothing may replace an array after the Model is built. The one exception
    to "constant": an emitter pool (passes.emitters) sets the inverse mass and
    radius of its own slots at births and deaths; every other array is written once, here.
    """

    def __init__(self, scene: Scene, device):
        self.device = wp.get_device(device)
        self.launcher = Launcher(self.device)
        self.launch = self.launcher.launch
        self.differentiable = False
        self.precision = scene.precision
        self.scalar, self.vec3, self.numpy_scalar = SCALARS[scene.precision]
        self.mat33 = MATRICES[self.scalar]
        self.quat = QUATERNIONS[self.scalar]
        self.gravity = self.vec3(*scene.gravity)
        self.gravity_magnitude = float(np.linalg.norm(scene.gravity))
        self.drag = self.scalar(scene.drag)
        self.drag_value = float(scene.drag)
        self.wind = self.vec3(*scene.wind)
        self.particle_count = scene.particle_count
        self.spring_count = scene.spring_count
        self.plane_count = len(scene.planes)
        self.body_count = scene.body_count
        #: (name, first global index, count) of each particle group, and each body's name: for messages
        self.particle_groups = [(group.name, group.start, group.count) for group in scene.particle_groups]
        self.body_names = [body.name for body in scene.bodies]
        for name in _ARRAYS + ("springs", "planes", "particle_material", "body_mass"):
            setattr(self, name, None)
        self.blocks = blocks.of(self.scalar)
        precisions.declare(self.scalar)   # the generic kernels' overloads in this precision, built together
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
        self.particle_material = blocks.fill(self.blocks.ParticleMaterial, inv_mass=self.particle_inv_mass,
                                             radius=self.particle_radius, restitution=self.particle_restitution,
                                             friction=self.particle_friction)

    def _build_springs(self, scene: Scene) -> None:
        self.spring_pairs = _array(scene.spring_array("pairs").astype(np.int32), wp.vec2i, self.device)
        for key in ("stiffness", "damping", "rest_length"):
            setattr(self, f"spring_{key}", _array(scene.spring_array(key), self.scalar, self.device))
        self.springs = blocks.fill(self.blocks.Springs, pairs=self.spring_pairs, stiffness=self.spring_stiffness,
                                   damping=self.spring_damping, rest_length=self.spring_rest_length)

    def _build_bodies(self, scene: Scene) -> None:
        mass, inertia = scene.body_array("mass"), scene.body_array("inertia")
        kinematic = np.array([body.track is not None for body in scene.bodies])
        if kinematic.any():   # far heavier than anything they push, so they are not pushed back (they are reset)
            heaviest = mass[~kinematic].max() if (~kinematic).any() else 1.0
            scale = np.where(kinematic, KINEMATIC_MASS_RATIO * heaviest / mass, 1.0)
            mass, inertia = mass * scale, inertia * scale[:, None, None]
        self.body_inv_mass = _array(1.0 / mass, self.scalar, self.device)
        self.body_inv_inertia = _array(np.linalg.inv(inertia), self.mat33, self.device)
        for key in ("drag", "angular_drag", "restitution", "friction"):
            setattr(self, f"body_{key}", _array(scene.body_array(key), self.scalar, self.device))
        self.body_mass = blocks.fill(self.blocks.BodyMass, inv_mass=self.body_inv_mass,
                                     inv_inertia=self.body_inv_inertia)

    def _build_planes(self, scene: Scene) -> None:
        planes = scene.planes
        self.plane_normal = _array([p.normal for p in planes], self.vec3, self.device)
        for key in ("offset", "restitution", "friction"):
            setattr(self, f"plane_{key}", _array([getattr(p, key) for p in planes], self.scalar, self.device))
        self.planes = blocks.fill(self.blocks.Planes, normal=self.plane_normal, offset=self.plane_offset,
                                  restitution=self.plane_restitution, friction=self.plane_friction)

    def make_differentiable(self) -> None:
        """From now on launch through core.tape's TapedLauncher (every launch a ``wp.launch``, which an active
        wp.Tape records), and give every float array a gradient (``array.grad``, zeroed: a tape's backward adds
        into it). Called once, before anything launches (a Simulator(differentiable=True), right after assembly)."""
        self.differentiable = True
        self.launcher = TapedLauncher(self.device)
        self.launch = self.launcher.launch
        for name in _ARRAYS:
            array = getattr(self, name)
            if array is not None and array.dtype in (self.scalar, self.vec3, self.mat33):
                array.requires_grad = True
        for block, layout in ((self.springs, "Springs"), (self.planes, "Planes"),
                              (self.particle_material, "ParticleMaterial"), (self.body_mass, "BodyMass")):
            for field in blocks.LAYOUTS[layout] if block is not None else ():
                setattr(block, field, getattr(block, field))   # a struct keeps the gradients its arrays were set with

    def no_planes(self):
        """A Planes block of no planes, for kernels that take planes where none apply."""
        return blocks.fill(self.blocks.Planes, normal=self.empty(self.vec3), offset=self.empty(),
                           restitution=self.empty(), friction=self.empty())

    def empty(self, dtype=None):
        """A zero-length array of this model's scalar (or the given) type, for absent optional inputs."""
        return wp.empty(0, dtype=dtype or self.scalar, device=self.device)

    def zeros(self, count: int, dtype=None):
        """A zeroed array of ``count`` elements of this model's scalar (or the given) type on its device."""
        return wp.zeros(count, dtype=dtype or self.scalar, device=self.device)

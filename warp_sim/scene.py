"""Scene: the host-side description a user builds (numpy, validated on entry). SI units, Y up."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import checks
from .rotations import quat_to_matrix
from .shapes import MassProperties, Shape

PRECISIONS = ("float32", "float64")


@dataclass(frozen=True)
class ParticleGroup:
    """The particles one add_particles call made: global indices start .. start + count - 1.
    pooled: the slots of an emitter's pool, of which only the live ones exist at any time."""
    name: str
    start: int
    count: int
    color: tuple
    pooled: bool = False


@dataclass(frozen=True)
class Plane:
    """The static plane normal . x = offset; bodies stay on the side the unit normal points to."""
    name: str
    normal: np.ndarray
    offset: float
    restitution: float
    friction: float


@dataclass(frozen=True)
class RigidBody:
    """One rigid body as added: its shape, mass properties and initial state (world frame, SI).

    position: the centre of mass [m] (the shape's origin sits at position - R com);
    orientation: unit quaternion (x, y, z, w); momentum P [kg m/s] and angular
    momentum L [kg m^2/s]; drag [N s/m] and angular_drag [N m s/rad]; restitution
    and friction for contacts.
    """
    name: str
    shape: Shape
    mass: MassProperties
    position: np.ndarray
    orientation: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    drag: float
    angular_drag: float
    restitution: float
    friction: float
    color: tuple


class Scene:
    """What to simulate: particles, springs, rigid bodies, planes, and the global forces.

    gravity [m/s^2]; drag: linear drag coefficient on every particle and the
    default for every body [N s/m], the force -drag (v - wind); angular_drag: the
    default rotational viscosity of bodies [N m s/rad], the torque
    -angular_drag omega; wind: the air's velocity [m/s]; precision: "float32" or
    "float64" for the whole simulated state.
    """

    def __init__(self, gravity=(0.0, -9.81, 0.0), precision: str = "float32", drag: float = 0.0,
                 wind=(0.0, 0.0, 0.0), angular_drag: float = 0.0):
        self.gravity = checks.vec3("gravity", gravity)
        self.precision = checks.choice("precision", precision, PRECISIONS)
        self.drag = checks.scalar("drag", drag, low=0.0)
        self.angular_drag = checks.scalar("angular_drag", angular_drag, low=0.0)
        self.wind = checks.vec3("wind", wind)
        self.particle_groups: list[ParticleGroup] = []
        self.bodies: list[RigidBody] = []
        self._body_names: set[str] = set()      # unique-name checks stay O(1) for 10^5 bodies
        self.fields: list = []
        self.emitters: list = []
        self.planes: list[Plane] = []
        self._particles: dict[str, list[np.ndarray]] = {key: [] for key in (
            "position", "velocity", "mass", "radius", "pinned", "restitution", "friction")}
        self._springs: dict[str, list[np.ndarray]] = {key: [] for key in (
            "pairs", "stiffness", "damping", "rest_length")}

    # particles -----------------------------------------------------------------
    @property
    def particle_count(self) -> int:
        return sum(group.count for group in self.particle_groups)

    def particle_array(self, key: str) -> np.ndarray:
        """One per-particle quantity of every group, concatenated: position, velocity (N, 3) [m, m/s];
        mass [kg], radius [m], pinned (bool), restitution, friction (-1 where a particle has none)."""
        chunks = self._particles[key]
        if chunks:
            return np.concatenate(chunks)
        return np.zeros((0, 3) if key in ("position", "velocity") else 0)

    def add_particles(self, positions, velocities=None, mass=1.0, radius=0.01, pinned=None,
                      restitution=None, friction=None, name: str | None = None,
                      color=(0.9, 0.5, 0.1)) -> np.ndarray:
        """Add point masses; returns their global indices.

        positions, velocities: (N, 3) [m], [m/s]; mass [kg] and radius [m]: one value or
        one per particle; pinned: indices into this call's positions of particles with
        infinite mass, which never move; restitution in [0, 1] and friction >= 0, where
        given, are averaged with each plane's. name and color (RGB 0..1) are for USD.
        """
        x = checks.finite_array("positions", positions, (-1, 3))
        count = len(x)
        if count == 0:
            raise checks.fail("positions", positions, "need at least one particle")
        v = np.zeros_like(x) if velocities is None else checks.finite_array("velocities", velocities, (count, 3))
        m = checks.per_element("mass", mass, count, low=0.0, low_open=True)
        r = checks.per_element("radius", radius, count, low=0.0)
        pin = np.zeros(count, dtype=bool)
        if pinned is not None:
            pin[checks.indices("pinned", pinned, count, (-1,))] = True
            v[pin] = 0.0
        e = np.full(count, -1.0) if restitution is None else checks.per_element("restitution", restitution, count,
                                                                                low=0.0)
        if restitution is not None and e.max() > 1.0:
            raise checks.fail("restitution", restitution, "must lie in [0, 1]")
        mu = np.full(count, -1.0) if friction is None else checks.per_element("friction", friction, count, low=0.0)
        rgb = tuple(checks.finite_array("color", color, (3,)))
        return self._append_particles(name or f"group{len(self.particle_groups)}", rgb, False,
                                      (x, v, m, r, pin, e, mu))

    def _append_particles(self, label: str, rgb: tuple, pooled: bool, chunks: tuple) -> np.ndarray:
        if any(group.name == label for group in self.particle_groups):
            raise checks.fail("name", label, "particle group names must be unique")
        start, count = self.particle_count, len(chunks[0])
        for key, chunk in zip(self._particles, chunks):
            self._particles[key].append(chunk)
        self.particle_groups.append(ParticleGroup(label, start, count, rgb, pooled))
        return np.arange(start, start + count)

    # emitters ------------------------------------------------------------------
    def add_emitter(self, rate: float = 100.0, lifetime=2.0, position=(0.0, 0.0, 0.0), direction=(0.0, 1.0, 0.0),
                    spread: float = 15.0, speed=1.0, shape: str = "point", radius: float | None = None,
                    half_extents=None, mesh=None, size=0.01, mass=0.001, color=(1.0, 1.0, 1.0), opacity=1.0,
                    bursts=(), start: float = 0.0, stop: float | None = None, capacity: int | None = None,
                    seed: int = 0, restitution: float | None = None, friction: float | None = None,
                    kill_planes=(), kill_on_contact: bool = False, name: str | None = None):
        """Add a particle emitter with its own pool of particles; returns its Emitter description.

        rate [particles/s] (births follow it exactly: particle k at start + (k + 1/2) / rate);
        bursts: ((time [s], count), ...) extra births; start, stop: the stream's interval [s].
        lifetime [s], speed [m/s], mass [kg]: a constant or a uniform (min, max) range.
        shape: "point", "disc" (radius, normal = direction), "sphere" (surface) or "ball"
        (volume) of radius [m], "box" of half_extents [m], or "mesh" (the surface of a
        trimesh mesh or file, by area, offset by position). direction: a unit axis, or
        "normal" (outward) for sphere, ball and mesh; spread: the cone's half-angle in
        [0, 180] degrees. size (particle radius [m]), color (RGB in 0..1) and opacity (0..1):
        a constant, a (min, max) range drawn at birth, or a ws.Ramp over normalised age.
        capacity: pool slots (default ceil(rate x max lifetime) + 1 + burst counts); when
        it is full, births are skipped and counted (Simulator.emitter_stats()), never
        overwrite a live particle. seed: integer in [0, 2^31). restitution and friction:
        averaged with each plane's, as for particles. kill_planes: ((normal, offset), ...),
        particles with normal . x < offset die; kill_on_contact: die on touching a plane.
        """
        from .emitters import make_emitter

        label = name or f"emitter{len(self.emitters)}"
        emitter = make_emitter(len(self.emitters), self.particle_count, label, rate, lifetime, position, direction,
                               spread, speed, shape, radius, half_extents, mesh, size, mass, color, opacity,
                               bursts, start, stop, capacity, seed, kill_planes, kill_on_contact)
        n = emitter.capacity
        e = -1.0 if restitution is None else checks.scalar("restitution", restitution, low=0.0, high=1.0)
        mu = -1.0 if friction is None else checks.scalar("friction", friction, low=0.0)
        rgb = tuple(float(c) for c in emitter.color[0])
        self._append_particles(label, rgb, True, (np.zeros((n, 3)), np.zeros((n, 3)), np.ones(n), np.zeros(n),
                                                  np.ones(n, dtype=bool), np.full(n, e), np.full(n, mu)))
        self.emitters.append(emitter)
        return emitter

    # springs -------------------------------------------------------------------
    @property
    def spring_count(self) -> int:
        return sum(len(chunk) for chunk in self._springs["pairs"])

    def spring_array(self, key: str) -> np.ndarray:
        """One per-spring quantity, concatenated: pairs (K, 2) global particle indices;
        stiffness [N/m], damping [N s/m], rest_length [m]."""
        chunks = self._springs[key]
        if chunks:
            return np.concatenate(chunks)
        return np.zeros((0, 2), dtype=np.int64) if key == "pairs" else np.zeros(0)

    def add_springs(self, pairs, stiffness, damping=0.0, rest_length=None) -> np.ndarray:
        """Add damped springs between particle pairs; returns their global spring indices.

        pairs: (K, 2) global particle indices; stiffness ks [N/m] and damping kd [N s/m]:
        one value or one per spring, >= 0; rest_length [m]: per spring or one value,
        by default each spring's current length (which must then be non-zero).
        """
        p = checks.indices("pairs", pairs, self.particle_count, (-1, 2))
        count = len(p)
        if count == 0:
            raise checks.fail("pairs", pairs, "need at least one spring")
        self_loops = np.flatnonzero(p[:, 0] == p[:, 1])
        if len(self_loops):
            k = self_loops[0]
            raise checks.fail("pairs", pairs, f"a spring must join two different particles; "
                                              f"spring {k} joins particle {p[k, 0]} to itself")
        ks = checks.per_element("stiffness", stiffness, count, low=0.0)
        kd = checks.per_element("damping", damping, count, low=0.0)
        if rest_length is None:
            x = self.particle_array("position")
            length = np.linalg.norm(x[p[:, 1]] - x[p[:, 0]], axis=1)
            zero = np.flatnonzero(length == 0.0)
            if len(zero):
                k = zero[0]
                raise checks.fail("rest_length", None,
                                  f"spring {k} joins coincident particles {tuple(p[k])}, so its rest length "
                                  "cannot default to its length; give rest_length")
        else:
            length = checks.per_element("rest_length", rest_length, count, low=0.0)
        start = self.spring_count
        for key, chunk in zip(self._springs, (p, ks, kd, length)):
            self._springs[key].append(chunk)
        return np.arange(start, start + count)

    # rigid bodies --------------------------------------------------------------
    @property
    def body_count(self) -> int:
        return len(self.bodies)

    def add_rigid_body(self, shape: Shape, density: float | None = None, mass: float | None = None,
                       position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0),
                       linear_velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0),
                       restitution: float = 0.5, friction: float = 0.4, drag: float | None = None,
                       angular_drag: float | None = None, name: str | None = None,
                       color=(0.6, 0.6, 0.65)) -> int:
        """Add a rigid body; returns its body index.

        shape: a ws.Sphere, Box, Capsule, Cylinder, MeshShape or PointMasses; density
        [kg/m^3] or mass [kg] (one of them; density 1000 when neither); position: where
        the shape's own origin goes [m] (for a mesh or point masses the body's centre of
        mass then lies at position + R com); orientation: quaternion (x, y, z, w),
        normalised with a warning if off unit length; linear_velocity of the centre of
        mass [m/s] and angular_velocity [rad/s], world frame; restitution in [0, 1],
        friction >= 0; drag [N s/m] and angular_drag [N m s/rad] default to the scene's.
        """
        if not isinstance(shape, Shape):
            raise checks.fail("shape", shape, "expected a warp_sim shape: Sphere, Box, Capsule, Cylinder, "
                                              "MeshShape or PointMasses")
        properties = shape.mass_properties(density=density, mass=mass)
        q = checks.unit_quaternion("orientation", orientation)
        R = quat_to_matrix(q)
        inertia_world = R @ properties.inertia @ R.T
        label = name or f"body{len(self.bodies)}"
        if label in self._body_names:
            raise checks.fail("name", label, "body names must be unique")
        body = RigidBody(
            name=label, shape=shape, mass=properties,
            position=checks.vec3("position", position) + R @ properties.com,
            orientation=q,
            momentum=properties.mass * checks.vec3("linear_velocity", linear_velocity),
            angular_momentum=inertia_world @ checks.vec3("angular_velocity", angular_velocity),
            drag=self.drag if drag is None else checks.scalar("drag", drag, low=0.0),
            angular_drag=self.angular_drag if angular_drag is None else checks.scalar(
                "angular_drag", angular_drag, low=0.0),
            restitution=checks.scalar("restitution", restitution, low=0.0, high=1.0),
            friction=checks.scalar("friction", friction, low=0.0),
            color=tuple(checks.finite_array("color", color, (3,))),
        )
        self.bodies.append(body)
        self._body_names.add(label)
        return len(self.bodies) - 1

    def body_array(self, key: str) -> np.ndarray:
        """One per-body quantity stacked over the bodies: position (B, 3) [m], orientation (B, 4),
        momentum (B, 3), angular_momentum (B, 3), drag, angular_drag, restitution, friction (B,);
        and from the mass properties: mass (B,) [kg], inertia (B, 3, 3) body frame [kg m^2]."""
        if key == "mass":
            return np.array([body.mass.mass for body in self.bodies])
        if key == "inertia":
            return np.array([body.mass.inertia for body in self.bodies]).reshape(-1, 3, 3)
        values = [getattr(body, key) for body in self.bodies]
        width = {"position": 3, "orientation": 4, "momentum": 3, "angular_momentum": 3}.get(key)
        return np.array(values, dtype=np.float64).reshape((-1, width) if width else (-1,))

    # force fields --------------------------------------------------------------
    def add_field(self, field) -> int:
        """Add a force field acting on every particle (ws.Attractor, ws.Vortex, ws.Turbulence);
        returns its index. Fields accelerate particles independently of their mass."""
        from .fields import Field

        if not isinstance(field, Field):
            raise checks.fail("field", field, "expected a warp_sim force field: Attractor, Vortex or Turbulence")
        self.fields.append(field)
        return len(self.fields) - 1

    # planes --------------------------------------------------------------------
    def add_plane(self, normal, offset: float = 0.0, restitution: float = 0.5, friction: float = 0.4,
                  name: str | None = None) -> int:
        """Add the static plane normal . x = offset [m]; returns its index.

        Particles stay on the side the normal points to. restitution in [0, 1];
        friction: Coulomb coefficient >= 0.
        """
        plane = Plane(
            name=name or f"Plane{len(self.planes)}",
            normal=checks.unit_vec3("normal", normal),
            offset=checks.scalar("offset", offset),
            restitution=checks.scalar("restitution", restitution, low=0.0, high=1.0),
            friction=checks.scalar("friction", friction, low=0.0),
        )
        if any(existing.name == plane.name for existing in self.planes):
            raise checks.fail("name", plane.name, "plane names must be unique")
        self.planes.append(plane)
        return len(self.planes) - 1

    def add_ground(self, restitution: float = 0.5, friction: float = 0.4) -> int:
        """Add the ground, the plane y = 0 with normal +Y; returns its plane index."""
        return self.add_plane((0.0, 1.0, 0.0), 0.0, restitution, friction, name="Ground")

    def __repr__(self) -> str:
        return (f"Scene({self.particle_count} particles, {self.spring_count} springs, {self.body_count} bodies, "
                f"{len(self.planes)} planes, {self.precision})")

"""Scene: the host-side description a user builds (numpy, validated on entry). SI units, Y up."""
from __future__ import annotations

import numpy as np

from ..util import checks
from ..util.rotations import quat_to_matrix
from . import cloth, ranges, usd_reader, usd_writer
from .emitters import make_emitter
from .fields import Field
from .joints import Joint, world_joint
from .parts import Collider, ParticleGroup, Plane, RigidBody, SurfaceMesh
from .revisions import Revised, changes
from .shapes import MassProperties, NoShape, Shape
from .tracks import Track

PRECISIONS = ("float32", "float64")
_SHAPE_NAMES = "Sphere, Box, Capsule, Cylinder, MeshShape or PointMasses"


def _keys(kinematic) -> tuple:
    if not isinstance(kinematic, (tuple, list)) or len(kinematic) != 3:
        raise checks.fail("kinematic", kinematic, "expected (times [s], positions [m], orientations (x, y, z, w))")
    return tuple(kinematic)


def _frozen(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only: a change goes through an attribute set, which counts in the scene's revision."""
    array.setflags(write=False)
    return array


def _shape(shape) -> Shape:
    """``shape`` if it is a warp_sim Shape, else ValueError."""
    if not isinstance(shape, Shape):
        raise checks.fail("shape", shape, f"expected a warp_sim shape: {_SHAPE_NAMES}")
    return shape


class Scene(Revised):
    """What to simulate: particles, springs, rigid bodies, static colliders, planes, and the global forces.

    gravity: [m/s^2], (3,)
    drag: linear drag coefficient on every particle and the default for every body, the force -drag (v - wind)
        [N s/m]
    angular_drag: the default rotational viscosity of bodies, the torque -angular_drag omega [N m s/rad]
    wind: the air's velocity [m/s], (3,)
    precision: "float32" or "float64" for the whole simulated state
    usd_paths: for a scene read by ``from_usd``, each simulated prim's path -> (kind, index): "body" or "collider"
        and its index, "plane" and its plane index, "cloth" or "particles" and the particle ids; else empty
    usd_source: for such a scene, the stage it came from (scene.usd_reader.UsdSource), else None
    revision: a count of its changes (add_* calls, attribute sets); a Simulator refuses to step a scene whose
        revision moved since it was built

    Every value must fit the precision, as must what a simulation derives from it (1/m, k/m, the inverse
    inertia: ``scene.ranges``); in float32 a mass of 1e-300 kg or a stiffness of 1e39 N/m is refused where given.
    """

    def __init__(self, gravity=(0.0, -9.81, 0.0), precision: str = "float32", drag: float = 0.0,
                 wind=(0.0, 0.0, 0.0), angular_drag: float = 0.0):
        self.precision = checks.choice("precision", precision, PRECISIONS)
        self.gravity, self.drag, self.angular_drag, self.wind = gravity, drag, angular_drag, wind
        self.particle_groups: list[ParticleGroup] = []
        self.bodies: list[RigidBody] = []
        self._body_names: set[str] = set()      # unique-name checks stay O(1) for 10^5 bodies
        self.fields: list = []
        self.emitters: list = []
        self.meshes: list[SurfaceMesh] = []     # cloths and soft bodies
        self.planes: list[Plane] = []
        self.colliders: list[Collider] = []     # static shapes: infinite mass, never move
        self.joints: list[Joint] = []           # constraints between bodies (scene.joints)
        self._particles: dict[str, list[np.ndarray]] = {key: [] for key in (
            "position", "velocity", "mass", "radius", "pinned", "restitution", "friction")}
        self._springs: dict[str, list[np.ndarray]] = {key: [] for key in (
            "pairs", "stiffness", "damping", "rest_length")}
        self.usd_paths: dict[str, tuple] = {}
        self.usd_source = None


    # the global forces: checked (and within the precision) however they are set, since a set counts in the revision
    @property
    def gravity(self) -> np.ndarray:
        return self._gravity

    @gravity.setter
    def gravity(self, value) -> None:
        self._gravity = _frozen(checks.fits("gravity", checks.vec3("gravity", value), self.precision))

    @property
    def wind(self) -> np.ndarray:
        return self._wind

    @wind.setter
    def wind(self, value) -> None:
        self._wind = _frozen(checks.fits("wind", checks.vec3("wind", value), self.precision))

    @property
    def drag(self) -> float:
        return self._drag

    @drag.setter
    def drag(self, value) -> None:
        self._drag = float(checks.fits("drag", checks.scalar("drag", value, low=0.0), self.precision))

    @property
    def angular_drag(self) -> float:
        return self._angular_drag

    @angular_drag.setter
    def angular_drag(self, value) -> None:
        self._angular_drag = float(checks.fits("angular_drag", checks.scalar("angular_drag", value, low=0.0),
                                               self.precision))
    @classmethod
    def from_usd(cls, path_or_stage, *, time=0, precision: str = "float32") -> Scene:
        """A Scene from a stage's UsdPhysics description (and ``warpSim:`` attributes) at time code ``time``, in SI
        and Y up; what it cannot simulate is warned about once per kind, naming the prims (docs/usd.md)."""
        return usd_reader.read(cls, path_or_stage, time, precision)

    def to_usd(self, path) -> str:
        """Write the scene as a UsdPhysics stage (Y up, metres) that from_usd reads back; returns the path."""
        return usd_writer.write(self, path)

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

    @changes
    def add_particles(self, positions, velocities=None, mass=1.0, radius=0.01, pinned=None,
                      restitution=None, friction=None, name: str | None = None,
                      color=(0.9, 0.5, 0.1)) -> np.ndarray:
        """Add point masses; returns their global indices.

        positions, velocities: (N, 3) [m], [m/s]; mass [kg] and radius [m]: one value or
        one per particle; pinned: indices into this call's positions of particles with
        infinite mass, which never move; restitution in [0, 1] and friction >= 0, where
        given, are averaged with each plane's. name and color (RGB 0..1) are for USD.
        """
        x = checks.fits("positions", checks.finite_array("positions", positions, (-1, 3)), self.precision)
        count = len(x)
        if count == 0:
            raise checks.fail("positions", positions, "need at least one particle")
        v = np.zeros_like(x) if velocities is None else checks.fits(
            "velocities", checks.finite_array("velocities", velocities, (count, 3)), self.precision)
        m = checks.per_element("mass", mass, count, low=0.0, low_open=True)
        r = checks.per_element("radius", radius, count, low=0.0)
        ranges.particles(self.precision, mass, m, radius, r, self.drag)
        pin = np.zeros(count, dtype=bool)
        if pinned is not None:
            pin[checks.indices("pinned", pinned, count, (-1,))] = True
            v[pin] = 0.0
        e = np.full(count, -1.0) if restitution is None else checks.per_element("restitution", restitution, count,
                                                                                low=0.0)
        if restitution is not None and e.max() > 1.0:
            raise checks.fail("restitution", restitution, "must lie in [0, 1]")
        mu = np.full(count, -1.0) if friction is None else checks.per_element("friction", friction, count, low=0.0)
        rgb = tuple(checks.unit_interval("color", color, (3,)))
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
    @changes
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
        label = name or f"emitter{len(self.emitters)}"
        emitter = make_emitter(len(self.emitters), self.particle_count, label, rate, lifetime, position, direction,
                               spread, speed, shape, radius, half_extents, mesh, size, mass, color, opacity,
                               bursts, start, stop, capacity, seed, kill_planes, kill_on_contact)
        ranges.emitter(self.precision, emitter)
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

    @changes
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
        self._refuse_duplicate_springs(pairs, p)
        ks = checks.per_element("stiffness", stiffness, count, low=0.0)
        kd = checks.per_element("damping", damping, count, low=0.0)
        ranges.springs(self.precision, stiffness, ks, damping, kd, p, self.particle_array("mass"),
                       self.particle_array("pinned"))
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

    def _refuse_duplicate_springs(self, given, pairs: np.ndarray) -> None:
        """A ValueError naming the first pair joined twice (either way round), in this call or by an earlier one:
        a repeated spring would double the stiffness silently."""
        earlier = self._springs["pairs"]
        existing = np.concatenate(earlier) if earlier else np.zeros((0, 2), np.int64)
        combined = np.sort(np.concatenate([existing, pairs]), axis=1)
        _, first, inverse = np.unique(combined, axis=0, return_index=True, return_inverse=True)
        repeats = np.flatnonzero(first[inverse.ravel()] != np.arange(len(combined)))
        if repeats.size:
            k, original = int(repeats[0]) - len(existing), int(first[inverse.ravel()[repeats[0]]])
            where = ("a spring added before (add_springs, a cloth or a soft body)" if original < len(existing)
                     else f"spring {original - len(existing)} of this call")
            raise checks.fail("pairs", given, f"spring {k} joins particles {tuple(int(i) for i in pairs[k])}, already "
                                              f"joined by {where}; each pair may have one spring")

    # cloth and soft bodies -----------------------------------------------------
    @changes
    def add_cloth_grid(self, resolution=(32, 32), size=(1.0, 1.0), position=(0.0, 0.0, 0.0),
                       orientation=(0.0, 0.0, 0.0, 1.0), mass: float | None = None, density: float | None = None,
                       stiffness=(1.0e4, 1.0e4, 1.0e3), damping=(1.0, 1.0, 0.1), pinned=(), velocity=(0.0, 0.0, 0.0),
                       drag: float = 0.0, lift: float = 0.0, air_density: float = 1.2,
                       max_stretch: float | None = None, radius=0.002, restitution: float | None = None,
                       friction: float | None = None, name: str | None = None,
                       color=(0.8, 0.3, 0.3)) -> np.ndarray:
        """Add a rectangular mass-spring cloth; returns its global particle ids, shape (ny, nx) (row-major).

        resolution (nx, ny): ny rows of nx vertices (each >= 2); size (width, height) [m].
        The grid lies in its local x-y plane, x along the width and y along the height,
        centred on ``position`` [m], then turned by ``orientation`` (quaternion x, y, z, w)
        about its centre: by default it hangs upright facing +z; (-sin 45deg, 0, 0, cos 45deg)
        lays it flat facing +y, its last row ("top") towards -z. Vertex (i, j), column i, row j,
        is ids[j, i]; row 0 is the bottom (-y), column 0 the left (-x).
        mass: the total [kg], or density: per unit area [kg/m^2] (not both; neither: 0.1 kg/m^2);
        a vertex gets a quarter of the mass of each quad it belongs to (corners and edges less).
        stiffness [N/m] and damping [N s/m]: per family (structural, shear, bend), or one value
        for all: structural springs along rows and columns, shear springs across both diagonals
        of each quad, bend springs to the second neighbours along rows and columns; rest length =
        initial length. pinned: vertex indices (row-major, into this grid) and/or names "corners",
        "top_corners" (both ends of the last row), "top", "bottom", "left", "right" (whole edges).
        velocity [m/s]: initial, of every free vertex. drag, lift (>= 0), air_density [kg/m^3] and
        max_stretch (strain limit of structural and shear springs, > 0, or None) are recorded for
        aerodynamics and strain limiting. radius [m] (collision; default 2 mm, half a thickness that
        keeps a cloth lying on the ground from coinciding with it), restitution, friction, name
        and color as for add_particles. Recorded in ``scene.meshes`` with the quads as faces.
        """
        topology = cloth.grid_cloth(resolution, size)
        nx, ny = cloth.grid_resolution(resolution)
        masses = cloth.total_masses(topology.weights, mass, density, cloth.DEFAULT_CLOTH_DENSITY, "m^2")
        pins = cloth.grid_pins(pinned, nx, ny)
        ids = self._add_surface("cloth", topology, masses, pins, position, orientation, velocity, stiffness, damping,
                                radius, restitution, friction, name, color, (drag, lift, air_density, max_stretch))
        return ids.reshape(ny, nx)

    @changes
    def add_cloth_mesh(self, mesh, position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0),
                       mass: float | None = None, density: float | None = None, stiffness=(1.0e4, 1.0e4, 1.0e3),
                       damping=(1.0, 1.0, 0.1), pinned=(), velocity=(0.0, 0.0, 0.0), drag: float = 0.0,
                       lift: float = 0.0, air_density: float = 1.2, max_stretch: float | None = None, radius=0.002,
                       restitution: float | None = None, friction: float | None = None, name: str | None = None,
                       color=(0.8, 0.3, 0.3)) -> np.ndarray:
        """Add a mass-spring cloth on any triangle (or triangulated quad) mesh; returns its global particle ids.

        mesh: a trimesh.Trimesh or a file trimesh reads (``trimesh.load(path, force="mesh",
        process=False)``: vertices kept as they are, vertex i is ids[i]; see cloth.load_mesh for
        what is rejected). Its vertices [m] are turned by ``orientation`` about the mesh origin and
        moved by ``position``. The structural, shear and bend families are found by the rules in
        warp_sim.scene.cloth (on a triangulated quad grid they match add_cloth_grid's). mass [kg] or
        density [kg/m^2] (not both; neither: 0.1 kg/m^2), spread by area: each triangle gives a
        third of its mass to each corner. pinned: vertex indices. Every other argument as for
        add_cloth_grid. Recorded in ``scene.meshes`` with the mesh's triangles as faces.
        """
        vertices, faces = cloth.load_mesh(mesh)
        topology = cloth.mesh_cloth(vertices, faces)
        masses = cloth.total_masses(topology.weights, mass, density, cloth.DEFAULT_CLOTH_DENSITY, "m^2")
        pins = cloth.vertex_pins(pinned, topology.count)
        return self._add_surface("cloth", topology, masses, pins, position, orientation, velocity, stiffness, damping,
                                 radius, restitution, friction, name, color, (drag, lift, air_density, max_stretch))

    @changes
    def add_soft_mesh(self, mesh, mass: float = 1.0, stiffness: float = 1.0e4, damping: float = 1.0,
                      distribution: str = "uniform", internal: str | None = "two_ring",
                      internal_stiffness: float | None = None, internal_damping: float | None = None, pinned=(),
                      position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0), velocity=(0.0, 0.0, 0.0),
                      radius=0.002, restitution: float | None = None, friction: float | None = None,
                      name: str | None = None, color=(0.3, 0.6, 0.9)) -> np.ndarray:
        """Add a soft body: every mesh vertex a point mass, every edge a damped spring; returns its particle ids.

        mesh: as for add_cloth_mesh (vertex i is ids[i]), turned by ``orientation`` about the mesh
        origin and moved by ``position`` [m]. mass [kg]: the total, spread by ``distribution``:
        "uniform" (evenly), "area" (a third of each triangle's area to its corners) or "volume"
        (closed meshes only: with c the solid's centroid, each tetrahedron (c, triangle) gives a
        third of its volume to the triangle's corners; a vertex whose share is not positive, in
        a solid not star-shaped about c, is rejected). stiffness [N/m] and damping [N s/m] of the
        edge springs (rest length = edge length). internal="two_ring" adds a spring between every
        two vertices exactly two edges apart, with internal_stiffness and internal_damping (default:
        stiffness and damping): edge springs alone let a closed surface dent (a vertex mirrored
        through its neighbours' plane keeps every edge length), two-ring springs resist that as
        bend springs resist folding a cloth; None adds none. pinned: vertex indices; velocity
        [m/s]: initial. radius, restitution, friction, name, color as for add_cloth_grid.
        Recorded in ``scene.meshes`` (springs: "structural" = edges, "bend" = two-ring, "shear" empty).
        """
        vertices, faces = cloth.load_mesh(mesh)
        topology = cloth.soft_mesh(vertices, faces, distribution, internal)
        masses = cloth.total_masses(topology.weights, mass, None, None, "")
        pins = cloth.vertex_pins(pinned, topology.count)
        ks = checks.scalar("stiffness", stiffness, low=0.0)
        kd = checks.scalar("damping", damping, low=0.0)
        ks_in = ks if internal_stiffness is None else checks.scalar("internal_stiffness", internal_stiffness, low=0.0)
        kd_in = kd if internal_damping is None else checks.scalar("internal_damping", internal_damping, low=0.0)
        return self._add_surface("soft", topology, masses, pins, position, orientation, velocity, (ks, 0.0, ks_in),
                                 (kd, 0.0, kd_in), radius, restitution, friction, name, color, (0.0, 0.0, 1.2, None))

    def _add_surface(self, prefix: str, topology, masses: np.ndarray, pins: np.ndarray, position, orientation,
                     velocity, stiffness, damping, radius, restitution, friction, name, color, aero) -> np.ndarray:
        """Place a cloth.Topology, check the remaining options, then add its particles, springs and SurfaceMesh
        (nothing is added unless every check passes)."""
        ks, kd = cloth.family_values("stiffness", stiffness), cloth.family_values("damping", damping)
        q = checks.unit_quaternion("orientation", orientation)
        x = topology.vertices @ quat_to_matrix(q).T + checks.vec3("position", position)
        count = len(x)
        v = np.tile(checks.vec3("velocity", velocity), (count, 1))
        v[pins] = 0.0
        pin = np.zeros(count, dtype=bool)
        pin[pins] = True
        r = checks.per_element("radius", radius, count, low=0.0)
        checks.fits("position", x, self.precision, given=position, derived="vertex")
        checks.fits("velocity", v, self.precision)
        ranges.particles(self.precision, masses, masses, radius, r, self.drag)
        e = np.full(count, -1.0 if restitution is None else checks.scalar("restitution", restitution, 0.0, 1.0))
        mu = np.full(count, -1.0 if friction is None else checks.scalar("friction", friction, low=0.0))
        rgb = tuple(checks.unit_interval("color", color, (3,)))
        drag, lift, air_density, max_stretch = aero
        drag, lift = checks.scalar("drag", drag, low=0.0), checks.scalar("lift", lift, low=0.0)
        air_density = checks.scalar("air_density", air_density, low=0.0, low_open=True)
        if max_stretch is not None:
            max_stretch = checks.scalar("max_stretch", max_stretch, low=0.0, low_open=True)
        if name is None:
            taken = {group.name for group in self.particle_groups}
            name = next(f"{prefix}{k}" for k in range(len(self.meshes), len(self.meshes) + len(taken) + 1)
                        if f"{prefix}{k}" not in taken)
        ids = self._append_particles(name, rgb, False, (x, v, masses, r, pin, e, mu))
        start = int(ids[0])
        springs = {}
        for family, stiff, damp in zip(cloth.FAMILIES, ks, kd):
            pairs = topology.springs[family]
            length = np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1)
            pairs, length = pairs[length > 0.0], length[length > 0.0]  # coincident (unjoined) vertices: no spring
            springs[family] = (self.add_springs(pairs + start, stiff, damp, rest_length=length) if len(pairs)
                               else np.zeros(0, dtype=np.int64))
        self.meshes.append(SurfaceMesh(name, start, count, topology.face_counts, topology.face_indices,
                                       topology.triangles + start, springs, rgb, drag, lift, air_density,
                                       max_stretch))
        return ids

    # rigid bodies --------------------------------------------------------------
    @property
    def body_count(self) -> int:
        return len(self.bodies)

    @changes
    def add_rigid_body(self, shape: Shape | None, density: float | None = None, mass: float | None = None,
                       position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0),
                       linear_velocity=(0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0),
                       restitution: float = 0.5, friction: float = 0.4, drag: float | None = None,
                       angular_drag: float | None = None, name: str | None = None,
                       color=(0.6, 0.6, 0.65), mass_properties: MassProperties | None = None,
                       kinematic=None) -> int:
        """Add a rigid body; returns its body index.

        shape: a ws.Sphere, Box, Capsule, Cylinder, MeshShape (solid) or PointMasses, or None with mass_properties
        (a body that collides with nothing, e.g. a joint's anchor); density
        [kg/m^3] or mass [kg] (one of them; density 1000 when neither); position: where
        the shape's own origin goes [m] (for a mesh or point masses the body's centre of
        mass then lies at position + R com); orientation: quaternion (x, y, z, w),
        normalised with a warning if off unit length; linear_velocity of the centre of
        mass [m/s] and angular_velocity [rad/s], world frame; restitution in [0, 1],
        friction >= 0; drag [N s/m] and angular_drag [N m s/rad] default to the scene's; mass_properties (instead
        of density or mass): the body's own MassProperties in the shape's frame (a USD MassAPI's); kinematic:
        (times [s], positions [m], orientations) keys of the shape's origin that the body follows, pushing others
        without being pushed (its position and orientation are then the pose at time 0).
        """
        if mass_properties is not None and (not isinstance(mass_properties, MassProperties) or density or mass):
            raise checks.fail("mass_properties", mass_properties, "expected a MassProperties, without density or mass")
        if shape is None and mass_properties is not None:
            shape = NoShape()
        properties = mass_properties or _shape(shape).mass_properties(density=density, mass=mass)
        _shape(shape)
        drag = self.drag if drag is None else checks.scalar("drag", drag, low=0.0)
        angular_drag = self.angular_drag if angular_drag is None else checks.scalar("angular_drag", angular_drag,
                                                                                    low=0.0)
        ranges.body(self.precision, properties, shape, drag, angular_drag)
        track = None if kinematic is None else Track.of(*_keys(kinematic), properties.com)
        if track is not None:
            position, orientation = track.pose(0.0)
            position = position - quat_to_matrix(orientation) @ properties.com
        q = checks.unit_quaternion("orientation", orientation)
        R = quat_to_matrix(q)
        inertia_world = R @ properties.inertia @ R.T
        label = name or f"body{len(self.bodies)}"
        if label in self._body_names:
            raise checks.fail("name", label, "body names must be unique")
        body = RigidBody(
            name=label, shape=shape, mass=properties,
            position=checks.fits("position", checks.vec3("position", position), self.precision) + R @ properties.com,
            orientation=q,
            momentum=checks.fits("linear_velocity", properties.mass * checks.fits(
                "linear_velocity", checks.vec3("linear_velocity", linear_velocity), self.precision), self.precision,
                given=linear_velocity, derived="momentum (mass x velocity)"),
            angular_momentum=checks.fits("angular_velocity", inertia_world @ checks.fits(
                "angular_velocity", checks.vec3("angular_velocity", angular_velocity), self.precision),
                self.precision, given=angular_velocity, derived="angular momentum (I omega)"),
            drag=drag, angular_drag=angular_drag,
            restitution=checks.scalar("restitution", restitution, low=0.0, high=1.0),
            friction=checks.scalar("friction", friction, low=0.0),
            color=tuple(checks.unit_interval("color", color, (3,))), track=track,
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

    @changes
    @changes
    def add_joint(self, kind, parent, child, *, anchor, axis=(1.0, 0.0, 0.0), limits=None, drive=None,
                  collide: bool = False, break_force: float | None = None, break_torque: float | None = None,
                  orientation=None, name: str | None = None) -> int:
        """Join body ``child`` to body ``parent`` (None: the world); returns the joint's index.

        kind: "revolute" (a hinge about axis), "prismatic" (a slider along axis), "ball", "fixed", "distance",
        or a ws.D6 (per-axis locks, limits and drives); anchor: the joint's point in world space at this moment
        [m], or two (the parent's, the child's); axis: the joint axis in world space (or orientation, the joint
        frame's world quaternion (x, y, z, w), for a D6); limits: (lower, upper) [rad] for a hinge, [m] for a
        slider, (min, max) [m] for a distance joint (default: the anchors' distance now), the cone half-angle
        [rad] for a ball; drive: a ws.Drive (SI) on a hinge or slider; collide: whether the two bodies still
        collide; break_force [N] / break_torque [N m]: the joint breaks above them (None: never).
        """
        joint = world_joint(self, kind, parent, child, anchor=anchor, axis=axis, orientation=orientation,
                            limits=limits, drive=drive, collide=collide, break_force=break_force,
                            break_torque=break_torque, name=name)
        self.joints.append(joint)
        return len(self.joints) - 1

    # static colliders ----------------------------------------------------------
    @changes
    def add_collider(self, shape: Shape, position=(0.0, 0.0, 0.0), orientation=(0.0, 0.0, 0.0, 1.0),
                     restitution: float = 0.5, friction: float = 0.4, name: str | None = None,
                     color=(0.45, 0.45, 0.5)) -> int:
        """Add a static collider (infinite mass, never moves); returns its index into ``scene.colliders``.

        shape: any warp_sim shape, including a surface ``MeshShape(mesh, solid=False)`` (e.g. a
        terrain); position: where the shape's own origin goes [m]; orientation: quaternion
        (x, y, z, w), normalised with a warning if off unit length; restitution in [0, 1],
        friction >= 0; name (unique among colliders, default "collider<k>") and color (RGB 0..1) for USD.
        """
        ranges.sized(self.precision, _shape(shape))
        collider = Collider(
            name=name or f"collider{len(self.colliders)}", shape=_shape(shape),
            position=checks.fits("position", checks.vec3("position", position), self.precision),
            orientation=checks.unit_quaternion("orientation", orientation),
            restitution=checks.scalar("restitution", restitution, low=0.0, high=1.0),
            friction=checks.scalar("friction", friction, low=0.0),
            color=tuple(checks.unit_interval("color", color, (3,))),
        )
        if any(existing.name == collider.name for existing in self.colliders):
            raise checks.fail("name", collider.name, "collider names must be unique")
        for array in (collider.position, collider.orientation):
            array.setflags(write=False)
        self.colliders.append(collider)
        return len(self.colliders) - 1

    # force fields --------------------------------------------------------------
    @changes
    def add_field(self, field) -> int:
        """Add a force field acting on every particle (ws.Attractor, ws.Vortex, ws.Turbulence);
        returns its index. Fields accelerate particles independently of their mass."""
        if not isinstance(field, Field):
            raise checks.fail("field", field, "expected a warp_sim force field: Attractor, Vortex or Turbulence")
        self.fields.append(field)
        return len(self.fields) - 1

    # planes --------------------------------------------------------------------
    @changes
    def add_plane(self, normal, offset: float = 0.0, restitution: float = 0.5, friction: float = 0.4,
                  name: str | None = None) -> int:
        """Add the static plane normal . x = offset [m]; returns its index.

        Particles stay on the side the normal points to. restitution in [0, 1];
        friction: Coulomb coefficient >= 0.
        """
        plane = Plane(
            name=name or f"Plane{len(self.planes)}",
            normal=checks.unit_vec3("normal", normal),
            offset=float(checks.fits("offset", checks.scalar("offset", offset), self.precision)),
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
                f"{len(self.colliders)} colliders, {len(self.joints)} joints, {len(self.planes)} planes, "
                f"{self.precision})")

"""Bodies in collision: bodies against bodies, static colliders and planes; particles against shapes.

Each step (``BodyContacts.apply``, after the solver):
1. broad phase: a hash grid over the bodies' centres (rebuilt every step, linear in the
   body count) gives the pairs whose bounding spheres, grown by how far each body moves
   over the step and the contact margin, overlap; static colliders and planes are tested
   per body;
2. narrow phase at the start of the step: sample points (box corners, capsule and
   sphere centres with their radius, cylinder rims, mesh vertices) against the other
   shape's signed distance, and box-box contact polygons by separating axes; every
   contact that could close within the step is kept, so nothing tunnels;
3. response on the solver's end-of-step state: the time of impact of each contact
   within the step, collision impulses with restitution and Coulomb friction there
   (Gauss-Seidel, repeated so impacts propagate through touching bodies), then
   sequential impulses for resting and sliding contact, then a position projection
   that removes any overlap without changing velocities (so it adds no energy).

A contact's restitution and friction are the means of the two sides' values. Restitution
applies to impacts faster than ``bounce_speed`` (default 2 |g| h, the speed gravity gives
in two steps); slower ones are resting contact, so bodies settle instead of jittering.
The alternative response, "penalty", is a spring and damper force per contact.

Buffers of pairs and contacts grow as needed: no contact is dropped.
"""
from __future__ import annotations

import math

import numpy as np
import warp as wp

from .dynamics import Forces, ForceTerm
from .kernels import contacts as contact_kernels
from .kernels import detection as detection_kernels
from .kernels.geometry import KINDS
from .model import Model, State

CYLINDER_RIM_SAMPLES = 16   # points on each rim of a cylinder tested against other shapes


def shape_samples(shape) -> tuple[np.ndarray, float]:
    """Contact sample points (shape frame) [m] and their radius [m]: spheres at these points stand for the shape
    where another shape's signed distance is tested."""
    kind = shape.kind
    if kind == "sphere":
        return np.zeros((1, 3)), shape.radius
    if kind == "box":
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
        return corners * np.asarray(shape.size), 0.0
    if kind == "capsule":
        return np.array([[0.0, -shape.half_height, 0.0], [0.0, 0.0, 0.0], [0.0, shape.half_height, 0.0]]), shape.radius
    if kind == "cylinder":
        angles = np.linspace(0.0, 2.0 * math.pi, CYLINDER_RIM_SAMPLES, endpoint=False)
        ring = np.stack([shape.radius * np.cos(angles), np.zeros_like(angles), shape.radius * np.sin(angles)], 1)
        return np.concatenate([ring - [0, shape.half_height, 0], ring + [0, shape.half_height, 0]]), 0.0
    if kind == "mesh":
        return np.asarray(shape.vertices, dtype=np.float64), 0.0
    if kind == "points":
        return np.asarray(shape.positions, dtype=np.float64), shape.radius
    raise ValueError(f"shape kind {kind!r} has no contact geometry")


def _size(shape) -> tuple:
    size = tuple(float(s) for s in shape.size)
    if shape.kind == "points":
        size = (float(shape.radius),)
    return (size + (0.0, 0.0, 0.0))[:3]


def _first_faces(faces: np.ndarray, vertex_count: int) -> np.ndarray:
    """Per vertex, the lowest index of a face using it (-1 if none)."""
    owner = np.full(vertex_count, np.iinfo(np.int32).max, dtype=np.int64)
    np.minimum.at(owner, faces.ravel(), np.repeat(np.arange(len(faces)), 3))
    owner[owner == np.iinfo(np.int32).max] = -1
    return owner.astype(np.int32)


class ContactGeometry:
    """The scene's collision shapes on the device (``geoms``: a kernels.contacts.Geoms), bodies then colliders."""

    def __init__(self, model: Model):
        scene = model.scene
        device = model.device
        self.body_count = scene.body_count
        colliders = getattr(scene, "colliders", [])
        self.static_count = len(colliders)
        self.meshes: list[wp.Mesh] = []   # kept alive: the geoms hold their ids
        kinds, sizes, coms, mesh_ids, starts, counts, radii, bounds, e, mu = ([] for _ in range(10))
        samples, owner_starts, owners, xs, qs = [], [], [], [], []
        sample_total = owner_total = 0

        def add(shape, com, mesh_points, bound, restitution, friction, x, q, static_mesh_faces=None):
            nonlocal sample_total, owner_total
            kinds.append(KINDS[shape.kind])
            sizes.append(_size(shape))
            coms.append(com)
            mesh_id = 0
            if shape.kind == "mesh":
                mesh = wp.Mesh(points=wp.array(mesh_points, dtype=wp.vec3f, device=device),
                               indices=wp.array(np.asarray(shape.faces, dtype=np.int32).ravel(), dtype=wp.int32,
                                                device=device))
                self.meshes.append(mesh)
                mesh_id = mesh.id
            mesh_ids.append(mesh_id)
            owner_starts.append(owner_total)
            if static_mesh_faces is not None:   # static meshes: vertices found by BVH query, not looped over
                owners.append(_first_faces(static_mesh_faces, len(mesh_points)))
                owner_total += len(mesh_points)
                points, radius = np.zeros((0, 3)), 0.0
            else:
                points, radius = shape_samples(shape)
            starts.append(sample_total)
            counts.append(len(points))
            samples.append(points)
            sample_total += len(points)
            radii.append(radius)
            bounds.append(bound)
            e.append(restitution)
            mu.append(friction)
            xs.append(x)
            qs.append(q)

        for body in scene.bodies:
            shape = body.shape
            mesh_points = shape.vertices if shape.kind == "mesh" else None
            add(shape, body.mass.com, mesh_points, shape.bounding_radius, body.restitution, body.friction,
                body.position, body.orientation)
        for collider in colliders:
            shape = collider.shape
            if shape.kind == "mesh":   # stored in world axes about the centre of its box: pose (centre, identity)
                from .rotations import quat_to_matrix

                world = np.asarray(shape.vertices) @ quat_to_matrix(collider.orientation).T + collider.position
                centre = (world.min(axis=0) + world.max(axis=0)) / 2.0
                local = world - centre
                add(shape, np.zeros(3), local, float(np.max(np.linalg.norm(local, axis=1))), collider.restitution,
                    collider.friction, centre, np.array([0.0, 0.0, 0.0, 1.0]), static_mesh_faces=shape.faces)
            else:
                add(shape, np.zeros(3), None, _origin_bound(shape), collider.restitution, collider.friction,
                    collider.position, collider.orientation)

        g = detection_kernels.Geoms()

        def array(values, dtype, shape=None):
            data = np.asarray(values, dtype=np.float64 if dtype not in (wp.int32, wp.uint64) else None)
            if shape is not None:
                data = data.reshape(shape)
            return wp.array(data, dtype=dtype, device=device)

        g.kind = array(kinds, wp.int32)
        g.size = array(sizes, wp.vec3f, (-1, 3))
        g.com = array(coms, wp.vec3f, (-1, 3))
        g.mesh = wp.array(np.asarray(mesh_ids, dtype=np.uint64), dtype=wp.uint64, device=device)
        g.sample_start = array(starts, wp.int32)
        g.sample_count = array(counts, wp.int32)
        g.samples = array(np.concatenate(samples) if samples else np.zeros((0, 3)), wp.vec3f, (-1, 3))
        g.sample_radius = array(radii, wp.float32)
        g.owner_start = array(owner_starts, wp.int32)
        g.owner = wp.array(np.concatenate(owners) if owners else np.zeros(0, np.int32), dtype=wp.int32, device=device)
        g.bound = array(bounds, wp.float32)
        g.restitution = array(e, wp.float32)
        g.friction = array(mu, wp.float32)
        g.x = array(xs, wp.vec3f, (-1, 3))
        g.q = array(qs, wp.quatf, (-1, 4))
        g.reach = array(bounds, wp.float32)
        g.body_count = self.body_count
        self.geoms = g
        self.max_reach = wp.zeros(1, dtype=wp.float32, device=device)
        self.body_bound = max((b.shape.bounding_radius for b in scene.bodies), default=0.0)


def _origin_bound(shape) -> float:
    """Radius [m] about a primitive's (or point set's, or mesh's) own origin enclosing it."""
    if shape.kind == "mesh":
        return float(np.max(np.linalg.norm(shape.vertices, axis=1)))
    if shape.kind == "points":
        return float(np.max(np.linalg.norm(shape.positions, axis=1))) + shape.radius
    return shape.bounding_radius


class _Buffer:
    """A growable device buffer of pairs or contacts (a kernels.detection.ContactBuffer)."""

    def __init__(self, device, capacity: int, with_points: bool):
        self.device = device
        self.with_points = with_points
        self.count = wp.zeros(1, dtype=wp.int32, device=device)
        self.grows = 0
        self._allocate(capacity)

    def _allocate(self, capacity: int) -> None:
        self.capacity = capacity
        b = detection_kernels.ContactBuffer()
        b.count = self.count
        b.ids = wp.empty(capacity, dtype=wp.vec2i, device=self.device)
        size = capacity if self.with_points else 0
        b.normal = wp.empty(size, dtype=wp.vec3f, device=self.device)
        b.point1 = wp.empty(size, dtype=wp.vec3f, device=self.device)
        b.point2 = wp.empty(size, dtype=wp.vec3f, device=self.device)
        b.radius1 = wp.empty(size, dtype=wp.float32, device=self.device)
        b.radius2 = wp.empty(size, dtype=wp.float32, device=self.device)
        self.buffer = b

    def fill(self, launch) -> int:
        """Run ``launch(buffer)``; if it wrote more than fits, grow to fit and run it again. Returns the count."""
        while True:
            self.count.zero_()
            launch(self.buffer)
            count = int(self.count.numpy()[0])
            if count <= self.capacity:
                return count
            self.grows += 1
            self._allocate(max(2 * self.capacity, count + count // 4))

    @property
    def nbytes(self) -> int:
        b = self.buffer
        return sum(a.capacity for a in (b.ids, b.normal, b.point1, b.point2, b.radius1, b.radius2))


class Detection:
    """Broad and narrow phase over a pose pair (start, end) of the bodies: ``detect`` fills ``contacts``."""

    def __init__(self, model: Model, geometry: ContactGeometry, margin: float):
        self.model = model
        self.geometry = geometry
        self.margin = float(margin)
        device = model.device
        self.pairs = _Buffer(device, max(64, 8 * model.body_count), with_points=False)
        self.contacts = _Buffer(device, max(256, 16 * model.body_count), with_points=True)
        dim = int(min(128, max(8, 2.0 * model.body_count ** (1.0 / 3.0))))   # cells hash into dim^3 buckets
        self.grid = wp.HashGrid(dim, dim, dim, device=device) if model.body_count else None
        self.cell = max(2.0 * geometry.body_bound + self.margin, 1e-3)
        self.planes_normal = wp.array(np.array([p.normal for p in model.scene.planes]).reshape(-1, 3),
                                      dtype=wp.vec3f, device=device)
        self.planes_offset = wp.array([p.offset for p in model.scene.planes], dtype=wp.float32, device=device)
        self.planes_restitution = wp.array([p.restitution for p in model.scene.planes], dtype=wp.float32,
                                           device=device)
        self.planes_friction = wp.array([p.friction for p in model.scene.planes], dtype=wp.float32, device=device)
        self.pair_count = 0
        self.count = 0

    def detect(self, start: State, end: State) -> int:
        """Contacts at the start poses that could close before the end poses; returns their count."""
        m = self.model
        geoms = self.geometry.geoms
        B = m.body_count
        self.geometry.max_reach.zero_()
        m.launch(detection_kernels.gather_poses, B, [start.body_x, start.body_q, end.body_x, end.body_q, self.margin,
                                                   geoms, self.geometry.max_reach])
        self.grid.build(geoms.x[:B], self.cell)
        statics = self.geometry.static_count

        def pairs(buffer):
            m.launch(detection_kernels.find_pairs, B, [geoms, self.grid.id, statics, self.planes_normal,
                                                     self.planes_offset, self.geometry.max_reach, buffer])

        self.pair_count = self.pairs.fill(pairs)

        def contacts(buffer):
            m.launch(detection_kernels.narrow_phase, self.pair_count, [self.pairs.buffer, geoms, self.planes_normal,
                                                                     self.planes_offset, self.margin, buffer])

        self.count = self.contacts.fill(contacts) if self.pair_count else 0
        return self.count


class BodyContacts:
    """The impulse response with time of impact (see the module docstring).

    margin [m]: gap below which shapes count as in contact (besides what the step's motion
    could close); slop [m]: overlap the position projection leaves (so resting contacts stay
    found); bounce_speed [m/s]: slower impacts do not bounce (None: 2 |g| h); collision_sweeps,
    contact_sweeps, position_sweeps: Gauss-Seidel passes of each stage.
    """

    def __init__(self, model: Model, margin: float = 0.005, slop: float = 1.0e-4, bounce_speed: float | None = None,
                 collision_sweeps: int = 8, contact_sweeps: int = 24, position_sweeps: int = 4):
        self.model = model
        self.geometry = ContactGeometry(model)
        self.detection = Detection(model, self.geometry, margin)
        self.slop = slop
        self.bounce_speed = bounce_speed
        self.sweeps = (collision_sweeps, contact_sweeps, position_sweeps)
        self.position_response = 0.5   # the solver's (Integrator.position_response), set by the Simulator
        B = model.body_count
        device = model.device
        vec3, mat33, scalar = model.vec3, model.mat33, model.scalar
        self.v, self.w, self.v_collided, self.w_collided = (wp.zeros(B, dtype=vec3, device=device) for _ in range(4))
        self.inv_inertia_world = wp.zeros(B, dtype=mat33, device=device)
        self.body_impact = wp.zeros(B, dtype=scalar, device=device)
        self._capacity = 0
        self._ensure(self.detection.contacts.capacity)

    def _ensure(self, capacity: int) -> None:
        if capacity <= self._capacity:
            return
        m = self.model
        self._capacity = capacity
        vec3, scalar = m.vec3, m.scalar
        self.anchor1, self.anchor2, self.normal, self.impulse_t = (
            wp.zeros(capacity, dtype=vec3, device=m.device) for _ in range(4))
        self.impact_time, self.after_impact, self.min_normal_speed, self.restitution, self.friction, \
            self.impulse_n, self.rounding1, self.rounding2, self.target, self.collision_n = (
                wp.zeros(capacity, dtype=scalar, device=m.device) for _ in range(10))
        self.collision_t = wp.zeros(capacity, dtype=vec3, device=m.device)
        slots = 1 << int(2 * capacity - 1).bit_length()   # a power of two, at least twice the contacts
        self.table_used = wp.zeros(slots, dtype=wp.int32, device=m.device)
        self.table_keys = wp.zeros(slots, dtype=wp.vec2i, device=m.device)
        self.table_cells = wp.zeros(slots, dtype=wp.vec3i, device=m.device)
        self.table_n = wp.zeros(slots, dtype=scalar, device=m.device)
        self.table_t = wp.zeros(slots, dtype=vec3, device=m.device)

    @property
    def count(self) -> int:
        """Contacts found in the last step."""
        return self.detection.count

    def stats(self) -> dict:
        """Last step's pairs and contacts, buffer capacities, how often they grew, and their bytes."""
        d = self.detection
        per_contact = 5 * 3 * self.model.numpy_scalar().itemsize + 5 * self.model.numpy_scalar().itemsize
        return dict(pairs=d.pair_count, contacts=d.count, pair_capacity=d.pairs.capacity,
                    contact_capacity=d.contacts.capacity, grows=d.pairs.grows + d.contacts.grows,
                    bytes=d.pairs.nbytes + d.contacts.nbytes + self._capacity * per_contact)

    def apply(self, start: State, end: State, h: float) -> None:
        """Detect over the step from ``start`` to ``end`` (h seconds) and correct ``end`` in place."""
        m = self.model
        count = self.detection.detect(start, end)
        if count == 0:
            self.table_used.zero_()   # nothing to warm-start from next step
            return
        self._ensure(count)
        T = m.scalar
        gravity = float(np.linalg.norm(m.scene.gravity))
        bounce = self.bounce_speed if self.bounce_speed is not None else max(2.0 * gravity * h, 1e-6)
        B = m.body_count
        c = self.detection.contacts.buffer
        d = self.detection
        m.launch(contact_kernels.load_velocities, B, [end.body_q, end.body_P, end.body_L, m.body_inv_mass,
                                                      m.body_inv_inertia, self.v, self.w, self.inv_inertia_world,
                                                      self.body_impact])
        m.launch(contact_kernels.prepare_contacts, count, [
            c, self.geometry.geoms, d.planes_restitution, d.planes_friction,
            start.body_x, start.body_q, start.body_P, start.body_L, end.body_x, end.body_q, end.body_P, end.body_L,
            m.body_inv_mass, m.body_inv_inertia, T(h), T(bounce), T(self.slop),
            self.anchor1, self.anchor2, self.rounding1, self.rounding2, self.normal, self.impact_time,
            self.after_impact, self.min_normal_speed,
            self.restitution,
            self.friction, self.impulse_n, self.impulse_t, self.body_impact])
        geoms = self.geometry.geoms
        table = [self.table_used, self.table_keys, self.table_cells, self.table_n, self.table_t]
        m.launch(contact_kernels.recall_impulses, count, [geoms, c.ids, self.anchor1, self.normal, *table,
                                                          self.impulse_n, self.impulse_t])
        collisions, contacts, positions = self.sweeps
        m.launch(contact_kernels.collision_sweeps, 1, [
            count, collisions, c.ids, B, T(h), start.body_x, start.body_q, end.body_x, end.body_q, self.anchor1,
            self.anchor2, self.rounding1, self.rounding2, self.normal, self.impact_time, self.after_impact,
            self.restitution, self.friction,
            m.body_inv_mass, self.inv_inertia_world, T(bounce), self.target, self.collision_n, self.collision_t,
            self.v, self.w])
        wp.copy(self.v_collided, self.v)
        wp.copy(self.w_collided, self.w)
        m.launch(contact_kernels.contact_sweeps, 1, [
            count, contacts, c.ids, B, end.body_q, self.anchor1, self.anchor2, self.rounding1, self.rounding2,
            self.normal, self.min_normal_speed,
            self.friction, m.body_inv_mass, self.inv_inertia_world, self.impulse_n, self.impulse_t, self.v, self.w])
        self.table_used.zero_()
        m.launch(contact_kernels.remember_impulses, count, [geoms, c.ids, self.anchor1, self.impulse_n,
                                                            self.impulse_t, *table])
        m.launch(contact_kernels.finish_response, B, [
            T(h), T(self.position_response), m.body_inv_mass, m.body_inv_inertia, end.body_P, end.body_L,
            self.v_collided, self.w_collided, self.v, self.w, self.body_impact, end.body_x, end.body_q, end.body_P,
            end.body_L])
        m.launch(contact_kernels.project_positions, 1, [
            count, positions, c.ids, B, self.anchor1, self.anchor2, self.rounding1, self.rounding2, self.normal,
            m.body_inv_mass,
            m.body_inv_inertia, T(self.slop), end.body_x, end.body_q])


class ContactPenalty(ForceTerm):
    """Penalty response: each overlap of bodies, colliders and planes pushes with stiffness [N/m] and a damper
    whose bounce has the contact's restitution (see kernels.contacts.penalty_forces)."""

    targets = frozenset({"bodies"})

    def __init__(self, model: Model, stiffness: float, margin: float = 0.0):
        self.model = model
        self.stiffness = model.scalar(stiffness)
        self.detection = Detection(model, ContactGeometry(model), margin)

    def apply(self, state: State, t: float, forces: Forces) -> None:
        m = self.model
        count = self.detection.detect(state, state)
        if count:
            d = self.detection
            m.launch(contact_kernels.penalty_forces, count, [
                d.contacts.buffer, d.geometry.geoms, d.planes_restitution, d.planes_friction, state.body_x,
                state.body_q, state.body_P, state.body_L, m.body_inv_mass, m.body_inv_inertia, self.stiffness,
                forces.body_f, forces.body_t])


class ParticleShapeContacts:
    """Particles (and cloth and soft-body vertices) against bodies and static colliders, one way: shapes push
    particles, at the end of each step (see kernels.contacts.push_particles)."""

    def __init__(self, model: Model, geometry: ContactGeometry, detection: Detection | None):
        self.model = model
        self.geometry = geometry
        self.detection = detection
        self.touched = model.empty(wp.int32)

    def apply(self, end: State) -> None:
        m = self.model
        grid = self.detection.grid.id if self.detection is not None and self.detection.grid is not None else 0
        empty_vec, empty_q = m.empty(m.vec3), m.empty(wp.types.quaternion(m.scalar))
        bodies = [end.body_x, end.body_q, end.body_P, end.body_L, m.body_inv_mass, m.body_inv_inertia] \
            if m.body_count else [empty_vec, empty_q, empty_vec, empty_vec, m.empty(), m.empty(m.mat33)]
        m.launch(contact_kernels.push_particles, m.particle_count, [
            self.geometry.geoms, wp.uint64(grid), self.geometry.static_count, self.geometry.max_reach, *bodies,
            end.particle_x, end.particle_v, m.particle_inv_mass, m.particle_radius, m.particle_restitution,
            m.particle_friction, self.touched])

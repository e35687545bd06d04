"""Bodies in collision: the impulse response against bodies, static colliders and planes, a pass after each step.

Each step (``BodyContacts.apply``, after the solver), with the detection of ``warp_sim.detection``:
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
The alternative response, "penalty", is a force term (``warp_sim.forces.penalty``).

Buffers of pairs and contacts grow as needed: no contact is dropped.
"""
from __future__ import annotations

import warp as wp

from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..detection import Detection
from ..kernels import contacts as contact_kernels


class BodyContacts(Pass):
    """The impulse response with time of impact (see the module docstring), a Pass.

    detection: the broad and narrow phase it responds to (its margin [m] is the gap below which shapes count
        as in contact, besides what the step's motion could close)
    position_response: the solver's beta (Solver.position_response): how far a velocity change moves a body
    slop: overlap the position projection leaves, so resting contacts stay found [m]
    bounce_speed: slower impacts do not bounce [m/s] (None: 2 |g| h)
    collision_sweeps, contact_sweeps, position_sweeps: Gauss-Seidel passes of each stage
    """

    def __init__(self, model: Model, detection: Detection, position_response: float, slop: float = 1.0e-4,
                 bounce_speed: float | None = None, collision_sweeps: int = 8, contact_sweeps: int = 24,
                 position_sweeps: int = 4):
        self.model = model
        self.geometry = detection.geometry
        self.detection = detection
        self.slop = slop
        self.bounce_speed = bounce_speed
        self.sweeps = (collision_sweeps, contact_sweeps, position_sweeps)
        self.position_response = position_response
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

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        """Detect over the step from ``start`` to ``end`` (h seconds) and correct ``end`` in place."""
        m = self.model
        count = self.detection.detect(start, end)
        if count == 0:
            self.table_used.zero_()   # nothing to warm-start from next step
            return
        self._ensure(count)
        T = m.scalar
        gravity = m.gravity_magnitude
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

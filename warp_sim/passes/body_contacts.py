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
from ..kernels import blocks
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
        vec3, mat33, scalar = model.vec3, model.mat33, model.scalar
        zeros = model.zeros
        self.work = blocks.fill(model.blocks.BodyVelocities, v=zeros(B, vec3), w=zeros(B, vec3),
                                inv_inertia_world=zeros(B, mat33), impact=zeros(B, scalar))
        # the velocities after the collision phase (the same inertia and impacts as the working set)
        self.collided = blocks.fill(model.blocks.BodyVelocities, v=zeros(B, vec3), w=zeros(B, vec3),
                                    inv_inertia_world=self.work.inv_inertia_world, impact=self.work.impact)
        self._capacity = 0
        self._ensure(self.detection.contacts.capacity)

    def _ensure(self, capacity: int) -> None:
        """Per-contact rows and the warm-start table for at least ``capacity`` contacts (they only grow)."""
        if capacity <= self._capacity:
            return
        m = self.model
        self._capacity = capacity
        self.rows = blocks.fill(m.blocks.ContactRows, **{name: m.zeros(capacity, var.type.dtype)
                                                          for name, var in m.blocks.ContactRows.vars.items()})
        slots = 1 << int(2 * capacity - 1).bit_length()   # a power of two, at least twice the contacts
        self.table = blocks.fill(m.blocks.ImpulseTable, used=m.zeros(slots, wp.int32), keys=m.zeros(slots, wp.vec2i),
                                 cells=m.zeros(slots, wp.vec3i), n=m.zeros(slots), t=m.zeros(slots, m.vec3))

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
            self.table.used.zero_()   # nothing to warm-start from next step
            return
        self._ensure(count)
        T = m.scalar
        gravity = m.gravity_magnitude
        bounce = self.bounce_speed if self.bounce_speed is not None else max(2.0 * gravity * h, 1e-6)
        B = m.body_count
        c = self.detection.contacts.buffer
        rows, work, table, geoms = self.rows, self.work, self.table, self.geometry.geoms
        mass = m.body_mass
        m.launch(contact_kernels.load_velocities, B, [end.bodies, mass, work])
        m.launch(contact_kernels.prepare_contacts, count, [c, geoms, start.bodies, end.bodies, mass, T(h), T(bounce),
                                                           T(self.slop), rows, work])
        m.launch(contact_kernels.recall_impulses, count, [geoms, c.ids, rows, table])
        collisions, contacts, positions = self.sweeps
        m.launch(contact_kernels.collision_sweeps, 1, [count, collisions, c.ids, B, T(h), start.bodies, end.bodies,
                                                       rows, mass, work, T(bounce)])
        wp.copy(self.collided.v, work.v)
        wp.copy(self.collided.w, work.w)
        m.launch(contact_kernels.contact_sweeps, 1, [count, contacts, c.ids, B, end.bodies, rows, mass, work])
        table.used.zero_()
        m.launch(contact_kernels.remember_impulses, count, [geoms, c.ids, rows, table])
        m.launch(contact_kernels.finish_response, B, [T(h), T(self.position_response), mass, self.collided, work,
                                                      end.bodies])
        m.launch(contact_kernels.project_positions, 1, [count, positions, c.ids, B, rows, mass, T(self.slop),
                                                        end.bodies])

"""Bodies in collision: the impulse response against bodies, static colliders and planes, a pass after each step.

Each step (``BodyContacts.apply``, after the solver), with the detection of ``warp_sim.detection``:
1. broad phase: every pair up to 128 bodies, beyond that a hash grid over the bodies' centres
   (rebuilt every step, linear in the body count), gives the pairs whose bounding spheres, grown
   by how far each body moves over the step and the contact margin, overlap; static colliders
   and planes are tested per body;
2. narrow phase at the start of the step: sample points (box corners, capsule and
   sphere centres with their radius, cylinder rims, mesh vertices) against the other
   shape's signed distance, and box-box contact polygons by separating axes; every
   contact that could close within the step is kept, so nothing tunnels;
3. manifolds: the contacts grouped by pair and the pairs coloured so that no two of a
   colour share a body (``detection.ContactManifolds``);
4. response on the solver's end-of-step state, graph-coloured Gauss-Seidel: every sweep
   is one launch per colour with one thread per manifold, which solves its contacts
   together. The time of impact of each contact within the step, collision impulses with
   restitution and Coulomb friction there (swept so impacts propagate through touching
   bodies), then sequential impulses for resting and sliding contact, warm-started from
   last step's, then a position projection that removes overlap without changing
   velocities (so it adds no energy): partly between bodies each step (``relax``, which
   keeps tall stacks from leaning), fully against static colliders and planes, which come
   last in every sweep.

A contact's restitution and friction are the means of the two sides' values. Restitution
applies to impacts faster than ``bounce_speed`` (default 2 |g| h, the speed gravity gives
in two steps); slower ones are resting contact, so bodies settle instead of jittering.
The alternative response, "penalty", is a force term (``warp_sim.forces.penalty``).

In a differentiable run the response runs on the tape instead, launch by launch (``passes.contact_adjoint``),
for the scenes it covers (``CoveredBodyContacts``).

Buffers of pairs and contacts grow as needed: no contact is dropped.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..detection import ContactManifolds, Detection
from ..kernels import blocks
from ..kernels import contacts as contact_kernels
from .contact_adjoint import TapedResponse


class BodyContacts(Pass):
    """The impulse response with time of impact (see the module docstring), a Pass.

    detection: the broad and narrow phase it responds to (its margin [m] is the gap below which shapes count
        as in contact, besides what the step's motion could close)
    position_response: the solver's beta (Solver.position_response): how far a velocity change moves a body
    slop: overlap the position projection leaves, so resting contacts stay found [m]
    bounce_speed: slower impacts do not bounce [m/s] (None: 2 |g| h)
    sweeps: Gauss-Seidel sweeps of the collision, contact and position stages (each one launch per colour; on
        the CPU, uncaptured, one launch per run of colours)
    iterations: how often a manifold's own contacts are iterated within one sweep, per stage
    tolerance: a manifold's resting iterations stop once no update changes a contact velocity by more [m/s]
    relax: the share of a body-body overlap the projection removes per step [1] (all of it against statics)
    manifolds: the grouping and colouring (ContactManifolds)
    joints: the scene's joints (passes.Joints) or None: rows of the same solve, swept after the body-body contact
        colours and before the static ones in every resting and position sweep
    max_step: the longest step it takes [s] (Pass.max_step; the Simulator's contact_step, by default 1/120 s:
        the longest at which the default sweeps hold stacks and landing piles; None: no sub-steps)
    hold_impact_time: in a differentiable run, hold the times of impact (the naive discrete gradient, which misses
        how a bounce moves with its impact time; for comparison only)
    """

    hold_impact_time = False

    capturable = True   # captured steps launch over the last counts with headroom, gated on the device (replay_held)
    merge_cpu_colours = True   # uncaptured on the CPU, a run of colours is one launch (_sweep); False: one each

    persistent = ("_capacity", "table.used", "table.keys", "table.cells", "table.n", "table.t")   # the warm start

    def persistent_parts(self) -> dict:
        """The joints' accumulated impulses and states, swept inside this pass."""
        return {"joints": self.joints} if self.joints is not None else {}

    def __init__(self, model: Model, detection: Detection, position_response: float, slop: float = 1.0e-4,
                 bounce_speed: float | None = None, sweeps: tuple[int, int, int] = (8, 16, 4),
                 iterations: tuple[int, int, int] = (8, 2, 2), relax: float = 0.2, tolerance: float = 1.0e-4,
                 max_step: float | None = None, joints=None):
        self.model = model
        self.joints = joints
        if joints is not None:
            self.capturable = False   # its uncaptured steps without contacts run the joints alone
        self.geometry = detection.geometry
        self.detection = detection
        self.manifolds = ContactManifolds(model, detection)
        self.slop = slop
        self.bounce_speed = bounce_speed
        self.sweeps = sweeps
        self.iterations = iterations
        self.relax = relax
        self.tolerance = tolerance
        self.max_step = max_step
        self.position_response = position_response
        B = model.body_count
        vec3, mat33, scalar = model.vec3, model.mat33, model.scalar
        zeros = model.zeros
        self.work = blocks.fill(model.blocks.BodyVelocities, v=zeros(B, vec3), w=zeros(B, vec3),
                                inv_inertia_world=zeros(B, mat33), impact=zeros(B, scalar), stamp=zeros(B, wp.int32))
        # the velocities after the collision phase (the same inertia, impacts and stamps as the working set)
        self.collided = blocks.fill(model.blocks.BodyVelocities, v=zeros(B, vec3), w=zeros(B, vec3),
                                    inv_inertia_world=self.work.inv_inertia_world, impact=self.work.impact,
                                    stamp=self.work.stamp)
        # per body, 1 where a joint holds it: it drifts as symplectic Euler (contacts.finish_response)
        self.drift = joints.drift if joints is not None else zeros(B, wp.int32)
        self._capacity = 0
        self._ensure(self.detection.contacts.capacity)
        self._recorded_sizes = None
        self._places = None   # uncaptured on the CPU: each colour's first place in the manifolds' order (_sweep)
        self.taped = TapedResponse(self)   # the response of a differentiable run

    @property
    def kernels(self) -> tuple[str, ...]:
        """Its kernel modules: the joints' too where it sweeps them, its taped response's in a differentiable run."""
        return tuple(dict.fromkeys(("contacts", "detection", "manifolds", "rigid",
                                    *(self.joints.kernels if self.joints is not None else ()),
                                    *(("contact_adjoint",) if self.model.differentiable else ()))))

    def carried(self) -> list:
        """The joints' impulses in a differentiable run (Joints.carried), which it sweeps."""
        return self.joints.carried() if self.joints is not None else []

    def carry(self, arrays: list) -> None:
        if self.joints is not None:
            self.joints.carry(arrays)

    def bounce(self, h: float) -> float:
        """The slowest approach [m/s] that bounces in a step of h seconds (``bounce_speed``, by default 2 |g| h)."""
        return self.bounce_speed if self.bounce_speed is not None else max(2.0 * self.model.gravity_magnitude * h,
                                                                           1e-6)

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

    def before_restore(self, values: dict) -> None:
        self._ensure(values["_capacity"])

    @property
    def count(self) -> int:
        """Contacts found in the last step."""
        return self.detection.count

    def stats(self) -> dict:
        """Last step's pairs, contacts and colours, buffer capacities, how often they grew, and their bytes."""
        d = self.detection
        per_contact = 5 * 3 * self.model.numpy_scalar().itemsize + 5 * self.model.numpy_scalar().itemsize
        return dict(pairs=d.pair_count, contacts=d.count, colours=len(self.manifolds.colours),
                    body_colours=self.manifolds.body_colours, pair_capacity=d.pairs.capacity,
                    contact_capacity=d.contacts.capacity, grows=d.pairs.grows + d.contacts.grows,
                    bytes=d.pairs.nbytes + d.contacts.nbytes + self._capacity * per_contact)

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        """Detect over the step from ``start`` to ``end`` (h seconds) and correct ``end`` in place.

        While a step is captured (core.capture) nothing is read back: the launches run over the last uncaptured
        counts and colouring's colours with headroom, and the response runs only where the device's
        gates say that they held everything (``replay_held``); a step whose launches missed something leaves
        ``end`` as the solver wrote it and the warm start as it was, and is done again uncaptured."""
        m = self.model
        if m.differentiable:
            self.taped.apply(start, end, t, h)
            return
        capturing = m.launcher.capturing
        count = self.detection.detect(start, end)
        if count == 0:
            self.table.used.zero_()   # nothing to warm-start from next step
            if self.joints is not None:
                self.joints.apply(start, end, t, h)
            return
        self._ensure(self.detection.contacts.capacity)
        threads = self.detection.threads()[1]
        T = m.scalar
        bounce = self.bounce(h)
        B = m.body_count
        contacts = self.detection.contacts
        c = contacts.buffer
        rows, work, table, geoms = self.rows, self.work, self.table, self.geometry.geoms
        mass = m.body_mass
        manifolds = self.manifolds
        joints = self.joints
        manifolds.sort()
        slot = manifolds.slot
        m.launch(contact_kernels.load_velocities, B, [end.bodies, mass, work])
        m.launch(contact_kernels.prepare_contacts, threads, [c, slot, manifolds.row_ids, geoms, start.bodies,
                                                             end.bodies, mass, T(h), T(bounce), T(self.slop), rows,
                                                             work, manifolds.impacts])
        colours, body_colours, impacts = manifolds.colour()
        # on the CPU, uncaptured: each colour's first place in the manifolds' order, for _sweep's one launch a run
        self._places = None
        if m.device.is_cpu and not capturing:
            firsts = np.cumsum([0] + [n for _, n in colours[:-1]]).tolist()
            self._places = {k: first for (k, _), first in zip(colours, firsts)}
        (collision_sweeps, contact_sweeps, position_sweeps), (collision_iterations, contact_iterations,
                                                              position_iterations) = self.sweeps, self.iterations

        def collide():
            prepared = m.launcher.prepare(contact_kernels.collide_manifolds, 1, [
                manifolds.set, 0, collision_iterations, 0, T(h), start.bodies, end.bodies, rows, mass, work,
                T(bounce), work.stamp])
            for sweep in range(collision_sweeps):
                prepared.set(3, sweep)
                self._sweep(prepared, colours, 1)

        def respond():   # the warm start is read here, after the gates: a missed step must leave it as it was
            m.launch(contact_kernels.recall_impulses, threads, [geoms, c.ids, c.count, slot, rows, table])
            wp.copy(self.collided.v, work.v)
            wp.copy(self.collided.w, work.w)
            m.launch(contact_kernels.prepare_rows, threads, [manifolds.row_ids, c.count, B, end.bodies, rows, mass,
                                                             work])
            self._sweep(m.launcher.prepare(contact_kernels.warm_start_manifolds, 1, [
                manifolds.set, 0, rows, mass, work, manifolds.row_ids]), colours, 1)
            if joints is not None:
                joints.warm_start(start, mass, work)
            solve = m.launcher.prepare(contact_kernels.solve_manifolds, 1, [
                manifolds.set, 0, contact_iterations, 0, T(self.tolerance), rows, mass, work, work.stamp])
            for sweep in range(max(contact_sweeps, joints.velocity_sweeps if joints is not None else 0)):
                number = collision_sweeps + 1 + sweep   # after the collision sweeps, whose stamps they follow
                solve.set(3, number)
                if joints is None:
                    self._sweep(solve, colours, 1)
                    continue
                self._sweep(solve, colours[:body_colours], 1)
                joints.velocity_sweep(start, mass, work, h, number)
                self._sweep(solve, colours[body_colours:], 1)
            if joints is not None:
                joints.finish(h, t)
            m.launch(contact_kernels.finish_response, B, [T(h), T(self.position_response), mass, self.collided,
                                                          work, start.bodies, end.bodies, self.drift])
            # positions: the body-body colours relaxed, the static ones in full, last
            project = m.launcher.prepare(contact_kernels.project_manifolds, 1, [
                manifolds.set, 0, position_iterations, 0, rows, mass, T(self.slop), T(self.relax), end.bodies,
                work.stamp])
            relax, full = T(self.relax), T(1.0)
            manifolds.quiet.zero_()      # every manifold is looked at in the first position sweep
            work.stamp.fill_(-1)
            for sweep in range(max(position_sweeps, joints.position_sweeps if joints is not None else 0)):
                project.set(3, sweep)
                project.set(7, relax)
                self._sweep(project, colours[:body_colours], 1)
                if joints is not None:
                    joints.position_sweep(end, mass, work.stamp, sweep)
                project.set(7, full)
                self._sweep(project, colours[body_colours:], 1)

        def remember():   # this step's impulses, for the next step's warm start
            table.used.zero_()
            m.launch(contact_kernels.remember_impulses, threads, [geoms, c.ids, c.count, slot, rows, table])

        if not capturing:
            if impacts:
                collide()
            respond()
            remember()
            return
        wp.capture_if(manifolds.collide, on_true=collide)
        wp.capture_if(manifolds.respond, on_true=respond)
        wp.capture_if(manifolds.keep, on_true=remember)

    def before_capture(self) -> bool:
        self.detection.before_capture()
        self._recorded_sizes = self._sizes()
        return self.manifolds.before_capture()

    def _sizes(self) -> tuple:
        """The capacities whose growth reallocates the arrays a captured step launches on."""
        d, manifolds = self.detection, self.manifolds
        return d.pairs.capacity, d.contacts.capacity, manifolds.colour_capacity, self._capacity

    def capture_intact(self) -> bool:
        return self._sizes() == self._recorded_sizes

    def replay_held(self) -> bool:
        """After a captured step's replay: whether its launches held all of it (no count and no colour over its
        threads; one int read back). False: the step must be done again, uncaptured."""
        return int(self.manifolds.missed.numpy()[0]) == 0

    def _sweep(self, prepared, colours: list[tuple[int, int]], sweeps: int) -> None:
        """``sweeps`` Gauss-Seidel sweeps of a prepared manifold kernel: one launch per colour, a thread per manifold
        (input 1 of the kernel is the colour; it launches at least as many threads as the colour has manifolds).
        Uncaptured on the CPU, whose launch runs its threads one after another in order, one launch for the whole
        run of colours instead (kernels.manifolds.manifold_rows), the same sweep bit for bit."""
        if not colours:
            return
        if self.merge_cpu_colours and self._places is not None:
            colours = [(-1 - self._places[colours[0][0]], sum(n for _, n in colours))]
        prepared.sweep(1, colours, sweeps)


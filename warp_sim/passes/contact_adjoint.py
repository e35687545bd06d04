"""Body contacts in a differentiable run: their response recorded on the tape launch by launch
(``TapedResponse``), and which scenes it covers (``refusal``).

The forward pass (passes.body_contacts) solves in place, a thread per manifold looping over its contacts and
iterations, which no tape can take back. In a differentiable run the same response runs as launches that each
write arrays of their own (kernels.contact_adjoint): every update of a Gauss-Seidel sweep is one launch per
colour and per contact slot of the manifolds, from the velocities (or poses) before it into new ones, so Warp's
adjoint of each replays it on what it saw. In order, each step:

1. off the tape: detection, manifolds and colours, as forward (integers, and the float32 narrow phase);
2. the contacts' normals, gaps and times of impact from the start poses (taped_rows), so that the time of impact
   follows the state: a later impact, from a higher drop, moves the bounce and everything after it;
3. the collision sweeps (impulses with restitution at the time of impact), until a sweep finds no impact;
4. the resting sweeps (warm-started), every manifold's iterations in full, until a sweep changes nothing. The
   forward stops a manifold's iterations at its ``tolerance`` and skips those that stopped changing: choices that
   make its result a fine staircase of the inputs (steps of about the tolerance, 1e-4 m/s), each step's slope not
   the run's (a resting box's gradient 2 % off central differences with them, 8e-5 without); a differentiable run
   differs from a forward one by about that in its resting contacts (a resting box's height by 4e-9 m);
5. finish_response (the position moved by the collision's velocity change over the rest of the step), then the
   position projection, until a sweep pushes nothing; the result is copied into the end state.

What the gradient means: through an impact, it is the derivative of the bounce at its time of impact (the
post-impact velocity -e u and the position it reaches over the rest of the step, both moving with the impact time
as the state moves it). Where contacts rest or switch (a contact starts or stops touching or pushing, an impact
falls below ``bounce_speed``), it is the derivative with those choices held as the run made them: exact for every
run that makes the same choices, one-sided where a change of the input would change one.
``BodyContacts.hold_impact_time`` holds the times of impact too: the naive discrete gradient, which misses how
the bounce moves with the impact (for comparison only).

Friction: the Coulomb impulses of the same updates, each contact's coefficient the mean of its sides' in the
model's precision (the bodies' and planes' own, so that a gradient reaches them). Where a contact slides, the
limit mu Jn carries mu and Jn into the gradient; where it sticks, the impulse is whatever stops the sliding, and
mu does not enter (held: the one-sided derivative of a contact that stays stuck).

Covered (``refusal`` says why not): contacts between spheres, of any body on planes, and of spheres on static
spheres, with restitution and friction; the joints it sweeps (passes.joint_adjoint's TapedJoints: their warm
start with the contacts', their velocity sweep between the body-body colours and the static ones of each
resting sweep, their position sweep likewise, as forward).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.state import State
from ..core.tape import active_tape, copies, paused
from ..kernels import blocks
from ..kernels import contact_adjoint as taped
from ..kernels import contacts as contact_kernels
from ..kernels.geometry import KINDS

NONE = np.iinfo(np.int32).max   # no winner row (kernels.contact_adjoint.taped_impacts)


def refusal(contacts) -> str | None:
    """Why the taped response does not cover the scene of ``contacts`` (a BodyContacts pass), or None where it does."""
    geoms, bodies = contacts.geometry.geoms, contacts.model.body_count
    kinds = geoms.kind.numpy()
    if (kinds[bodies:] != KINDS["sphere"]).any():
        return "static colliders other than spheres"
    shaped = kinds[:bodies][kinds[:bodies] != KINDS["none"]]
    if shaped.size > 1 and (shaped != KINDS["sphere"]).any():
        return "pairs of bodies other than two spheres"
    return None


def _grad_zeros(model, count: int, dtype) -> wp.array:
    return wp.zeros(count, dtype=dtype, device=model.device, requires_grad=True)


def _held(block, names: tuple):
    """A struct like ``block`` (Warp's) whose fields ``names`` are copies of its arrays, the rest the same."""
    held = block._cls()
    for name in block._cls.vars:
        setattr(held, name, wp.clone(getattr(block, name)) if name in names else getattr(block, name))
    return held


class TapedResponse:
    """The response of a BodyContacts pass (``contacts``) in a differentiable run, on the tape (module docstring;
    ``contacts.hold_impact_time`` holds the times of impact: the naive gradient)."""

    def __init__(self, contacts):
        self.contacts = contacts

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        """Detect over the step from ``start`` to ``end`` (h seconds) and correct ``end``: what BodyContacts.apply
        does, every launch that changes a float on the tape."""
        bc = self.contacts
        with paused():
            found = bc.detection.detect(start, end)
        if found == 0:
            with paused():
                bc.table.used.zero_()   # nothing to warm-start from next step
            if bc.joints is not None:
                bc.joints.apply(start, end, t, h)   # in a differentiable run, its taped solve
            return
        with paused():
            bc._ensure(bc.detection.contacts.capacity)
            bc.manifolds.sort()
            colours, body_colours, _ = bc.manifolds.colour()
        m = bc.model
        self.slots = int(bc.manifolds.counts.numpy().max())   # the most contacts of a manifold
        self._hold()
        self.rows_count = bc.detection.threads()[1]
        pre = State(end.layout, m.scalar, m.device, requires_grad=True)
        wp.copy(pre.y, end.y)   # what the solver wrote, read by everything below (end is overwritten last)
        rows, work = self._prepare(start, pre, h)
        v, w = self._collide(start, pre, rows, work, h, colours)
        collided = self._velocities(work, v, w)
        joints = bc.joints.taped if bc.joints is not None else None
        if joints is not None:
            joints.begin()
        v, w, jn, jt = self._rest(start, pre, rows, collided, colours, body_colours, joints, h)
        fin = State(end.layout, m.scalar, m.device, requires_grad=True)
        wp.copy(fin.y, pre.y)
        m.launcher.launch_in_place(contact_kernels.finish_response, m.body_count, [
            m.scalar(h), m.scalar(bc.position_response), m.body_mass, collided, self._velocities(work, v, w),
            start.bodies, self._bodies(fin), bc.drift], fin.y)
        x, q = self._project(fin, rows, colours, body_colours, joints)
        if joints is not None:
            joints.commit()
        for field, value in (("body_x", x), ("body_q", q), ("body_P", fin.body_P), ("body_L", fin.body_L)):
            wp.copy(getattr(end, field), value)
        with paused():   # this step's impulses, for the next step's warm start
            bc.table.used.zero_()
            c = self.contact_set
            m.launch(contact_kernels.remember_impulses, self.rows_count, [
                self.geoms, c.ids, c.count, self.slot, self._rows(rows, impulse_n=jn, impulse_t=jt), bc.table])

    def _hold(self) -> None:
        """This step's contacts, manifolds, start poses of the shapes and rows of the contacts (``contact_set``,
        ``manifold_set``, ``geoms``, ``slot``): on a tape, copies of the arrays that later steps overwrite, which
        the adjoints of this step's launches read again (off a tape, the pass's own)."""
        bc = self.contacts
        c, manifolds, geoms = bc.detection.contacts.buffer, bc.manifolds, bc.geometry.geoms
        if active_tape() is None:
            self.contact_set, self.manifold_set, self.geoms, self.slot = c, manifolds.set, geoms, manifolds.slot
            return
        with paused():
            self.contact_set = _held(c, ("count", "ids", "normal", "point1", "point2", "radius1", "radius2"))
            self.manifold_set = _held(manifolds.set, ("row_ids", "offsets", "counts", "order", "starts", "sizes"))
            self.geoms = _held(geoms, ("x", "q"))
            self.slot = wp.clone(manifolds.slot)

    def _bodies(self, state: State):
        return blocks.fill(self.contacts.model.blocks.Bodies, x=state.body_x, q=state.body_q, P=state.body_P,
                           L=state.body_L)

    def _velocities(self, work, v: wp.array, w: wp.array):
        """The working set ``work`` (BodyVelocities) with velocities v, w."""
        return blocks.fill(self.contacts.model.blocks.BodyVelocities, v=v, w=w,
                           inv_inertia_world=work.inv_inertia_world, impact=work.impact, stamp=work.stamp)

    def _rows(self, rows, **fields):
        """The ContactRows ``rows`` with some fields replaced."""
        layout = self.contacts.model.blocks.ContactRows
        return blocks.fill(layout, **{name: fields.get(name, getattr(rows, name)) for name in layout.vars})

    def _prepare(self, start: State, pre: State, h: float):
        """The contacts' rows (taped_rows) and the working set: the end velocities, and each body's earliest impact
        taken from one row (kernels.contact_adjoint.impact_rows)."""
        bc = self.contacts
        m, n = bc.model, self.rows_count
        T, B = m.scalar, m.body_count
        layout = m.blocks.ContactRows
        rows, scratch = ({name: _grad_zeros(m, n, var.type.dtype) for name, var in layout.vars.items()}
                         for _ in range(2))
        rows, scratch = blocks.fill(layout, **rows), blocks.fill(layout, **scratch)
        work = blocks.fill(m.blocks.BodyVelocities, v=_grad_zeros(m, B, m.vec3), w=_grad_zeros(m, B, m.vec3),
                           inv_inertia_world=_grad_zeros(m, B, m.mat33), impact=_grad_zeros(m, B, T),
                           stamp=m.zeros(B, wp.int32))
        m.launch(contact_kernels.load_velocities, B, [self._bodies(pre), m.body_mass, work])
        c, row_ids = self.contact_set, self.manifold_set.row_ids
        bounces = m.zeros(n, wp.int32)
        inputs = [c, self.slot, row_ids, self.geoms,
                  m.planes if m.planes is not None else m.no_planes(), start.bodies, self._bodies(pre), m.body_mass,
                  m.body_restitution, m.body_friction, T(h), T(bc.bounce(h)), T(bc.slop), m.empty(), rows, bounces]
        if bc.hold_impact_time:
            with paused():
                m.launch(taped.taped_rows, n, inputs[:-2] + [scratch, bounces])
            inputs[-3] = scratch.impact_time
        m.launch(taped.taped_rows, n, inputs)
        with paused():
            first = wp.full(B, 1.0e30, dtype=T, device=m.device)
            winner = wp.full(B, NONE, dtype=wp.int32, device=m.device)
            m.launch(taped.earliest_impacts, n, [row_ids, c.count, B, rows.impact_time, bounces, first])
            m.launch(taped.impact_rows, n, [row_ids, c.count, B, rows.impact_time, bounces, first, winner])
        impact = _grad_zeros(m, B, T)
        m.launch(taped.taped_impacts, B, [winner, rows, T(h), impact])
        work.impact = impact
        return rows, work

    def _collide(self, start: State, pre: State, rows, work, h: float, colours: list) -> tuple:
        """The collision sweeps; returns the velocities after them."""
        bc = self.contacts
        m, n = bc.model, self.rows_count
        T = m.scalar
        v, w = work.v, work.w
        sweeps, iterations = bc.sweeps[0], bc.iterations[0]
        inputs = [self.manifold_set, 0, T(h), start.bodies, self._bodies(pre), rows]
        for _sweep in range(sweeps):
            collided = False
            for colour, size in colours:
                target = _grad_zeros(m, n, T)
                hits = m.zeros(1, wp.int32)
                inputs[1] = colour
                m.launch(taped.taped_targets, size, inputs + [self._velocities(work, v, w), T(bc.bounce(h)), target,
                                                              hits])
                if int(hits.numpy()[0]) == 0:
                    continue
                collided = True
                jn, jt = _grad_zeros(m, n, T), _grad_zeros(m, n, m.vec3)
                for _iteration in range(iterations):
                    for slot in range(self.slots):
                        outputs = copies(v, w, jn, jt)
                        m.launch(taped.taped_collide, size, [self.manifold_set, colour, slot, *inputs[2:],
                                                             m.body_mass, work.inv_inertia_world, target, v, w, jn,
                                                             jt, *outputs])
                        v, w, jn, jt = outputs
            if not collided:   # nothing changed: every later sweep would find no impact either
                break
        return v, w

    def _rest(self, start: State, pre: State, rows, collided, colours: list, body_colours: int, joints,
              h: float) -> tuple:
        """Warm start and the resting sweeps from the collided velocities, the joints' (``joints``: a TapedJoints,
        or None) between the body-body colours and the static ones of each sweep; returns (v, w, Jn, Jt)."""
        bc = self.contacts
        m, n = bc.model, self.rows_count
        c, manifolds = self.contact_set, self.manifold_set
        with paused():
            m.launch(contact_kernels.recall_impulses, n, [self.geoms, c.ids, c.count, self.slot, rows, bc.table])
        m.launch(contact_kernels.prepare_rows, n, [manifolds.row_ids, c.count, m.body_count, self._bodies(pre), rows,
                                                   m.body_mass, collided])
        v, w = collided.v, collided.w
        for colour, size in colours:
            v, w = copies(v, w)
            m.launch(contact_kernels.warm_start_manifolds, size, [
                manifolds, colour, rows, m.body_mass, self._velocities(collided, v, w), manifolds.row_ids])
        if joints is not None:
            v, w = joints.warm_start(start, v, w)
        state = [v, w, rows.impulse_n, rows.impulse_t]

        def solve(colour: int, size: int, slot: int, moved: wp.array, _):
            outputs = copies(*state)
            m.launch(taped.taped_solve, size, [manifolds, colour, slot, rows, m.body_mass, collided.inv_inertia_world,
                                               *state, *outputs, moved])
            state[:] = outputs

        def joint_sweep():
            state[0], state[1] = joints.velocity_sweep(start, collided.inv_inertia_world, state[0], state[1], h)

        groups = [(colours[:body_colours], None), (colours[body_colours:], None)]
        if joints is None:
            self._sweeps(groups, bc.sweeps[1], bc.iterations[1], solve)
        else:
            self._sweeps(groups, bc.sweeps[1], bc.iterations[1], solve, joint_sweep, joints.joints.velocity_sweeps)
        return tuple(state)

    def _project(self, fin: State, rows, colours: list, body_colours: int, joints) -> tuple:
        """The position sweeps from the finished state: body-body colours relaxed, the joints' (``joints``, or
        None), static ones in full; returns the positions and orientations."""
        bc = self.contacts
        m = bc.model
        T = m.scalar
        state = [fin.body_x, fin.body_q]

        def push(colour: int, size: int, slot: int, moved: wp.array, relax: float):
            outputs = copies(*state)
            m.launch(taped.taped_project, size, [self.manifold_set, colour, slot, rows, m.body_mass, T(bc.slop),
                                                 T(relax), *state, *outputs, moved])
            state[:] = outputs

        def joint_sweep():
            state[0], state[1] = joints.position_sweep(state[0], state[1])

        groups = [(colours[:body_colours], bc.relax), (colours[body_colours:], 1.0)]
        if joints is None:
            self._sweeps(groups, bc.sweeps[2], bc.iterations[2], push)
        else:
            self._sweeps(groups, bc.sweeps[2], bc.iterations[2], push, joint_sweep, joints.joints.position_sweeps)
        return tuple(state)

    def _sweeps(self, groups: list, sweeps: int, iterations: int, update, joint_sweep=None,
                joint_sweeps: int = 0) -> None:
        """The Gauss-Seidel sweeps of the resting or the position stage: ``groups``, (colours, a value for
        ``update``) in order, each colour's manifolds iterated ``iterations`` times, update(colour, size, slot,
        moved, value) launching one taped update of row ``slot`` of the colour's manifolds; joint_sweep(), if
        given, after the first group (the joints' sweep, as forward: max(sweeps, joint_sweeps) of them). They end
        early after a sweep that changed nothing (``moved``) once the joints' are done: every later one would
        change nothing either."""
        m = self.contacts.model
        for sweep in range(max(sweeps, joint_sweeps if joint_sweep is not None else 0)):
            moved = m.zeros(1, wp.int32)
            for number, (colours, value) in enumerate(groups):
                for colour, size in colours:
                    for _iteration in range(iterations):
                        for slot in range(self.slots):
                            update(colour, size, slot, moved, value)
                if number == 0 and joint_sweep is not None:
                    joint_sweep()
            if int(moved.numpy()[0]) == 0 and (joint_sweep is None or sweep + 1 >= joint_sweeps):
                break

"""Body contact response on a wp.Tape: the launches of ``passes.contact_adjoint``, whose adjoints Warp builds.

Each kernel reads its inputs and writes arrays no later launch overwrites (a thread writes only the rows and the
bodies of its own manifold's contact ``slot``, into arrays the caller copied from the inputs), so a tape's
backward replays each on the values it saw. The arithmetic is the forward's (``contacts``, ``impulses``); the
geometry of each contact is taken again from the start poses in the state's precision (a point fixed in body i
against a plane, or the line between two spheres' centres), so that the normal, the gap and the time of impact
follow the state they came from.

Private: every kernel here is for the simulator's own use (passes.contact_adjoint); their arguments may change
between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .contacts import (
    bouncing,
    colliding,
    contact_impact_levers,
    contact_row,
    impact_normal,
    impact_target,
    write_row,
)
from .detection import ContactBuffer, Geoms, beyond, is_body
from .impulses import impulse_update, pair_values, push_apart, row_update, store_pair
from .manifolds import ManifoldSet, manifold_rows
from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []


@wp.func
def body_point(geoms: Geoms, g: int, p: wp.vec3f):
    """The contact sample of geom g (a sphere's: its centre) nearest the world point p at the float32 start pose
    the narrow phase used, exactly, in g's frame about its centre of mass [m]."""
    local = wp.quat_rotate_inv(geoms.q[g], p - geoms.x[g]) + geoms.com[g]
    first = geoms.sample_start[g]
    nearest = first
    for k in range(first + 1, first + geoms.sample_count[g]):
        if wp.length(geoms.samples[k] - local) < wp.length(geoms.samples[nearest] - local):
            nearest = k
    return geoms.samples[nearest] - geoms.com[g]


@wp.func
def pair_value(geoms: Geoms, plane_values: wp.array(dtype=Any), static_values: wp.array(dtype=wp.float32),
               values: wp.array(dtype=Any), i: int, j: int):
    """A contact's restitution or friction (contacts.pair_material's) in the model's precision, from the bodies'
    own ``values`` (the Model's body_restitution or body_friction) and the planes' (``plane_values``), which carry
    gradients in a differentiable run: the mean of body i's and the other side's (a body's, plane -1 - j's, or a
    static collider's float32 one in ``static_values``, the Geoms' restitution or friction)."""
    other = values[i]
    if j < 0:
        other = plane_values[-1 - j]
    elif is_body(j, geoms.body_count):
        other = values[j]
    else:
        other = type(other)(static_values[j])
    return type(other)(0.5) * (values[i] + other)


@wp.kernel
def taped_rows(contacts: ContactBuffer, slot: wp.array(dtype=wp.int32), row_ids: wp.array(dtype=wp.vec2i),
               geoms: Geoms, planes: Any, start: Any, end: Any, mass: Any, restitution: wp.array(dtype=Any),
               friction: wp.array(dtype=Any), h: Any, bounce_speed: Any, slop: Any, held_time: wp.array(dtype=Any),
               rows: Any, bounces: wp.array(dtype=wp.int32)):
    """contacts.prepare_contacts with each contact's normal and points from the start poses: point1 body i's
    sample the narrow phase found (body_point), point2 its foot on the plane, or the other sphere's centre (a
    body's or a static one's) with n along the centres at the time of impact (contacts.impact_normal); its
    restitution and friction pair_value's, from the bodies' own ``restitution`` and ``friction`` (the Model's, so
    that a gradient reaches them) and the planes'.
    held_time: empty, or the times of impact [s] per row to use instead (held: the naive gradient); bounces: per
    row, 1 where the contact counts toward its bodies' impact time (contacts.bouncing)."""
    c = wp.tid()
    if beyond(contacts.count, c, contacts.ids.shape[0]):
        return
    pair = contacts.ids[c]
    i = pair[0]
    j = pair[1]
    dynamic = is_body(j, geoms.body_count)
    p1 = start.x[i] + wp.quat_rotate(wp.normalize(start.q[i]), type(start.P[0])(body_point(geoms, i,
                                                                                       contacts.point1[c])))
    n = type(p1)(contacts.normal[c])
    p2 = p1
    if j >= 0:
        local2 = body_point(geoms, j, contacts.point2[c])
        p2 = type(p1)(geoms.x[j] + wp.quat_rotate(geoms.q[j], local2))   # a static sphere's centre
        if dynamic:
            p2 = start.x[j] + wp.quat_rotate(wp.normalize(start.q[j]), type(p1)(local2))
        n = wp.normalize(p1 - p2)
    else:
        n = planes.normal[-1 - j]
        p2 = p1 - n * (wp.dot(n, p1) - planes.offset[-1 - j])
    round1 = -type(h)(contacts.radius1[c])
    round2 = type(h)(contacts.radius2[c])
    n = impact_normal(geoms, i, j, dynamic, n, p1, p2, round1, round2, start, end)   # two spheres': at the impact
    a1, a2, t, vn_start, an, closing = contact_row(i, j, dynamic, n, p1, p2, round1, round2, start, end, mass, h,
                                                   slop)
    r = slot[c]
    if held_time.shape[0] > 0:
        t = held_time[r]
    e = pair_value(geoms, planes.restitution, geoms.restitution, restitution, i, j)
    mu = pair_value(geoms, planes.friction, geoms.friction, friction, i, j)
    row_ids[r] = pair
    write_row(rows, r, a1, a2, round1, round2, n, t, closing, an, h, e, mu)
    bounces[r] = wp.where(bouncing(t, vn_start, an, bounce_speed), 1, 0)


@wp.kernel
def earliest_impacts(row_ids: wp.array(dtype=wp.vec2i), count: wp.array(dtype=wp.int32), body_count: int,
                     times: wp.array(dtype=Any), bounces: wp.array(dtype=wp.int32), first: wp.array(dtype=Any)):
    """first[i]: the earliest impact time [s] of body i among its bouncing rows (``times``; left where none)."""
    k = wp.tid()
    if beyond(count, k, row_ids.shape[0]):
        return
    if bounces[k] == 0:
        return
    wp.atomic_min(first, row_ids[k][0], times[k])
    if is_body(row_ids[k][1], body_count):
        wp.atomic_min(first, row_ids[k][1], times[k])


@wp.kernel
def impact_rows(row_ids: wp.array(dtype=wp.vec2i), count: wp.array(dtype=wp.int32), body_count: int,
                times: wp.array(dtype=Any), bounces: wp.array(dtype=wp.int32), first: wp.array(dtype=Any),
                winner: wp.array(dtype=wp.int32)):
    """winner[i]: the lowest bouncing row whose time is body i's earliest (-1 unchanged where none), so that one
    row, not every row of the same time, carries the body's impact time into the gradient."""
    k = wp.tid()
    if beyond(count, k, row_ids.shape[0]):
        return
    if bounces[k] == 0:
        return
    i = row_ids[k][0]
    j = row_ids[k][1]
    if times[k] == first[i]:
        wp.atomic_min(winner, i, k)
    if is_body(j, body_count):
        if times[k] == first[j]:
            wp.atomic_min(winner, j, k)


@wp.kernel
def taped_impacts(winner: wp.array(dtype=wp.int32), rows: Any, h: Any, impact: wp.array(dtype=Any)):
    """impact[i]: body i's earliest impact as a fraction of the step (its winner row's time over h; 2: none), the
    BodyVelocities.impact that contacts.finish_response reads."""
    i = wp.tid()
    impact[i] = type(h)(2.0)
    if winner[i] < 2147483647:
        impact[i] = rows.impact_time[winner[i]] / h


@wp.kernel
def taped_targets(manifolds: ManifoldSet, colour: int, h: Any, start: Any, end: Any, rows: Any, work: Any,
                  bounce_speed: Any, target: wp.array(dtype=Any), hits: wp.array(dtype=wp.int32)):
    """contacts.impact_target of every row of one colour's manifolds, by the working velocities now (a thread per
    manifold); hits[0] counts the rows that collide."""
    p, c, last = manifold_rows(manifolds, colour, wp.tid())
    if p < 0:
        return
    for k in range(c, last):
        target[k] = impact_target(manifolds.row_ids[k], manifolds.body_count, start, end, h, rows, work, k,
                                  bounce_speed)
        if colliding(target[k]):
            wp.atomic_add(hits, 0, 1)


@wp.func
def slot_row(manifolds: ManifoldSet, colour: int, slot: int, thread: int):
    """(the pair, row ``slot`` of it) of the colour's manifold number ``thread``; a pair of -1 past the colour's
    manifolds or the manifold's rows."""
    p, c, last = manifold_rows(manifolds, colour, thread)
    if c + slot >= last:
        p = -1
    return p, c + slot


@wp.kernel
def taped_collide(manifolds: ManifoldSet, colour: int, slot: int, h: Any, start: Any, end: Any, rows: Any,
                  mass: Any, inv_inertia_world: wp.array(dtype=Any), target: wp.array(dtype=Any),
                  v_in: wp.array(dtype=Any), w_in: wp.array(dtype=Any), jn_in: wp.array(dtype=Any),
                  jt_in: wp.array(dtype=Any), v_out: wp.array(dtype=Any), w_out: wp.array(dtype=Any),
                  jn_out: wp.array(dtype=Any), jt_out: wp.array(dtype=Any)):
    """One collision update (impulses.impulse_update at the time of impact) of row ``slot`` of each manifold of a
    colour, where it collides (``target``, from taped_targets): velocities v, w and the row's accumulated
    collision impulses jn, jt from the inputs into the outputs."""
    p, k = slot_row(manifolds, colour, slot, wp.tid())
    if p < 0:
        return
    if not colliding(target[k]):
        return
    pair = manifolds.row_ids[k]
    body_count = manifolds.body_count
    r1, r2 = contact_impact_levers(pair, body_count, start, end, h, rows, k)
    v1, w1, v2, w2 = pair_values(v_in, w_in, pair, body_count)
    m1, I1, m2, I2 = pair_values(mass.inv_mass, inv_inertia_world, pair, body_count)
    v1, w1, v2, w2, jn, jt = impulse_update(v1, w1, v2, w2, m1, I1, m2, I2, is_body(pair[1], body_count), r1, r2,
                                            rows.normal[k], target[k], rows.friction[k], jn_in[k], jt_in[k])
    store_pair(v_out, w_out, pair, body_count, v1, w1, v2, w2)
    jn_out[k] = jn
    jt_out[k] = jt


@wp.kernel
def taped_solve(manifolds: ManifoldSet, colour: int, slot: int, rows: Any, mass: Any,
                inv_inertia_world: wp.array(dtype=Any), v_in: wp.array(dtype=Any), w_in: wp.array(dtype=Any),
                jn_in: wp.array(dtype=Any), jt_in: wp.array(dtype=Any), v_out: wp.array(dtype=Any),
                w_out: wp.array(dtype=Any), jn_out: wp.array(dtype=Any), jt_out: wp.array(dtype=Any),
                moved: wp.array(dtype=wp.int32)):
    """One resting update (impulses.row_update) of row ``slot`` of each manifold of a colour: velocities and the
    row's accumulated impulses from the inputs into the outputs; moved[0] = 1 where it changed any velocity."""
    p, k = slot_row(manifolds, colour, slot, wp.tid())
    if p < 0:
        return
    pair = manifolds.row_ids[k]
    body_count = manifolds.body_count
    v1, w1, v2, w2 = pair_values(v_in, w_in, pair, body_count)
    m1, I1, m2, I2 = pair_values(mass.inv_mass, inv_inertia_world, pair, body_count)
    v1, w1, v2, w2, jn, jt, moved_by = row_update(v1, w1, v2, w2, m1, I1, m2, I2, is_body(pair[1], body_count),
                                                  rows, k, jn_in[k], jt_in[k])
    store_pair(v_out, w_out, pair, body_count, v1, w1, v2, w2)
    jn_out[k] = jn
    jt_out[k] = jt
    if moved_by > type(moved_by)(0.0):
        moved[0] = 1


@wp.kernel
def taped_project(manifolds: ManifoldSet, colour: int, slot: int, rows: Any, mass: Any, slop: Any, relax: Any,
                  x_in: wp.array(dtype=Any), q_in: wp.array(dtype=Any), x_out: wp.array(dtype=Any),
                  q_out: wp.array(dtype=Any), moved: wp.array(dtype=wp.int32)):
    """One push of the position projection (impulses.push_apart) at row ``slot`` of each manifold of a colour:
    poses x, q from the inputs into the outputs; moved[0] = 1 where it pushed."""
    p, k = slot_row(manifolds, colour, slot, wp.tid())
    if p < 0:
        return
    pair = manifolds.row_ids[k]
    body_count = manifolds.body_count
    x1, q1, x2, q2 = pair_values(x_in, q_in, pair, body_count)
    m1, B1, m2, B2 = pair_values(mass.inv_mass, mass.inv_inertia, pair, body_count)
    x1, q1, x2, q2, d = push_apart(x1, q1, x2, q2, m1, B1, m2, B2, is_body(pair[1], body_count), rows, k, slop,
                                   relax)
    if d > type(d)(0.0):
        store_pair(x_out, q_out, pair, body_count, x1, q1, x2, q2)
        moved[0] = 1


register(globals(), held_time="scalar", restitution="scalar", friction="scalar", times="scalar", first="scalar",
         impact="scalar", target="scalar", inv_inertia_world="mat33", v_in="vec3", w_in="vec3", v_out="vec3",
         w_out="vec3", jn_in="scalar", jt_in="vec3", jn_out="scalar", jt_out="vec3", x_in="vec3", q_in="quat",
         x_out="vec3", q_out="quat")

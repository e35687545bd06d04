"""Body contact response: time of impact, collision and contact impulses with friction, warm starting,
position projection (penalty forces are in ``penalty``, particles pushed by shapes in ``particle_shapes``).

The response works in the state's precision on the solver's end-of-step state, from the
contacts ``detection`` found at the start of the step (see there for their layout). One contact's
updates are functions on values in ``impulses``, which the taped response (``contact_adjoint``) shares.

Private: every kernel and function here is for the simulator's own use (the body contact passes);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .detection import ContactBuffer, Geoms, beyond, is_body
from .geometry import SPHERE
from .impulses import (
    impulse_update,
    lever,
    pair_response,
    pair_values,
    pair_velocity,
    point_velocity,
    push_apart,
    push_pair,
    response_mass,  # noqa: F401 (kernels.joints takes it from here)
    row_update,
    store_pair,
    turn,
)
from .manifolds import ManifoldSet, manifold_rows, touch, untouched
from .planes import first_contact_time
from .precisions import register
from .rigid import angular_velocity

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []


# response ------------------------------------------------------------------------
@wp.func
def state_point_velocity(q: Any, P: Any, L: Any, inv_mass: Any, inv_inertia: Any, r: Any):
    """Velocity [m/s] of the body point at world offset r [m] from the centre of mass."""
    return point_velocity(P * inv_mass, angular_velocity(q, inv_inertia, L), r)


@wp.func
def body_point_velocity(bodies: Any, mass: Any, i: int, r: Any):
    """Velocity [m/s] of body i's point at world offset r [m] from its centre of mass (Bodies, BodyMass blocks)."""
    return state_point_velocity(bodies.q[i], bodies.P[i], bodies.L[i], mass.inv_mass[i], mass.inv_inertia[i], r)


@wp.func
def pair_material(geoms: Geoms, i: int, j: int):
    """A contact's restitution and friction: the means of body i's values and the other side's (a body, a
    static collider, or plane -1 - j)."""
    e = geoms.restitution[i]
    mu = geoms.friction[i]
    if j < 0:
        e = 0.5 * (e + geoms.plane_restitution[-1 - j])
        mu = 0.5 * (mu + geoms.plane_friction[-1 - j])
    else:
        e = 0.5 * (e + geoms.restitution[j])
        mu = 0.5 * (mu + geoms.friction[j])
    return e, mu


@wp.func
def contact_row(i: int, j: int, dynamic: bool, n: Any, p1: Any, p2: Any, round1: Any, round2: Any, start: Any,
                end: Any, mass: Any, h: Any, slop: Any):
    """A contact's anchors in the body frames and its time of impact within the step, from its normal n and points
    p1, p2 [m] at the start of the step (rounding1 = -radius1 and rounding2 = radius2 along n from them to the
    surfaces).

    Over the step the gap follows d(t) = d0 + vn t + an t^2 / 2 with vn the normal relative
    velocity at the start and an the normal relative acceleration the solver produced; the
    earliest root is the time of impact (or the linear crossing of the start and end gaps).
    Returns (a1, a2 [m]: a2 in the world for a static side, t [s]: -1 where it closes in no time of the step,
    vn [m/s], an [m/s^2], closing [m/s]: the approach a speculative contact may keep, gap / h, else 0)."""
    zero = type(h)(0.0)
    a1 = wp.quat_rotate_inv(wp.normalize(start.q[i]), p1 - start.x[i])
    a2 = p2
    vn_start = wp.dot(n, body_point_velocity(start, mass, i, lever(start.q[i], a1, n, round1)))
    end2 = p2 + n * round2
    if dynamic:
        a2 = wp.quat_rotate_inv(wp.normalize(start.q[j]), p2 - start.x[j])
        vn_start -= wp.dot(n, body_point_velocity(start, mass, j, lever(start.q[j], a2, n, round2)))
        end2 = end.x[j] + lever(end.q[j], a2, n, round2)
    gap_end = wp.dot(n, end.x[i] + lever(end.q[i], a1, n, round1) - end2)
    gap = wp.dot(n, p1 - p2) + round1 - round2
    # the normal acceleration from forces: the change of the centres' velocities (rotation alone is kinematic)
    dv = (end.P[i] - start.P[i]) * mass.inv_mass[i]
    if dynamic:
        dv -= (end.P[j] - start.P[j]) * mass.inv_mass[j]
    an = wp.dot(n, dv) / h
    t = first_contact_time(gap, vn_start, type(h)(0.5) * an, h)
    if t < zero and gap_end < zero:
        t = zero
        if gap > zero:
            t = h * wp.clamp(gap / (gap - gap_end), zero, type(h)(1.0))
    if t < zero and gap <= slop:   # touching: impacts passed on by neighbours happen now
        t = zero
    # resting contact: no approach at the end of the step where it closes or touches; elsewhere (speculative)
    # the approach may close the gap but not more
    closing = zero
    if t < zero and gap > slop:
        closing = gap / h
    return a1, a2, t, vn_start, an, closing


@wp.func
def moved_point(start: Any, end: Any, i: int, p: Any):
    """Where body i's point at p [m] at the start of the step is at the end of it."""
    return end.x[i] + wp.quat_rotate(wp.normalize(end.q[i]), wp.quat_rotate_inv(wp.normalize(start.q[i]),
                                                                               p - start.x[i]))


@wp.func
def impact_normal(geoms: Geoms, i: int, j: int, dynamic: bool, n: Any, p1: Any, p2: Any, round1: Any, round2: Any,
                  start: Any, end: Any):
    """A contact's normal for contact_row(): between two spheres (centres p1, p2 [m] at the start of the step, radii
    -round1 and round2) the line of centres at their time of impact, each centre on the straight line from its start
    to where the end poses put it: d0 + w s (d0 = p1 - p2, w its change over the step) at the earliest s in [0, 1]
    where |d0 + w s| = r1 + r2. Spheres that overlap at the start or do not meet in the step, other pairs: n."""
    out = n
    if j >= 0:
        if geoms.kind[i] == SPHERE and geoms.kind[j] == SPHERE:
            c2 = p2
            if dynamic:
                c2 = moved_point(start, end, j, p2)
            d0 = p1 - p2
            w = moved_point(start, end, i, p1) - c2 - d0
            b = wp.dot(d0, w)
            c = wp.dot(d0, d0) - (round2 - round1) * (round2 - round1)
            disc = b * b - wp.dot(w, w) * c
            if c > type(b)(0.0) and b < type(b)(0.0) and disc >= type(b)(0.0):
                s = c / (wp.sqrt(disc) - b)   # the smaller root, (-b - sqrt(disc)) / |w|^2, without cancellation
                if s <= type(round2)(1.0):
                    out = wp.normalize(d0 + w * s)
    return out


@wp.func
def write_row(rows: Any, r: int, a1: Any, a2: Any, round1: Any, round2: Any, n: Any, t: Any, closing: Any, an: Any,
              h: Any, e: Any, mu: Any):
    """Row r of the ContactRows from contact_row()'s values and the materials e, mu; no impulses yet."""
    zero = type(h)(0.0)
    rows.anchor1[r] = a1
    rows.anchor2[r] = a2
    rows.rounding1[r] = round1
    rows.rounding2[r] = round2
    rows.normal[r] = n
    rows.impact_time[r] = t
    rows.min_normal_speed[r] = -closing
    rows.after_impact[r] = an * (h - t)
    rows.restitution[r] = e
    rows.friction[r] = mu
    rows.impulse_n[r] = zero
    rows.impulse_t[r] = n * zero


@wp.func
def bouncing(t: Any, vn_start: Any, an: Any, bounce_speed: Any):
    """Whether a contact of contact_row()'s t, vn and an counts toward its bodies' time of impact (work.impact):
    it closes within the step, faster than bounce_speed [m/s] by the start velocities and the forces."""
    return t >= type(t)(0.0) and vn_start + an * t < -bounce_speed


@wp.kernel
def prepare_contacts(contacts: ContactBuffer, slot: wp.array(dtype=wp.int32), row_ids: wp.array(dtype=wp.vec2i),
                     geoms: Geoms, start: Any, end: Any, mass: Any, h: Any, bounce_speed: Any, slop: Any, rows: Any,
                     work: Any, impacts: wp.array(dtype=wp.int32)):
    """Per contact: anchors in the body frames, the time of impact within the step (contact_row) along the
    normal (impact_normal: between two spheres, the line of centres at the impact), materials.

    after_impact: the normal velocity the forces add after the impact, a_n (h - t) [m/s].
    start, end: the bodies at the start and end of the step (Bodies); mass: BodyMass; rows: the contacts'
    ContactRows, written at row slot[c] (sorted by pair), and row_ids, the row's bodies; work.impact: per
    body, the earliest impact (fraction of the step) among its bouncing contacts; impacts[0] counts the
    contacts that collide in the first collision sweep (the sweeps run only if any; work must hold the end
    velocities, load_velocities).
    """
    c = wp.tid()
    if beyond(contacts.count, c, contacts.ids.shape[0]):
        return
    pair = contacts.ids[c]
    i = pair[0]
    j = pair[1]
    round1 = -type(h)(contacts.radius1[c])
    round2 = type(h)(contacts.radius2[c])
    dynamic = is_body(j, geoms.body_count)
    p1 = type(start.P[0])(contacts.point1[c])
    p2 = type(p1)(contacts.point2[c])
    n = impact_normal(geoms, i, j, dynamic, type(p1)(contacts.normal[c]), p1, p2, round1, round2, start, end)
    a1, a2, t, vn_start, an, closing = contact_row(i, j, dynamic, n, p1, p2, round1, round2, start, end, mass, h,
                                                   slop)
    e, mu = pair_material(geoms, i, j)
    r = slot[c]
    row_ids[r] = pair
    write_row(rows, r, a1, a2, round1, round2, n, t, closing, an, h, type(h)(e), type(h)(mu))
    if t >= type(h)(0.0):   # would the first collision sweep find this contact colliding?
        r1, r2 = impact_levers(pair, geoms.body_count, start, end, t / h, a1, a2, n, round1, round2)
        if wp.dot(relative_velocity(pair, geoms.body_count, work, r1, r2), n) - an * (h - t) < -bounce_speed:
            wp.atomic_add(impacts, 0, 1)
    if bouncing(t, vn_start, an, bounce_speed):
        wp.atomic_min(work.impact, i, t / h)
        if dynamic:
            wp.atomic_min(work.impact, j, t / h)


@wp.kernel
def load_velocities(bodies: Any, mass: Any, work: Any):
    """Working velocities v = P/M, omega = I^-1 L and I(t)^-1 = R I_body^-1 R^T at the end of the step."""
    i = wp.tid()
    R = wp.quat_to_matrix(wp.normalize(bodies.q[i]))
    inv_world = R * mass.inv_inertia[i] * wp.transpose(R)
    work.inv_inertia_world[i] = inv_world
    work.v[i] = bodies.P[i] * mass.inv_mass[i]
    work.w[i] = inv_world * bodies.L[i]
    work.impact[i] = type(mass.inv_mass[i])(2.0)
    work.stamp[i] = -1


@wp.func
def relative_velocity(ids: wp.vec2i, body_count: int, work: Any, r1: Any, r2: Any):
    """pair_velocity() of the pair's working velocities (BodyVelocities) at levers r1, r2 [m]."""
    v1, w1, v2, w2 = pair_values(work.v, work.w, ids, body_count)
    return pair_velocity(v1, w1, v2, w2, r1, r2, is_body(ids[1], body_count))


@wp.func
def apply_pair_impulse(ids: wp.vec2i, body_count: int, work: Any, mass: Any, r1: Any, r2: Any, J: Any):
    """Impulse J [N s] on the first body at r1, -J on the second at r2."""
    v1, w1, v2, w2 = pair_values(work.v, work.w, ids, body_count)
    m1, I1, m2, I2 = pair_values(mass.inv_mass, work.inv_inertia_world, ids, body_count)
    v1, w1, v2, w2 = push_pair(v1, w1, v2, w2, m1, I1, m2, I2, is_body(ids[1], body_count), r1, r2, J)
    store_pair(work.v, work.w, ids, body_count, v1, w1, v2, w2)


@wp.func
def pair_mass(ids: wp.vec2i, body_count: int, work: Any, mass: Any, r1: Any, r2: Any, n: Any):
    m1, I1, m2, I2 = pair_values(mass.inv_mass, work.inv_inertia_world, ids, body_count)
    return pair_response(m1, I1, m2, I2, is_body(ids[1], body_count), r1, r2, n)


@wp.func
def levers(ids: wp.vec2i, body_count: int, q: wp.array(dtype=Any), a1: Any, a2: Any, n: Any, round1: Any,
           round2: Any):
    """World offsets [m] from the two centres of mass to the contact's surface points (zero for a static side)."""
    r2 = a2 * type(a2[0])(0.0)
    if is_body(ids[1], body_count):
        r2 = lever(q[ids[1]], a2, n, round2)
    return lever(q[ids[0]], a1, n, round1), r2


@wp.func
def contact_levers(pair: wp.vec2i, body_count: int, q: wp.array(dtype=Any), rows: Any, c: int):
    """levers() of contact c of the ContactRows at the orientations q."""
    return levers(pair, body_count, q, rows.anchor1[c], rows.anchor2[c], rows.normal[c], rows.rounding1[c],
                  rows.rounding2[c])


@wp.func
def impact_levers(ids: wp.vec2i, body_count: int, start: Any, end: Any, fraction: Any, a1: Any, a2: Any,
                  n: Any, round1: Any, round2: Any):
    """Lever arms [m] from each centre to one point, midway between the two surface points, with the poses
    interpolated to the time of impact: equal and opposite impulses there keep the pair's angular momentum."""
    i = ids[0]
    j = ids[1]
    x1 = start.x[i] + (end.x[i] - start.x[i]) * fraction
    p1 = x1 + lever(start.q[i] + (end.q[i] - start.q[i]) * fraction, a1, n, round1)
    p2 = a2 + n * round2
    x2 = a2
    if is_body(j, body_count):
        x2 = start.x[j] + (end.x[j] - start.x[j]) * fraction
        p2 = x2 + lever(start.q[j] + (end.q[j] - start.q[j]) * fraction, a2, n, round2)
    point = (p1 + p2) * type(fraction)(0.5)
    return point - x1, point - x2


@wp.func
def contact_impact_levers(pair: wp.vec2i, body_count: int, start: Any, end: Any, h: Any, rows: Any, k: int):
    """impact_levers() of contact k of the ContactRows at its time of impact within the step of h seconds."""
    return impact_levers(pair, body_count, start, end, rows.impact_time[k] / h, rows.anchor1[k], rows.anchor2[k],
                         rows.normal[k], rows.rounding1[k], rows.rounding2[k])


@wp.func
def accumulate(pair: wp.vec2i, body_count: int, work: Any, mass: Any, r1: Any, r2: Any, n: Any, target: Any,
               mu: Any, old_n: Any, old_t: Any):
    """impulse_update() of a contact on the working velocities, in place. Returns (Jn, Jt)."""
    v1, w1, v2, w2 = pair_values(work.v, work.w, pair, body_count)
    m1, I1, m2, I2 = pair_values(mass.inv_mass, work.inv_inertia_world, pair, body_count)
    v1, w1, v2, w2, total, Jt = impulse_update(v1, w1, v2, w2, m1, I1, m2, I2, is_body(pair[1], body_count), r1, r2,
                                               n, target, mu, old_n, old_t)
    store_pair(work.v, work.w, pair, body_count, v1, w1, v2, w2)
    return total, Jt


@wp.func
def impact_target(pair: wp.vec2i, body_count: int, start: Any, end: Any, h: Any, rows: Any, work: Any, k: int,
                  bounce_speed: Any):
    """The normal velocity [m/s] contact k must leave with where it collides (it approaches faster than
    bounce_speed at its time of impact, by the working velocities): -e times its approach, plus what the forces
    add after the impact; elsewhere -1e30 (colliding() is false)."""
    target = type(bounce_speed)(-1.0e30)
    if rows.impact_time[k] >= type(h)(0.0):
        n = rows.normal[k]
        r1, r2 = contact_impact_levers(pair, body_count, start, end, h, rows, k)
        approach = wp.dot(relative_velocity(pair, body_count, work, r1, r2), n) - rows.after_impact[k]
        if approach < -bounce_speed:
            target = rows.after_impact[k] - rows.restitution[k] * approach
    return target


@wp.func
def colliding(target: Any):
    """Whether an impact_target() is one (a contact that collides)."""
    return target > type(target)(-1.0e29)


@wp.kernel
def collide_manifolds(manifolds: ManifoldSet, colour: int, iterations: int, sweep: int, h: Any, start: Any, end: Any,
                      rows: Any, mass: Any, work: Any, bounce_speed: Any, stamp: wp.array(dtype=wp.int32)):
    """One sweep of collisions over one colour of manifolds, a thread each (graph-coloured Gauss-Seidel; the
    sweeps repeat so that impacts propagate through touching bodies, as in Newton's cradle). A manifold whose
    contacts approach faster than bounce_speed at their time of impact collides: each such contact must leave
    with -e times its approach speed u (plus what the forces add after the impact), which for one contact is
    the lecture's impulse j = -(1 + e) u / (1/M1 + 1/M2 + n . ((I1^-1 (r1 x n)) x r1) + n . ((I2^-1 (r2 x n))
    x r2)), with Coulomb friction up to mu j. The contacts of one manifold (a box landing flat: four corners)
    are solved together, by accumulated impulses iterated ``iterations`` times, so simultaneous contacts share
    the impulse instead of the first one taking it all and spinning the body.

    After the first sweep a manifold is looked at again only if an impulse of the sweep before or of this one
    changed one of its bodies (stamp: work.stamp, per body the last sweep that changed it): otherwise its contacts
    stand as it left them, separating, and it would find no impact (exact, and most of a pile's manifolds are
    quiet)."""
    p, c, last = manifold_rows(manifolds, colour, wp.tid())
    if p < 0:
        return
    body_count = manifolds.body_count
    if sweep > 0 and untouched(manifolds, stamp, c, sweep):
        return
    zero = type(bounce_speed)(0.0)
    impacts = int(0)
    for k in range(c, last):
        rows.target[k] = impact_target(manifolds.row_ids[k], body_count, start, end, h, rows, work, k, bounce_speed)
        rows.collision_n[k] = zero
        rows.collision_t[k] = rows.normal[k] * zero
        if colliding(rows.target[k]):
            impacts += 1
    if impacts > 0:
        for _iteration in range(iterations):
            for k in range(c, last):
                if colliding(rows.target[k]):
                    pair = manifolds.row_ids[k]
                    n = rows.normal[k]
                    r1, r2 = contact_impact_levers(pair, body_count, start, end, h, rows, k)
                    jn, jt = accumulate(pair, body_count, work, mass, r1, r2, n, rows.target[k], rows.friction[k],
                                        rows.collision_n[k], rows.collision_t[k])
                    rows.collision_n[k] = jn
                    rows.collision_t[k] = jt
        touch(manifolds, stamp, c, sweep)   # the bodies this manifold changed


@wp.kernel
def prepare_rows(row_ids: wp.array(dtype=wp.vec2i), count: wp.array(dtype=wp.int32), body_count: int, end: Any,
                 rows: Any, mass: Any, work: Any):
    """Per row, what the resting solve keeps fixed: the levers at the end poses, a tangent basis (tangent1 along
    the sliding velocity, if any), and the effective masses along n and the tangents (Box2D's contact points);
    count[0]: the rows (the contacts found)."""
    k = wp.tid()
    if beyond(count, k, row_ids.shape[0]):
        return
    pair = row_ids[k]
    r1, r2 = contact_levers(pair, body_count, end.q, rows, k)
    n = rows.normal[k]
    rel = relative_velocity(pair, body_count, work, r1, r2)
    slide = rel - n * wp.dot(rel, n)
    t1 = wp.cross(n, type(n)(type(rel[0])(1.0), type(rel[0])(0.0), type(rel[0])(0.0)))
    if wp.abs(n[0]) > type(rel[0])(0.5):
        t1 = wp.cross(n, type(n)(type(rel[0])(0.0), type(rel[0])(1.0), type(rel[0])(0.0)))
    if wp.length(slide) > type(rel[0])(1.0e-9):
        t1 = slide
    t1 = wp.normalize(t1)
    t2 = wp.cross(n, t1)
    one = type(rel[0])(1.0)
    rows.lever1[k] = r1
    rows.lever2[k] = r2
    rows.tangent1[k] = t1
    rows.tangent2[k] = t2
    rows.mass_n[k] = one / pair_mass(pair, body_count, work, mass, r1, r2, n)
    rows.mass_t1[k] = one / pair_mass(pair, body_count, work, mass, r1, r2, t1)
    rows.mass_t2[k] = one / pair_mass(pair, body_count, work, mass, r1, r2, t2)


@wp.kernel
def warm_start_manifolds(manifolds: ManifoldSet, colour: int, rows: Any, mass: Any, work: Any,
                         row_ids: wp.array(dtype=wp.vec2i)):
    """Apply last step's impulses of the same contacts (warm starting) over one colour of manifolds (row_ids:
    manifolds.row_ids, see solve_manifolds)."""
    p, c, last = manifold_rows(manifolds, colour, wp.tid())
    if p < 0:
        return
    for k in range(c, last):
        apply_pair_impulse(row_ids[k], manifolds.body_count, work, mass, rows.lever1[k], rows.lever2[k],
                           rows.normal[k] * rows.impulse_n[k] + rows.impulse_t[k])


@wp.func
def solve_row(pair: wp.vec2i, body_count: int, rows: Any, mass: Any, work: Any, k: int):
    """row_update() of row k on the working velocities and the row's accumulated impulses, in place. Returns the
    largest velocity change [m/s] the update made at the contact (normal or tangential)."""
    v1, w1, v2, w2 = pair_values(work.v, work.w, pair, body_count)
    m1, I1, m2, I2 = pair_values(mass.inv_mass, work.inv_inertia_world, pair, body_count)
    v1, w1, v2, w2, total, Jt, change = row_update(v1, w1, v2, w2, m1, I1, m2, I2, is_body(pair[1], body_count), rows,
                                                   k, rows.impulse_n[k], rows.impulse_t[k])
    store_pair(work.v, work.w, pair, body_count, v1, w1, v2, w2)
    rows.impulse_n[k] = total
    rows.impulse_t[k] = Jt
    return change


@wp.kernel
def solve_manifolds(manifolds: ManifoldSet, colour: int, iterations: int, sweep: int, tolerance: Any, rows: Any,
                    mass: Any, work: Any, stamp: wp.array(dtype=wp.int32)):
    """One sweep of resting and sliding contact over one colour of manifolds: sequential impulses
    (``solve_row``) toward a normal velocity of at least min_normal_speed at the end of the step, the
    manifold's contacts iterated together (a box's corners settle as one block, so a tall stack does not lean
    from the order in which its corners were solved), up to ``iterations`` times and until no update changes
    a contact's velocity by more than ``tolerance`` [m/s]. A manifold whose last update changed no velocity by
    more than a hundredth of the tolerance, and whose bodies no such update has changed since, is skipped
    (``sweep`` numbers the sweeps; stamp: work.stamp, per body the last sweep that changed it).

    The manifold kernels take an array directly (stamp, row_ids): Warp's CPU code then specialises for contiguous
    arrays, which also spares each thread a copy of the argument structs (17 ns a thread down to 1)."""
    p, c, last = manifold_rows(manifolds, colour, wp.tid())
    if p < 0:
        return
    if manifolds.quiet[p] == 1 and untouched(manifolds, stamp, c, sweep):
        return
    largest = type(tolerance)(0.0)
    change = type(tolerance)(0.0)
    for _iteration in range(iterations):
        change = type(tolerance)(0.0)
        for k in range(c, last):
            change = wp.max(change, solve_row(manifolds.row_ids[k], manifolds.body_count, rows, mass, work, k))
        largest = wp.max(largest, change)
        if change <= tolerance:
            break
    still = tolerance * type(tolerance)(0.01)   # what counts as no change at all, for skipping
    if largest > still:
        touch(manifolds, stamp, c, sweep)
    manifolds.quiet[p] = wp.where(change <= still, 1, 0)


# warm starting: last step's impulses, found again by pair and anchor cell -----------------
@wp.func
def contact_cell(geoms: Geoms, i: int, a1: Any):
    """The anchor on body i rounded to cells of a tenth of its bounding radius: a contact's identity across steps."""
    cell = type(a1[0])(0.1 * geoms.bound[i])
    return wp.vec3i(int(wp.round(a1[0] / cell)), int(wp.round(a1[1] / cell)), int(wp.round(a1[2] / cell)))


@wp.func
def contact_slot(pair: wp.vec2i, cell: wp.vec3i, mask: int):
    key = pair[0] * 73856093 ^ pair[1] * 19349663 ^ cell[0] * 83492791 ^ cell[1] * 24036583 ^ cell[2] * 50331653
    return key & mask


@wp.func
def first_slot(geoms: Geoms, pair: wp.vec2i, anchor1: Any, table: Any):
    """(the contact's cell, the table's index mask, the slot its probe starts at) for a contact of ``pair``."""
    cell = contact_cell(geoms, pair[0], anchor1)
    mask = table.used.shape[0] - 1
    return cell, mask, contact_slot(pair, cell, mask)


@wp.kernel
def remember_impulses(geoms: Geoms, ids: wp.array(dtype=wp.vec2i), count: wp.array(dtype=wp.int32),
                      rows_of: wp.array(dtype=wp.int32), rows: Any, table: Any):
    """Store each contact's accumulated impulses (contact c's row rows_of[c]) in an open-addressing table (capacity a
    power of two)."""
    if beyond(count, wp.tid(), ids.shape[0]):
        return
    c = rows_of[wp.tid()]
    pair = ids[wp.tid()]
    cell, mask, slot = first_slot(geoms, pair, rows.anchor1[c], table)
    for _probe in range(table.used.shape[0]):
        if wp.atomic_cas(table.used, slot, 0, 1) == 0:
            table.keys[slot] = pair
            table.cells[slot] = cell
            table.n[slot] = rows.impulse_n[c]
            table.t[slot] = rows.impulse_t[c]
            break
        slot = (slot + 1) & mask


@wp.kernel
def recall_impulses(geoms: Geoms, ids: wp.array(dtype=wp.vec2i), count: wp.array(dtype=wp.int32),
                    rows_of: wp.array(dtype=wp.int32), rows: Any, table: Any):
    """Start each contact (contact c's row rows_of[c]) from last step's impulses of the same contact (each stored
    entry used once), friction projected onto the new tangent plane."""
    if beyond(count, wp.tid(), ids.shape[0]):
        return
    c = rows_of[wp.tid()]
    pair = ids[wp.tid()]
    cell, mask, slot = first_slot(geoms, pair, rows.anchor1[c], table)
    for _probe in range(table.used.shape[0]):
        state = table.used[slot]
        if state == 0:
            break
        if table.keys[slot][0] == pair[0] and table.keys[slot][1] == pair[1] and table.cells[slot] == cell:
            if wp.atomic_cas(table.used, slot, 1, 2) == 1:
                n = rows.normal[c]
                rows.impulse_n[c] = table.n[slot]
                rows.impulse_t[c] = table.t[slot] - n * wp.dot(n, table.t[slot])
                break
        slot = (slot + 1) & mask


@wp.kernel
def finish_response(h: Any, position_response: Any, mass: Any, collided: Any, work: Any, start: Any, end: Any,
                    drift: wp.array(dtype=wp.int32)):
    """Write the response into the end-of-step state. A collision impulse acts at the body's time of impact
    t, so the position moves by its velocity change times the rest of the step, (h - t); a contact impulse
    stands for a force over the whole step, so the position moves as the solver moves it for a force,
    beta h times the velocity change (beta = Integrator.position_response; a body at rest stays exactly at
    rest). P = M v; L changes by the impulses' moments, I(t) times the change of omega.

    A body with drift[i] = 1 (held by a joint: passes.joints) moves instead as symplectic Euler moves it,
    from the start of the step with the end velocities, x = x0 + h v1, q = exp(h omega1) q0 (less a
    collision's velocity change times t h): constraint impulses with any other drift gain or lose energy
    (a pendulum under rk4 swings 45 % wider in 10 s at 1/60 s); L = I(q) omega1."""
    i = wp.tid()
    one = type(h)(1.0)
    t = work.impact[i]
    if t > one:
        t = type(h)(0.0)
    v0 = end.P[i] * mass.inv_mass[i]
    R0 = wp.quat_to_matrix(wp.normalize(end.q[i]))
    w0 = R0 * mass.inv_inertia[i] * wp.transpose(R0) * end.L[i]
    end.P[i] = work.v[i] / mass.inv_mass[i]
    if drift[i] == 1:
        end.x[i] = start.x[i] + work.v[i] * h - (collided.v[i] - v0) * (t * h)
        angle = work.w[i] * h - (collided.w[i] - w0) * (t * h)
        spin = wp.length(angle)
        q1 = wp.normalize(start.q[i])
        if spin > type(h)(0.0):
            q1 = wp.normalize(wp.quat_from_axis_angle(angle / spin, spin) * q1)
        end.q[i] = q1
        R1 = wp.quat_to_matrix(q1)
        end.L[i] = R1 * wp.inverse(mass.inv_inertia[i]) * wp.transpose(R1) * work.w[i]
        return
    shift = (collided.v[i] - v0) * ((one - t) * h) + (work.v[i] - collided.v[i]) * (position_response * h)
    angle = (collided.w[i] - w0) * ((one - t) * h) + (work.w[i] - collided.w[i]) * (position_response * h)
    end.x[i] = end.x[i] + shift
    end.q[i] = turn(end.q[i], angle)
    end.L[i] = end.L[i] + R0 * wp.inverse(mass.inv_inertia[i]) * wp.transpose(R0) * (work.w[i] - w0)  # I(t) dw


@wp.kernel
def project_manifolds(manifolds: ManifoldSet, colour: int, iterations: int, sweep: int, rows: Any, mass: Any,
                      slop: Any, relax: Any, end: Any, stamp: wp.array(dtype=wp.int32)):
    """One sweep of the position projection over one colour of manifolds: push overlapping bodies apart along
    the normals, ``relax`` of the way to within ``slop`` [m] of touching, positions only (no energy added), a
    manifold's contacts iterated together up to ``iterations`` times, until none is deeper than ``slop``. A
    manifold that pushed nothing last time, whose bodies no push has moved since (``sweep`` numbers the
    sweeps; stamp: per body, the last sweep that moved it), is skipped (exact)."""
    p, c0, last = manifold_rows(manifolds, colour, wp.tid())
    if p < 0:
        return
    if manifolds.quiet[p] == 1 and untouched(manifolds, stamp, c0, sweep):
        return
    body_count = manifolds.body_count
    zero = type(slop)(0.0)
    pushed = int(0)
    for _iteration in range(iterations):
        deepest = zero
        for c in range(c0, last):
            pair = manifolds.row_ids[c]
            x1, q1, x2, q2 = pair_values(end.x, end.q, pair, body_count)
            m1, B1, m2, B2 = pair_values(mass.inv_mass, mass.inv_inertia, pair, body_count)
            x1, q1, x2, q2, depth = push_apart(x1, q1, x2, q2, m1, B1, m2, B2, is_body(pair[1], body_count), rows, c,
                                               slop, relax)
            if depth > zero:
                pushed = 1
                deepest = wp.max(deepest, depth)
                store_pair(end.x, end.q, pair, body_count, x1, q1, x2, q2)
        if deepest == zero:
            break
    if pushed == 1:
        touch(manifolds, stamp, c0, sweep)
    manifolds.quiet[p] = 1 - pushed


register(globals())

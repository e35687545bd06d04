"""Body contact response: time of impact, collision and contact impulses with friction, warm starting,
position projection (penalty forces are in ``penalty``, particles pushed by shapes in ``particle_shapes``).

The response works in the state's precision on the solver's end-of-step state, from the
contacts ``detection`` found at the start of the step (see there for their layout).

Private: every kernel and function here is for the simulator's own use (the body contact passes);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .detection import ContactBuffer, Geoms, beyond, is_body
from .manifolds import ManifoldSet, manifold_rows, touch, untouched
from .planes import first_contact_time
from .precisions import register
from .rigid import angular_velocity

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []


# response ------------------------------------------------------------------------
@wp.func
def point_velocity(v: Any, w: Any, r: Any):
    return v + wp.cross(w, r)


@wp.func
def state_point_velocity(q: Any, P: Any, L: Any, inv_mass: Any, inv_inertia: Any, r: Any):
    """Velocity [m/s] of the body point at world offset r [m] from the centre of mass."""
    return point_velocity(P * inv_mass, angular_velocity(q, inv_inertia, L), r)


@wp.func
def body_point_velocity(bodies: Any, mass: Any, i: int, r: Any):
    """Velocity [m/s] of body i's point at world offset r [m] from its centre of mass (Bodies, BodyMass blocks)."""
    return state_point_velocity(bodies.q[i], bodies.P[i], bodies.L[i], mass.inv_mass[i], mass.inv_inertia[i], r)


@wp.func
def lever(q: Any, anchor: Any, n: Any, rounding: Any):
    """World offset [m] from a centre of mass to a contact: the anchor turned by q, then ``rounding`` along n."""
    return wp.quat_rotate(wp.normalize(q), anchor) + n * rounding


@wp.func
def response_mass(inv_mass: Any, inv_inertia_world: Any, r: Any, n: Any):
    """n . (1/M n + (I^-1 (r x n)) x r): the inverse effective mass of a body point along unit n."""
    return inv_mass + wp.dot(n, wp.cross(inv_inertia_world * wp.cross(r, n), r))


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


@wp.kernel
def prepare_contacts(contacts: ContactBuffer, slot: wp.array(dtype=wp.int32), row_ids: wp.array(dtype=wp.vec2i),
                     geoms: Geoms, start: Any, end: Any, mass: Any, h: Any, bounce_speed: Any, slop: Any, rows: Any,
                     work: Any, impacts: wp.array(dtype=wp.int32)):
    """Per contact: anchors in the body frames (rounding1 = -radius1 and rounding2 = radius2 along n from
    them to the surfaces), the time of impact within the step, materials.

    Over the step the gap follows d(t) = d0 + vn t + an t^2 / 2 with vn the normal relative
    velocity at the start and an the normal relative acceleration the solver produced; the
    earliest root is the time of impact (or the linear crossing of the start and end gaps).
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
    i = contacts.ids[c][0]
    j = contacts.ids[c][1]
    zero = type(h)(0.0)
    half = type(h)(0.5)
    n = type(start.P[0])(contacts.normal[c])
    p1 = type(n)(contacts.point1[c])
    p2 = type(n)(contacts.point2[c])
    dynamic = is_body(j, geoms.body_count)
    round1 = -type(h)(contacts.radius1[c])
    round2 = type(h)(contacts.radius2[c])
    a1 = wp.quat_rotate_inv(wp.normalize(start.q[i]), p1 - start.x[i])
    a2 = p2
    vn_start = wp.dot(n, body_point_velocity(start, mass, i, lever(start.q[i], a1, n, round1)))
    end2 = p2 + n * round2
    if dynamic:
        a2 = wp.quat_rotate_inv(wp.normalize(start.q[j]), p2 - start.x[j])
        vn_start -= wp.dot(n, body_point_velocity(start, mass, j, lever(start.q[j], a2, n, round2)))
        end2 = end.x[j] + lever(end.q[j], a2, n, round2)
    gap_end = wp.dot(n, end.x[i] + lever(end.q[i], a1, n, round1) - end2)
    e32, mu32 = pair_material(geoms, i, j)
    e = type(h)(e32)
    mu = type(h)(mu32)
    gap = wp.dot(n, p1 - p2) + round1 - round2
    # the normal acceleration from forces: the change of the centres' velocities (rotation alone is kinematic)
    dv = (end.P[i] - start.P[i]) * mass.inv_mass[i]
    if dynamic:
        dv -= (end.P[j] - start.P[j]) * mass.inv_mass[j]
    an = wp.dot(n, dv) / h
    t = first_contact_time(gap, vn_start, half * an, h)
    if t < zero and gap_end < zero:
        t = zero
        if gap > zero:
            t = h * wp.clamp(gap / (gap - gap_end), zero, type(h)(1.0))
    if t < zero and gap <= slop:   # touching: impacts passed on by neighbours happen now
        t = zero
    r = slot[c]
    row_ids[r] = contacts.ids[c]
    rows.anchor1[r] = a1
    rows.anchor2[r] = a2
    rows.rounding1[r] = round1
    rows.rounding2[r] = round2
    rows.normal[r] = n
    rows.impact_time[r] = t
    # resting contact: no approach at the end of the step where it closes or touches; elsewhere (speculative)
    # the approach may close the gap but not more
    closing = zero
    if t < zero and gap > slop:
        closing = gap / h
    rows.min_normal_speed[r] = -closing
    rows.after_impact[r] = an * (h - t)
    rows.restitution[r] = e
    rows.friction[r] = mu
    rows.impulse_n[r] = zero
    rows.impulse_t[r] = type(n)()
    if t >= zero:   # would the first collision sweep find this contact colliding?
        pair = contacts.ids[c]
        r1, r2 = impact_levers(pair, geoms.body_count, start, end, t / h, a1, a2, n, round1, round2)
        if wp.dot(relative_velocity(pair, geoms.body_count, work, r1, r2), n) - an * (h - t) < -bounce_speed:
            wp.atomic_add(impacts, 0, 1)
    if t >= zero and vn_start + an * t < -bounce_speed:
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
    i = ids[0]
    j = ids[1]
    rel = point_velocity(work.v[i], work.w[i], r1)
    if is_body(j, body_count):
        rel -= point_velocity(work.v[j], work.w[j], r2)
    return rel


@wp.func
def apply_pair_impulse(ids: wp.vec2i, body_count: int, work: Any, mass: Any, r1: Any, r2: Any, J: Any):
    """Impulse J [N s] on the first body at r1, -J on the second at r2."""
    i = ids[0]
    j = ids[1]
    work.v[i] = work.v[i] + J * mass.inv_mass[i]
    work.w[i] = work.w[i] + work.inv_inertia_world[i] * wp.cross(r1, J)
    if is_body(j, body_count):
        work.v[j] = work.v[j] - J * mass.inv_mass[j]
        work.w[j] = work.w[j] - work.inv_inertia_world[j] * wp.cross(r2, J)


@wp.func
def pair_mass(ids: wp.vec2i, body_count: int, work: Any, mass: Any, r1: Any, r2: Any, n: Any):
    k = response_mass(mass.inv_mass[ids[0]], work.inv_inertia_world[ids[0]], r1, n)
    if is_body(ids[1], body_count):
        k += response_mass(mass.inv_mass[ids[1]], work.inv_inertia_world[ids[1]], r2, n)
    return k


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
def friction_impulse(ids: wp.vec2i, body_count: int, work: Any, mass: Any, r1: Any, r2: Any, n: Any, rel: Any):
    """The impulse that would stop the tangential sliding rel - (rel . n) n, and its length."""
    slide = rel - n * wp.dot(rel, n)
    speed = wp.length(slide)
    J = slide * type(speed)(0.0)
    if speed > type(speed)(1.0e-12):
        direction = slide / speed
        J = direction * (-speed / pair_mass(ids, body_count, work, mass, r1, r2, direction))
    return J


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
    """One sequential-impulse update of a contact: the accumulated normal impulse [N s] moves toward the one
    that leaves normal velocity ``target`` [m/s], kept >= 0; then the accumulated friction impulse toward
    the one that stops sliding, kept in the Coulomb disc |Jt| <= mu Jn. Returns (Jn, Jt)."""
    zero = old_n * type(old_n)(0.0)
    rel = relative_velocity(pair, body_count, work, r1, r2)
    k = pair_mass(pair, body_count, work, mass, r1, r2, n)
    total = wp.max(old_n + (target - wp.dot(rel, n)) / k, zero)
    Jt = old_t
    if total > zero or old_n > zero:
        apply_pair_impulse(pair, body_count, work, mass, r1, r2, n * (total - old_n))
        rel = relative_velocity(pair, body_count, work, r1, r2)
        Jt = old_t + friction_impulse(pair, body_count, work, mass, r1, r2, n, rel)
        limit = mu * total
        length = wp.length(Jt)
        if length > limit:
            Jt = Jt * (limit / length)
        apply_pair_impulse(pair, body_count, work, mass, r1, r2, Jt - old_t)
    return total, Jt


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
        pair = manifolds.row_ids[k]
        rows.target[k] = type(bounce_speed)(-1.0e30)
        rows.collision_n[k] = zero
        rows.collision_t[k] = rows.normal[k] * zero
        if rows.impact_time[k] >= zero:
            n = rows.normal[k]
            r1, r2 = contact_impact_levers(pair, body_count, start, end, h, rows, k)
            approach = wp.dot(relative_velocity(pair, body_count, work, r1, r2), n) - rows.after_impact[k]
            if approach < -bounce_speed:
                rows.target[k] = rows.after_impact[k] - rows.restitution[k] * approach
                impacts += 1
    if impacts > 0:
        for _iteration in range(iterations):
            for k in range(c, last):
                if rows.target[k] > type(bounce_speed)(-1.0e29):
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
    """One sequential-impulse update of row k with its fixed levers and masses: the accumulated normal impulse
    [N s] toward the one that leaves normal velocity min_normal_speed, kept >= 0; then the accumulated
    friction impulse toward the one that stops sliding along both tangents, kept in the Coulomb disc
    |Jt| <= mu Jn. Returns the largest velocity change [m/s] the update made at the contact (normal or
    tangential)."""
    r1 = rows.lever1[k]
    r2 = rows.lever2[k]
    n = rows.normal[k]
    old_n = rows.impulse_n[k]
    zero = old_n * type(old_n)(0.0)
    rel = relative_velocity(pair, body_count, work, r1, r2)
    total = wp.max(old_n + (rows.min_normal_speed[k] - wp.dot(rel, n)) * rows.mass_n[k], zero)
    change = wp.abs(total - old_n) / rows.mass_n[k]
    if total > zero or old_n > zero:
        apply_pair_impulse(pair, body_count, work, mass, r1, r2, n * (total - old_n))
        rel = relative_velocity(pair, body_count, work, r1, r2)
        t1 = rows.tangent1[k]
        t2 = rows.tangent2[k]
        old_t = rows.impulse_t[k]
        Jt = old_t - t1 * (wp.dot(rel, t1) * rows.mass_t1[k]) - t2 * (wp.dot(rel, t2) * rows.mass_t2[k])
        limit = rows.friction[k] * total
        length = wp.length(Jt)
        if length > limit:
            Jt = Jt * (limit / length)
        apply_pair_impulse(pair, body_count, work, mass, r1, r2, Jt - old_t)
        rows.impulse_t[k] = Jt
        change = wp.max(change, wp.length(Jt - old_t) / rows.mass_t1[k])
    rows.impulse_n[k] = total
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


@wp.func
def turn(q: Any, angle: Any):
    """q turned by the small rotation vector angle [rad], renormalised."""
    half = type(angle[0])(0.5)
    spin = type(q)(angle[0], angle[1], angle[2], type(angle[0])(0.0))
    return wp.normalize(q + (spin * q) * half)


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
            i = pair[0]
            j = pair[1]
            n = rows.normal[c]
            r1, r2 = contact_levers(pair, body_count, end.q, rows, c)
            p2 = rows.anchor2[c] + n * rows.rounding2[c]
            if is_body(j, body_count):
                p2 = end.x[j] + r2
            depth = -wp.dot(n, end.x[i] + r1 - p2) - slop
            if depth > zero:
                pushed = 1
                deepest = wp.max(deepest, depth)
                R1 = wp.quat_to_matrix(wp.normalize(end.q[i]))
                inv1 = R1 * mass.inv_inertia[i] * wp.transpose(R1)
                k = response_mass(mass.inv_mass[i], inv1, r1, n)
                inv2 = inv1
                if is_body(j, body_count):
                    R2 = wp.quat_to_matrix(wp.normalize(end.q[j]))
                    inv2 = R2 * mass.inv_inertia[j] * wp.transpose(R2)
                    k += response_mass(mass.inv_mass[j], inv2, r2, n)
                push = relax * depth / k
                end.x[i] = end.x[i] + n * (push * mass.inv_mass[i])
                end.q[i] = turn(end.q[i], inv1 * wp.cross(r1, n) * push)
                if is_body(j, body_count):
                    end.x[j] = end.x[j] - n * (push * mass.inv_mass[j])
                    end.q[j] = turn(end.q[j], -(inv2 * wp.cross(r2, n)) * push)
        if deepest == zero:
            break
    if pushed == 1:
        touch(manifolds, stamp, c0, sweep)
    manifolds.quiet[p] = 1 - pushed


register(globals())

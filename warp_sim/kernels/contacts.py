"""Body contact response: time of impact, collision and contact impulses with friction, position projection,
penalty forces, and particles pushed by shapes.

The response works in the state's precision on the solver's end-of-step state, from the
contacts ``detection`` found at the start of the step (see there for their layout).

Private: every kernel and function here is for the simulator's own use (the body contact passes);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .detection import ContactBuffer, Geoms, is_body
from .planes import first_contact_time
from .precisions import declare_precisions
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
def lever(q: Any, anchor: Any, n: Any, rounding: Any):
    """World offset [m] from a centre of mass to a contact: the anchor turned by q, then ``rounding`` along n."""
    return wp.quat_rotate(wp.normalize(q), anchor) + n * rounding


@wp.func
def response_mass(inv_mass: Any, inv_inertia_world: Any, r: Any, n: Any):
    """n . (1/M n + (I^-1 (r x n)) x r): the inverse effective mass of a body point along unit n."""
    return inv_mass + wp.dot(n, wp.cross(inv_inertia_world * wp.cross(r, n), r))


@wp.func
def pair_material(geoms: Geoms, plane_restitution: wp.array(dtype=wp.float32),
                  plane_friction: wp.array(dtype=wp.float32), i: int, j: int):
    """A contact's restitution and friction: the means of body i's values and the other side's (a body, a
    static collider, or plane -1 - j)."""
    e = geoms.restitution[i]
    mu = geoms.friction[i]
    if j < 0:
        e = 0.5 * (e + plane_restitution[-1 - j])
        mu = 0.5 * (mu + plane_friction[-1 - j])
    else:
        e = 0.5 * (e + geoms.restitution[j])
        mu = 0.5 * (mu + geoms.friction[j])
    return e, mu


@wp.kernel
def prepare_contacts(
    contacts: ContactBuffer,
    geoms: Geoms,
    plane_restitution: wp.array(dtype=wp.float32),
    plane_friction: wp.array(dtype=wp.float32),
    x_start: wp.array(dtype=Any),
    q_start: wp.array(dtype=Any),
    P_start: wp.array(dtype=Any),
    L_start: wp.array(dtype=Any),
    x_end: wp.array(dtype=Any),
    q_end: wp.array(dtype=Any),
    P_end: wp.array(dtype=Any),
    L_end: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia: wp.array(dtype=Any),
    h: Any,
    bounce_speed: Any,
    slop: Any,
    anchor1: wp.array(dtype=Any),
    anchor2: wp.array(dtype=Any),
    rounding1: wp.array(dtype=Any),
    rounding2: wp.array(dtype=Any),
    normal: wp.array(dtype=Any),
    impact_time: wp.array(dtype=Any),
    after_impact: wp.array(dtype=Any),
    min_normal_speed: wp.array(dtype=Any),
    restitution: wp.array(dtype=Any),
    friction: wp.array(dtype=Any),
    impulse_n: wp.array(dtype=Any),
    impulse_t: wp.array(dtype=Any),
    body_impact: wp.array(dtype=Any),
):
    """Per contact: anchors in the body frames (rounding1 = -radius1 and rounding2 = radius2 along n from
    them to the surfaces), the time of impact within the step, materials.

    Over the step the gap follows d(t) = d0 + vn t + an t^2 / 2 with vn the normal relative
    velocity at the start and an the normal relative acceleration the solver produced; the
    earliest root is the time of impact (or the linear crossing of the start and end gaps).
    after_impact: the normal velocity the forces add after the impact, a_n (h - t) [m/s].
    body_impact: per body, the earliest impact (fraction of the step) among its bouncing contacts.
    """
    c = wp.tid()
    i = contacts.ids[c][0]
    j = contacts.ids[c][1]
    zero = type(h)(0.0)
    half = type(h)(0.5)
    n = type(P_start[0])(contacts.normal[c])
    p1 = type(n)(contacts.point1[c])
    p2 = type(n)(contacts.point2[c])
    dynamic = is_body(j, geoms.body_count)
    round1 = -type(h)(contacts.radius1[c])
    round2 = type(h)(contacts.radius2[c])
    a1 = wp.quat_rotate_inv(wp.normalize(q_start[i]), p1 - x_start[i])
    a2 = p2
    vn_start = wp.dot(n, state_point_velocity(q_start[i], P_start[i], L_start[i], inv_mass[i], inv_inertia[i],
                                              lever(q_start[i], a1, n, round1)))
    end2 = p2 + n * round2
    if dynamic:
        a2 = wp.quat_rotate_inv(wp.normalize(q_start[j]), p2 - x_start[j])
        vn_start -= wp.dot(n, state_point_velocity(q_start[j], P_start[j], L_start[j], inv_mass[j], inv_inertia[j],
                                                   lever(q_start[j], a2, n, round2)))
        end2 = x_end[j] + lever(q_end[j], a2, n, round2)
    gap_end = wp.dot(n, x_end[i] + lever(q_end[i], a1, n, round1) - end2)
    e32, mu32 = pair_material(geoms, plane_restitution, plane_friction, i, j)
    e = type(h)(e32)
    mu = type(h)(mu32)
    gap = wp.dot(n, p1 - p2) + round1 - round2
    # the normal acceleration from forces: the change of the centres' velocities (rotation alone is kinematic)
    dv = (P_end[i] - P_start[i]) * inv_mass[i]
    if dynamic:
        dv -= (P_end[j] - P_start[j]) * inv_mass[j]
    an = wp.dot(n, dv) / h
    t = first_contact_time(gap, vn_start, half * an, h)
    if t < zero and gap_end < zero:
        t = zero
        if gap > zero:
            t = h * wp.clamp(gap / (gap - gap_end), zero, type(h)(1.0))
    if t < zero and gap <= slop:   # touching: impacts passed on by neighbours happen now
        t = zero
    anchor1[c] = a1
    anchor2[c] = a2
    rounding1[c] = round1
    rounding2[c] = round2
    normal[c] = n
    impact_time[c] = t
    # resting contact: no approach at the end of the step where it closes or touches; elsewhere (speculative)
    # the approach may close the gap but not more
    closing = zero
    if t < zero and gap > slop:
        closing = gap / h
    min_normal_speed[c] = -closing
    after_impact[c] = an * (h - t)
    restitution[c] = e
    friction[c] = mu
    impulse_n[c] = zero
    impulse_t[c] = type(n)()
    if t >= zero and vn_start + an * t < -bounce_speed:
        wp.atomic_min(body_impact, i, t / h)
        if dynamic:
            wp.atomic_min(body_impact, j, t / h)


@wp.kernel
def load_velocities(
    q: wp.array(dtype=Any),
    P: wp.array(dtype=Any),
    L: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    w: wp.array(dtype=Any),
    inv_inertia_world: wp.array(dtype=Any),
    body_impact: wp.array(dtype=Any),
):
    """Working velocities v = P/M, omega = I^-1 L and I(t)^-1 = R I_body^-1 R^T at the end of the step."""
    i = wp.tid()
    R = wp.quat_to_matrix(wp.normalize(q[i]))
    inv_world = R * inv_inertia[i] * wp.transpose(R)
    inv_inertia_world[i] = inv_world
    v[i] = P[i] * inv_mass[i]
    w[i] = inv_world * L[i]
    body_impact[i] = type(inv_mass[i])(2.0)


@wp.func
def relative_velocity(ids: wp.vec2i, body_count: int, v: wp.array(dtype=Any), w: wp.array(dtype=Any),
                      r1: Any, r2: Any):
    i = ids[0]
    j = ids[1]
    rel = point_velocity(v[i], w[i], r1)
    if is_body(j, body_count):
        rel -= point_velocity(v[j], w[j], r2)
    return rel


@wp.func
def apply_pair_impulse(ids: wp.vec2i, body_count: int, v: wp.array(dtype=Any), w: wp.array(dtype=Any),
                       inv_mass: wp.array(dtype=Any), inv_inertia_world: wp.array(dtype=Any),
                       r1: Any, r2: Any, J: Any):
    """Impulse J [N s] on the first body at r1, -J on the second at r2."""
    i = ids[0]
    j = ids[1]
    v[i] = v[i] + J * inv_mass[i]
    w[i] = w[i] + inv_inertia_world[i] * wp.cross(r1, J)
    if is_body(j, body_count):
        v[j] = v[j] - J * inv_mass[j]
        w[j] = w[j] - inv_inertia_world[j] * wp.cross(r2, J)


@wp.func
def pair_mass(ids: wp.vec2i, body_count: int, inv_mass: wp.array(dtype=Any),
              inv_inertia_world: wp.array(dtype=Any), r1: Any, r2: Any, n: Any):
    k = response_mass(inv_mass[ids[0]], inv_inertia_world[ids[0]], r1, n)
    if is_body(ids[1], body_count):
        k += response_mass(inv_mass[ids[1]], inv_inertia_world[ids[1]], r2, n)
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
def friction_impulse(ids: wp.vec2i, body_count: int, inv_mass: wp.array(dtype=Any),
                     inv_inertia_world: wp.array(dtype=Any), r1: Any, r2: Any, n: Any, rel: Any):
    """The impulse that would stop the tangential sliding rel - (rel . n) n, and its length."""
    slide = rel - n * wp.dot(rel, n)
    speed = wp.length(slide)
    J = slide * type(speed)(0.0)
    if speed > type(speed)(1.0e-12):
        direction = slide / speed
        J = direction * (-speed / pair_mass(ids, body_count, inv_mass, inv_inertia_world, r1, r2, direction))
    return J


@wp.func
def impact_levers(ids: wp.vec2i, body_count: int, x_start: wp.array(dtype=Any), q_start: wp.array(dtype=Any),
                  x_end: wp.array(dtype=Any), q_end: wp.array(dtype=Any), fraction: Any, a1: Any, a2: Any, n: Any,
                  round1: Any, round2: Any):
    """Lever arms [m] from each centre to one point, midway between the two surface points, with the poses
    interpolated to the time of impact: equal and opposite impulses there keep the pair's angular momentum."""
    i = ids[0]
    j = ids[1]
    x1 = x_start[i] + (x_end[i] - x_start[i]) * fraction
    p1 = x1 + lever(q_start[i] + (q_end[i] - q_start[i]) * fraction, a1, n, round1)
    p2 = a2 + n * round2
    x2 = a2
    if is_body(j, body_count):
        x2 = x_start[j] + (x_end[j] - x_start[j]) * fraction
        p2 = x2 + lever(q_start[j] + (q_end[j] - q_start[j]) * fraction, a2, n, round2)
    point = (p1 + p2) * type(fraction)(0.5)
    return point - x1, point - x2


@wp.func
def accumulate(pair: wp.vec2i, body_count: int, v: wp.array(dtype=Any), w: wp.array(dtype=Any),
               inv_mass: wp.array(dtype=Any), inv_inertia_world: wp.array(dtype=Any), r1: Any, r2: Any, n: Any,
               target: Any, mu: Any, old_n: Any, old_t: Any):
    """One sequential-impulse update of a contact: the accumulated normal impulse [N s] moves toward the one
    that leaves normal velocity ``target`` [m/s], kept >= 0; then the accumulated friction impulse toward
    the one that stops sliding, kept in the Coulomb disc |Jt| <= mu Jn. Returns (Jn, Jt)."""
    zero = old_n * type(old_n)(0.0)
    rel = relative_velocity(pair, body_count, v, w, r1, r2)
    k = pair_mass(pair, body_count, inv_mass, inv_inertia_world, r1, r2, n)
    total = wp.max(old_n + (target - wp.dot(rel, n)) / k, zero)
    Jt = old_t
    if total > zero or old_n > zero:
        apply_pair_impulse(pair, body_count, v, w, inv_mass, inv_inertia_world, r1, r2, n * (total - old_n))
        rel = relative_velocity(pair, body_count, v, w, r1, r2)
        Jt = old_t + friction_impulse(pair, body_count, inv_mass, inv_inertia_world, r1, r2, n, rel)
        limit = mu * total
        length = wp.length(Jt)
        if length > limit:
            Jt = Jt * (limit / length)
        apply_pair_impulse(pair, body_count, v, w, inv_mass, inv_inertia_world, r1, r2, Jt - old_t)
    return total, Jt


@wp.kernel
def collision_sweeps(
    count: int,
    sweeps: int,
    ids: wp.array(dtype=wp.vec2i),
    body_count: int,
    h: Any,
    x_start: wp.array(dtype=Any),
    q_start: wp.array(dtype=Any),
    x: wp.array(dtype=Any),
    q: wp.array(dtype=Any),
    anchor1: wp.array(dtype=Any),
    anchor2: wp.array(dtype=Any),
    rounding1: wp.array(dtype=Any),
    rounding2: wp.array(dtype=Any),
    normal: wp.array(dtype=Any),
    impact_time: wp.array(dtype=Any),
    after_impact: wp.array(dtype=Any),
    restitution: wp.array(dtype=Any),
    friction: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia_world: wp.array(dtype=Any),
    bounce_speed: Any,
    target: wp.array(dtype=Any),
    collision_n: wp.array(dtype=Any),
    collision_t: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    w: wp.array(dtype=Any),
):
    """Collisions, pair after pair (Gauss-Seidel), repeated so that impacts propagate through touching
    bodies (Newton's cradle). A pair whose contacts approach faster than bounce_speed at their time of
    impact collides: each such contact must leave with -e times its approach speed u (plus what the
    forces add after the impact), which for one contact is the lecture's impulse
    j = -(1 + e) u / (1/M1 + 1/M2 + n . ((I1^-1 (r1 x n)) x r1) + n . ((I2^-1 (r2 x n)) x r2)), with
    Coulomb friction up to mu j. The contacts of one pair (a box landing flat: four corners) are solved
    together, by accumulated impulses iterated to convergence, so simultaneous contacts share the
    impulse instead of the first one taking it all and spinning the body. A pair's contacts are
    consecutive in the buffer (the narrow phase writes them together; where a parallel device
    interleaves them, each run of them is solved as a group)."""
    zero = type(bounce_speed)(0.0)
    for _sweep in range(sweeps):
        c = int(0)
        while c < count:
            pair = ids[c]
            end = c + 1
            while end < count and ids[end][0] == pair[0] and ids[end][1] == pair[1]:
                end += 1
            impacts = int(0)
            for k in range(c, end):
                target[k] = type(bounce_speed)(-1.0e30)
                collision_n[k] = zero
                collision_t[k] = normal[k] * zero
                if impact_time[k] >= zero:
                    n = normal[k]
                    r1, r2 = impact_levers(pair, body_count, x_start, q_start, x, q, impact_time[k] / h, anchor1[k],
                                           anchor2[k], n, rounding1[k], rounding2[k])
                    approach = wp.dot(relative_velocity(pair, body_count, v, w, r1, r2), n) - after_impact[k]
                    if approach < -bounce_speed:
                        target[k] = after_impact[k] - restitution[k] * approach
                        impacts += 1
            if impacts > 0:
                for _iteration in range(sweeps):
                    for k in range(c, end):
                        if target[k] > type(bounce_speed)(-1.0e29):
                            n = normal[k]
                            r1, r2 = impact_levers(pair, body_count, x_start, q_start, x, q, impact_time[k] / h,
                                                   anchor1[k], anchor2[k], n, rounding1[k], rounding2[k])
                            jn, jt = accumulate(pair, body_count, v, w, inv_mass, inv_inertia_world, r1, r2, n,
                                                target[k], friction[k], collision_n[k], collision_t[k])
                            collision_n[k] = jn
                            collision_t[k] = jt
            c = end


@wp.kernel
def contact_sweeps(
    count: int,
    sweeps: int,
    ids: wp.array(dtype=wp.vec2i),
    body_count: int,
    q: wp.array(dtype=Any),
    anchor1: wp.array(dtype=Any),
    anchor2: wp.array(dtype=Any),
    rounding1: wp.array(dtype=Any),
    rounding2: wp.array(dtype=Any),
    normal: wp.array(dtype=Any),
    min_normal_speed: wp.array(dtype=Any),
    friction: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia_world: wp.array(dtype=Any),
    impulse_n: wp.array(dtype=Any),
    impulse_t: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    w: wp.array(dtype=Any),
):
    """Resting and sliding contact, sequential impulses (``accumulate``) toward a normal velocity of at least
    min_normal_speed at the end of the step, starting from the impulses the same contact needed last
    step (warm starting), so stacks converge in a few sweeps."""
    for c in range(count):   # warm start: last step's impulses of the same contacts
        pair = ids[c]
        r1, r2 = levers(pair, body_count, q, anchor1[c], anchor2[c], normal[c], rounding1[c], rounding2[c])
        apply_pair_impulse(pair, body_count, v, w, inv_mass, inv_inertia_world, r1, r2,
                           normal[c] * impulse_n[c] + impulse_t[c])
    for _sweep in range(sweeps):
        for c in range(count):
            pair = ids[c]
            n = normal[c]
            r1, r2 = levers(pair, body_count, q, anchor1[c], anchor2[c], n, rounding1[c], rounding2[c])
            jn, jt = accumulate(pair, body_count, v, w, inv_mass, inv_inertia_world, r1, r2, n, min_normal_speed[c],
                                friction[c], impulse_n[c], impulse_t[c])
            impulse_n[c] = jn
            impulse_t[c] = jt


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


@wp.kernel
def remember_impulses(
    geoms: Geoms,
    ids: wp.array(dtype=wp.vec2i),
    anchor1: wp.array(dtype=Any),
    impulse_n: wp.array(dtype=Any),
    impulse_t: wp.array(dtype=Any),
    used: wp.array(dtype=wp.int32),
    keys: wp.array(dtype=wp.vec2i),
    cells: wp.array(dtype=wp.vec3i),
    stored_n: wp.array(dtype=Any),
    stored_t: wp.array(dtype=Any),
):
    """Store each contact's accumulated impulses in an open-addressing table (capacity a power of two)."""
    c = wp.tid()
    pair = ids[c]
    cell = contact_cell(geoms, pair[0], anchor1[c])
    mask = used.shape[0] - 1
    slot = contact_slot(pair, cell, mask)
    for _probe in range(used.shape[0]):
        if wp.atomic_cas(used, slot, 0, 1) == 0:
            keys[slot] = pair
            cells[slot] = cell
            stored_n[slot] = impulse_n[c]
            stored_t[slot] = impulse_t[c]
            break
        slot = (slot + 1) & mask


@wp.kernel
def recall_impulses(
    geoms: Geoms,
    ids: wp.array(dtype=wp.vec2i),
    anchor1: wp.array(dtype=Any),
    normal: wp.array(dtype=Any),
    used: wp.array(dtype=wp.int32),
    keys: wp.array(dtype=wp.vec2i),
    cells: wp.array(dtype=wp.vec3i),
    stored_n: wp.array(dtype=Any),
    stored_t: wp.array(dtype=Any),
    impulse_n: wp.array(dtype=Any),
    impulse_t: wp.array(dtype=Any),
):
    """Start each contact from last step's impulses of the same contact (each stored entry used once), friction
    projected onto the new tangent plane."""
    c = wp.tid()
    pair = ids[c]
    cell = contact_cell(geoms, pair[0], anchor1[c])
    mask = used.shape[0] - 1
    slot = contact_slot(pair, cell, mask)
    for _probe in range(used.shape[0]):
        state = used[slot]
        if state == 0:
            break
        if keys[slot][0] == pair[0] and keys[slot][1] == pair[1] and cells[slot] == cell:
            if wp.atomic_cas(used, slot, 1, 2) == 1:
                n = normal[c]
                impulse_n[c] = stored_n[slot]
                impulse_t[c] = stored_t[slot] - n * wp.dot(n, stored_t[slot])
                break
        slot = (slot + 1) & mask


@wp.func
def turn(q: Any, angle: Any):
    """q turned by the small rotation vector angle [rad], renormalised."""
    half = type(angle[0])(0.5)
    spin = type(q)(angle[0], angle[1], angle[2], type(angle[0])(0.0))
    return wp.normalize(q + (spin * q) * half)


@wp.kernel
def finish_response(
    h: Any,
    position_response: Any,
    inv_mass: wp.array(dtype=Any),
    inv_inertia: wp.array(dtype=Any),
    P_end: wp.array(dtype=Any),
    L_end: wp.array(dtype=Any),
    v_collided: wp.array(dtype=Any),
    w_collided: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    w: wp.array(dtype=Any),
    body_impact: wp.array(dtype=Any),
    x: wp.array(dtype=Any),
    q: wp.array(dtype=Any),
    P: wp.array(dtype=Any),
    L: wp.array(dtype=Any),
):
    """Write the response into the end-of-step state. A collision impulse acts at the body's time of impact
    t, so the position moves by its velocity change times the rest of the step, (h - t); a contact impulse
    stands for a force over the whole step, so the position moves as the solver moves it for a force,
    beta h times the velocity change (beta = Integrator.position_response; so a body at rest stays
    exactly at rest). P = M v; L changes by the
    impulses' moments, I(t) times the change of omega, and is then kept for the rest of the step."""
    i = wp.tid()
    one = type(h)(1.0)
    t = body_impact[i]
    if t > one:
        t = type(h)(0.0)
    v0 = P_end[i] * inv_mass[i]
    R0 = wp.quat_to_matrix(wp.normalize(q[i]))
    w0 = R0 * inv_inertia[i] * wp.transpose(R0) * L_end[i]
    shift = (v_collided[i] - v0) * ((one - t) * h) + (v[i] - v_collided[i]) * (position_response * h)
    angle = (w_collided[i] - w0) * ((one - t) * h) + (w[i] - w_collided[i]) * (position_response * h)
    x[i] = x[i] + shift
    q_new = turn(q[i], angle)
    q[i] = q_new
    P[i] = v[i] / inv_mass[i]
    L[i] = L_end[i] + R0 * wp.inverse(inv_inertia[i]) * wp.transpose(R0) * (w[i] - w0)   # L += I(t) (omega change)


@wp.kernel
def project_positions(
    count: int,
    sweeps: int,
    ids: wp.array(dtype=wp.vec2i),
    body_count: int,
    anchor1: wp.array(dtype=Any),
    anchor2: wp.array(dtype=Any),
    rounding1: wp.array(dtype=Any),
    rounding2: wp.array(dtype=Any),
    normal: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia: wp.array(dtype=Any),
    slop: Any,
    x: wp.array(dtype=Any),
    q: wp.array(dtype=Any),
):
    """Push overlapping bodies apart along the contact normals to within ``slop`` [m] of touching, positions
    only (velocities untouched, so no energy is added), Gauss-Seidel over the contacts."""
    zero = type(slop)(0.0)
    for _sweep in range(sweeps):
        for c in range(count):
            pair = ids[c]
            i = pair[0]
            j = pair[1]
            n = normal[c]
            r1, r2 = levers(pair, body_count, q, anchor1[c], anchor2[c], n, rounding1[c], rounding2[c])
            p2 = anchor2[c] + n * rounding2[c]
            if is_body(j, body_count):
                p2 = x[j] + r2
            depth = -wp.dot(n, x[i] + r1 - p2) - slop
            if depth > zero:
                R1 = wp.quat_to_matrix(wp.normalize(q[i]))
                inv1 = R1 * inv_inertia[i] * wp.transpose(R1)
                k = response_mass(inv_mass[i], inv1, r1, n)
                inv2 = inv1
                if is_body(j, body_count):
                    R2 = wp.quat_to_matrix(wp.normalize(q[j]))
                    inv2 = R2 * inv_inertia[j] * wp.transpose(R2)
                    k += response_mass(inv_mass[j], inv2, r2, n)
                push = depth / k
                x[i] = x[i] + n * (push * inv_mass[i])
                q[i] = turn(q[i], inv1 * wp.cross(r1, n) * push)
                if is_body(j, body_count):
                    x[j] = x[j] - n * (push * inv_mass[j])
                    q[j] = turn(q[j], -(inv2 * wp.cross(r2, n)) * push)


declare_precisions(globals())

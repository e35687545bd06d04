"""One contact's response on values: a pair's velocities and masses, an impulse on a pair, a sequential-impulse
update of one contact (an impact's or a resting row's, with Coulomb friction), one push of the position projection.

The body contact kernels (``contacts``, in place on their working arrays) and their taped form
(``contact_adjoint``, from arrays into new ones, which a wp.Tape can take back) share these, so both do the
same arithmetic. A pair is body 1 and body 2 where ``dynamic``, else a static side (a collider or a plane),
whose velocities, masses and levers are zeros and unused.

Private: every function here (there are no kernels) is for the simulator's own use (the body contact kernels);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .detection import is_body

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []


@wp.func
def point_velocity(v: Any, w: Any, r: Any):
    return v + wp.cross(w, r)


@wp.func
def lever(q: Any, anchor: Any, n: Any, rounding: Any):
    """World offset [m] from a centre of mass to a contact: the anchor turned by q, then ``rounding`` along n."""
    return wp.quat_rotate(wp.normalize(q), anchor) + n * rounding


@wp.func
def response_mass(inv_mass: Any, inv_inertia_world: Any, r: Any, n: Any):
    """n . (1/M n + (I^-1 (r x n)) x r): the inverse effective mass of a body point along unit n."""
    return inv_mass + wp.dot(n, wp.cross(inv_inertia_world * wp.cross(r, n), r))


@wp.func
def turn(q: Any, angle: Any):
    """q turned by the small rotation vector angle [rad], renormalised."""
    half = type(angle[0])(0.5)
    spin = type(q)(angle[0], angle[1], angle[2], type(angle[0])(0.0))
    return wp.normalize(q + (spin * q) * half)


@wp.func
def pair_values(a: wp.array(dtype=Any), b: wp.array(dtype=Any), pair: wp.vec2i, body_count: int):
    """(a1, b1, a2, b2): two per-body arrays' entries of the pair's bodies (velocities v, w; poses x, q; inverse
    masses and inertias), zeros for a static side."""
    a2 = a[pair[0]] - a[pair[0]]   # a zero of any element type
    b2 = b[pair[0]] - b[pair[0]]
    if is_body(pair[1], body_count):
        a2 = a[pair[1]]
        b2 = b[pair[1]]
    return a[pair[0]], b[pair[0]], a2, b2


@wp.func
def store_pair(a: wp.array(dtype=Any), b: wp.array(dtype=Any), pair: wp.vec2i, body_count: int, a1: Any, b1: Any,
               a2: Any, b2: Any):
    """Write pair_values() back (a static side's are left out)."""
    a[pair[0]] = a1
    b[pair[0]] = b1
    if is_body(pair[1], body_count):
        a[pair[1]] = a2
        b[pair[1]] = b2


@wp.func
def pair_velocity(v1: Any, w1: Any, v2: Any, w2: Any, r1: Any, r2: Any, dynamic: bool):
    """Velocity [m/s] of body 1's point at lever r1 relative to body 2's at r2."""
    rel = point_velocity(v1, w1, r1)
    if dynamic:
        rel -= point_velocity(v2, w2, r2)
    return rel


@wp.func
def pair_response(m1: Any, I1: Any, m2: Any, I2: Any, dynamic: bool, r1: Any, r2: Any, n: Any):
    """The pair's inverse effective mass along unit n [1/kg] (m: inverse masses, I: world inverse inertias)."""
    k = response_mass(m1, I1, r1, n)
    if dynamic:
        k += response_mass(m2, I2, r2, n)
    return k


@wp.func
def push_pair(v1: Any, w1: Any, v2: Any, w2: Any, m1: Any, I1: Any, m2: Any, I2: Any, dynamic: bool, r1: Any,
              r2: Any, J: Any):
    """The four velocities after an impulse J [N s] on body 1 at r1 and -J on body 2 at r2."""
    v1 = v1 + J * m1
    w1 = w1 + I1 * wp.cross(r1, J)
    if dynamic:
        v2 = v2 - J * m2
        w2 = w2 - I2 * wp.cross(r2, J)
    return v1, w1, v2, w2


@wp.func
def sliding_impulse(m1: Any, I1: Any, m2: Any, I2: Any, dynamic: bool, r1: Any, r2: Any, n: Any, rel: Any):
    """The impulse [N s] that would stop the tangential sliding rel - (rel . n) n."""
    slide = rel - n * wp.dot(rel, n)
    speed = wp.length(slide)
    J = slide * type(speed)(0.0)
    if speed > type(speed)(1.0e-12):
        direction = slide / speed
        J = direction * (-speed / pair_response(m1, I1, m2, I2, dynamic, r1, r2, direction))
    return J


@wp.func
def coulomb(Jt: Any, limit: Any):
    """Jt shortened to the Coulomb disc |Jt| <= limit [N s]."""
    length = wp.length(Jt)
    if length > limit:
        Jt = Jt * (limit / length)
    return Jt


@wp.func
def impulse_update(v1: Any, w1: Any, v2: Any, w2: Any, m1: Any, I1: Any, m2: Any, I2: Any, dynamic: bool, r1: Any,
                   r2: Any, n: Any, target: Any, mu: Any, old_n: Any, old_t: Any):
    """One sequential-impulse update of a contact at levers r1, r2: the accumulated normal impulse [N s] moves
    toward the one that leaves normal velocity ``target`` [m/s], kept >= 0; then the accumulated friction impulse
    toward the one that stops sliding, kept in the Coulomb disc |Jt| <= mu Jn. Returns (v1, w1, v2, w2, Jn, Jt)."""
    zero = old_n * type(old_n)(0.0)
    rel = pair_velocity(v1, w1, v2, w2, r1, r2, dynamic)
    k = pair_response(m1, I1, m2, I2, dynamic, r1, r2, n)
    total = wp.max(old_n + (target - wp.dot(rel, n)) / k, zero)
    Jt = old_t
    if total > zero or old_n > zero:
        v1, w1, v2, w2 = push_pair(v1, w1, v2, w2, m1, I1, m2, I2, dynamic, r1, r2, n * (total - old_n))
        rel = pair_velocity(v1, w1, v2, w2, r1, r2, dynamic)
        Jt = coulomb(old_t + sliding_impulse(m1, I1, m2, I2, dynamic, r1, r2, n, rel), mu * total)
        v1, w1, v2, w2 = push_pair(v1, w1, v2, w2, m1, I1, m2, I2, dynamic, r1, r2, Jt - old_t)
    return v1, w1, v2, w2, total, Jt


@wp.func
def row_update(v1: Any, w1: Any, v2: Any, w2: Any, m1: Any, I1: Any, m2: Any, I2: Any, dynamic: bool, rows: Any,
               k: int, old_n: Any, old_t: Any):
    """One sequential-impulse update of resting row k (ContactRows) with its fixed levers and masses: the
    accumulated normal impulse [N s] toward the one that leaves normal velocity min_normal_speed, kept >= 0; then
    the accumulated friction impulse toward the one that stops sliding along both tangents, kept in the Coulomb
    disc |Jt| <= mu Jn. Returns (v1, w1, v2, w2, Jn, Jt, the largest velocity change the update made at the
    contact [m/s], normal or tangential)."""
    r1 = rows.lever1[k]
    r2 = rows.lever2[k]
    n = rows.normal[k]
    zero = old_n * type(old_n)(0.0)
    rel = pair_velocity(v1, w1, v2, w2, r1, r2, dynamic)
    total = wp.max(old_n + (rows.min_normal_speed[k] - wp.dot(rel, n)) * rows.mass_n[k], zero)
    change = wp.abs(total - old_n) / rows.mass_n[k]
    Jt = old_t
    if total > zero or old_n > zero:
        v1, w1, v2, w2 = push_pair(v1, w1, v2, w2, m1, I1, m2, I2, dynamic, r1, r2, n * (total - old_n))
        rel = pair_velocity(v1, w1, v2, w2, r1, r2, dynamic)
        t1 = rows.tangent1[k]
        t2 = rows.tangent2[k]
        Jt = old_t - t1 * (wp.dot(rel, t1) * rows.mass_t1[k]) - t2 * (wp.dot(rel, t2) * rows.mass_t2[k])
        Jt = coulomb(Jt, rows.friction[k] * total)
        v1, w1, v2, w2 = push_pair(v1, w1, v2, w2, m1, I1, m2, I2, dynamic, r1, r2, Jt - old_t)
        change = wp.max(change, wp.length(Jt - old_t) / rows.mass_t1[k])
    return v1, w1, v2, w2, total, Jt, change


@wp.func
def push_apart(x1: Any, q1: Any, x2: Any, q2: Any, m1: Any, B1: Any, m2: Any, B2: Any, dynamic: bool, rows: Any,
               c: int, slop: Any, relax: Any):
    """One push of the position projection at contact c (ContactRows): where the bodies overlap deeper than
    ``slop`` [m], ``relax`` of the way out along the normal, positions only (B: the body-frame inverse inertias).
    Returns (x1, q1, x2, q2, the depth beyond the slop [m], > 0 where it pushed)."""
    n = rows.normal[c]
    r1 = lever(q1, rows.anchor1[c], n, rows.rounding1[c])
    r2 = n * type(slop)(0.0)
    p2 = rows.anchor2[c] + n * rows.rounding2[c]
    if dynamic:
        r2 = lever(q2, rows.anchor2[c], n, rows.rounding2[c])
        p2 = x2 + r2
    depth = -wp.dot(n, x1 + r1 - p2) - slop
    if depth > type(slop)(0.0):
        R1 = wp.quat_to_matrix(wp.normalize(q1))
        inv1 = R1 * B1 * wp.transpose(R1)
        k = response_mass(m1, inv1, r1, n)
        inv2 = inv1
        if dynamic:
            R2 = wp.quat_to_matrix(wp.normalize(q2))
            inv2 = R2 * B2 * wp.transpose(R2)
            k += response_mass(m2, inv2, r2, n)
        push = relax * depth / k
        x1 = x1 + n * (push * m1)
        q1 = turn(q1, inv1 * wp.cross(r1, n) * push)
        if dynamic:
            x2 = x2 - n * (push * m2)
            q2 = turn(q2, -(inv2 * wp.cross(r2, n)) * push)
    return x1, q1, x2, q2, depth

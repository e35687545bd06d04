"""Particle-plane contacts: the time-of-impact impulse response (the penalty forces are in ``penalty``).

A plane k is the set n_k . x = offset_k with unit normal n_k; particles of radius r
are kept on the side n_k points to (n_k . x >= offset_k + r). Restitution e and
friction mu of a contact are the plane's values, averaged with the particle's own
where the particle has one (a negative particle value means "none").

A differentiable run launches resolve_plane_impacts_differentiable instead: the same response, written so that
Warp's adjoint of it is exact, the time of impact included (the post-impact state depends on it, and it on the
state before the step).

Public (``__all__``): resolve_plane_impacts.
Private: resolve_plane_impacts_chunked (the same, many particles a thread), resolve_plane_impacts_differentiable
and the Warp functions contact_material, first_contact_time, coulomb_friction, clear_of_planes, outside_planes,
earliest_contact, contact_event, push_out, plane_response, held, first_inside, plane_response_differentiable and
resolve_particle, for the simulator's own use; their arguments may change between releases.
"""
from typing import Any

import warp as wp

from .precisions import register

__all__ = ["resolve_plane_impacts"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

MAX_EVENTS = wp.constant(4)  # contacts resolved per particle per step before the final projection


@wp.func
def contact_material(plane_value: Any, particle_values: wp.array(dtype=Any), i: int):
    """The plane's value, or the mean with particle i's value where it has one."""
    value = plane_value
    if particle_values.shape[0] > 0:
        own = particle_values[i]
        if own >= type(own)(0.0):
            value = type(own)(0.5) * (value + own)
    return value


@wp.func
def first_contact_time(d0: Any, b: Any, c: Any, horizon: Any):
    """Earliest t in [0, horizon] where d0 + b t + c t^2 reaches 0 moving inwards; -1 if none.

    d0: signed distance to the plane at t = 0 [m]; b: normal velocity [m/s];
    c: half the normal acceleration [m/s^2]. A particle already touching or inside
    (d0 <= 0) contacts at t = 0 if it is moving or accelerating inwards, and when
    it comes back if it is moving out but accelerated in.
    """
    zero = type(d0)(0.0)
    none = type(d0)(-1.0)
    result = none
    if d0 <= zero:
        if b < zero or (b == zero and c < zero):
            result = zero
        elif c < zero and b > zero:
            # leaving, but accelerated back: it returns to this level at t = -b / c
            back = -b / c
            if back <= horizon:
                result = back
    else:
        end = d0 + (b + c * horizon) * horizon
        if end <= zero or c > zero:
            if c == zero:
                if b < zero:
                    result = -d0 / b
            else:
                disc = b * b - type(d0)(4.0) * c * d0
                if disc >= zero:
                    root = wp.sqrt(disc)
                    q = type(d0)(-0.5) * (b - root)
                    if b >= zero:
                        q = type(d0)(-0.5) * (b + root)
                    t1 = q / c
                    t2 = none
                    if q != zero:
                        t2 = d0 / q
                    if t1 >= zero and t1 <= horizon:
                        result = t1
                    if t2 >= zero and t2 <= horizon and (result < zero or t2 < result):
                        result = t2
    return result


@wp.func
def coulomb_friction(vt: Any, max_change: Any):
    """Reduce tangential velocity vt by at most max_change >= 0 [m/s], stopping it rather than reversing it (the
    speed is compared squared first, so that a contact that sticks, the common case, takes no root or division)."""
    speed_squared = wp.dot(vt, vt)
    out = vt * type(max_change)(0.0)
    if speed_squared > max_change * max_change:
        speed = wp.sqrt(speed_squared)
        out = vt * ((speed - max_change) / speed)
    return out


@wp.func
def clear_of_planes(x_start: Any, v_start: Any, v: Any, r: Any, normals: wp.array(dtype=Any),
                    offsets: wp.array(dtype=Any), h: Any):
    """Whether a particle of radius r [m] going over h [s] from (x_start [m], v_start [m/s]) to the velocity v [m/s]
    stays clear of every plane, so that plane_response would change nothing: over the step its distance to a plane
    moves by at most (|vn| + |dvn| / 2) h (the quadratic path plane_response assumes, dvn the normal change of
    velocity) and the end point by at most (|vn| + |dvn|) h, and each plane is more than four times the former
    away. A cheap test that lets most particles of a scene skip the contact search (the fused step)."""
    dv = v - v_start
    half = type(h)(0.5)
    clear = bool(True)
    for k in range(normals.shape[0]):
        n = normals[k]
        reach = (wp.abs(wp.dot(n, v_start)) + half * wp.abs(wp.dot(n, dv))) * h
        if wp.dot(n, x_start) - offsets[k] - r <= type(h)(4.0) * reach:
            clear = False
    return clear


@wp.func
def outside_planes(x: Any, r: Any, normals: wp.array(dtype=Any), offsets: wp.array(dtype=Any)):
    """Whether a particle of radius r [m] at x [m] is on the allowed side of every plane, by r or more (so that
    plane_response's final projection leaves it where it is)."""
    outside = bool(True)
    for k in range(normals.shape[0]):
        if wp.dot(normals[k], x) < offsets[k] + r:
            outside = False
    return outside


@wp.func
def earliest_contact(xs: Any, vs: Any, a: Any, r: Any, planes: Any, remaining: Any):
    """The first plane a particle of radius r [m] meets within ``remaining`` [s] from (xs [m], vs [m/s]) under the
    constant acceleration a [m/s^2]: (its contact time [s] from now, its index), or (-1, -1) if none."""
    half = type(r)(0.5)
    best = type(r)(-1.0)
    best_k = int(-1)
    for k in range(planes.normal.shape[0]):
        n = planes.normal[k]
        d0 = wp.dot(n, xs) - planes.offset[k] - r
        tc = first_contact_time(d0, wp.dot(n, vs), half * wp.dot(n, a), remaining)
        if tc >= type(r)(0.0) and (best_k < 0 or tc < best):
            best = tc
            best_k = k
    return best, best_k


@wp.func
def contact_event(i: int, xs: Any, vs: Any, a: Any, t: Any, best: Any, k: int, material: Any, planes: Any, h: Any):
    """One contact of plane_response: particle i, at (xs [m], vs [m/s]) at time t [s] of a step of h [s] under the
    acceleration a [m/s^2], meets plane k ``best`` seconds later. Returns (xs, vs, a, t) at the contact after its
    response (an impact's reflection with friction, or a resting contact's support and friction) and the end of
    the step (xe [m], ve [m/s]) travelled from there."""
    zero = type(h)(0.0)
    half = type(h)(0.5)
    r = material.radius[i]
    n = planes.normal[k]
    xs = xs + (vs + half * a * best) * best
    xs = xs - n * (wp.dot(n, xs) - planes.offset[k] - r)
    vs = vs + a * best
    t = t + best
    remaining = h - t
    inv_remaining = type(h)(0.0)
    if remaining > zero:
        inv_remaining = type(h)(1.0) / remaining   # off the chain of dependent operations below
    e = contact_material(planes.restitution[k], material.restitution, i)
    mu = contact_material(planes.friction[k], material.friction, i)
    vn = wp.dot(vs, n)
    an = wp.dot(a, n)
    # an impact when vn < -1e-6 (|vs| + |an| h): -vn - 1e-6 |an| h > 1e-6 |vs|, compared squared (no root)
    margin = -vn - type(h)(1e-6) * wp.abs(an) * h
    if margin > zero and margin * margin > type(h)(1e-12) * wp.dot(vs, vs):
        # impact: reflect the normal velocity, friction bounded by the normal impulse
        vt = coulomb_friction(vs - vn * n, mu * (type(h)(1.0) + e) * (-vn))
        vs = vt - e * vn * n
    elif an < zero and remaining > zero:
        # resting contact: the plane supports the normal acceleration for the rest of
        # the step; friction acts with that impulse (static if it suffices, else kinetic)
        support = -an * remaining
        if vn < zero:
            support = support - vn
            vn = zero
        vt0 = vs - wp.dot(vs, n) * n
        vt_free = vt0 + (a - an * n) * remaining
        vt_end = coulomb_friction(vt_free, mu * support)
        vs = vt0 + vn * n
        a = (vt_end - vt0) * inv_remaining
    xe = xs + (vs + half * a * remaining) * remaining
    ve = vs + a * remaining
    return xs, vs, a, t, xe, ve


@wp.func
def push_out(x: Any, v: Any, n: Any, depth: Any):
    """A particle ``depth`` [m] inside a plane of normal n moved out along n, its inward normal velocity removed."""
    x = x + depth * n
    vn = wp.dot(v, n)
    if vn < type(depth)(0.0):
        v = v - vn * n
    return x, v


@wp.func
def plane_response(i: int, x_start: Any, v_start: Any, x: Any, v: Any, material: Any, planes: Any, h: Any):
    """resolve_plane_impacts for free particle i moving over h [s] from (x_start [m], v_start [m/s]) to (x, v):
    the corrected (x, v) and 1 if it touched a plane, else 0 (the fused step calls it)."""
    zero = type(h)(0.0)
    r = material.radius[i]
    xs = x_start
    vs = v_start
    a = (v - vs) * (type(h)(1.0) / h)
    xe = x
    ve = v
    t = zero
    touched = int(0)
    for _event in range(MAX_EVENTS):
        best, best_k = earliest_contact(xs, vs, a, r, planes, h - t)
        if best_k < 0:
            break
        touched = 1
        xs, vs, a, t, xe, ve = contact_event(i, xs, vs, a, t, best, best_k, material, planes, h)
    # final projection: no particle ends a step inside any plane
    for k in range(planes.normal.shape[0]):
        n = planes.normal[k]
        depth = planes.offset[k] + r - wp.dot(n, xe)
        if depth > zero:
            touched = 1
            xe, ve = push_out(xe, ve, n, depth)
    return xe, ve, touched


@wp.func
def held(t: wp.float64):
    """t, whose gradient is dropped: the naive adjoint's contact time (plane_response_differentiable)."""
    return t


@wp.func_grad(held)
def adj_held(t: wp.float64, adj_ret: wp.float64):
    pass


@wp.func
def held(t: wp.float32):
    """held in float32."""
    return t


@wp.func_grad(held)
def adj_held32(t: wp.float32, adj_ret: wp.float32):
    pass


@wp.func
def first_inside(x: Any, r: Any, planes: Any, after: int):
    """The first plane after index ``after`` that a particle of radius r [m] at x [m] is inside of, or -1."""
    found = int(-1)
    for k in range(after + 1, planes.normal.shape[0]):
        if found < 0 and planes.offset[k] + r - wp.dot(planes.normal[k], x) > type(r)(0.0):
            found = k
    return found


@wp.func
def plane_response_differentiable(i: int, x_start: Any, v_start: Any, x: Any, v: Any, material: Any, planes: Any,
                                  h: Any, hold_time: int):
    """plane_response in a form whose adjoint Warp builds right, for a differentiable run: the loops over contact
    events and final projections unrolled, MAX_EVENTS each, without a break; the plane searches (loops Warp runs
    dynamically, whose adjoint would be wrong) return an index only, and each contact time is computed again for
    its plane outside them, so its gradient (that of the time of impact) reaches the response. The same result as
    plane_response wherever at most MAX_EVENTS planes need the final projection. hold_time 1: the contact times'
    gradients dropped (the naive adjoint, the impact time held fixed: for comparison only)."""
    zero = type(h)(0.0)
    half = type(h)(0.5)
    r = material.radius[i]
    xs = x_start
    vs = v_start
    a = (v - vs) * (type(h)(1.0) / h)
    xe = x
    ve = v
    t = zero
    touched = int(0)
    searching = bool(True)
    for _event in range(MAX_EVENTS):
        if searching:
            _best, k = earliest_contact(xs, vs, a, r, planes, h - t)
            if k < 0:
                searching = False
            else:
                n = planes.normal[k]
                best = first_contact_time(wp.dot(n, xs) - planes.offset[k] - r, wp.dot(n, vs), half * wp.dot(n, a),
                                          h - t)
                if hold_time != 0:
                    best = held(best)
                touched = 1
                xs, vs, a, t, xe, ve = contact_event(i, xs, vs, a, t, best, k, material, planes, h)
    last = int(-1)
    for _projection in range(MAX_EVENTS):
        k = first_inside(xe, r, planes, last)
        if k >= 0:
            n = planes.normal[k]
            touched = 1
            xe, ve = push_out(xe, ve, n, planes.offset[k] + r - wp.dot(n, xe))
            last = k
    return xe, ve, touched


@wp.kernel
def resolve_plane_impacts(
    x_start: wp.array(dtype=Any),
    v_start: wp.array(dtype=Any),
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    material: Any,
    planes: Any,
    h: Any,
    touched_out: wp.array(dtype=wp.int32),
):
    """Detect plane crossings over a step of h seconds and respond at the time of impact.

    Over the step the particle moves from (x_start, v_start) with the constant
    acceleration a = (v - v_start) / h, which is exact for uniform gravity. The
    earliest crossing is found by solving the quadratic in time; the particle is put
    there, its normal velocity reflected, v' = v - (1 + e)(v . n) n, its tangential
    velocity reduced by Coulomb friction (mu times the normal impulse, never
    reversing), and it travels the rest of the step, repeatedly. A particle pressed
    onto a plane with no approach speed is in resting contact: the plane takes up
    the normal acceleration and friction acts with the impulse that supports it.
    No energy is added, and no particle ends the step inside a plane. x and v
    (the integrator's end of step) are updated in place; pinned particles are skipped.
    Launch with dim = the number of particles, after the step from (x_start, v_start).

    Args:
        x_start: positions at the start of the step (vec3) [m]
        v_start: velocities at the start of the step (vec3) [m/s]
        x: positions at the end of the step, corrected in place (vec3) [m]
        v: velocities at the end of the step, corrected in place (vec3) [m/s]
        material: inverse masses (0: pinned, skipped), radii, own restitution and friction (ParticleMaterial) [1/kg]
        planes: unit normals n_k to the allowed side, offsets n_k . x = offset_k, restitution, friction (Planes) [m]
        h: the step [s]
        touched_out: set to 1 for each particle that touched a plane in the step, or an empty array [1]
    """
    resolve_particle(wp.tid(), x_start, v_start, x, v, material, planes, h, touched_out)


@wp.func
def resolve_particle(i: int, x_start: wp.array(dtype=Any), v_start: wp.array(dtype=Any), x: wp.array(dtype=Any),
                     v: wp.array(dtype=Any), material: Any, planes: Any, h: Any, touched_out: wp.array(dtype=wp.int32)):
    """resolve_plane_impacts' work for particle i."""
    if material.inv_mass[i] == type(h)(0.0):
        return
    xs = x_start[i]
    vs = v_start[i]
    x1 = x[i]
    v1 = v[i]
    # clear of every plane over the step (no contact to find) and at its end (nothing to project): unchanged
    if clear_of_planes(xs, vs, v1, material.radius[i], planes.normal, planes.offset, h) and outside_planes(
            x1, material.radius[i], planes.normal, planes.offset):
        return
    xe, ve, touched = plane_response(i, xs, vs, x1, v1, material, planes, h)
    if touched != 0:
        x[i] = xe
        v[i] = ve
        if touched_out.shape[0] > 0:
            touched_out[i] = 1


@wp.kernel
def resolve_plane_impacts_chunked(x_start: wp.array(dtype=Any), v_start: wp.array(dtype=Any),
                                  x: wp.array(dtype=Any), v: wp.array(dtype=Any), material: Any, planes: Any,
                                  h: Any, touched_out: wp.array(dtype=wp.int32), base: int, chunk: int):
    """resolve_plane_impacts for the particles chunk * (base + tid) to chunk * (base + tid + 1) - 1 (launch with
    dim = ceil(particles / chunk), base 0, or in pieces from their bases: core.cpu_threads): a CPU thread first
    copies all its arguments, the structs' arrays too, so there a thread takes many particles
    (passes.plane_contacts); the same result particle by particle."""
    first = (base + wp.tid()) * chunk
    for i in range(first, wp.min(first + chunk, x.shape[0])):
        resolve_particle(i, x_start, v_start, x, v, material, planes, h, touched_out)


@wp.kernel
def resolve_plane_impacts_differentiable(x_start: wp.array(dtype=Any), v_start: wp.array(dtype=Any),
                                         x: wp.array(dtype=Any), v: wp.array(dtype=Any), material: Any,
                                         planes: Any, h: Any, hold_time: int, touched_out: wp.array(dtype=wp.int32)):
    """resolve_plane_impacts for a differentiable run (launch with dim = the number of particles): the response by
    plane_response_differentiable, whose adjoint carries each impact's time; x and v corrected in place (a taped
    launch restores them around its adjoint: core.tape.launch_in_place). hold_time 1: the naive adjoint, the
    impact times held fixed (for comparison)."""
    i = wp.tid()
    if material.inv_mass[i] > type(h)(0.0):
        xs = x_start[i]
        vs = v_start[i]
        x1 = x[i]
        v1 = v[i]
        r = material.radius[i]
        if not (clear_of_planes(xs, vs, v1, r, planes.normal, planes.offset, h) and outside_planes(
                x1, r, planes.normal, planes.offset)):
            xe, ve, touched = plane_response_differentiable(i, xs, vs, x1, v1, material, planes, h, hold_time)
            if touched != 0:
                x[i] = xe
                v[i] = ve
                if touched_out.shape[0] > 0:
                    touched_out[i] = 1


register(globals())

"""Body contacts: broad phase, narrow phase, time-of-impact impulses with friction, position projection.

Geometry is queried at the start of a step in float32 (``Geoms``, ``ContactBuffer``);
the response works in the state's precision on the solver's end-of-step state.

A contact pushes body ``ids[c][0]`` along +n away from ``ids[c][1]``, which is a body
(< body_count), a static collider (>= body_count) or a plane (-1 - k). point1 and point2
[m] are points of each body, and radius1 and radius2 [m] how far each surface lies from
them along the normal: the gap is n . (point1 - point2) - radius1 - radius2 (negative
when they overlap). A rounded part (a sphere, a capsule's end) is its centre and radius,
so its contact point stays under it as it rolls; elsewhere the radius is 0.
"""
from typing import Any

import warp as wp

from .geometry import (
    BOX,
    MESH,
    SPHERE,
    closest_on_segments,
    corner_sign,
    shape_distance,
)
from .planes import contact_material, coulomb_friction, first_contact_time
from .rigid import angular_velocity

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.struct
class Geoms:
    """Every collision shape: bodies first (geom i is body i), then static colliders."""

    kind: wp.array(dtype=wp.int32)
    size: wp.array(dtype=wp.vec3f)           # sphere (r, 0, 0); box half extents; capsule/cylinder (r, h/2, 0)
    com: wp.array(dtype=wp.vec3f)            # the pose origin in the shape frame (a body's centre of mass)
    mesh: wp.array(dtype=wp.uint64)          # wp.Mesh id of mesh shapes (shape frame; world frame for statics)
    sample_start: wp.array(dtype=wp.int32)   # contact sample points (shape frame), or a static mesh's vertices
    sample_count: wp.array(dtype=wp.int32)
    samples: wp.array(dtype=wp.vec3f)
    sample_radius: wp.array(dtype=wp.float32)
    owner_start: wp.array(dtype=wp.int32)    # static meshes: where their vertices start in ``owner``
    owner: wp.array(dtype=wp.int32)          # static meshes: the first face using each vertex
    bound: wp.array(dtype=wp.float32)        # radius of a sphere about the pose origin enclosing the shape [m]
    restitution: wp.array(dtype=wp.float32)
    friction: wp.array(dtype=wp.float32)
    x: wp.array(dtype=wp.vec3f)              # pose at the start of the step
    q: wp.array(dtype=wp.quatf)
    reach: wp.array(dtype=wp.float32)        # bound + motion over the step + contact margin [m]
    body_count: int


@wp.struct
class ContactBuffer:
    """Contacts (or candidate pairs, which use count and ids only), growable: count may exceed the capacity."""

    count: wp.array(dtype=wp.int32)
    ids: wp.array(dtype=wp.vec2i)
    normal: wp.array(dtype=wp.vec3f)
    point1: wp.array(dtype=wp.vec3f)
    point2: wp.array(dtype=wp.vec3f)
    radius1: wp.array(dtype=wp.float32)
    radius2: wp.array(dtype=wp.float32)


@wp.func
def is_body(g: int, body_count: int):
    return g >= 0 and g < body_count


@wp.func
def emit(buf: ContactBuffer, body_count: int, id1: int, id2: int, n: wp.vec3f, p1: wp.vec3f, r1: float,
         p2: wp.vec3f, r2: float):
    """Append a contact pushing id1 along +n away from id2, stored with a body first."""
    a = id1
    b = id2
    nn = n
    pa = p1
    pb = p2
    ra = r1
    rb = r2
    if not is_body(a, body_count):
        a = id2
        b = id1
        nn = -n
        pa = p2
        pb = p1
        ra = r2
        rb = r1
    slot = wp.atomic_add(buf.count, 0, 1)
    if slot < buf.ids.shape[0]:
        buf.ids[slot] = wp.vec2i(a, b)
        buf.normal[slot] = nn
        buf.point1[slot] = pa
        buf.point2[slot] = pb
        buf.radius1[slot] = ra
        buf.radius2[slot] = rb


@wp.func
def emit_pair(buf: ContactBuffer, a: int, b: int):
    slot = wp.atomic_add(buf.count, 0, 1)
    if slot < buf.ids.shape[0]:
        buf.ids[slot] = wp.vec2i(a, b)


# broad phase ------------------------------------------------------------------
@wp.kernel
def gather_poses(
    x_start: wp.array(dtype=Any),
    q_start: wp.array(dtype=Any),
    x_end: wp.array(dtype=Any),
    q_end: wp.array(dtype=Any),
    margin: float,
    geoms: Geoms,
    max_reach: wp.array(dtype=wp.float32),
):
    """Copy each body's start pose into the geoms and bound how far its surface can move over the step."""
    i = wp.tid()
    x = wp.vec3f(x_start[i])
    q = wp.quatf(q_start[i])
    geoms.x[i] = x
    geoms.q[i] = q
    qe = wp.quatf(q_end[i])
    cos_half = wp.min(wp.abs(wp.dot(q, qe)), 1.0)
    turn = 2.0 * wp.acos(cos_half)   # rotation angle between the poses [rad]
    travel = wp.length(wp.vec3f(x_end[i]) - x) + geoms.bound[i] * wp.min(turn, 2.0)
    reach = geoms.bound[i] + travel + margin
    geoms.reach[i] = reach
    wp.atomic_max(max_reach, 0, reach)


@wp.kernel
def find_pairs(
    geoms: Geoms,
    grid: wp.uint64,
    static_count: int,
    plane_normal: wp.array(dtype=wp.vec3f),
    plane_offset: wp.array(dtype=wp.float32),
    max_reach: wp.array(dtype=wp.float32),
    pairs: ContactBuffer,
):
    """Candidate pairs of body i: bodies j > i near it in the hash grid, static colliders and planes it may reach."""
    i = wp.tid()
    x = geoms.x[i]
    reach = geoms.reach[i]
    query = wp.hash_grid_query(grid, x, reach + max_reach[0])
    j = int(0)
    while wp.hash_grid_query_next(query, j):
        if j > i and wp.length(geoms.x[j] - x) <= reach + geoms.reach[j]:
            emit_pair(pairs, i, j)
    for s in range(static_count):
        g = geoms.body_count + s
        if wp.length(geoms.x[g] - x) <= reach + geoms.bound[g]:
            emit_pair(pairs, i, g)
    for k in range(plane_normal.shape[0]):
        if wp.dot(plane_normal[k], x) - plane_offset[k] <= reach:
            emit_pair(pairs, i, -1 - k)


# narrow phase -----------------------------------------------------------------
@wp.func
def sample_world(geoms: Geoms, g: int, k: int):
    """World position of sample k of geom g at its start pose."""
    local = geoms.samples[geoms.sample_start[g] + k] - geoms.com[g]
    return geoms.x[g] + wp.quat_rotate(geoms.q[g], local)


@wp.func
def distance_to(geoms: Geoms, g: int, p: wp.vec3f, max_dist: float):
    """Signed distance [m] and world outward normal of geom g at world point p."""
    local = wp.quat_rotate_inv(geoms.q[g], p - geoms.x[g]) + geoms.com[g]
    d, n = shape_distance(geoms.kind[g], geoms.size[g], geoms.mesh[g], geoms.samples, geoms.sample_start[g],
                          geoms.sample_count[g], local, max_dist)
    return d, wp.quat_rotate(geoms.q[g], n)


@wp.func
def samples_against_plane(geoms: Geoms, a: int, plane: int, n: wp.vec3f, offset: float, margin: float,
                          buf: ContactBuffer):
    r = geoms.sample_radius[a]
    for k in range(geoms.sample_count[a]):
        p = sample_world(geoms, a, k)
        gap = wp.dot(n, p) - offset - r
        if gap < margin:
            emit(buf, geoms.body_count, a, -1 - plane, n, p, r, p - n * (gap + r), 0.0)


@wp.func
def samples_against_shape(geoms: Geoms, a: int, b: int, margin: float, buf: ContactBuffer):
    """Sample points of a (spheres of its sample radius) against the signed distance of b."""
    r = geoms.sample_radius[a]
    for k in range(geoms.sample_count[a]):
        p = sample_world(geoms, a, k)
        d, n = distance_to(geoms, b, p, geoms.bound[b] + margin + r)
        if d - r < margin:
            rb = float(0.0)   # a sphere's side of the contact is its centre and radius too
            if geoms.kind[b] == SPHERE:
                rb = geoms.size[b][0]
            emit(buf, geoms.body_count, a, b, n, p, r, p - n * (d + rb), rb)


@wp.func
def mesh_vertices_against_shape(geoms: Geoms, m: int, a: int, margin: float, buf: ContactBuffer):
    """The vertices of static mesh m (world frame) near body a against a's signed distance."""
    extent = geoms.bound[a] + margin
    corner = wp.vec3f(extent, extent, extent)
    mesh_id = geoms.mesh[m]
    mesh = wp.mesh_get(mesh_id)
    centre = geoms.x[a] - geoms.x[m]   # static meshes are stored unrotated about their pose origin
    query = wp.mesh_query_aabb(mesh_id, centre - corner, centre + corner)
    face = int(0)
    while wp.mesh_query_aabb_next(query, face):
        for c in range(3):
            v = mesh.indices[3 * face + c]
            if geoms.owner[geoms.owner_start[m] + v] == face:
                p = mesh.points[v] + geoms.x[m]
                d, n = distance_to(geoms, a, p, extent)
                if d < margin:
                    emit(buf, geoms.body_count, m, a, n, p, 0.0, p - n * d, 0.0)


@wp.func
def box_axis(geoms: Geoms, g: int, k: int):
    e = wp.vec3f(0.0)
    e[k] = 1.0
    return wp.quat_rotate(geoms.q[g], e)


@wp.func
def box_separation(geoms: Geoms, a: int, b: int, axis: wp.vec3f):
    """Separation [m] of boxes a and b along a unit axis (negative: overlap)."""
    ra = float(0.0)
    rb = float(0.0)
    for k in range(3):
        ra += geoms.size[a][k] * wp.abs(wp.dot(box_axis(geoms, a, k), axis))
        rb += geoms.size[b][k] * wp.abs(wp.dot(box_axis(geoms, b, k), axis))
    return wp.abs(wp.dot(geoms.x[b] - geoms.x[a], axis)) - ra - rb


Polygon = wp.types.matrix(shape=(8, 3), dtype=wp.float32)   # up to 8 vertices, one per row


@wp.func
def clip_polygon(polygon: Polygon, count: int, normal: wp.vec3f, offset: float):
    """Sutherland-Hodgman: the part of a convex polygon with normal . p <= offset (vertices on it kept once)."""
    out = Polygon()
    k = int(0)
    for i in range(count):
        a = polygon[i]
        b = polygon[(i + 1) % count]
        da = wp.dot(a, normal) - offset
        db = wp.dot(b, normal) - offset
        if da <= 0.0:
            out[k] = a
            k += 1
        if (da < 0.0 and db > 0.0) or (da > 0.0 and db < 0.0):
            out[k] = a + (b - a) * (da / (da - db))
            k += 1
    return out, k


@wp.func
def box_face_contacts(geoms: Geoms, ref: int, inc: int, face_axis: int, margin: float, buf: ContactBuffer):
    """Contacts of the face of box ref normal to face_axis with the most opposed face of box inc: that
    face clipped to the sides of the reference face, each vertex with its gap along the reference normal."""
    n = box_axis(geoms, ref, face_axis)
    if wp.dot(geoms.x[inc] - geoms.x[ref], n) < 0.0:
        n = -n
    centre = geoms.x[ref] + n * geoms.size[ref][face_axis]
    k = int(0)
    best = float(-1.0)
    for j in range(3):
        along = wp.abs(wp.dot(box_axis(geoms, inc, j), n))
        if along > best:
            best = along
            k = j
    f = box_axis(geoms, inc, k)
    if wp.dot(f, n) > 0.0:
        f = -f
    u1 = box_axis(geoms, inc, (k + 1) % 3) * geoms.size[inc][(k + 1) % 3]
    u2 = box_axis(geoms, inc, (k + 2) % 3) * geoms.size[inc][(k + 2) % 3]
    inc_centre = geoms.x[inc] + f * geoms.size[inc][k]
    polygon = Polygon()
    for c in range(4):
        polygon[c] = inc_centre + u1 * corner_sign(c, 0) + u2 * corner_sign(c, 1)
    count = int(4)
    for side in range(4):
        axis = (face_axis + 1 + side % 2) % 3
        t = box_axis(geoms, ref, axis)
        if side >= 2:
            t = -t
        polygon, count = clip_polygon(polygon, count, t, wp.dot(centre, t) + geoms.size[ref][axis])
    for c in range(count):
        p = polygon[c]
        gap = wp.dot(p - centre, n)
        if gap < margin:
            emit(buf, geoms.body_count, inc, ref, n, p, 0.0, p - n * gap, 0.0)


@wp.func
def box_box(geoms: Geoms, a: int, b: int, margin: float, buf: ContactBuffer):
    """Separating-axis test over the 15 axes; a face axis gives the overlap polygon, an edge pair one point.
    Face axes win unless an edge axis separates more by a relative tolerance (stable resting stacks)."""
    best = float(-1.0e30)
    best_axis = int(-1)
    for k in range(6):
        owner = a
        if k >= 3:
            owner = b
        s = box_separation(geoms, a, b, box_axis(geoms, owner, k % 3))
        if s > best:
            best = s
            best_axis = k
    if best > margin:
        return
    scale = wp.min(wp.min(geoms.size[a]), wp.min(geoms.size[b]))
    edge_best = best + 1.0e-3 * scale
    edge_axis = wp.vec3f(0.0)
    edge_i = int(-1)
    edge_j = int(-1)
    for i in range(3):
        for j in range(3):
            axis = wp.cross(box_axis(geoms, a, i), box_axis(geoms, b, j))
            if wp.length(axis) > 1.0e-4:
                axis = wp.normalize(axis)
                s = box_separation(geoms, a, b, axis)
                if s > margin:
                    return
                if s > edge_best:
                    edge_best = s
                    edge_axis = axis
                    edge_i = i
                    edge_j = j
    if edge_i < 0:
        if best_axis < 3:
            box_face_contacts(geoms, a, b, best_axis, margin, buf)
        else:
            box_face_contacts(geoms, b, a, best_axis - 3, margin, buf)
        return
    # edge against edge: the supporting edges of a and b along the axis from a to b
    L = edge_axis
    if wp.dot(geoms.x[b] - geoms.x[a], L) < 0.0:
        L = -L
    ca = geoms.x[a]
    cb = geoms.x[b]
    for k in range(3):
        if k != edge_i:
            axis_a = box_axis(geoms, a, k)
            ca += axis_a * (geoms.size[a][k] * wp.sign(wp.dot(axis_a, L)))
        if k != edge_j:
            axis_b = box_axis(geoms, b, k)
            cb -= axis_b * (geoms.size[b][k] * wp.sign(wp.dot(axis_b, L)))
    da = box_axis(geoms, a, edge_i) * geoms.size[a][edge_i]
    db = box_axis(geoms, b, edge_j) * geoms.size[b][edge_j]
    pa, pb = closest_on_segments(ca - da, ca + da, cb - db, cb + db)
    emit(buf, geoms.body_count, a, b, -L, pa, 0.0, pb, 0.0)


@wp.kernel
def narrow_phase(
    pairs: ContactBuffer,
    geoms: Geoms,
    plane_normal: wp.array(dtype=wp.vec3f),
    plane_offset: wp.array(dtype=wp.float32),
    margin: float,
    contacts: ContactBuffer,
):
    """Contacts of candidate pair p at the start of the step, for gaps below the pair's margin (the contact
    margin plus how far the bodies can move over the step, so nothing passes through in one step)."""
    p = wp.tid()
    a = pairs.ids[p][0]
    b = pairs.ids[p][1]
    reach_a = geoms.reach[a] - geoms.bound[a]
    if b < 0:
        k = -1 - b
        samples_against_plane(geoms, a, k, plane_normal[k], plane_offset[k], reach_a, contacts)
        return
    pair_margin = reach_a + geoms.reach[b] - geoms.bound[b]
    if not is_body(b, geoms.body_count):
        pair_margin = reach_a
    ka = geoms.kind[a]
    kb = geoms.kind[b]
    if ka == BOX and kb == BOX:
        box_box(geoms, a, b, pair_margin, contacts)
    elif ka == SPHERE:
        samples_against_shape(geoms, a, b, pair_margin, contacts)
    elif kb == SPHERE:
        samples_against_shape(geoms, b, a, pair_margin, contacts)
    else:
        samples_against_shape(geoms, a, b, pair_margin, contacts)
        if kb == MESH and not is_body(b, geoms.body_count):
            mesh_vertices_against_shape(geoms, b, a, pair_margin, contacts)
        else:
            samples_against_shape(geoms, b, a, pair_margin, contacts)


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
    e = zero
    mu = zero
    if j < 0:
        e = type(h)(0.5 * (geoms.restitution[i] + plane_restitution[-1 - j]))
        mu = type(h)(0.5 * (geoms.friction[i] + plane_friction[-1 - j]))
    else:
        e = type(h)(0.5 * (geoms.restitution[i] + geoms.restitution[j]))
        mu = type(h)(0.5 * (geoms.friction[i] + geoms.friction[j]))
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


# particles against shapes ----------------------------------------------------------
@wp.kernel
def push_particles(
    geoms: Geoms,
    grid: wp.uint64,
    static_count: int,
    max_reach: wp.array(dtype=wp.float32),
    body_x: wp.array(dtype=Any),
    body_q: wp.array(dtype=Any),
    body_P: wp.array(dtype=Any),
    body_L: wp.array(dtype=Any),
    body_inv_mass: wp.array(dtype=Any),
    body_inv_inertia: wp.array(dtype=Any),
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    radius: wp.array(dtype=Any),
    particle_restitution: wp.array(dtype=Any),
    particle_friction: wp.array(dtype=Any),
    touched_out: wp.array(dtype=wp.int32),
):
    """One-way contact of particles with bodies and static colliders at the end of the step: a particle
    inside a shape is moved to its surface, its normal velocity relative to the surface reflected with
    restitution e and its sliding slowed by Coulomb friction (mu times the normal impulse per unit mass,
    never reversing). Pinned particles are skipped. e and mu: the shape's, averaged with the particle's own."""
    i = wp.tid()
    if inv_mass[i] == type(inv_mass[i])(0.0):
        return
    zero = type(inv_mass[i])(0.0)
    one = type(inv_mass[i])(1.0)
    r = radius[i]
    for s in range(static_count):   # statics are few; bodies come from the hash grid
        push_particle_from(geoms, geoms.body_count + s, body_x, body_q, body_P, body_L, body_inv_mass,
                           body_inv_inertia, x, v, r, particle_restitution, particle_friction, i, touched_out, zero,
                           one)
    if geoms.body_count > 0:
        query = wp.hash_grid_query(grid, wp.vec3f(x[i]), float(r) + max_reach[0])
        b = int(0)
        while wp.hash_grid_query_next(query, b):
            push_particle_from(geoms, b, body_x, body_q, body_P, body_L, body_inv_mass, body_inv_inertia, x, v, r,
                               particle_restitution, particle_friction, i, touched_out, zero, one)


@wp.func
def push_particle_from(geoms: Geoms, g: int, body_x: wp.array(dtype=Any), body_q: wp.array(dtype=Any),
                       body_P: wp.array(dtype=Any), body_L: wp.array(dtype=Any), body_inv_mass: wp.array(dtype=Any),
                       body_inv_inertia: wp.array(dtype=Any), x: wp.array(dtype=Any), v: wp.array(dtype=Any),
                       r: Any, particle_restitution: wp.array(dtype=Any), particle_friction: wp.array(dtype=Any),
                       i: int, touched_out: wp.array(dtype=wp.int32), zero: Any, one: Any):
    body = is_body(g, geoms.body_count)
    local = wp.quat_rotate_inv(geoms.q[g], wp.vec3f(x[i]) - geoms.x[g]) + geoms.com[g]   # statics: float32 pose
    if body:
        local = wp.vec3f(wp.quat_rotate_inv(wp.normalize(body_q[g]), x[i] - body_x[g])) + geoms.com[g]
    if wp.length(local - geoms.com[g]) > geoms.bound[g] + wp.float32(r):
        return
    d, n_local = shape_distance(geoms.kind[g], geoms.size[g], geoms.mesh[g], geoms.samples, geoms.sample_start[g],
                                geoms.sample_count[g], local, geoms.bound[g] + wp.float32(r))
    depth = r - type(r)(d)
    if depth <= zero:
        return
    n = type(x[i])(wp.quat_rotate(geoms.q[g], n_local))
    surface_v = x[i] * zero
    if body:
        q = wp.normalize(body_q[g])
        n = wp.quat_rotate(q, type(x[i])(n_local))
        surface_v = state_point_velocity(q, body_P[g], body_L[g], body_inv_mass[g], body_inv_inertia[g],
                                         x[i] - body_x[g])
    x[i] = x[i] + n * depth
    rel = v[i] - surface_v
    vn = wp.dot(rel, n)
    if vn < zero:
        e = contact_material(type(r)(geoms.restitution[g]), particle_restitution, i)
        mu = contact_material(type(r)(geoms.friction[g]), particle_friction, i)
        tangential = rel - n * vn
        rel = coulomb_friction(tangential, -(one + e) * vn * mu) - n * (e * vn)
        v[i] = surface_v + rel
    if touched_out.shape[0] > 0:
        touched_out[i] = 1


# penalty response ------------------------------------------------------------------
@wp.kernel
def penalty_forces(
    contacts: ContactBuffer,
    geoms: Geoms,
    plane_restitution: wp.array(dtype=wp.float32),
    plane_friction: wp.array(dtype=wp.float32),
    x: wp.array(dtype=Any),
    q: wp.array(dtype=Any),
    P: wp.array(dtype=Any),
    L: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia: wp.array(dtype=Any),
    stiffness: Any,
    body_f: wp.array(dtype=Any),
    body_t: wp.array(dtype=Any),
):
    """Spring and damper on each overlap: F_n = max(k depth - c v_n, 0) along n, with c = 2 zeta sqrt(k m)
    for the pair's reduced mass m and the damping ratio zeta = -ln e / sqrt(pi^2 + ln^2 e) whose
    bounce has restitution e (zeta = 1 for e = 0); friction opposes sliding with min(mu F_n, c |v_t|)."""
    c = wp.tid()
    i = contacts.ids[c][0]
    j = contacts.ids[c][1]
    zero = type(stiffness)(0.0)
    n = type(x[0])(contacts.normal[c])
    p1 = type(n)(contacts.point1[c]) - n * type(stiffness)(contacts.radius1[c])   # the surface points
    p2 = type(n)(contacts.point2[c]) + n * type(stiffness)(contacts.radius2[c])
    depth = -wp.dot(n, p1 - p2)
    if depth <= zero:
        return
    r1 = p1 - x[i]
    rel = state_point_velocity(q[i], P[i], L[i], inv_mass[i], inv_inertia[i], r1)
    inverse_mass = inv_mass[i]
    dynamic = is_body(j, geoms.body_count)
    r2 = p2 * zero
    e = zero
    mu = zero
    if dynamic:
        r2 = p2 - x[j]
        rel -= state_point_velocity(q[j], P[j], L[j], inv_mass[j], inv_inertia[j], r2)
        inverse_mass += inv_mass[j]
    if j < 0:
        e = type(stiffness)(0.5 * (geoms.restitution[i] + plane_restitution[-1 - j]))
        mu = type(stiffness)(0.5 * (geoms.friction[i] + plane_friction[-1 - j]))
    else:
        e = type(stiffness)(0.5 * (geoms.restitution[i] + geoms.restitution[j]))
        mu = type(stiffness)(0.5 * (geoms.friction[i] + geoms.friction[j]))
    zeta = type(stiffness)(1.0)
    if e > zero:
        log_e = wp.log(e)
        zeta = -log_e / wp.sqrt(type(stiffness)(wp.pi * wp.pi) + log_e * log_e)
    damping = type(stiffness)(2.0) * zeta * wp.sqrt(stiffness / inverse_mass)
    vn = wp.dot(rel, n)
    fn = wp.max(stiffness * depth - damping * vn, zero)
    slide = rel - n * vn
    speed = wp.length(slide)
    F = n * fn
    if speed > type(stiffness)(1.0e-12):
        F -= slide * (wp.min(mu * fn, damping * speed) / speed)
    wp.atomic_add(body_f, i, F)
    wp.atomic_add(body_t, i, wp.cross(r1, F))
    if dynamic:
        wp.atomic_sub(body_f, j, F)
        wp.atomic_sub(body_t, j, wp.cross(r2, F))


# both precisions declared up front: the module then compiles once with every kernel, rather than once per
# new overload as a simulation first launches each (minutes on a cold cache for this large module)
_VECTORS = {"x_start", "P_start", "L_start", "x_end", "P_end", "L_end", "anchor1", "anchor2", "normal", "impulse_t",
            "collision_t",
            "v", "w", "v_collided", "w_collided", "x", "P", "L", "stored_t", "body_x", "body_P", "body_L", "body_f",
            "body_t"}
_QUATERNIONS = {"q_start", "q_end", "q", "body_q"}
_MATRICES = {"inv_inertia", "inv_inertia_world", "body_inv_inertia"}


def _declare_precisions() -> None:
    kinds = ((wp.float32, wp.vec3f, wp.quatf, wp.mat33f), (wp.float64, wp.vec3d, wp.quatd, wp.mat33d))
    for kernel in (value for value in list(globals().values()) if isinstance(value, wp.Kernel)):
        generic = [a for a in kernel.adj.args
                   if a.type is Any or (isinstance(a.type, wp.array) and a.type.dtype is Any)]
        if not generic:
            continue
        for scalar, vec3, quat, mat33 in kinds:
            types = {}
            for arg in generic:
                if arg.type is Any:
                    types[arg.label] = scalar
                else:
                    dtype = vec3 if arg.label in _VECTORS else quat if arg.label in _QUATERNIONS else \
                        mat33 if arg.label in _MATRICES else scalar
                    types[arg.label] = wp.array(dtype=dtype)
            wp.overload(kernel, types)


_declare_precisions()

"""Collision detection for bodies: the shapes on the device, broad phase (every pair, or a hash grid) and narrow phase.

Geometry is queried at the start of a step in float32 (``Geoms``, ``ContactBuffer``).
A contact pushes body ``ids[c][0]`` along +n away from ``ids[c][1]``, which is a body
(< body_count), a static collider (>= body_count) or a plane (-1 - k). point1 and point2
[m] are points of each body, and radius1 and radius2 [m] how far each surface lies from
them along the normal: the gap is n . (point1 - point2) - radius1 - radius2 (negative
when they overlap). A rounded part (a sphere, a capsule's end) is its centre and radius,
so its contact point stays under it as it rolls; elsewhere the radius is 0.

Private: every kernel, function and struct here is for the simulator's own use (warp_sim.detection);
their arguments may change between releases. ``__all__`` is empty.
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
    two_sided_distance,
)
from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []


@wp.struct
class Geoms:
    """Every collision shape: bodies first (geom i is body i), then static colliders."""

    kind: wp.array(dtype=wp.int32)
    size: wp.array(dtype=wp.vec3f)           # sphere (r, 0, 0); box half extents; capsule/cylinder (r, h/2, 0)
    com: wp.array(dtype=wp.vec3f)            # the pose origin in the shape frame (a body's centre of mass)
    mesh: wp.array(dtype=wp.uint64)          # wp.Mesh id of mesh shapes (shape frame; world frame for statics)
    two_sided: wp.array(dtype=wp.int32)      # 1 for a static surface (an open or double-sided mesh): no inside
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
    plane_normal: wp.array(dtype=wp.vec3f)   # the planes n . x = offset [m], their restitution and friction
    plane_offset: wp.array(dtype=wp.float32)
    plane_restitution: wp.array(dtype=wp.float32)
    plane_friction: wp.array(dtype=wp.float32)
    skip_start: wp.array(dtype=wp.int32)     # per body and one more: where its pairs left out start in ``skip``
    skip: wp.array(dtype=wp.int32)           # the geoms a body does not collide with (jointed ones), j > i
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
    pair: wp.array(dtype=wp.int32)           # contacts: the candidate pair each came from (its manifold)


@wp.func
def is_body(g: int, body_count: int):
    return g >= 0 and g < body_count


@wp.func
def beyond(count: wp.array(dtype=wp.int32), i: int, capacity: int):
    """Whether entry i lies past what a growable buffer holds: its count (count[0], which may exceed the
    capacity when the buffer overflowed) or its capacity. A launch over the capacity (a captured step, whose
    thread count is fixed when recorded) exits early there; a launch over the count never does."""
    return i >= wp.min(count[0], capacity)


@wp.func
def emit(buf: ContactBuffer, pair: int, body_count: int, id1: int, id2: int, n: wp.vec3f, p1: wp.vec3f, r1: float,
         p2: wp.vec3f, r2: float):
    """Append a contact of candidate pair ``pair`` pushing id1 along +n away from id2, stored with a body first."""
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
        buf.pair[slot] = pair


@wp.func
def emit_pair(buf: ContactBuffer, a: int, b: int):
    slot = wp.atomic_add(buf.count, 0, 1)
    if slot < buf.ids.shape[0]:
        buf.ids[slot] = wp.vec2i(a, b)


# broad phase ------------------------------------------------------------------
@wp.kernel
def gather_poses(start: Any, end: Any, margin: float, geoms: Geoms, max_reach: wp.array(dtype=wp.float32)):
    """Copy each body's start pose (start: Bodies) into the geoms and bound how far its surface can move over the
    step to its end pose (end: Bodies); max_reach: [the largest reach, the largest travel]."""
    i = wp.tid()
    x = wp.vec3f(start.x[i])
    q = wp.quatf(start.q[i])
    geoms.x[i] = x
    geoms.q[i] = q
    qe = wp.quatf(end.q[i])
    cos_half = wp.min(wp.abs(wp.dot(q, qe)), 1.0)
    turn = 2.0 * wp.acos(cos_half)   # rotation angle between the poses [rad]
    travel = wp.length(wp.vec3f(end.x[i]) - x) + geoms.bound[i] * wp.min(turn, 2.0)
    reach = geoms.bound[i] + travel + margin
    geoms.reach[i] = reach
    wp.atomic_max(max_reach, 0, reach)
    wp.atomic_max(max_reach, 1, travel)


@wp.func
def skipped(geoms: Geoms, i: int, g: int):
    """Whether body i and geom g > i are left out of collision (the two bodies of a joint, unless it collides)."""
    for k in range(geoms.skip_start[i], geoms.skip_start[i + 1]):
        if geoms.skip[k] == g:
            return True
    return False


@wp.func
def static_pairs(geoms: Geoms, i: int, static_reach: float, static_count: int, pairs: ContactBuffer):
    """Candidate pairs of body i with the static colliders and planes it may reach (static_reach [m])."""
    x = geoms.x[i]
    for s in range(static_count):
        g = geoms.body_count + s
        if wp.length(geoms.x[g] - x) <= static_reach + geoms.bound[g] and not skipped(geoms, i, g):
            emit_pair(pairs, i, g)
    for k in range(geoms.plane_normal.shape[0]):
        if wp.dot(geoms.plane_normal[k], x) - geoms.plane_offset[k] <= static_reach:
            emit_pair(pairs, i, -1 - k)


@wp.kernel
def find_pairs(geoms: Geoms, grid: wp.uint64, static_count: int, max_reach: wp.array(dtype=wp.float32),
               pairs: ContactBuffer):
    """Candidate pairs of body i: bodies j > i near it in the hash grid, static colliders and planes it may reach.
    Against statics the reach is grown by the largest travel of any body: the response can pass a neighbour's
    speed on to body i (a pile landing pushes its lowest layer down), and the ground must see that coming."""
    i = wp.tid()
    x = geoms.x[i]
    reach = geoms.reach[i]
    query = wp.hash_grid_query(grid, x, reach + max_reach[0])
    j = int(0)
    while wp.hash_grid_query_next(query, j):
        if j > i and wp.length(geoms.x[j] - x) <= reach + geoms.reach[j] and not skipped(geoms, i, j):
            emit_pair(pairs, i, j)
    static_pairs(geoms, i, reach + max_reach[1], static_count, pairs)


@wp.kernel
def find_all_pairs(geoms: Geoms, static_count: int, max_reach: wp.array(dtype=wp.float32), pairs: ContactBuffer):
    """find_pairs without the hash grid, for a few bodies: body i against every body j > i (cheaper than building
    the grid below about a hundred bodies on the CPU, where the build costs some 50 us whatever the count)."""
    i = wp.tid()
    x = geoms.x[i]
    reach = geoms.reach[i]
    for j in range(i + 1, geoms.body_count):
        if wp.length(geoms.x[j] - x) <= reach + geoms.reach[j] and not skipped(geoms, i, j):
            emit_pair(pairs, i, j)
    static_pairs(geoms, i, reach + max_reach[1], static_count, pairs)


# narrow phase -----------------------------------------------------------------
@wp.func
def sample_world(geoms: Geoms, g: int, k: int):
    """World position of sample k of geom g at its start pose."""
    local = geoms.samples[geoms.sample_start[g] + k] - geoms.com[g]
    return geoms.x[g] + wp.quat_rotate(geoms.q[g], local)


@wp.func
def distance_to(geoms: Geoms, g: int, p: wp.vec3f, side: wp.vec3f, max_dist: float):
    """Signed distance [m] and world outward normal of geom g at world point p; a two-sided surface's sign is
    that of the side the world point ``side`` (the centre of the body p belongs to) lies on."""
    local = wp.quat_rotate_inv(geoms.q[g], p - geoms.x[g]) + geoms.com[g]
    d = float(0.0)
    n = wp.vec3f(0.0)
    if geoms.two_sided[g] != 0:
        d, n = two_sided_distance(geoms.mesh[g], local, wp.quat_rotate_inv(geoms.q[g], side - geoms.x[g])
                                  + geoms.com[g], max_dist)
    else:
        d, n = shape_distance(geoms.kind[g], geoms.size[g], geoms.mesh[g], geoms.samples, geoms.sample_start[g],
                              geoms.sample_count[g], local, max_dist)
    return d, wp.quat_rotate(geoms.q[g], n)


@wp.func
def samples_against_plane(geoms: Geoms, a: int, plane: int, n: wp.vec3f, offset: float, margin: float,
                          buf: ContactBuffer, pair: int):
    r = geoms.sample_radius[a]
    for k in range(geoms.sample_count[a]):
        p = sample_world(geoms, a, k)
        gap = wp.dot(n, p) - offset - r
        if gap < margin:
            emit(buf, pair, geoms.body_count, a, -1 - plane, n, p, r, p - n * (gap + r), 0.0)


@wp.func
def samples_against_shape(geoms: Geoms, a: int, b: int, margin: float, buf: ContactBuffer, pair: int):
    """Sample points of a (spheres of its sample radius) against the signed distance of b."""
    r = geoms.sample_radius[a]
    for k in range(geoms.sample_count[a]):
        p = sample_world(geoms, a, k)
        d, n = distance_to(geoms, b, p, geoms.x[a], geoms.bound[b] + margin + r)
        if d - r < margin:
            rb = float(0.0)   # a sphere's side of the contact is its centre and radius too
            if geoms.kind[b] == SPHERE:
                rb = geoms.size[b][0]
            emit(buf, pair, geoms.body_count, a, b, n, p, r, p - n * (d + rb), rb)


@wp.func
def mesh_vertices_against_shape(geoms: Geoms, m: int, a: int, margin: float, buf: ContactBuffer, pair: int):
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
                d, n = distance_to(geoms, a, p, p, extent)
                if d < margin:
                    emit(buf, pair, geoms.body_count, m, a, n, p, 0.0, p - n * d, 0.0)


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
def box_face_contacts(geoms: Geoms, ref: int, inc: int, face_axis: int, margin: float, buf: ContactBuffer, pair: int):
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
            emit(buf, pair, geoms.body_count, inc, ref, n, p, 0.0, p - n * gap, 0.0)


@wp.func
def box_box(geoms: Geoms, a: int, b: int, margin: float, buf: ContactBuffer, pair: int):
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
    if edge_i < 0:   # a face of a (best_axis < 3) or of b is the reference face
        ref = a
        inc = b
        if best_axis >= 3:
            ref = b
            inc = a
        box_face_contacts(geoms, ref, inc, best_axis % 3, margin, buf, pair)
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
    emit(buf, pair, geoms.body_count, a, b, -L, pa, 0.0, pb, 0.0)


@wp.kernel
def narrow_phase(pairs: ContactBuffer, geoms: Geoms, max_reach: wp.array(dtype=wp.float32), contacts: ContactBuffer):
    """Contacts of candidate pair p at the start of the step, for gaps below the pair's margin (the contact
    margin plus how far the bodies can move over the step, so nothing passes through in one step; against a
    static, plus the largest travel of any body, as in find_pairs)."""
    p = wp.tid()
    if beyond(pairs.count, p, pairs.ids.shape[0]):
        return
    a = pairs.ids[p][0]
    b = pairs.ids[p][1]
    reach_a = geoms.reach[a] - geoms.bound[a]
    if b < 0:
        k = -1 - b
        samples_against_plane(geoms, a, k, geoms.plane_normal[k], geoms.plane_offset[k], reach_a + max_reach[1],
                              contacts, p)
        return
    pair_margin = reach_a + geoms.reach[b] - geoms.bound[b]
    if not is_body(b, geoms.body_count):
        pair_margin = reach_a + max_reach[1]
    ka = geoms.kind[a]
    kb = geoms.kind[b]
    if ka == BOX and kb == BOX:
        box_box(geoms, a, b, pair_margin, contacts, p)
        return
    # a sphere's centre against the other shape; otherwise the samples of each against the other (a static
    # mesh by its vertices). One call site per function: each is compiled once (a cold start compiles less)
    first = a
    second = b
    if ka != SPHERE and kb == SPHERE:
        first = b
        second = a
    samples_against_shape(geoms, first, second, pair_margin, contacts, p)
    if ka == SPHERE or kb == SPHERE:
        return
    if kb == MESH and not is_body(b, geoms.body_count):
        mesh_vertices_against_shape(geoms, b, a, pair_margin, contacts, p)
    else:
        samples_against_shape(geoms, b, a, pair_margin, contacts, p)


register(globals())

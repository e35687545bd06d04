"""Shape geometry for contacts: signed distances with outward normals, and box-box contact polygons.

Every shape is queried in its own frame (primitives centred on the origin, capsule and
cylinder axes along +Y). A signed distance d [m] is negative inside; the normal n is
the unit outward direction of steepest increase. Mesh distances use Warp's BVH
queries (``wp.mesh_query_point_sign_normal`` for a closed mesh: the sign from the
angle-weighted pseudo normal), in float32 as ``wp.Mesh`` stores them. A surface (an open
or double-sided static mesh) has two sides and no inside: ``two_sided_distance`` takes
the side of a point of the body it is tested against (its centre), not the winding.

Private: every function here (there are no kernels) is for the simulator's own use;
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []

SPHERE = wp.constant(0)
BOX = wp.constant(1)
CAPSULE = wp.constant(2)
CYLINDER = wp.constant(3)
MESH = wp.constant(4)
POINTS = wp.constant(5)
SIDE_SKIN = wp.constant(1.0e-3)   # [m] how far behind a two-sided surface a body's point still counts on its side

KINDS = {"sphere": 0, "box": 1, "capsule": 2, "cylinder": 3, "mesh": 4, "points": 5,
         "none": 6}   # no shape: shape_distance is max_dist everywhere and it has no samples, so it never touches


@wp.func
def axis_vector(like: Any, k: int):
    """The unit vector along axis k (0, 1, 2) of the vector type of ``like``."""
    e = type(like)()
    e[k] = type(like[0])(1.0)
    return e


@wp.func
def sign_of(x: Any):
    """+1 for x >= 0, else -1."""
    s = type(x)(1.0)
    if x < type(x)(0.0):
        s = type(x)(-1.0)
    return s


@wp.func
def direction_or(v: Any, fallback: Any):
    """v normalised, or ``fallback`` where v has (almost) no length; returns (direction, length)."""
    length = wp.length(v)
    out = fallback
    if length > type(length)(1.0e-12):
        out = v / length
    return out, length


@wp.func
def sphere_distance(radius: Any, p: Any):
    n, length = direction_or(p, axis_vector(p, 1))
    return length - radius, n


@wp.func
def box_distance(half: Any, p: Any):
    zero = type(p[0])(0.0)
    q = type(p)(wp.abs(p[0]) - half[0], wp.abs(p[1]) - half[1], wp.abs(p[2]) - half[2])
    outside = type(p)(wp.max(q[0], zero), wp.max(q[1], zero), wp.max(q[2], zero))
    length = wp.length(outside)
    d = length
    n = type(p)()
    if length > zero:
        n = type(p)(sign_of(p[0]) * outside[0], sign_of(p[1]) * outside[1], sign_of(p[2]) * outside[2]) / length
    else:
        k = int(0)
        if q[1] > q[k]:
            k = 1
        if q[2] > q[k]:
            k = 2
        d = q[k]
        n = axis_vector(p, k) * sign_of(p[k])
    return d, n


@wp.func
def capsule_distance(radius: Any, half_height: Any, p: Any):
    core = type(p)(p[0] * type(radius)(0.0), wp.clamp(p[1], -half_height, half_height), p[2] * type(radius)(0.0))
    n, length = direction_or(p - core, axis_vector(p, 0))
    return length - radius, n


@wp.func
def cylinder_distance(radius: Any, half_height: Any, p: Any):
    zero = type(radius)(0.0)
    radial, rho = direction_or(type(p)(p[0], zero, p[2]), axis_vector(p, 0))
    dr = rho - radius
    dy = wp.abs(p[1]) - half_height
    up = axis_vector(p, 1) * sign_of(p[1])
    d = dy
    n = up
    if dr > zero and dy > zero:
        d = wp.sqrt(dr * dr + dy * dy)
        n = (radial * dr + up * dy) / d
    elif dr > dy:
        d = dr
        n = radial
    return d, n


@wp.func
def points_distance(samples: wp.array(dtype=Any), start: int, count: int, radius: Any, p: Any):
    d = type(radius)(1.0e30)
    n = axis_vector(p, 1)
    for k in range(count):
        dk, nk = sphere_distance(radius, p - samples[start + k])
        if dk < d:
            d = dk
            n = nk
    return d, n


@wp.func
def mesh_distance(mesh: wp.uint64, p: Any, max_dist: Any):
    """Signed distance to a wp.Mesh (its own frame) within max_dist; max_dist and +Y beyond it."""
    d = max_dist
    n = axis_vector(p, 1)
    query = wp.mesh_query_point_sign_normal(mesh, wp.vec3f(p), wp.float32(max_dist))
    if query.result:
        closest = type(p)(wp.mesh_eval_position(mesh, query.face, query.u, query.v))
        face_normal = type(p)(wp.mesh_eval_face_normal(mesh, query.face))
        direction, length = direction_or(p - closest, face_normal * type(d)(query.sign))
        d = length * type(d)(query.sign)
        n = direction * type(d)(query.sign)
    return d, n


@wp.func
def two_sided_distance(mesh: wp.uint64, p: wp.vec3f, side: wp.vec3f, max_dist: float):
    """Distance [m] from p to a two-sided surface (a wp.Mesh, its own frame) within max_dist, and the unit normal:
    |p - c| and the direction from the closest point c to p (the face normal towards point ``side``, a body's
    centre, where they coincide). A point behind the face as seen from ``side`` by at most SIDE_SKIN (a body's
    corner sunk in by the contacts' slop) is on the body's side: minus its depth, along that face normal, so its
    contact pushes it back. Farther behind, it keeps its own side (a body reaching past an edge of the surface).
    Beyond max_dist: max_dist and +Y."""
    d = max_dist
    n = wp.vec3f(0.0, 1.0, 0.0)
    query = wp.mesh_query_point_no_sign(mesh, p, max_dist)
    if query.result:
        closest = wp.mesh_eval_position(mesh, query.face, query.u, query.v)
        facing = wp.mesh_eval_face_normal(mesh, query.face)
        front = facing * sign_of(wp.dot(facing, side - closest))
        height = wp.dot(p - closest, front)
        if height < 0.0 and height >= -SIDE_SKIN:
            d = height
            n = front
        else:
            n, d = direction_or(p - closest, front)
    return d, n


@wp.func
def shape_distance(kind: int, size: Any, mesh: wp.uint64, samples: wp.array(dtype=Any), start: int, count: int,
                   p: Any, max_dist: Any):
    """Signed distance [m] and outward unit normal of a shape at point p of its frame."""
    d = max_dist
    n = axis_vector(p, 1)
    if kind == SPHERE:
        d, n = sphere_distance(size[0], p)
    elif kind == BOX:
        d, n = box_distance(size, p)
    elif kind == CAPSULE:
        d, n = capsule_distance(size[0], size[1], p)
    elif kind == CYLINDER:
        d, n = cylinder_distance(size[0], size[1], p)
    elif kind == MESH:
        d, n = mesh_distance(mesh, p, max_dist)
    elif kind == POINTS:
        d, n = points_distance(samples, start, count, size[0], p)
    return d, n


@wp.func
def closest_on_segments(p0: Any, p1: Any, q0: Any, q1: Any):
    """The closest points (on [p0, p1], on [q0, q1]) of two segments."""
    zero = type(p0[0])(0.0)
    one = type(p0[0])(1.0)
    d1 = p1 - p0
    d2 = q1 - q0
    r = p0 - q0
    a = wp.dot(d1, d1)
    e = wp.dot(d2, d2)
    f = wp.dot(d2, r)
    c = wp.dot(d1, r)
    b = wp.dot(d1, d2)
    denom = a * e - b * b
    s = zero
    if denom > type(a)(1.0e-12) * a * e:
        s = wp.clamp((b * f - c * e) / denom, zero, one)
    t = zero
    if e > zero:
        t = (b * s + f) / e
    if t < zero:
        t = zero
        if a > zero:
            s = wp.clamp(-c / a, zero, one)
    elif t > one:
        t = one
        if a > zero:
            s = wp.clamp((b - c) / a, zero, one)
    return p0 + d1 * s, q0 + d2 * t


@wp.func
def corner_sign(k: int, axis: int):
    """Signs walking a rectangle's corners k = 0..3 counter-clockwise: (+,+), (-,+), (-,-), (+,-)."""
    s = 1.0
    if axis == 0 and (k == 1 or k == 2):
        s = -1.0
    if axis == 1 and k >= 2:
        s = -1.0
    return s

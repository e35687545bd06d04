"""Particles (and cloth and soft-body vertices) against bodies and static colliders, one way: shapes push
particles, swept over each step against the static colliders and projected out of every shape at its end.

Against static colliders a particle's motion over the step is swept (continuous collision, the time of impact);
at the end of each step, particles are projected out of every shape (resting contact, and moving bodies, which
are not swept: a body moves over the step, and the detection's hash grid finds the bodies near the end point).

The sweep. A particle of radius r moves over a step of h seconds from its start position to its end position (the
integrator's), taken as the straight chord between them, run through at an even pace over the step. Each piece of
collision geometry is convex: a box, sphere, capsule or cylinder, or one triangle of a mesh (a mesh's triangles come
from its BVH, those whose boxes meet the chord's box grown by r). The gap f(t) = distance(chord(t)) - r of a convex
piece is a convex function of the chord parameter t, so Newton's method from t = 0 never steps past its first root:
that root (within TOL r) is the particle's first touch, found in a few steps. The touch is a hit when the path goes
on to penetrate the piece by SKIN r (half the radius, found the same way); a path that stays shallower (a particle
sliding or resting on the piece, or passing an internal edge of a mesh) is left to the end-of-step projection, and
its centre stays at least r / 2 from the surface, so it never reaches the far side. So a chord shorter than SKIN r -
2 TOL r cannot hit from a start outside, and is not swept (a particle resting, or slow for its radius and the step).
Both marches stop after MAX_MARCH steps: the first then touches at its last point (known clear), the second counts
as a hit. Triangles are unsigned distances, so an open surface (``MeshShape(solid=False)``) holds particles on both
of its sides; a particle whose centre starts a sweep inside a solid shape (a box, ..., a closed mesh) is left to the
projection.

At the earliest hit over all static colliders the particle is placed at distance r from the piece on its near
side. Its velocity there is that of the path of constant acceleration through the chord's ends with the end
velocity (rk4's and Verlet's own path under constant forces; for implicit and symplectic Euler, whose positions
move by h v1, the end velocity v1 throughout: their start velocity is not what moved them). The response is a
change of velocity, applied to the end velocity and to the rest of the chord alike (so x1 = x0 + h v1 still
holds for the Euler methods): an impact reflects the normal velocity with restitution e and slows the sliding by
Coulomb friction (mu times the normal impulse, never reversing); an approach no faster than twice the step's own
normal change of velocity (gravity's g h) is resting contact, with e = 0, as for bodies (``bounce_speed``).
Neither the rest nor the end velocity then goes into the surface, and friction acts with the normal velocity
that took away. e and mu: the collider's, averaged with the particle's own (planes.contact_material). It then
travels the rest of the step, which is swept again; after MAX_EVENTS hits a further hit stops it at that contact
(the inward normal velocity removed). So no particle ends a step past a static shape or more than r / 2 into it,
and the projection, with the same rule for resting contact, removes what is left.

Private: every kernel and function here is for the simulator's own use (the particle-shape pass);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .contacts import body_point_velocity
from .detection import Geoms, is_body
from .geometry import MESH, direction_or, shape_distance
from .planes import contact_material, coulomb_friction
from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []

MAX_EVENTS = wp.constant(4)   # hits a particle responds to per step against static colliders; a further one stops it
MAX_MARCH = wp.constant(24)   # Newton steps of one march along the chord against one convex piece
SKIN = wp.constant(0.5)       # [r] depth into a piece a path may reach unswept (left to the projection)
TOL = wp.constant(0.01)       # [r] a gap within TOL r is touching
TOL_MIN = wp.constant(1.0e-6)   # [m] the touching tolerance at least (float32 geometry; particles of radius 0)
MAX_SWEEPS = wp.constant(5)   # MAX_EVENTS + 1: the sweep after the last response, which can only stop the particle


@wp.kernel
def collide_particles(geoms: Geoms, grid: wp.uint64, static_count: int, max_reach: wp.array(dtype=wp.float32),
                      double_sided: wp.array(dtype=wp.int32), bodies: Any, mass: Any, x_start: wp.array(dtype=Any),
                      v_start: wp.array(dtype=Any), x: wp.array(dtype=Any), v: wp.array(dtype=Any), material: Any,
                      h: Any, touched_out: wp.array(dtype=wp.int32)):
    """Continuous collision of particles with the static colliders over a step of h [s] (the module's sweep),
    then push_particles' end-of-step projection out of every shape, bodies too, with open surfaces held on both
    sides and approaches no faster than twice the step's own normal change of velocity resting (restitution 0).
    x_start [m], v_start [m/s]: the step's start; x [m], v [m/s]: its end, corrected in place; double_sided: per
    static collider, 1 for an open surface (unsigned distances), else 0; the rest as push_particles. Pinned
    particles are skipped."""
    i = wp.tid()
    if material.inv_mass[i] == h * type(h)(0.0):
        return
    change = v[i] - v_start[i]   # the step's own change of velocity: slower approaches than twice it rest
    if static_count > 0:
        xe, ve, touched = sweep_particle(geoms, static_count, double_sided, i, x_start[i], change, x[i], v[i],
                                         material, h)
        if touched != 0:
            x[i] = xe
            v[i] = ve
            if touched_out.shape[0] > 0:
                touched_out[i] = 1
    project_particle(geoms, grid, static_count, max_reach, double_sided, bodies, mass, x, v, material, i, change,
                     touched_out)


@wp.kernel
def push_particles(geoms: Geoms, grid: wp.uint64, static_count: int, max_reach: wp.array(dtype=wp.float32),
                   double_sided: wp.array(dtype=wp.int32), bodies: Any, mass: Any, x: wp.array(dtype=Any),
                   v: wp.array(dtype=Any), material: Any, touched_out: wp.array(dtype=wp.int32)):
    """One-way contact of particles with bodies and static colliders at the end of the step: a particle
    inside a shape is moved to its surface, its normal velocity relative to the surface reflected with
    restitution e and its sliding slowed by Coulomb friction (mu times the normal impulse per unit mass,
    never reversing). Pinned particles are skipped. e and mu: the shape's, averaged with the particle's own.
    bodies, mass: the bodies' Bodies and BodyMass blocks (empty arrays without bodies); material: the
    particles' ParticleMaterial; double_sided: per static collider, 1 for an open surface held on both sides
    (unsigned distance), or an empty array: every open surface a terrain, inside below it (the projection as it
    was before the sweep: ParticleShapeContacts(continuous=False))."""
    i = wp.tid()
    if material.inv_mass[i] == type(material.inv_mass[i])(0.0):
        return
    project_particle(geoms, grid, static_count, max_reach, double_sided, bodies, mass, x, v, material, i,
                     x[i] * type(material.inv_mass[i])(0.0), touched_out)


@wp.func
def project_particle(geoms: Geoms, grid: wp.uint64, static_count: int, max_reach: wp.array(dtype=wp.float32),
                     double_sided: wp.array(dtype=wp.int32), bodies: Any, mass: Any, x: wp.array(dtype=Any),
                     v: wp.array(dtype=Any), material: Any, i: int, change: Any,
                     touched_out: wp.array(dtype=wp.int32)):
    """push_particles' work for free particle i; double_sided: per static collider, 1 for an open surface held
    on both sides (unsigned distance), or an empty array (every surface a terrain); change [m/s]: the step's own
    change of velocity, an approach no faster than twice its normal part is resting contact (restitution 0;
    zero: restitution at any approach, as push_particles)."""
    zero = type(material.inv_mass[i])(0.0)
    one = type(material.inv_mass[i])(1.0)
    r = material.radius[i]
    for s in range(static_count):   # statics are few; bodies come from the hash grid
        both = int(0)
        if double_sided.shape[0] > 0:
            both = double_sided[s]
        push_particle_from(geoms, geoms.body_count + s, both, bodies, mass, x, v, r, material, i, change, touched_out,
                           zero, one)
    if geoms.body_count > 0:
        query = wp.hash_grid_query(grid, wp.vec3f(x[i]), float(r) + max_reach[0])
        b = int(0)
        while wp.hash_grid_query_next(query, b):
            push_particle_from(geoms, b, 0, bodies, mass, x, v, r, material, i, change, touched_out, zero, one)


@wp.func
def surface_distance(mesh: wp.uint64, p: wp.vec3f, max_dist: wp.float32):
    """Unsigned distance [m] from p to an open surface (a wp.Mesh, its own frame) within max_dist, and the unit
    direction from its closest point to p (its face normal where p lies on it); beyond max_dist, 2 max_dist + 1 m
    (so that it stays beyond a float64 radius rounded to max_dist) and +Y."""
    d = wp.float32(2.0) * max_dist + wp.float32(1.0)
    n = wp.vec3f(0.0, 1.0, 0.0)
    query = wp.mesh_query_point_no_sign(mesh, p, max_dist)
    if query.result:
        closest = wp.mesh_eval_position(mesh, query.face, query.u, query.v)
        n, d = direction_or(p - closest, wp.mesh_eval_face_normal(mesh, query.face))
    return d, n


@wp.func
def push_particle_from(geoms: Geoms, g: int, double_sided: int, bodies: Any, mass: Any, x: wp.array(dtype=Any),
                       v: wp.array(dtype=Any), r: Any, material: Any, i: int, change: Any,
                       touched_out: wp.array(dtype=wp.int32), zero: Any, one: Any):
    body = is_body(g, geoms.body_count)
    local = wp.quat_rotate_inv(geoms.q[g], wp.vec3f(x[i]) - geoms.x[g]) + geoms.com[g]   # statics: float32 pose
    if body:
        local = wp.vec3f(wp.quat_rotate_inv(wp.normalize(bodies.q[g]), x[i] - bodies.x[g])) + geoms.com[g]
    if wp.length(local - geoms.com[g]) > geoms.bound[g] + wp.float32(r):
        return
    d = wp.float32(0.0)
    n_local = wp.vec3f(0.0, 1.0, 0.0)
    if double_sided != 0:
        d, n_local = surface_distance(geoms.mesh[g], local, wp.float32(r))   # only a surface within r pushes
    else:
        d, n_local = shape_distance(geoms.kind[g], geoms.size[g], geoms.mesh[g], geoms.samples, geoms.sample_start[g],
                                    geoms.sample_count[g], local, geoms.bound[g] + wp.float32(r))
    depth = r - type(r)(d)
    if depth <= zero:
        return
    n = type(x[i])(wp.quat_rotate(geoms.q[g], n_local))
    surface_v = x[i] * zero
    if body:
        q = wp.normalize(bodies.q[g])
        n = wp.quat_rotate(q, type(x[i])(n_local))
        surface_v = body_point_velocity(bodies, mass, g, x[i] - bodies.x[g])
    x[i] = x[i] + n * depth
    rel = v[i] - surface_v
    vn = wp.dot(rel, n)
    if vn < zero:
        e = contact_material(type(r)(geoms.restitution[g]), material.restitution, i)
        if -vn <= type(r)(2.0) * wp.abs(wp.dot(change, n)):
            e = zero   # resting: no faster than the step's own change (gravity's g h)
        mu = contact_material(type(r)(geoms.friction[g]), material.friction, i)
        tangential = rel - n * vn
        rel = coulomb_friction(tangential, -(one + e) * vn * mu) - n * (e * vn)
        v[i] = surface_v + rel
    if touched_out.shape[0] > 0:
        touched_out[i] = 1


@wp.func
def sweep_particle(geoms: Geoms, static_count: int, double_sided: wp.array(dtype=wp.int32), i: int, xs: Any,
                   change: Any, xe: Any, ve: Any, material: Any, h: Any):
    """collide_particles' sweep for free particle i going over h [s] from xs [m] to (xe [m], ve [m/s]), its
    velocity changed by ``change`` [m/s] over the step: the corrected end (x [m], v [m/s]) and 1 if it hit a static
    collider, else 0 (and (xe, ve))."""
    zero = h * type(h)(0.0)
    one = type(h)(1.0)
    r = material.radius[i]
    tol = wp.max(type(r)(TOL) * r, type(r)(TOL_MIN))
    skin = type(r)(SKIN) * r
    pa = xs   # the chord still to go: from pa to (pb, vb), over the step's last ``span`` seconds
    pb = xe
    vb = ve
    span = h
    touched = int(0)
    for event in range(MAX_SWEEPS):
        if wp.length(pb - pa) < skin - type(h)(2.0) * tol:
            break   # too short to go skin deep from a start outside: nothing to sweep (the projection's)
        frac, f, n, g = first_hit(geoms, static_count, double_sided, pa, pb - pa, r, tol, skin)
        if g < 0:
            break
        touched = 1
        # the velocity there: of the path of constant acceleration from pa to (pb, vb) over the span (for rk4 or
        # Verlet under constant forces the integrator's own; for implicit and symplectic Euler, x1 = x0 + h v1, vb)
        vc = vb
        if span > zero:
            vc = (pb - pa) * (type(h)(2.0) / span) - vb
            vc = vc + (vb - vc) * frac
        pc = pa + (pb - pa) * frac - n * f   # on the near side, r from the piece
        if event == MAX_SWEEPS - 1:   # hits enough for one step: it stops at this one
            vn = wp.dot(vb, n)
            if vn < zero:
                vb = vb - n * vn
            pb = pc
            break
        e = contact_material(type(r)(geoms.restitution[g]), material.restitution, i)
        mu = contact_material(type(r)(geoms.friction[g]), material.friction, i)
        remaining = span * (one - frac)
        if -wp.dot(vc, n) <= type(h)(2.0) * wp.abs(wp.dot(change, n)):
            e = zero   # resting: an approach no faster than the step's own change (gravity's g h) does not bounce
        rest, vb = respond(vc, (pb - pa) * (one - frac), vb, n, remaining, e, mu, h)
        pa = pc
        pb = pc + rest
        span = remaining
    return pb, vb, touched


@wp.func
def respond(vc: Any, rest: Any, vb: Any, n: Any, remaining: Any, e: Any, mu: Any, h: Any):
    """The response to a hit with unit normal n [1] at the velocity vc [m/s], applied as a change of velocity to the
    motion still to go: the chord's rest [m] over the remaining [s] of the step and the end velocity vb [m/s]
    (so that an integrator's own relation of the two, x1 = x0 + h v1 for implicit and symplectic Euler, is
    kept). An impact (approach faster than 1e-6 of the speed and of the normal velocity change to the end)
    reflects the normal velocity with restitution e [1] (0 for resting contact, the caller's choice) and slows
    the sliding by Coulomb friction mu [1] times the normal impulse, never reversing it; then, impact or not,
    neither the rest nor the end velocity goes into the surface (resting contact), and friction acts with the
    normal velocity that takes away. Returns (the new rest [m], the new end velocity [m/s])."""
    zero = h * type(h)(0.0)
    one = type(h)(1.0)
    vn = wp.dot(vc, n)
    dv = vc * zero
    margin = -vn - type(h)(1e-6) * wp.abs(wp.dot(vb - vc, n))
    if margin > zero and margin * margin > type(h)(1e-12) * wp.dot(vc, vc):
        tangential = vc - vn * n
        dv = coulomb_friction(tangential, mu * (one + e) * (-vn)) - tangential - (one + e) * vn * n
    out_rest = rest + dv * remaining
    out_v = vb + dv
    rest_n = wp.dot(out_rest, n)
    if rest_n < zero:
        out_rest = out_rest - rest_n * n
    end_n = wp.dot(out_v, n)
    if end_n < zero:   # resting: the surface takes the inward velocity, friction its impulse
        out_v = out_v - end_n * n
        slide = coulomb_friction(out_v, mu * (-end_n)) - out_v
        out_v = out_v + slide
        out_rest = out_rest + slide * remaining
    return out_rest, out_v


@wp.func
def first_hit(geoms: Geoms, static_count: int, double_sided: wp.array(dtype=wp.int32), pa: Any, seg: Any, r: Any,
              tol: Any, skin: Any):
    """The earliest hit over every static collider of a particle of radius r [m] along the chord pa + seg t,
    t in [0, 1] (pa, seg [m]): (t, the gap there [m], the unit normal from the collider to the particle, the
    collider's geom index), or (1, 0, 0, -1) where none is hit."""
    zero = r * type(r)(0.0)
    best = type(r)(1.0)
    best_f = zero
    best_n = seg * zero
    best_g = int(-1)
    for s in range(static_count):
        g = geoms.body_count + s
        if not chord_near(type(pa)(geoms.x[g]), pa, seg, type(r)(geoms.bound[g]) + r + tol):
            continue
        touch = zero
        f = zero
        n = best_n
        hit = int(0)
        if geoms.kind[g] == MESH:
            touch, f, n, hit = sweep_mesh(geoms, g, 1 - double_sided[s], pa, seg, r, tol, skin, best)
        else:
            touch, f, n, hit = sweep_piece(geoms, g, -1, pa, seg, r, tol, skin, best)
        if hit != 0 and (best_g < 0 or touch < best):
            best = touch
            best_f = f
            best_n = n
            best_g = g
    return best, best_f, best_n, best_g


@wp.func
def chord_near(centre: Any, pa: Any, seg: Any, reach: Any):
    """Whether the chord pa + seg t, t in [0, 1] [m], comes within reach [m] of centre [m]."""
    w = centre - pa
    length_squared = wp.dot(seg, seg)
    t = reach * type(reach)(0.0)
    if length_squared > t:
        t = wp.clamp(wp.dot(w, seg) / length_squared, t, type(reach)(1.0))
    gap = w - seg * t
    return wp.dot(gap, gap) <= reach * reach


@wp.func
def sweep_mesh(geoms: Geoms, g: int, closed: int, pa: Any, seg: Any, r: Any, tol: Any, skin: Any, t_end: Any):
    """sweep_piece over the triangles of static mesh g near the chord pa + seg t, t in [0, t_end]: the earliest
    hit (t, gap [m], normal, 1) or (t_end, 0, 0, 0). closed: 1 for a closed mesh, whose hits are dropped where the
    chord starts with its centre inside (left to the projection)."""
    mesh = geoms.mesh[g]
    start = wp.quat_rotate_inv(geoms.q[g], wp.vec3f(pa) - geoms.x[g]) + geoms.com[g]
    end = wp.quat_rotate_inv(geoms.q[g], wp.vec3f(pa + seg * t_end) - geoms.x[g]) + geoms.com[g]
    grow = wp.float32(r + tol)
    query = wp.mesh_query_aabb(mesh, wp.min(start, end) - wp.vec3f(grow, grow, grow),
                               wp.max(start, end) + wp.vec3f(grow, grow, grow))
    face = int(0)
    best = t_end
    best_f = r * type(r)(0.0)
    best_n = seg * type(r)(0.0)
    found = int(0)
    while wp.mesh_query_aabb_next(query, face):
        touch, f, n, hit = sweep_piece(geoms, g, face, pa, seg, r, tol, skin, best)
        if hit != 0 and (found == 0 or touch < best):
            best = touch
            best_f = f
            best_n = n
            found = 1
    if found != 0 and closed != 0:
        d, _n = shape_distance(MESH, geoms.size[g], mesh, geoms.samples, 0, 0, start,
                               wp.float32(2.0) * geoms.bound[g] + wp.length(start))
        if d < wp.float32(0.0):
            found = 0
    return best, best_f, best_n, found


@wp.func
def sweep_piece(geoms: Geoms, g: int, face: int, pa: Any, seg: Any, r: Any, tol: Any, skin: Any, t_end: Any):
    """One convex piece of static geom g (its shape, or triangle ``face`` of its mesh where face >= 0) against a
    particle of radius r [m] along the chord pa + seg t, t in [0, t_end] [m]: (t of the first touch, the gap there
    [m], the unit normal there from the piece to the particle, 1 if the path then penetrates the piece by skin
    [m], else 0). Newton's steps on the convex gap never pass its roots; tol [m]: a gap within it is touching."""
    zero = r * type(r)(0.0)
    t = zero
    f, fd, n = piece_gap(geoms, g, face, pa, seg, t, r)
    touch = type(r)(-1.0)
    marching = int(1)
    if face < 0 and f < -r:   # the centre inside a solid shape: the projection's
        marching = 0
    for _k in range(MAX_MARCH * marching):
        if f <= tol:
            touch = t
            marching = 0
            break
        if fd >= zero:   # moving away from here on
            marching = 0
            break
        t = t + f / (-fd)
        if t > t_end:
            marching = 0
            break
        f, fd, n = piece_gap(geoms, g, face, pa, seg, t, r)
    if marching != 0:   # out of steps: it touches at the last point, known clear
        touch = t
    hit = int(0)
    if touch >= zero:
        target = tol - skin
        t2 = touch
        f2 = f
        fd2 = fd
        marching = int(1)
        for _k in range(MAX_MARCH):
            if fd2 >= zero:   # it gets no deeper
                marching = 0
                break
            if f2 <= target:
                hit = 1
                marching = 0
                break
            t2 = t2 + (f2 - target + tol) / (-fd2)
            if t2 > t_end:
                marching = 0
                break
            f2, fd2, _n = piece_gap(geoms, g, face, pa, seg, t2, r)
        if marching != 0:
            hit = 1
    return touch, f, n, hit


@wp.func
def piece_gap(geoms: Geoms, g: int, face: int, pa: Any, seg: Any, t: Any, r: Any):
    """At the chord's point pa + seg t [m] of a particle of radius r [m]: the gap to static geom g's shape (face
    < 0) or to triangle ``face`` of its mesh, distance - r [m], its rate along the chord d gap / dt [m], and the
    unit normal from the piece to the point (world; a triangle's side facing the chord's start where the point
    lies on it)."""
    p = pa + seg * t
    local = wp.quat_rotate_inv(geoms.q[g], wp.vec3f(p) - geoms.x[g]) + geoms.com[g]
    d = wp.float32(0.0)
    n_local = wp.vec3f(0.0, 1.0, 0.0)
    if face < 0:
        d, n_local = shape_distance(geoms.kind[g], geoms.size[g], geoms.mesh[g], geoms.samples, geoms.sample_start[g],
                                    geoms.sample_count[g], local, geoms.bound[g] + wp.float32(r))
    else:
        mesh = geoms.mesh[g]
        a = wp.mesh_get_point(mesh, 3 * face)
        b = wp.mesh_get_point(mesh, 3 * face + 1)
        c = wp.mesh_get_point(mesh, 3 * face + 2)
        side = wp.normalize(wp.cross(b - a, c - a))
        if wp.dot(side, wp.quat_rotate_inv(geoms.q[g], wp.vec3f(seg))) > wp.float32(0.0):
            side = -side
        n_local, d = direction_or(local - triangle_closest(local, a, b, c), side)
    n = type(p)(wp.quat_rotate(geoms.q[g], n_local))
    return type(r)(d) - r, wp.dot(seg, n), n


@wp.func
def triangle_closest(p: wp.vec3f, a: wp.vec3f, b: wp.vec3f, c: wp.vec3f):
    """The point of triangle (a, b, c) closest to p [m] (Ericson, Real-Time Collision Detection, 5.1.5)."""
    zero = wp.float32(0.0)
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = wp.dot(ab, ap)
    d2 = wp.dot(ac, ap)
    bp = p - b
    d3 = wp.dot(ab, bp)
    d4 = wp.dot(ac, bp)
    cp = p - c
    d5 = wp.dot(ab, cp)
    d6 = wp.dot(ac, cp)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    out = a
    if d1 <= zero and d2 <= zero:
        out = a
    elif d3 >= zero and d4 <= d3:
        out = b
    elif vc <= zero and d1 >= zero and d3 <= zero:
        out = a + ab * (d1 / (d1 - d3))
    elif d6 >= zero and d5 <= d6:
        out = c
    elif vb <= zero and d2 >= zero and d6 <= zero:
        out = a + ac * (d2 / (d2 - d6))
    elif va <= zero and d4 - d3 >= zero and d5 - d6 >= zero:
        out = b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)))
    else:
        denom = wp.float32(1.0) / (va + vb + vc)
        out = a + ab * (vb * denom) + ac * (vc * denom)
    return out


register(globals())

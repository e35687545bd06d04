"""Particles (and cloth and soft-body vertices) against bodies and static colliders, one way: shapes push
particles at the end of each step.

Private: every kernel and function here is for the simulator's own use (the particle-shape pass);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .contacts import body_point_velocity
from .detection import Geoms, is_body
from .geometry import shape_distance
from .planes import contact_material, coulomb_friction
from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []


@wp.kernel
def push_particles(geoms: Geoms, grid: wp.uint64, static_count: int, max_reach: wp.array(dtype=wp.float32),
                   bodies: Any, mass: Any, x: wp.array(dtype=Any), v: wp.array(dtype=Any), material: Any,
                   touched_out: wp.array(dtype=wp.int32)):
    """One-way contact of particles with bodies and static colliders at the end of the step: a particle
    inside a shape is moved to its surface, its normal velocity relative to the surface reflected with
    restitution e and its sliding slowed by Coulomb friction (mu times the normal impulse per unit mass,
    never reversing). Pinned particles are skipped. e and mu: the shape's, averaged with the particle's own.
    bodies, mass: the bodies' Bodies and BodyMass blocks (empty arrays without bodies); material: the
    particles' ParticleMaterial."""
    i = wp.tid()
    if material.inv_mass[i] == type(material.inv_mass[i])(0.0):
        return
    zero = type(material.inv_mass[i])(0.0)
    one = type(material.inv_mass[i])(1.0)
    r = material.radius[i]
    for s in range(static_count):   # statics are few; bodies come from the hash grid
        push_particle_from(geoms, geoms.body_count + s, bodies, mass, x, v, r, material, i, touched_out, zero, one)
    if geoms.body_count > 0:
        query = wp.hash_grid_query(grid, wp.vec3f(x[i]), float(r) + max_reach[0])
        b = int(0)
        while wp.hash_grid_query_next(query, b):
            push_particle_from(geoms, b, bodies, mass, x, v, r, material, i, touched_out, zero, one)


@wp.func
def push_particle_from(geoms: Geoms, g: int, bodies: Any, mass: Any, x: wp.array(dtype=Any), v: wp.array(dtype=Any),
                       r: Any, material: Any, i: int, touched_out: wp.array(dtype=wp.int32), zero: Any, one: Any):
    body = is_body(g, geoms.body_count)
    local = wp.quat_rotate_inv(geoms.q[g], wp.vec3f(x[i]) - geoms.x[g]) + geoms.com[g]   # statics: float32 pose
    if body:
        local = wp.vec3f(wp.quat_rotate_inv(wp.normalize(bodies.q[g]), x[i] - bodies.x[g])) + geoms.com[g]
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
        q = wp.normalize(bodies.q[g])
        n = wp.quat_rotate(q, type(x[i])(n_local))
        surface_v = body_point_velocity(bodies, mass, g, x[i] - bodies.x[g])
    x[i] = x[i] + n * depth
    rel = v[i] - surface_v
    vn = wp.dot(rel, n)
    if vn < zero:
        e = contact_material(type(r)(geoms.restitution[g]), material.restitution, i)
        mu = contact_material(type(r)(geoms.friction[g]), material.friction, i)
        tangential = rel - n * vn
        rel = coulomb_friction(tangential, -(one + e) * vn * mu) - n * (e * vn)
        v[i] = surface_v + rel
    if touched_out.shape[0] > 0:
        touched_out[i] = 1


register(globals())

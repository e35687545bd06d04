"""Particle emitters on the device: births into a fixed-capacity pool, ageing, deaths, attributes over life.

A pool is the slice [start, start + capacity) of the global particle arrays. A
dead slot has inv_mass 0 and zero velocity, so the ODE solvers, contacts and the
guard leave it alone. Free slots sit on a stack (free_slots[0 .. free_count - 1]).
Each step: ``age_and_kill`` ages live particles and pushes the dead onto the
stack, then ``emit`` pops one slot per birth, then ``commit_births`` updates the
stack top and counts births that found no slot (skipped, never overwritten).

Randomness: every draw of a particle comes from ``wp.rand_init(seed, sequence)``
with the emitter's seed and the particle's sequence number, so a particle's
attributes depend only on (seed, emitter, id), on any device.

Private: every kernel and function here is for the simulator's own use (the emitter pass);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []

SHAPE_POINT = wp.constant(0)
SHAPE_DISC = wp.constant(1)
SHAPE_SPHERE = wp.constant(2)   # surface
SHAPE_BALL = wp.constant(3)     # volume
SHAPE_BOX = wp.constant(4)
SHAPE_MESH = wp.constant(5)     # surface, by area


@wp.func
def orthonormal_basis(axis: wp.vec3f):
    """Two unit vectors u, w with (u, w, axis) right-handed and orthonormal."""
    helper = wp.vec3f(1.0, 0.0, 0.0)
    if wp.abs(axis[0]) > 0.9:
        helper = wp.vec3f(0.0, 1.0, 0.0)
    u = wp.normalize(wp.cross(helper, axis))
    return u, wp.cross(axis, u)


@wp.func
def sample_cone(state: wp.uint32, axis: wp.vec3f, cos_spread: float):
    """A direction uniform over the spherical cap of half-angle spread about the unit axis."""
    cos_theta = 1.0 - wp.randf(state) * (1.0 - cos_spread)
    sin_theta = wp.sqrt(wp.max(0.0, 1.0 - cos_theta * cos_theta))
    phi = 2.0 * wp.pi * wp.randf(state)
    u, w = orthonormal_basis(axis)
    return cos_theta * axis + sin_theta * (wp.cos(phi) * u + wp.sin(phi) * w)


@wp.func
def uniform(state: wp.uint32, low: float, high: float):
    return low + (high - low) * wp.randf(state)


@wp.func
def ramp_value(keys: wp.array(dtype=float), values: wp.array(dtype=wp.vec4f), s: float):
    """Piecewise-linear interpolation of values (RGBA-like vec4) over keys (ascending in [0, 1]) at s."""
    n = keys.shape[0]
    k = int(1)
    while k < n - 1 and s > keys[k]:
        k += 1
    span = keys[k] - keys[k - 1]
    f = wp.clamp((s - keys[k - 1]) / wp.max(span, 1.0e-12), 0.0, 1.0)
    return values[k - 1] + f * (values[k] - values[k - 1])


@wp.struct
class Ramps:
    """An emitter's ramps over normalised age: keys ascending in [0, 1], values as vec4 (RGB, or the value first)."""
    color_keys: wp.array(dtype=float)
    color_values: wp.array(dtype=wp.vec4f)
    opacity_keys: wp.array(dtype=float)
    opacity_values: wp.array(dtype=wp.vec4f)
    size_keys: wp.array(dtype=float)
    size_values: wp.array(dtype=wp.vec4f)   # radius [m]


@wp.struct
class MeshSurface:
    """A mesh emitter's triangles (a, b, c) [m], world frame, and their cumulative area fractions cdf."""
    cdf: wp.array(dtype=float)
    a: wp.array(dtype=wp.vec3f)
    b: wp.array(dtype=wp.vec3f)
    c: wp.array(dtype=wp.vec3f)


@wp.struct
class Pool:
    """One emitter's slots (indexed by slot; the particle is start + slot): alive (1/0), ids, birth, age and
    lifetime [s] (float64), color (RGB), opacity; the free stack free_slots[0 .. free_count[0] - 1]."""
    alive: wp.array(dtype=wp.int32)
    ids: wp.array(dtype=wp.int64)
    birth: wp.array(dtype=wp.float64)
    age: wp.array(dtype=wp.float64)
    lifetime: wp.array(dtype=wp.float64)
    color: wp.array(dtype=wp.vec3f)
    opacity: wp.array(dtype=float)
    free_slots: wp.array(dtype=int)
    free_count: wp.array(dtype=int)


@wp.struct
class KillPlanes:
    """Planes behind which an emitter's particles die: n . x < offset [m] (float32)."""
    normal: wp.array(dtype=wp.vec3f)
    offset: wp.array(dtype=float)


@wp.func
def ramped_attributes(e: Any, s: float, ramps: Ramps, rgb: wp.vec3f, alpha: float, size: float):
    """(colour, opacity, size) at normalised age s: each from its ramp where the emitter has one, else as given."""
    if e.color_ramp == 1:
        c = ramp_value(ramps.color_keys, ramps.color_values, s)
        rgb = wp.vec3f(c[0], c[1], c[2])
    if e.opacity_ramp == 1:
        alpha = ramp_value(ramps.opacity_keys, ramps.opacity_values, s)[0]
    if e.size_ramp == 1:
        size = ramp_value(ramps.size_keys, ramps.size_values, s)[0]
    return rgb, alpha, size


@wp.struct
class EmitterParams:
    """The constants of one emitter (float32; converted to the state's precision in the kernels)."""
    shape: int
    position: wp.vec3f      # [m]
    axis: wp.vec3f          # unit emission axis (and disc normal)
    extent: wp.vec3f        # disc/sphere/ball: (radius, 0, 0); box: half extents [m]
    radial: int             # 1: emit along the outward normal of the shape instead of axis
    cos_spread: float       # cosine of the cone's half-angle
    speed: wp.vec2f         # [m/s] uniform range (min, max)
    lifetime: wp.vec2d      # [s], float64 so that a constant lifetime is exact
    size: wp.vec2f          # radius [m]
    mass: wp.vec2f          # [kg]
    color_low: wp.vec3f     # RGB range at birth (equal ends: a constant)
    color_high: wp.vec3f
    opacity: wp.vec2f
    color_ramp: int         # 1: colour follows the ramp over normalised age
    opacity_ramp: int
    size_ramp: int
    gravity: wp.vec3f       # [m/s^2], for placing births inside a step
    seed: int


@wp.func
def sample_mesh_surface(state: wp.uint32, mesh: MeshSurface):
    """(point, unit normal) uniform by area over the mesh's triangles."""
    r = wp.randf(state)
    lo = int(0)
    hi = mesh.cdf.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if mesh.cdf[mid] < r:
            lo = mid + 1
        else:
            hi = mid
    s = wp.sqrt(wp.randf(state))
    t = wp.randf(state)
    a = mesh.a[lo]
    b = mesh.b[lo]
    c = mesh.c[lo]
    p = (1.0 - s) * a + s * (1.0 - t) * b + s * t * c
    n = wp.normalize(wp.cross(b - a, c - a))
    return p, n


@wp.func
def sample_position(state: wp.uint32, e: EmitterParams, mesh: MeshSurface):
    """(offset from the emitter's position [m], outward unit normal there) for the emitter's shape."""
    offset = wp.vec3f()
    normal = e.axis
    if e.shape == SHAPE_DISC:
        d = wp.sample_unit_disk(state)
        u, w = orthonormal_basis(e.axis)
        offset = e.extent[0] * (d[0] * u + d[1] * w)
    elif e.shape == SHAPE_SPHERE:
        normal = wp.sample_unit_sphere_surface(state)
        offset = e.extent[0] * normal
    elif e.shape == SHAPE_BALL:
        offset = e.extent[0] * wp.sample_unit_sphere(state)
        if wp.length(offset) > 0.0:
            normal = wp.normalize(offset)
    elif e.shape == SHAPE_BOX:
        offset = wp.cw_mul(e.extent, wp.vec3f(2.0 * wp.randf(state) - 1.0, 2.0 * wp.randf(state) - 1.0,
                                              2.0 * wp.randf(state) - 1.0))
    elif e.shape == SHAPE_MESH:
        p, n = sample_mesh_surface(state, mesh)
        offset = p
        normal = n
    return offset, normal


@wp.kernel
def emit(
    e: EmitterParams,
    start: int,
    first_sequence: int,
    id_base: wp.int64,
    first_age: wp.float64,
    age_step: wp.float64,
    now: wp.float64,
    pool: Pool,
    mesh: MeshSurface,
    ramps: Ramps,
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    material: Any,
):
    """Birth j of a batch: particle sequence number first_sequence + j, id id_base + sequence, aged
    first_age - j age_step [s] now (its birth was that long ago) and placed ballistically since.

    Takes pool.free_slots[free_count - 1 - j] (slot indices within the pool); a birth
    with no free slot does nothing (commit_births counts it). Writes x [m], v [m/s],
    material.inv_mass [1/kg] and material.radius [m] of the global particle arrays at
    start + slot, and the pool's own arrays (indexed by slot).
    """
    j = wp.tid()
    top = pool.free_count[0]
    if j >= top:
        return
    slot = pool.free_slots[top - 1 - j]
    sequence = first_sequence + j
    state = wp.rand_init(e.seed, sequence)
    offset, normal = sample_position(state, e, mesh)
    axis = e.axis
    if e.radial == 1:
        axis = normal
    direction = sample_cone(state, axis, e.cos_spread)
    speed = uniform(state, e.speed[0], e.speed[1])
    life = e.lifetime[0] + (e.lifetime[1] - e.lifetime[0]) * wp.float64(wp.randf(state))
    size = uniform(state, e.size[0], e.size[1])
    mass = uniform(state, e.mass[0], e.mass[1])
    mix = wp.randf(state)
    alpha = uniform(state, e.opacity[0], e.opacity[1])
    # placed where a ballistic flight since its birth time puts it at the end of the step
    age_now = first_age - wp.float64(j) * age_step
    dt = float(age_now)
    velocity = speed * direction
    p = e.position + offset + dt * velocity + (0.5 * dt * dt) * e.gravity
    velocity = velocity + dt * e.gravity
    i = start + slot
    zero = x[i][0] * type(x[i][0])(0.0)
    x[i] = type(x[i])(type(zero)(p[0]), type(zero)(p[1]), type(zero)(p[2]))
    v[i] = type(v[i])(type(zero)(velocity[0]), type(zero)(velocity[1]), type(zero)(velocity[2]))
    material.inv_mass[i] = type(zero)(1.0 / mass)
    pool.alive[slot] = 1
    pool.ids[slot] = id_base + wp.int64(sequence)
    pool.birth[slot] = now - age_now
    pool.age[slot] = age_now
    pool.lifetime[slot] = life
    rgb = e.color_low + mix * (e.color_high - e.color_low)
    s = float(wp.min(age_now / life, wp.float64(1.0)))
    rgb, alpha, size = ramped_attributes(e, s, ramps, rgb, alpha, size)
    material.radius[i] = type(zero)(size)
    pool.color[slot] = rgb
    pool.opacity[slot] = alpha


@wp.kernel
def commit_births(births: int, free_count: wp.array(dtype=int), born: wp.array(dtype=wp.int64),
                  skipped: wp.array(dtype=wp.int64)):
    """After emit: pop the used slots off the free stack; count the births that found none. Launch with dim 1."""
    top = free_count[0]
    used = wp.min(births, top)
    free_count[0] = top - used
    born[0] = born[0] + wp.int64(used)
    skipped[0] = skipped[0] + wp.int64(births - used)


@wp.kernel
def age_and_kill(
    e: EmitterParams,
    start: int,
    now: wp.float64,
    kill: KillPlanes,
    planes: Any,
    touched: wp.array(dtype=wp.int32),
    pool: Pool,
    ramps: Ramps,
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    material: Any,
):
    """Age every live particle of the pool to now - birth [s] (float64); kill those past their
    lifetime (within 1e-9 s), behind a kill plane (n . x < offset) or, where contact ``planes`` are
    given (a kernels.blocks Planes, empty otherwise), touching one (flagged in touched by the impulse
    pass, or within radius + 1e-6 m); update colour, opacity and size from their ramps over normalised age.

    A death makes the slot inert (inv_mass 0, v 0, x kept) and pushes it onto free_slots.
    """
    slot = wp.tid()
    if pool.alive[slot] == 0:
        return
    i = start + slot
    a = now - pool.birth[slot]
    pool.age[slot] = a
    p = x[i]
    radius = material.radius[i]
    dead = a >= pool.lifetime[slot] - wp.float64(1.0e-9)
    if touched.shape[0] > 0:
        if touched[i] != 0:
            dead = True
            touched[i] = 0
    for k in range(kill.normal.shape[0]):
        n = kill.normal[k]
        if float(p[0]) * n[0] + float(p[1]) * n[1] + float(p[2]) * n[2] < kill.offset[k]:
            dead = True
    for k in range(planes.normal.shape[0]):
        if wp.dot(p, planes.normal[k]) - planes.offset[k] <= radius + type(radius)(1.0e-6):
            dead = True
    if dead:
        pool.alive[slot] = 0
        material.inv_mass[i] = type(radius)(0.0)
        v[i] = type(v[i])()
        top = wp.atomic_add(pool.free_count, 0, 1)
        pool.free_slots[top] = slot
        return
    s = float(wp.min(a / pool.lifetime[slot], wp.float64(1.0)))
    rgb, alpha, size = ramped_attributes(e, s, ramps, pool.color[slot], pool.opacity[slot], float(radius))
    pool.color[slot] = rgb
    pool.opacity[slot] = alpha
    material.radius[i] = type(radius)(size)


register(globals())

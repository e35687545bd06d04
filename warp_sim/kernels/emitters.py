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


@wp.func
def ramped_attributes(e: Any, s: float, color_keys: wp.array(dtype=float), color_values: wp.array(dtype=wp.vec4f),
                      opacity_keys: wp.array(dtype=float), opacity_values: wp.array(dtype=wp.vec4f),
                      size_keys: wp.array(dtype=float), size_values: wp.array(dtype=wp.vec4f), rgb: wp.vec3f,
                      alpha: float, size: float):
    """(colour, opacity, size) at normalised age s: each from its ramp where the emitter has one, else as given."""
    if e.color_ramp == 1:
        c = ramp_value(color_keys, color_values, s)
        rgb = wp.vec3f(c[0], c[1], c[2])
    if e.opacity_ramp == 1:
        alpha = ramp_value(opacity_keys, opacity_values, s)[0]
    if e.size_ramp == 1:
        size = ramp_value(size_keys, size_values, s)[0]
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
def sample_mesh_surface(state: wp.uint32, cdf: wp.array(dtype=float), a: wp.array(dtype=wp.vec3f),
                        b: wp.array(dtype=wp.vec3f), c: wp.array(dtype=wp.vec3f)):
    """(point, unit normal) uniform by area over triangles (a, b, c), cdf = cumulative area fractions."""
    r = wp.randf(state)
    lo = int(0)
    hi = cdf.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[mid] < r:
            lo = mid + 1
        else:
            hi = mid
    s = wp.sqrt(wp.randf(state))
    t = wp.randf(state)
    p = (1.0 - s) * a[lo] + s * (1.0 - t) * b[lo] + s * t * c[lo]
    n = wp.normalize(wp.cross(b[lo] - a[lo], c[lo] - a[lo]))
    return p, n


@wp.func
def sample_position(state: wp.uint32, e: EmitterParams, cdf: wp.array(dtype=float), a: wp.array(dtype=wp.vec3f),
                    b: wp.array(dtype=wp.vec3f), c: wp.array(dtype=wp.vec3f)):
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
        p, n = sample_mesh_surface(state, cdf, a, b, c)
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
    free_slots: wp.array(dtype=int),
    free_count: wp.array(dtype=int),
    mesh_cdf: wp.array(dtype=float),
    mesh_a: wp.array(dtype=wp.vec3f),
    mesh_b: wp.array(dtype=wp.vec3f),
    mesh_c: wp.array(dtype=wp.vec3f),
    color_keys: wp.array(dtype=float),
    color_values: wp.array(dtype=wp.vec4f),
    opacity_keys: wp.array(dtype=float),
    opacity_values: wp.array(dtype=wp.vec4f),
    size_keys: wp.array(dtype=float),
    size_values: wp.array(dtype=wp.vec4f),
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    radius: wp.array(dtype=Any),
    alive: wp.array(dtype=wp.int32),
    ids: wp.array(dtype=wp.int64),
    now: wp.float64,
    birth: wp.array(dtype=wp.float64),
    age: wp.array(dtype=wp.float64),
    lifetime: wp.array(dtype=wp.float64),
    color: wp.array(dtype=wp.vec3f),
    opacity: wp.array(dtype=float),
):
    """Birth j of a batch: particle sequence number first_sequence + j, id id_base + sequence, aged
    first_age - j age_step [s] now (its birth was that long ago) and placed ballistically since.

    Takes free_slots[free_count - 1 - j] (slot indices within the pool); a birth
    with no free slot does nothing (commit_births counts it). Writes x [m], v [m/s],
    inv_mass [1/kg] and radius [m] of the global particle arrays at start + slot,
    and the pool's own arrays (indexed by slot).
    """
    j = wp.tid()
    top = free_count[0]
    if j >= top:
        return
    slot = free_slots[top - 1 - j]
    sequence = first_sequence + j
    state = wp.rand_init(e.seed, sequence)
    offset, normal = sample_position(state, e, mesh_cdf, mesh_a, mesh_b, mesh_c)
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
    inv_mass[i] = type(zero)(1.0 / mass)
    alive[slot] = 1
    ids[slot] = id_base + wp.int64(sequence)
    birth[slot] = now - age_now
    age[slot] = age_now
    lifetime[slot] = life
    rgb = e.color_low + mix * (e.color_high - e.color_low)
    s = float(wp.min(age_now / life, wp.float64(1.0)))
    rgb, alpha, size = ramped_attributes(e, s, color_keys, color_values, opacity_keys, opacity_values, size_keys,
                                         size_values, rgb, alpha, size)
    radius[i] = type(zero)(size)
    color[slot] = rgb
    opacity[slot] = alpha


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
    kill_normal: wp.array(dtype=wp.vec3f),
    kill_offset: wp.array(dtype=float),
    now: wp.float64,
    contact_normal: wp.array(dtype=Any),
    contact_offset: wp.array(dtype=Any),
    touched: wp.array(dtype=wp.int32),
    color_keys: wp.array(dtype=float),
    color_values: wp.array(dtype=wp.vec4f),
    opacity_keys: wp.array(dtype=float),
    opacity_values: wp.array(dtype=wp.vec4f),
    size_keys: wp.array(dtype=float),
    size_values: wp.array(dtype=wp.vec4f),
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    radius: wp.array(dtype=Any),
    alive: wp.array(dtype=wp.int32),
    birth: wp.array(dtype=wp.float64),
    age: wp.array(dtype=wp.float64),
    lifetime: wp.array(dtype=wp.float64),
    color: wp.array(dtype=wp.vec3f),
    opacity: wp.array(dtype=float),
    free_slots: wp.array(dtype=int),
    free_count: wp.array(dtype=int),
):
    """Age every live particle of the pool to now - birth [s] (float64); kill those past their
    lifetime (within 1e-9 s), behind a kill plane (n . x < offset) or, where contact planes are
    given, touching one (flagged in touched by the impulse pass, or within radius + 1e-6 m);
    update colour, opacity and size from their ramps over normalised age.

    A death makes the slot inert (inv_mass 0, v 0, x kept) and pushes it onto free_slots.
    """
    slot = wp.tid()
    if alive[slot] == 0:
        return
    i = start + slot
    a = now - birth[slot]
    age[slot] = a
    p = x[i]
    dead = a >= lifetime[slot] - wp.float64(1.0e-9)
    if touched.shape[0] > 0:
        if touched[i] != 0:
            dead = True
            touched[i] = 0
    for k in range(kill_normal.shape[0]):
        n = kill_normal[k]
        if float(p[0]) * n[0] + float(p[1]) * n[1] + float(p[2]) * n[2] < kill_offset[k]:
            dead = True
    for k in range(contact_normal.shape[0]):
        if wp.dot(p, contact_normal[k]) - contact_offset[k] <= radius[i] + type(radius[i])(1.0e-6):
            dead = True
    if dead:
        alive[slot] = 0
        inv_mass[i] = type(inv_mass[i])(0.0)
        v[i] = type(v[i])()
        top = wp.atomic_add(free_count, 0, 1)
        free_slots[top] = slot
        return
    s = float(wp.min(a / lifetime[slot], wp.float64(1.0)))
    rgb, alpha, size = ramped_attributes(e, s, color_keys, color_values, opacity_keys, opacity_values, size_keys,
                                         size_values, color[slot], opacity[slot], float(radius[i]))
    color[slot] = rgb
    opacity[slot] = alpha
    radius[i] = type(radius[i])(size)

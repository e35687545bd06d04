"""Force fields acting on every particle: point attractors, vortices, curl-noise turbulence.

A field is an acceleration [m/s^2] independent of the particle's mass; each kernel
adds force = acceleration * m = acceleration / inv_mass into the force accumulator,
for every field of its kind (looped inside the kernel: one launch per kind), and
skips pinned particles (inv_mass 0). Thread i owns particle i, so the adds are
plain read-modify-writes: launch with dim = the number of particles. The field
arrays (center, strength, ...) hold one entry per field of the kind, k = 0 .. K-1.

Public (``__all__``): attractor_forces, vortex_forces, turbulence_forces, all the module's kernels.
"""
from typing import Any

import warp as wp

__all__ = ["attractor_forces", "vortex_forces", "turbulence_forces"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

#: Warp's curlnoise defaults: octave k has frequency LACUNARITY^k and weight GAIN^k
LACUNARITY = wp.constant(wp.float32(2.0))
GAIN = wp.constant(wp.float32(0.5))


@wp.kernel
def attractor_forces(
    x: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    center: wp.array(dtype=Any),
    strength: wp.array(dtype=Any),
    min_distance: wp.array(dtype=Any),
    force: wp.array(dtype=Any),
):
    """Accumulate m a with a = sum_k -GM_k (x - c_k) / max(|x - c_k|, d_k)^3 (inverse square).

    Inside min_distance d_k the field is that of a uniform ball of radius d_k (linear
    in x - c_k, zero at the centre, no singularity).

    Args:
        x: particle positions (vec3) [m]
        inv_mass: inverse masses 1/m, 0 for pinned (no force) [1/kg]
        center: the attractor positions c_k (vec3) [m]
        strength: GM_k, > 0 attracts, < 0 repels [m^3/s^2]
        min_distance: d_k > 0, the radius of the smoothed core [m]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    i = wp.tid()
    w = inv_mass[i]
    zero = type(w)(0.0)
    if w > zero:
        p = x[i]
        acc = type(p)()
        for k in range(center.shape[0]):
            d = p - center[k]
            r = wp.max(wp.length(d), min_distance[k])
            acc = acc - (strength[k] / (r * r * r)) * d
        force[i] = force[i] + acc / w


@wp.kernel
def vortex_forces(
    x: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    center: wp.array(dtype=Any),
    axis: wp.array(dtype=Any),
    strength: wp.array(dtype=Any),
    core_radius: wp.array(dtype=Any),
    force: wp.array(dtype=Any),
):
    """Accumulate m a with a = sum_k S_k (n_k x r) / (|r|^2 + rc_k^2), r the part of x - c_k normal to n_k.

    The core radius rc_k smooths the line singularity: the swirl peaks at |r| = rc_k
    at S_k / (2 rc_k).

    Args:
        x: particle positions (vec3) [m]
        inv_mass: inverse masses 1/m, 0 for pinned (no force) [1/kg]
        center: a point c_k on each vortex line (vec3) [m]
        axis: the unit direction n_k of each vortex line (vec3) [1]
        strength: S_k, > 0 swirls counter-clockwise about n_k (right-hand rule) [m^2/s^2]
        core_radius: rc_k > 0 [m]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    i = wp.tid()
    w = inv_mass[i]
    zero = type(w)(0.0)
    if w > zero:
        p = x[i]
        acc = type(p)()
        for k in range(center.shape[0]):
            n = axis[k]
            d = p - center[k]
            r = d - wp.dot(d, n) * n
            rc = core_radius[k]
            acc = acc + (strength[k] / (wp.dot(r, r) + rc * rc)) * wp.cross(n, r)
        force[i] = force[i] + acc / w


@wp.kernel
def turbulence_forces(
    x: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    t: Any,
    strength: wp.array(dtype=Any),
    inv_scale: wp.array(dtype=Any),
    frequency: wp.array(dtype=Any),
    seed: wp.array(dtype=wp.int32),
    octaves: wp.array(dtype=wp.int32),
    force: wp.array(dtype=Any),
):
    """Accumulate m a with a = sum_k A_k curlnoise(seed_k, (x / L_k, t f_k), octaves_k), divergence-free in x.

    Warp's noise is float32: the coordinates are formed in the arrays' precision,
    rounded to float32, and the noise converted back.

    Args:
        x: particle positions (vec3) [m]
        inv_mass: inverse masses 1/m, 0 for pinned (no force) [1/kg]
        t: the time [s]
        strength: A_k, the acceleration scale [m/s^2]
        inv_scale: 1 / L_k, L_k the size of the noise features [1/m]
        frequency: f_k, how fast the field changes, 0 for a steady field [1/s]
        seed: selects the noise field (wp.rand_init) [1]
        octaves: the number of noise octaves (Warp's lacunarity 2 and gain 1/2) [1]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    i = wp.tid()
    w = inv_mass[i]
    zero = type(w)(0.0)
    if w > zero:
        p = x[i]
        acc = type(p)()
        for k in range(strength.shape[0]):
            q = p * inv_scale[k]
            state = wp.rand_init(seed[k])
            noise = wp.vec3f()
            if frequency[k] == type(t)(0.0):   # steady: the 3-D curl noise, about 3x cheaper than the 4-D one
                coordinate3 = wp.vec3f(wp.float32(q[0]), wp.float32(q[1]), wp.float32(q[2]))
                noise = wp.curlnoise(state, coordinate3, wp.uint32(octaves[k]), LACUNARITY, GAIN)
            else:
                tau = t * frequency[k]
                coordinate = wp.vec4f(wp.float32(q[0]), wp.float32(q[1]), wp.float32(q[2]), wp.float32(tau))
                noise = wp.curlnoise(state, coordinate, wp.uint32(octaves[k]), LACUNARITY, GAIN)
            a = strength[k]
            acc = acc + type(p)(a * type(a)(noise[0]), a * type(a)(noise[1]), a * type(a)(noise[2]))
        force[i] = force[i] + acc / w

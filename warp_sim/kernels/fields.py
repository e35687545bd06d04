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

from .precisions import register

__all__ = ["attractor_forces", "vortex_forces", "turbulence_forces"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

#: Warp's curlnoise defaults: octave k has frequency LACUNARITY^k and weight GAIN^k
LACUNARITY = wp.constant(wp.float32(2.0))
GAIN = wp.constant(wp.float32(0.5))


@wp.func
def attractor_acceleration(p: Any, attractors: Any):
    """a [m/s^2] at p [m]: sum_k -GM_k (p - c_k) / max(|p - c_k|, d_k)^3."""
    acc = type(p)()
    for k in range(attractors.center.shape[0]):
        d = p - attractors.center[k]
        r = wp.max(wp.length(d), attractors.min_distance[k])
        acc = acc - (attractors.strength[k] / (r * r * r)) * d
    return acc


@wp.func
def vortex_acceleration(p: Any, vortices: Any):
    """a [m/s^2] at p [m]: sum_k S_k (n_k x r) / (|r|^2 + rc_k^2), r the part of p - c_k normal to n_k."""
    acc = type(p)()
    for k in range(vortices.center.shape[0]):
        n = vortices.axis[k]
        d = p - vortices.center[k]
        r = d - wp.dot(d, n) * n
        rc = vortices.core_radius[k]
        acc = acc + (vortices.strength[k] / (wp.dot(r, r) + rc * rc)) * wp.cross(n, r)
    return acc


@wp.func
def turbulence_acceleration(p: Any, t: Any, turbulences: Any):
    """a [m/s^2] at p [m] and time t [s]: sum_k A_k curlnoise(seed_k, (p / L_k, t f_k), octaves_k)."""
    acc = type(p)()
    for k in range(turbulences.strength.shape[0]):
        q = p * turbulences.inv_scale[k]
        state = wp.rand_init(turbulences.seed[k])
        octaves = wp.uint32(turbulences.octaves[k])
        noise = wp.vec3f()
        if turbulences.frequency[k] == type(t)(0.0):   # steady: the 3-D curl noise, about 3x cheaper than the 4-D
            noise = wp.curlnoise(state, wp.vec3f(wp.float32(q[0]), wp.float32(q[1]), wp.float32(q[2])), octaves,
                                 LACUNARITY, GAIN)
        else:
            tau = wp.float32(t * turbulences.frequency[k])
            noise = wp.curlnoise(state, wp.vec4f(wp.float32(q[0]), wp.float32(q[1]), wp.float32(q[2]), tau), octaves,
                                 LACUNARITY, GAIN)
        a = turbulences.strength[k]
        acc = acc + type(p)(a * type(a)(noise[0]), a * type(a)(noise[1]), a * type(a)(noise[2]))
    return acc


@wp.func
def is_free(inv_mass: wp.array(dtype=Any), i: int):
    """Whether particle i moves (inverse mass > 0): pinned particles and dead emitter slots feel no field."""
    return inv_mass[i] > type(inv_mass[i])(0.0)


@wp.kernel
def attractor_forces(x: wp.array(dtype=Any), inv_mass: wp.array(dtype=Any), attractors: Any,
                     force: wp.array(dtype=Any)):
    """Accumulate m a with a = sum_k -GM_k (x - c_k) / max(|x - c_k|, d_k)^3 (inverse square).

    Inside min_distance d_k the field is that of a uniform ball of radius d_k (linear
    in x - c_k, zero at the centre, no singularity).

    Args:
        x: particle positions (vec3) [m]
        inv_mass: inverse masses 1/m, 0 for pinned (no force) [1/kg]
        attractors: the centres c_k, GM_k (> 0 attracts, < 0 repels) and core radii d_k > 0 (Attractors) [m]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    i = wp.tid()
    if is_free(inv_mass, i):
        force[i] = force[i] + attractor_acceleration(x[i], attractors) / inv_mass[i]


@wp.kernel
def vortex_forces(x: wp.array(dtype=Any), inv_mass: wp.array(dtype=Any), vortices: Any, force: wp.array(dtype=Any)):
    """Accumulate m a with a = sum_k S_k (n_k x r) / (|r|^2 + rc_k^2), r the part of x - c_k normal to n_k.

    The core radius rc_k smooths the line singularity: the swirl peaks at |r| = rc_k
    at S_k / (2 rc_k); S_k > 0 swirls counter-clockwise about n_k (right-hand rule).

    Args:
        x: particle positions (vec3) [m]
        inv_mass: inverse masses 1/m, 0 for pinned (no force) [1/kg]
        vortices: a point c_k on each line, its unit direction n_k, strength S_k, core radius rc_k (Vortices) [m]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    i = wp.tid()
    if is_free(inv_mass, i):
        force[i] = force[i] + vortex_acceleration(x[i], vortices) / inv_mass[i]


@wp.kernel
def turbulence_forces(x: wp.array(dtype=Any), inv_mass: wp.array(dtype=Any), t: Any, turbulences: Any,
                      force: wp.array(dtype=Any)):
    """Accumulate m a with a = sum_k A_k curlnoise(seed_k, (x / L_k, t f_k), octaves_k), divergence-free in x.

    Warp's noise is float32: the coordinates are formed in the arrays' precision,
    rounded to float32, and the noise converted back.

    Args:
        x: particle positions (vec3) [m]
        inv_mass: inverse masses 1/m, 0 for pinned (no force) [1/kg]
        t: the time [s]
        turbulences: per field A_k, 1 / L_k, f_k (0: steady), its seed and octaves (Turbulences) [m/s^2]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    i = wp.tid()
    if is_free(inv_mass, i):
        force[i] = force[i] + turbulence_acceleration(x[i], t, turbulences) / inv_mass[i]


register(globals())

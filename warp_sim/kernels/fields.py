"""Force fields acting on every particle: point attractors, vortices, turbulence (the curl of a baked potential).

A field is an acceleration [m/s^2] independent of the particle's mass; each kernel
adds force = acceleration * m = acceleration / inv_mass into the force accumulator,
for every field of its kind (looped inside the kernel: one launch per kind), and
skips pinned particles (inv_mass 0). Thread i owns particle i, so the adds are
plain read-modify-writes: launch with dim = the number of particles. The field
arrays (center, strength, ...) hold one entry per field of the kind, k = 0 .. K-1.

Turbulence is the curl of a vector potential psi stored on a periodic grid of n^3 nodes
(float32 in both precisions) and read as a quadratic B-spline, psi(g) = sum_m psi_m B(g - m)
in grid units g: the curl is taken analytically from the spline's derivatives, so it is
divergence-free exactly inside each spline cell, and continuous across cells (psi is C^1).
``warp_sim.forces.turbulence`` bakes the grids (``bake_potentials``) and moves a time-varying
field's potential to the time of a launch (``blend_potentials``).

Public (``__all__``): attractor_forces, vortex_forces, turbulence_forces.
Private: bake_potentials and blend_potentials (the grids' bake and their time evolution), for the
simulator's own use; their arguments may change between releases.
"""
from typing import Any

import warp as wp

from .precisions import register

__all__ = ["attractor_forces", "vortex_forces", "turbulence_forces"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

#: octave k of a baked potential: Perlin noise of lattice spacing 1 / LACUNARITY^k and weight (GAIN / LACUNARITY)^k,
#: so that its curl (the acceleration) has GAIN^k the weight of octave 0's
LACUNARITY = wp.constant(2)
GAIN = wp.constant(wp.float32(0.5))
#: noise streams per (slice, component): octave k of component c of slice s draws from stream (3 s + c) 16 + k
STREAMS = wp.constant(16)


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
def spline_weights(f: wp.float32):
    """Quadratic B-spline weights of the nodes m - 1, m, m + 1 at g = m + f, f in [-1/2, 1/2], and their d/dg."""
    a = wp.float32(0.5) - f
    b = wp.float32(0.5) + f
    return (wp.vec3f(wp.float32(0.5) * a * a, wp.float32(0.75) - f * f, wp.float32(0.5) * b * b),
            wp.vec3f(-a, wp.float32(-2.0) * f, b))


@wp.func
def potential_curl(potential: wp.array(dtype=wp.vec3f), offset: int, nodes: int, g: wp.vec3f):
    """curl psi at g in [0, nodes]^3 [grid units], psi = sum_m psi_m B(g - m) the quadratic B-spline of the
    periodic grid stored at ``offset`` (nodes + 3 per axis, a ghost layer before and two after)."""
    stride = nodes + 3
    # the nearest node, in [0, nodes], stored at m + 1 (clamped: a non-finite g reads in bounds and gives NaN)
    mx = wp.clamp(int(wp.floor(g[0] + wp.float32(0.5))), 0, nodes)
    my = wp.clamp(int(wp.floor(g[1] + wp.float32(0.5))), 0, nodes)
    mz = wp.clamp(int(wp.floor(g[2] + wp.float32(0.5))), 0, nodes)
    wx, dx = spline_weights(g[0] - wp.float32(mx))
    wy, dy = spline_weights(g[1] - wp.float32(my))
    wz, dz = spline_weights(g[2] - wp.float32(mz))
    u = wp.vec3f()
    for i in range(3):
        sw = wp.vec3f()   # sum_j,k w_j w_k psi_ijk, sum_j,k w'_j w_k psi_ijk and sum_j,k w_j w'_k psi_ijk
        sd = wp.vec3f()
        dw = wp.vec3f()
        for j in range(3):
            row = offset + ((mx + i) * stride + my + j) * stride + mz
            p0 = potential[row]
            p1 = potential[row + 1]
            p2 = potential[row + 2]
            s = wz[0] * p0 + wz[1] * p1 + wz[2] * p2
            d = dz[0] * p0 + dz[1] * p1 + dz[2] * p2
            sw = sw + wy[j] * s
            sd = sd + dy[j] * s
            dw = dw + wy[j] * d
        # u += sum_jk grad(w_i w_j w_k) x psi_ijk, the gradient (w'_i w_j w_k, w_i w'_j w_k, w_i w_j w'_k)
        u = u + wp.vec3f(wx[i] * (sd[2] - dw[1]), wx[i] * dw[0] - dx[i] * sw[2], dx[i] * sw[1] - wx[i] * sd[0])
    return u


@wp.func
def field_turbulence(p: Any, turbulences: Any, potential: wp.array(dtype=wp.vec3f), k: int):
    """a [m/s^2] of turbulence field k at p [m]: A_k curl psi_k(g), g = frac(p / (P L_k)) n_k in grid units."""
    a = turbulences.strength[k]
    acc = type(p)()
    if a != type(a)(0.0):
        q = p * turbulences.inv_period[k]
        nodes = turbulences.nodes[k]
        n = type(a)(nodes)
        g = wp.vec3f(wp.float32((q[0] - wp.floor(q[0])) * n), wp.float32((q[1] - wp.floor(q[1])) * n),
                     wp.float32((q[2] - wp.floor(q[2])) * n))
        u = potential_curl(potential, turbulences.offset[k], nodes, g)
        acc = type(p)(a * type(a)(u[0]), a * type(a)(u[1]), a * type(a)(u[2]))
    return acc


@wp.func
def turbulence_acceleration(p: Any, turbulences: Any, potential: wp.array(dtype=wp.vec3f)):
    """a [m/s^2] at p [m]: the sum over the turbulence fields (field 0 outside the loop: 5 % faster on the CPU)."""
    acc = type(p)()
    count = turbulences.strength.shape[0]
    if count > 0:
        acc = field_turbulence(p, turbulences, potential, 0)
        for k in range(1, count):
            acc = acc + field_turbulence(p, turbulences, potential, k)
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
def turbulence_forces(x: wp.array(dtype=Any), inv_mass: wp.array(dtype=Any), turbulences: Any,
                      potential: wp.array(dtype=wp.vec3f), force: wp.array(dtype=Any)):
    """Accumulate m a with a = sum_k A_k curl psi_k(g_k), g_k = frac(x / (P L_k)) n_k, divergence-free in x.

    psi_k is field k's periodic potential: n_k nodes per axis spanning P L_k [m] (the block's
    inv_period is 1 / (P L_k)), stored from offset_k in ``potential`` with ghost layers ((n_k + 3)^3
    nodes, x slowest: the copies of nodes n_k - 1 before, 0 and 1 after the n_k periodic ones),
    read as a quadratic B-spline; its curl is taken in grid units, so A_k is the acceleration's
    scale. The grid is float32 in both precisions: the coordinates are formed in the arrays'
    precision, wrapped into the period, rounded to float32, and the curl converted back. A field
    of zero strength is skipped.

    Args:
        x: particle positions (vec3) [m]
        inv_mass: inverse masses 1/m, 0 for pinned (no force) [1/kg]
        turbulences: per field A_k, 1 / (P L_k), n_k and offset_k (Turbulences) [m/s^2]
        potential: every field's grid of vector potential at the launch's time, its curl's RMS 1 in grid units [1]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    i = wp.tid()
    if is_free(inv_mass, i):
        force[i] = force[i] + turbulence_acceleration(x[i], turbulences, potential) / inv_mass[i]


@wp.func
def octave_sum(seed: int, stream: int, q: wp.vec3f, period: int, octaves: int):
    """sum_k (GAIN / LACUNARITY)^k pnoise(q LACUNARITY^k) over octaves k, periodic over ``period`` lattice cells."""
    total = float(0.0)
    weight = float(1.0)
    scale = int(1)
    for k in range(octaves):
        state = wp.rand_init(seed, stream * STREAMS + k)
        lattice = period * scale
        total += weight * wp.pnoise(state, q * wp.float32(scale), lattice, lattice, lattice)
        weight = weight * GAIN / wp.float32(LACUNARITY)
        scale = scale * LACUNARITY
    return total


@wp.kernel
def bake_potentials(seed: int, nodes: int, period: int, octaves: int, potential: wp.array(dtype=wp.vec3f)):
    """potential[(s n + a) n + b) n + c] = psi of slice s at node (a, b, c): each component c' the octave sum of
    its own noise stream 3 s + c', at q = (a, b, c) period / nodes lattice cells. Launch over slices * nodes^3."""
    index = wp.tid()
    cube = nodes * nodes * nodes
    s = index // cube
    r = index - s * cube
    h = wp.float32(period) / wp.float32(nodes)
    q = wp.vec3f(wp.float32(r // (nodes * nodes)) * h, wp.float32((r // nodes) % nodes) * h,
                 wp.float32(r % nodes) * h)
    potential[index] = wp.vec3f(octave_sum(seed, 3 * s, q, period, octaves),
                                octave_sum(seed, 3 * s + 1, q, period, octaves),
                                octave_sum(seed, 3 * s + 2, q, period, octaves))


@wp.kernel
def blend_potentials(slices: wp.array(dtype=wp.vec3f), first: int, second: int, c_first: wp.float32,
                     c_second: wp.float32, potential: wp.array(dtype=wp.vec3f), offset: int):
    """potential[offset + i] = c_first slices[first + i] + c_second slices[second + i]: one grid's potential at a
    time, from two of its baked slices. Launch over the grid's nodes."""
    i = wp.tid()
    potential[offset + i] = c_first * slices[first + i] + c_second * slices[second + i]


register(globals())

"""Cloth: aerodynamic drag and lift per triangle, and Provot strain limiting of springs.

Public (``__all__``): aerodynamic_forces.
Private: limit_strain, measure_strain and reset_strain_counters (the strain-limiting pass), for
the simulator's own use; their arguments may change between releases.
"""
from typing import Any

import warp as wp

from .precisions import register

__all__ = ["aerodynamic_forces"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.kernel
def aerodynamic_forces(
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    triangles: wp.array(dtype=wp.vec3i),
    drag: wp.array(dtype=Any),
    lift: wp.array(dtype=Any),
    wind: Any,
    force: wp.array(dtype=Any),
):
    """Accumulate each triangle's air force F = F_D + F_L, one third on each of its vertices.

    u = (v_a + v_b + v_c) / 3 - wind, the air's velocity relative to the triangle
    [m/s]; c = (x_b - x_a) x (x_c - x_a), A = |c| / 2 its area [m^2] and n = c / |c|
    its unit normal (either orientation: both forces are even in n). With
    u_n = u . n:
        F_D = -drag A |u| u_n n
        F_L = -lift A u_n (|u| n - u_n u / |u|)
    i.e. F_L = -lift A |u|^2 cos(theta) sin(theta) l, theta the angle between n and u
    and l the unit vector normal to u in the plane of u and n on n's side. Launch with
    dim = the number of triangles; the forces are atomic adds. A degenerate triangle
    (zero area) or one at rest in the air feels nothing.

    Args:
        x: particle positions (vec3) [m]
        v: particle velocities (vec3) [m/s]
        triangles: the particle indices (a, b, c) of each triangle [1]
        drag: 1/2 rho C_D per triangle (rho the air's density, C_D the drag coefficient) [kg/m^3]
        lift: 1/2 rho C_L per triangle (C_L the lift coefficient) [kg/m^3]
        wind: the air's velocity (vec3) [m/s]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    t = wp.tid()
    a = triangles[t][0]
    b = triangles[t][1]
    c = triangles[t][2]
    xa = x[a]
    cross = wp.cross(x[b] - xa, x[c] - xa)
    twice_area = wp.length(cross)
    u = (v[a] + v[b] + v[c]) / type(twice_area)(3.0) - wind
    speed = wp.length(u)
    zero = type(twice_area)(0.0)
    if twice_area > zero and speed > zero:
        n = cross / twice_area
        un = wp.dot(u, n)
        area = type(twice_area)(0.5) * twice_area
        f = (-drag[t] * area * speed * un) * n - (lift[t] * area * un) * (speed * n - (un / speed) * u)
        share = f / type(twice_area)(3.0)
        wp.atomic_add(force, a, share)
        wp.atomic_add(force, b, share)
        wp.atomic_add(force, c, share)


@wp.kernel
def limit_strain(
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    pairs: wp.array(dtype=wp.vec2i),
    limit: wp.array(dtype=Any),
    inv_rest: wp.array(dtype=Any),
    offset: int,
    tolerance: Any,
    relaxation: Any,
    inv_h: Any,
    violations: wp.array(dtype=wp.int32),
    max_strain: wp.array(dtype=Any),
):
    """Shorten every spring of one colour that exceeds limit (1 + tolerance), in place.

    Spring s = offset + tid joins particles (i, j); L = |x_j - x_i|, d = (x_j - x_i) / L.
    When L > limit_s (1 + tolerance) the spring is shortened by
    e = min(relaxation (L - limit_s), L - L0_s) (relaxation 1: to exactly its limit;
    more: over-relaxed, but never below its rest length L0_s), its endpoints moving
    along it by the inverse-mass-weighted shares dx_i = w_i / (w_i + w_j) e d and
    dx_j = -w_j / (w_i + w_j) e d (w = 1/m, 0 for pinned; sum m dx = 0), and each
    velocity by dx inv_h. Such a spring is counted in violations[0]; every spring's
    strain L / L0_s - 1 (before any move) goes into max_strain[0] (atomic max). The
    springs of one colour share no particle, so the updates do not race. limit [m],
    inv_rest: 1 / L0 [1/m], inv_h: 1 / step [1/s]. Springs with both ends pinned are
    never listed.
    """
    s = offset + wp.tid()
    i = pairs[s][0]
    j = pairs[s][1]
    d = x[j] - x[i]
    length = wp.length(d)
    one = type(length)(1.0)
    wp.atomic_max(max_strain, 0, length * inv_rest[s] - one)
    target = limit[s]
    if length > target * (one + tolerance):
        wp.atomic_add(violations, 0, 1)
        wi = inv_mass[i]
        wj = inv_mass[j]
        shorten = wp.min(relaxation * (length - target), length - one / inv_rest[s])
        dx = d * (shorten / (length * (wi + wj)))
        x[i] = x[i] + wi * dx
        v[i] = v[i] + (wi * inv_h) * dx
        x[j] = x[j] - wj * dx
        v[j] = v[j] - (wj * inv_h) * dx


@wp.kernel
def measure_strain(
    x: wp.array(dtype=Any),
    pairs: wp.array(dtype=wp.vec2i),
    limit: wp.array(dtype=Any),
    inv_rest: wp.array(dtype=Any),
    tolerance: Any,
    violations: wp.array(dtype=wp.int32),
    max_strain: wp.array(dtype=Any),
):
    """Count the springs longer than limit (1 + tolerance) into violations[0] and put the
    largest strain L / L0 - 1 into max_strain[0] (atomic max), moving nothing."""
    s = wp.tid()
    length = wp.length(x[pairs[s][1]] - x[pairs[s][0]])
    one = type(length)(1.0)
    wp.atomic_max(max_strain, 0, length * inv_rest[s] - one)
    if length > limit[s] * (one + tolerance):
        wp.atomic_add(violations, 0, 1)


@wp.kernel
def reset_strain_counters(violations: wp.array(dtype=wp.int32), max_strain: wp.array(dtype=Any), start: Any):
    """violations[0] = 0 and max_strain[0] = start (-1: below any strain), before a sweep."""
    violations[0] = 0
    max_strain[0] = start


register(globals(), start="scalar")

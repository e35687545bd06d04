"""Damped Hooke springs between particle pairs (the lecture's spring-damper)."""
from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.kernel
def spring_forces(
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    pairs: wp.array(dtype=wp.vec2i),
    stiffness: wp.array(dtype=Any),
    damping: wp.array(dtype=Any),
    rest_length: wp.array(dtype=Any),
    force: wp.array(dtype=Any),
):
    """Accumulate f = (-ks (L - L0) - kd (v2 - v1).d) d on p2 and -f on p1.

    d = (p2 - p1) / L is the unit vector from p1 to p2 and L the current length [m].
    The damper opposes the rate of change of length (see README on the lecture's
    sign). pairs: (p1, p2) particle indices; stiffness ks [N/m]; damping kd
    [N s/m]; rest_length L0 [m]; force: per-particle accumulator [N] (atomic adds).
    A spring of zero current length has no direction and exerts no force.
    """
    s = wp.tid()
    i = pairs[s][0]
    j = pairs[s][1]
    delta = x[j] - x[i]
    length = wp.length(delta)
    if length > type(length)(0.0):
        d = delta / length
        magnitude = -stiffness[s] * (length - rest_length[s]) - damping[s] * wp.dot(v[j] - v[i], d)
        f = magnitude * d
        wp.atomic_add(force, j, f)
        wp.atomic_sub(force, i, f)

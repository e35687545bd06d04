"""Damped Hooke springs between particle pairs (the lecture's spring-damper).

Public (``__all__``): spring_forces, the module's only kernel.
"""
from typing import Any

import warp as wp

from .precisions import register

__all__ = ["spring_forces"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.kernel
def spring_forces(
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    springs: Any,
    force: wp.array(dtype=Any),
):
    """Accumulate f = (-ks (L - L0) - kd (v2 - v1).d) d on p2 and -f on p1.

    d = (x[p2] - x[p1]) / L is the unit vector from p1 to p2 and L the current length [m].
    The damper opposes the rate of change of length (see README on the lecture's
    sign). Launch with dim = the number of springs; the forces are atomic adds into
    ``force`` (zero it first for the springs' force alone). A spring of zero current
    length has no direction and exerts no force.

    Args:
        x: particle positions (vec3) [m]
        v: particle velocities (vec3) [m/s]
        springs: per spring its particles pairs (p1, p2), stiffness ks, damping kd, rest_length L0 (Springs) [N/m]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    s = wp.tid()
    i = springs.pairs[s][0]
    j = springs.pairs[s][1]
    delta = x[j] - x[i]
    length = wp.length(delta)
    if length > type(length)(0.0):
        d = delta / length
        magnitude = -springs.stiffness[s] * (length - springs.rest_length[s]) - springs.damping[s] * wp.dot(
            v[j] - v[i], d)
        f = magnitude * d
        wp.atomic_add(force, j, f)
        wp.atomic_sub(force, i, f)


register(globals())

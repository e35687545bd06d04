"""The particle derivative: accelerations from gravity, linear drag, wind and accumulated forces.

Public (``__all__``): particle_acceleration, the module's only kernel. ``acceleration`` is its function, which the
fused step (kernels.fused) calls too.
"""
from typing import Any

import warp as wp

from .precisions import register

__all__ = ["particle_acceleration"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.func
def acceleration(v: Any, force: Any, forced: bool, w: Any, gravity: Any, drag: Any, wind: Any):
    """g + (force + drag (wind - v)) w [m/s^2] for a particle of velocity v [m/s] and inverse mass w [1/kg] (the
    force [N] only where ``forced``); zero when pinned (w 0)."""
    acc = type(gravity)()
    if w > type(drag)(0.0):
        f = drag * (wind - v)
        if forced:
            f = f + force
        acc = gravity + f * w
    return acc


@wp.kernel
def particle_acceleration(
    v: wp.array(dtype=Any),
    force: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    gravity: Any,
    drag: Any,
    wind: Any,
    dv: wp.array(dtype=Any),
):
    """dv[i] = g + (f[i] + drag (wind - v[i])) / m[i]; zero for pinned particles (inv_mass 0).

    Launch with dim = the number of particles.

    Args:
        v: particle velocities (vec3) [m/s]
        force: accumulated forces, or an empty array when no force term is present (vec3) [N]
        inv_mass: inverse masses 1/m, 0 for pinned [1/kg]
        gravity: the gravitational acceleration g (vec3) [m/s^2]
        drag: the linear drag coefficient, the same for every particle [N s/m]
        wind: the air's velocity (vec3) [m/s]
        dv: the accelerations, written (vec3) [m/s^2]
    """
    i = wp.tid()
    forced = force.shape[0] > 0
    fi = type(gravity)()
    if forced:
        fi = force[i]
    dv[i] = acceleration(v[i], fi, forced, inv_mass[i], gravity, drag, wind)


register(globals())

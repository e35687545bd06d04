"""The particle derivative: accelerations from gravity, linear drag, wind and accumulated forces."""
from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


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

    v: velocities [m/s]; force: accumulated forces [N], or an empty array when no
    force term is present; inv_mass: 1/m [1/kg]; gravity [m/s^2]; drag: linear drag
    coefficient [N s/m]; wind: air velocity [m/s]; dv: accelerations out [m/s^2].
    """
    i = wp.tid()
    w = inv_mass[i]
    acc = type(gravity)()
    if w > type(drag)(0.0):
        f = drag * (wind - v[i])
        if force.shape[0] > 0:
            f = f + force[i]
        acc = gravity + f * w
    dv[i] = acc

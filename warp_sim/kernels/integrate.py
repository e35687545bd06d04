"""Element-wise arithmetic on flat state buffers, the building blocks of the ODE solvers.

All arrays are 1-D arrays of one float scalar type (a State's flat buffer or a
slice of it); ``h`` is a step in seconds of that scalar type.
"""
from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.kernel
def axpy(y: wp.array(dtype=Any), h: Any, dy: wp.array(dtype=Any), out: wp.array(dtype=Any)):
    """out = y + h * dy (``out`` may alias ``y``)."""
    i = wp.tid()
    out[i] = y[i] + h * dy[i]


@wp.kernel
def rk4_combine(
    y: wp.array(dtype=Any),
    h: Any,
    k1: wp.array(dtype=Any),
    k2: wp.array(dtype=Any),
    k3: wp.array(dtype=Any),
    k4: wp.array(dtype=Any),
    out: wp.array(dtype=Any),
):
    """out = y + h/6 (k1 + 2 k2 + 2 k3 + k4), the classical Runge-Kutta update."""
    i = wp.tid()
    two = type(h)(2.0)
    out[i] = y[i] + h / type(h)(6.0) * (k1[i] + two * k2[i] + two * k3[i] + k4[i])


@wp.kernel
def copy(source: wp.array(dtype=Any), out: wp.array(dtype=Any)):
    """out = source, element-wise (a launch, so it can be recorded and replayed)."""
    i = wp.tid()
    out[i] = source[i]

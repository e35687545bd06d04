"""Element-wise arithmetic on flat state buffers, the building blocks of the ODE solvers.

All arrays are 1-D arrays of one element type: the solvers pass a State's flat buffer
(or a slice of it) of float scalars, but any element type of the precision works
(scalars, vec3, quat, mat33), as long as every array of a launch has the same one;
``h`` is a step in seconds, a scalar of that precision. In the argument lists u stands
for each element's own unit (m, m/s, kg m/s, ...).

Public (``__all__``): axpy, copy, rk4_combine.
Private: the Dormand-Prince kernels dp_stage3, dp_stage4, dp_stage5, dp_stage6, dp_solution and
dp_error_max, for the simulator's own use (the adaptive solver); their arguments may change
between releases.
"""
from typing import Any

import warp as wp

from .precisions import register

__all__ = ["axpy", "copy", "rk4_combine"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.kernel
def axpy(y: wp.array(dtype=Any), h: Any, dy: wp.array(dtype=Any), out: wp.array(dtype=Any)):
    """out = y + h * dy, element-wise (``out`` may alias ``y``): an explicit Euler stage. Launch with dim = len(y).

    Args:
        y: start values (elementwise) [u]
        h: the step [s]
        dy: rates of change of y (elementwise) [u/s]
        out: the result y + h dy (elementwise) [u]
    """
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
    """out = y + h/6 (k1 + 2 k2 + 2 k3 + k4), the classical Runge-Kutta update. Launch with dim = len(y).

    Args:
        y: values at the start of the step (elementwise) [u]
        h: the step [s]
        k1: the slope at the start (elementwise) [u/s]
        k2: the first midpoint slope (elementwise) [u/s]
        k3: the second midpoint slope (elementwise) [u/s]
        k4: the slope at the end (elementwise) [u/s]
        out: the result, may alias y (elementwise) [u]
    """
    i = wp.tid()
    two = type(h)(2.0)
    out[i] = y[i] + h / type(h)(6.0) * (k1[i] + two * k2[i] + two * k3[i] + k4[i])


@wp.kernel
def copy(source: wp.array(dtype=Any), out: wp.array(dtype=Any)):
    """out = source, element-wise (a launch, so it can be recorded and replayed). Launch with dim = len(source).

    Args:
        source: the values to copy (elementwise) [u]
        out: the copy, same length and element type (elementwise) [u]
    """
    i = wp.tid()
    out[i] = source[i]



# Dormand-Prince 5(4) (Hairer, Norsett and Wanner, Solving ODEs I, II.5): the stages of one trial step
# of size h from y, with the tableau's weights written out (as ratios computed in the state's precision).
# dp_stage<j> writes the input of stage j, y + h sum_i a_ji k_i; dp_solution the fifth-order solution.


@wp.func
def _ratio(h: Any, numerator: float, denominator: float):
    return type(h)(numerator) / type(h)(denominator)


@wp.kernel
def dp_stage3(y: wp.array(dtype=Any), h: Any, k1: wp.array(dtype=Any), k2: wp.array(dtype=Any),
              out: wp.array(dtype=Any)):
    """out = y + h (3/40 k1 + 9/40 k2). (Stage 2 is ``axpy`` with h / 5.)"""
    i = wp.tid()
    out[i] = y[i] + h * (_ratio(h, 3.0, 40.0) * k1[i] + _ratio(h, 9.0, 40.0) * k2[i])


@wp.kernel
def dp_stage4(y: wp.array(dtype=Any), h: Any, k1: wp.array(dtype=Any), k2: wp.array(dtype=Any),
              k3: wp.array(dtype=Any), out: wp.array(dtype=Any)):
    """out = y + h (44/45 k1 - 56/15 k2 + 32/9 k3)."""
    i = wp.tid()
    out[i] = y[i] + h * (_ratio(h, 44.0, 45.0) * k1[i] - _ratio(h, 56.0, 15.0) * k2[i]
                         + _ratio(h, 32.0, 9.0) * k3[i])


@wp.kernel
def dp_stage5(y: wp.array(dtype=Any), h: Any, k1: wp.array(dtype=Any), k2: wp.array(dtype=Any),
              k3: wp.array(dtype=Any), k4: wp.array(dtype=Any), out: wp.array(dtype=Any)):
    """out = y + h (19372/6561 k1 - 25360/2187 k2 + 64448/6561 k3 - 212/729 k4)."""
    i = wp.tid()
    out[i] = y[i] + h * (_ratio(h, 19372.0, 6561.0) * k1[i] - _ratio(h, 25360.0, 2187.0) * k2[i]
                         + _ratio(h, 64448.0, 6561.0) * k3[i] - _ratio(h, 212.0, 729.0) * k4[i])


@wp.kernel
def dp_stage6(y: wp.array(dtype=Any), h: Any, k1: wp.array(dtype=Any), k2: wp.array(dtype=Any),
              k3: wp.array(dtype=Any), k4: wp.array(dtype=Any), k5: wp.array(dtype=Any), out: wp.array(dtype=Any)):
    """out = y + h (9017/3168 k1 - 355/33 k2 + 46732/5247 k3 + 49/176 k4 - 5103/18656 k5)."""
    i = wp.tid()
    out[i] = y[i] + h * (_ratio(h, 9017.0, 3168.0) * k1[i] - _ratio(h, 355.0, 33.0) * k2[i]
                         + _ratio(h, 46732.0, 5247.0) * k3[i] + _ratio(h, 49.0, 176.0) * k4[i]
                         - _ratio(h, 5103.0, 18656.0) * k5[i])


@wp.kernel
def dp_solution(y: wp.array(dtype=Any), h: Any, k1: wp.array(dtype=Any), k3: wp.array(dtype=Any),
                k4: wp.array(dtype=Any), k5: wp.array(dtype=Any), k6: wp.array(dtype=Any), out: wp.array(dtype=Any)):
    """out = y + h (35/384 k1 + 500/1113 k3 + 125/192 k4 - 2187/6784 k5 + 11/84 k6), the fifth-order
    solution (also the input of stage 7: the slope there is the next step's first)."""
    i = wp.tid()
    out[i] = y[i] + h * (_ratio(h, 35.0, 384.0) * k1[i] + _ratio(h, 500.0, 1113.0) * k3[i]
                         + _ratio(h, 125.0, 192.0) * k4[i] - _ratio(h, 2187.0, 6784.0) * k5[i]
                         + _ratio(h, 11.0, 84.0) * k6[i])


@wp.kernel
def dp_error_max(
    y: wp.array(dtype=Any),
    y_new: wp.array(dtype=Any),
    h: Any,
    k1: wp.array(dtype=Any),
    k3: wp.array(dtype=Any),
    k4: wp.array(dtype=Any),
    k5: wp.array(dtype=Any),
    k6: wp.array(dtype=Any),
    k7: wp.array(dtype=Any),
    atol: Any,
    rtol: Any,
    err_max: wp.array(dtype=Any),
):
    """err_max[0] = max(err_max[0], max_i |d_i| / (atol + rtol max(|y_i|, |y_new_i|))): the scaled error
    of a Dormand-Prince step from y to y_new, d = y5 - y4 = h (71/57600 k1 - 71/16695 k3 + 71/1920 k4
    - 17253/339200 k5 + 22/525 k6 - 1/40 k7). A non-finite y_new or d counts as an infinite error.
    ``err_max`` (one element) must be zeroed before the launch.
    """
    i = wp.tid()
    d = h * (_ratio(h, 71.0, 57600.0) * k1[i] - _ratio(h, 71.0, 16695.0) * k3[i] + _ratio(h, 71.0, 1920.0) * k4[i]
             - _ratio(h, 17253.0, 339200.0) * k5[i] + _ratio(h, 22.0, 525.0) * k6[i]
             - _ratio(h, 1.0, 40.0) * k7[i])
    scale = atol + rtol * wp.max(wp.abs(y[i]), wp.abs(y_new[i]))
    e = wp.abs(d) / scale
    if not (wp.isfinite(e) and wp.isfinite(y_new[i])):
        e = type(h)(wp.inf)
    if e > err_max[0]:      # a plain read first: most threads skip the atomic
        wp.atomic_max(err_max, 0, e)


register(globals(), copy={"source": "vec3", "out": "vec3"})   # copy: positions from velocities

"""Detection of non-finite or runaway states, recorded on the device without a host sync.

Public (``__all__``): check_finite_and_bounded.
Private: check_bodies (the rigid-body guard) and the Warp function record_first_bad, for the
simulator's own use; their arguments may change between releases.
"""
from typing import Any

import warp as wp

from .precisions import register

__all__ = ["check_finite_and_bounded"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

REASON_POSITION = wp.constant(0)  # position not finite
REASON_VELOCITY = wp.constant(1)  # velocity not finite
REASON_SPEED = wp.constant(2)  # speed above the bound


@wp.struct
class GuardRecord:
    """One component's record: first_step[0], the first bad step; first_key[0], 4 * element + reason of that
    step's lowest bad element (both int32, starting at the int32 maximum 2147483647: none yet)."""

    first_step: wp.array(dtype=wp.int32)
    first_key: wp.array(dtype=wp.int32)


@wp.func
def record_first_bad(step: int, key: int, record: GuardRecord):
    """Record a bad element (key = 4 * element + reason) at step; the lowest step and key win."""
    wp.atomic_min(record.first_step, 0, step)
    wp.atomic_min(record.first_key, 0, key)


@wp.func
def check_element(i: int, xi: Any, vi: Any, max_speed: Any, step: int, record: GuardRecord):
    """check_finite_and_bounded for element i of position xi [m] and velocity vi [m/s] (the fused step calls it)."""
    if record.first_step[0] < step:
        return
    speed_squared = wp.dot(vi, vi)
    # one finiteness test on a sum: any NaN or infinity in x or v makes it non-finite
    total = xi[0] + xi[1] + xi[2] + speed_squared
    if wp.isfinite(total) and speed_squared <= max_speed * max_speed:
        return
    reason = REASON_SPEED
    if wp.isfinite(xi) and wp.isfinite(vi) and speed_squared <= max_speed * max_speed:
        return  # finite values whose sum overflowed: nothing wrong
    if not wp.isfinite(xi):
        reason = REASON_POSITION
    elif not wp.isfinite(vi):
        reason = REASON_VELOCITY
    record_first_bad(step, 4 * i + reason, record)


@wp.kernel
def check_finite_and_bounded(x: wp.array(dtype=Any), v: wp.array(dtype=Any), max_speed: Any, step: int,
                             record: GuardRecord):
    """Record the first step at which any element is bad, and its lowest bad element.

    An element is bad when its position or velocity is not finite or its speed exceeds
    max_speed. Once a step is recorded in first_step[0], later steps leave the record
    alone. first_key[0] holds 4 * element + reason (REASON_POSITION 0, REASON_VELOCITY 1,
    REASON_SPEED 2), minimised over the bad elements of that step. Both records start at
    the int32 maximum (2147483647): set them so before the first launch. Launch with
    dim = the number of elements.

    Args:
        x: positions (vec3) [m]
        v: velocities (vec3) [m/s]
        max_speed: the speed bound [m/s]
        step: the number of the step being checked [1]
        record: the first bad step and its lowest bad element's key (GuardRecord) [1]
    """
    i = wp.tid()
    check_element(i, x[i], v[i], max_speed, step, record)


@wp.kernel
def check_bodies(bodies: Any, mass: Any, max_speed: Any, step: int, record: GuardRecord):
    """The rigid-body form of check_finite_and_bounded: position means x and q, velocity
    means P and L, and the speed is |P| / M [m/s]."""
    i = wp.tid()
    if record.first_step[0] < step:
        return
    qi = bodies.q[i]
    v = bodies.P[i] * mass.inv_mass[i]
    speed_squared = wp.dot(v, v)
    # one finiteness test on a sum first (the common case); the detailed tests only for the bad
    xi = bodies.x[i]
    Li = bodies.L[i]
    total = xi[0] + xi[1] + xi[2] + qi[0] + qi[1] + qi[2] + qi[3] + Li[0] + Li[1] + Li[2] + speed_squared
    if wp.isfinite(total) and speed_squared <= max_speed * max_speed:
        return
    position_ok = wp.isfinite(xi) and wp.isfinite(qi)
    velocity_ok = wp.isfinite(bodies.P[i]) and wp.isfinite(Li)
    if position_ok and velocity_ok and speed_squared <= max_speed * max_speed:
        return
    reason = REASON_SPEED
    if not position_ok:
        reason = REASON_POSITION
    elif not velocity_ok:
        reason = REASON_VELOCITY
    record_first_bad(step, 4 * i + reason, record)


register(globals())

"""Detection of non-finite or runaway states, recorded on the device without a host sync."""
from typing import Any

import warp as wp

REASON_POSITION = wp.constant(0)  # position not finite
REASON_VELOCITY = wp.constant(1)  # velocity not finite
REASON_SPEED = wp.constant(2)  # speed above the bound


@wp.kernel
def check_finite_and_bounded(
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    max_speed: Any,
    step: int,
    first_step: wp.array(dtype=wp.int32),
    first_key: wp.array(dtype=wp.int32),
):
    """Record the first step at which any element is bad, and its lowest bad element.

    x: positions [m]; v: velocities [m/s]; max_speed [m/s]. Once a step is recorded
    in first_step[0], later steps leave the record alone. first_key[0] holds
    4 * element + reason (REASON_*), minimised over the bad elements of that step.
    Both records start at the int32 maximum.
    """
    i = wp.tid()
    if first_step[0] < step:
        return
    reason = int(-1)
    if not wp.isfinite(x[i]):
        reason = REASON_POSITION
    elif not wp.isfinite(v[i]):
        reason = REASON_VELOCITY
    elif wp.length(v[i]) > max_speed:
        reason = REASON_SPEED
    if reason >= 0:
        wp.atomic_min(first_step, 0, step)
        wp.atomic_min(first_key, 0, 4 * i + reason)

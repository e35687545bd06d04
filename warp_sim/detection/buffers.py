"""Growable device buffers of candidate pairs and contacts: no contact is ever dropped."""
from __future__ import annotations

import math

import warp as wp

from ..kernels import detection as detection_kernels

#: a captured step's launches over what can grow: the count last seen uncaptured times HEADROOM, or plus SPARE
#: threads, whichever is more. A thread past the count exits at once (about 1 ns on the CPU), while a step whose
#: counts outgrow its launches is done again uncaptured, and graphs recorded afresh cost some 40 ms on the CPU
HEADROOM, SPARE = 1.25, 8


def launch_threads(count: int, capacity: int | None = None) -> int:
    """Threads a captured launch runs for ``count`` items seen last (HEADROOM, SPARE), at most ``capacity``."""
    threads = max(math.ceil(count * HEADROOM), count + SPARE)
    return threads if capacity is None else min(threads, capacity)


class GrowableBuffer:
    """A growable device buffer of pairs or contacts (a kernels.detection.ContactBuffer).

    capacity: entries allocated; count: a device int32 the kernels fill; grows: how often it grew
    buffer: the ContactBuffer struct (ids, and with points normal, point1 [m], point2 [m], radius1 [m],
        radius2 [m], pair: the candidate pair of each contact)
    """

    def __init__(self, device, capacity: int, with_points: bool):
        self.device = device
        self.with_points = with_points
        self.count = wp.zeros(1, dtype=wp.int32, device=device)
        self.grows = 0
        self._allocate(capacity)

    def _allocate(self, capacity: int) -> None:
        self.capacity = capacity
        b = detection_kernels.ContactBuffer()
        b.count = self.count
        b.ids = wp.empty(capacity, dtype=wp.vec2i, device=self.device)
        size = capacity if self.with_points else 0
        b.normal = wp.empty(size, dtype=wp.vec3f, device=self.device)
        b.point1 = wp.empty(size, dtype=wp.vec3f, device=self.device)
        b.point2 = wp.empty(size, dtype=wp.vec3f, device=self.device)
        b.radius1 = wp.empty(size, dtype=wp.float32, device=self.device)
        b.radius2 = wp.empty(size, dtype=wp.float32, device=self.device)
        b.pair = wp.empty(size, dtype=wp.int32, device=self.device)
        self.buffer = b

    def fill(self, launch, capturing: bool = False) -> int | None:
        """Run ``launch(buffer)``; if it wrote more than fits, grow to fit and run it again. Returns the count.
        While a step is captured (``capturing``) nothing is read back: it launches once and returns None, and the
        step's gate (kernels.manifolds.gate_response) sees a count over the launches' threads after the replay."""
        if capturing:
            self.count.zero_()
            launch(self.buffer)
            return None
        while True:
            self.count.zero_()
            launch(self.buffer)
            count = int(self.count.numpy()[0])
            if count <= self.capacity:
                return count
            self.grows += 1
            self._allocate(max(2 * self.capacity, count + count // 4))

    @property
    def nbytes(self) -> int:
        b = self.buffer
        return sum(a.capacity for a in (b.ids, b.normal, b.point1, b.point2, b.radius1, b.radius2, b.pair))

"""Recorded kernel launches: resolve a kernel's overload and pack its arguments once.

A simulator launches the same kernels on the same arrays every step (its two
states alternate), so each distinct (kernel, arrays and structs) launch is recorded once
with Warp's ``record_cmd`` and replayed, with only its scalar arguments (a step size,
a step index) set again. Arrays and struct arguments (kernels.blocks) are keyed by
identity: a struct must not have its fields reassigned after its first launch (make a
new one instead, as the growable contact buffers do). On the CPU this cuts the host cost of a launch about
twentyfold, which is what small scenes are bound by.
"""
from __future__ import annotations

import warp as wp


def _referenced(argument) -> bool:
    """Whether a launch argument is passed by reference (an array, or a struct of arrays), not by value."""
    return isinstance(argument, wp.array) or hasattr(getattr(argument, "_cls", None), "vars")


class Launcher:
    """Launch kernels on one device through a cache of recorded launches.

    The cache keeps the arrays it was recorded with alive, so a cached launch never
    points at freed memory; it lives as long as the owner (one per Model). A caller
    that passes new arrays on every call would fill it: past ``capacity`` entries it
    starts afresh, so memory stays bounded (and such calls cost a normal launch).
    """

    capacity = 512

    def __init__(self, device):
        self.device = device
        self._recorded: dict[tuple, tuple] = {}

    def launch(self, kernel, dim: int, inputs: list) -> None:
        """Run ``kernel`` over ``dim`` threads with ``inputs`` (arrays and scalars)."""
        if dim == 0:
            return
        key = (kernel, dim) + tuple(id(a) if _referenced(a) else None for a in inputs)
        entry = self._recorded.get(key)
        if entry is None:
            if len(self._recorded) >= self.capacity:
                self._recorded.clear()
            command = wp.launch(kernel, dim=dim, inputs=inputs, device=self.device, record_cmd=True)
            scalars = [i for i, a in enumerate(inputs) if not _referenced(a)]
            entry = (command, scalars, inputs)
            self._recorded[key] = entry
        else:
            command, scalars, _ = entry
            for i in scalars:
                command.set_param_at_index(i, inputs[i])
        command.launch()

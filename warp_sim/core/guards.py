"""Divergence guards: non-finite or runaway states stop the run with SimulationDiverged.

The check runs on the device after every step and records the first bad step and
element without a host synchronisation; the host reads the record when asked
(every ``step()`` call, every frame of ``run()``), so the error names the exact
step even when read a frame later.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import guards as guard_kernels

NO_RECORD = np.iinfo(np.int32).max


class SimulationDiverged(RuntimeError):
    """A simulation went non-finite or exceeded its bounds.

    Attributes: step (1-based index of the first bad step), time [s] at its end,
    component (e.g. "particles"), element (global index within the component), where (the element
    by its group and local index, or its body name), reason; frames_written and usd: set by
    ``Simulator.run`` when it kept the frames before the bad one.
    """

    def __init__(self, step: int, time: float, component: str, element: int, reason: str, detail: str = "",
                 where: str = ""):
        self.step, self.time, self.component, self.element, self.reason = step, time, component, element, reason
        self.where = where
        self.frames_written, self.usd = 0, None
        located = f" ({where})" if where else ""
        super().__init__(f"simulation diverged at step {step} (t = {time:.6g} s): {component} element "
                         f"{element}{located}: {reason}{detail}")


class Guard:
    """Per-component device records of the first bad step, with the host-side check."""

    kernels = ("guards",)

    def __init__(self, model, components, max_speed: float):
        self.components = list(components)
        self.max_speed = max_speed
        self._max_speed = model.scalar(max_speed)
        self.launch = model.launcher.off_tape   # no tape records the checks
        self.records = [guard_kernels.GuardRecord() for _ in self.components]
        for record in self.records:
            record.first_step = wp.full(1, NO_RECORD, dtype=wp.int32, device=model.device)
            record.first_key = wp.full(1, NO_RECORD, dtype=wp.int32, device=model.device)
        self.step_times: dict[int, float] = {}   # end time of each step since the last check

    max_unchecked_steps = 1 << 20

    def record(self, state, step: int, time: float, folded=()) -> None:
        """Launch the checks for the state after ``step`` (ending at ``time``); no sync. ``folded``: the names of
        the components whose check a fused step made already (solvers.fused)."""
        if len(self.step_times) >= self.max_unchecked_steps:   # never checked: keep memory bounded
            self.step_times.clear()
        self.step_times[step] = time
        for component, record in zip(self.components, self.records):
            if component.name not in folded:
                kernel, count, inputs = component.guard_inputs(state)
                self.launch(kernel, count, [*inputs, self._max_speed, step, record])

    def record_of(self, name: str):
        """The device record (kernels.guards.GuardRecord) of the component named ``name``, and the bound."""
        return self.records[[c.name for c in self.components].index(name)], self._max_speed

    def raise_if_diverged(self, state) -> None:
        """Read the records (a device sync) and raise SimulationDiverged for the earliest bad step."""
        found = []
        for component, record in zip(self.components, self.records):
            step = int(record.first_step.numpy()[0])
            if step != NO_RECORD:
                found.append((step, component, int(record.first_key.numpy()[0])))
        if not found:
            self.step_times.clear()
            return
        step, component, key = min(found, key=lambda item: item[0])
        element, reason = divmod(key, 4)
        detail = f" (now {component.describe(state, element)})"
        text = component.guard_reasons[reason] + (f" = {self.max_speed:g} m/s" if reason == 2 else "")
        raise SimulationDiverged(step, self.step_times.get(step, float("nan")), component.name, element,
                                 text, detail, component.locate(element))

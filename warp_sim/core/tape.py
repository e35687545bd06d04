"""The differentiable mode's launcher: every launch through ``wp.launch``, so that an active ``wp.Tape`` records it.

The forward launcher (core.launcher) replays recorded launches by calling compiled entry points, which no tape
sees; a differentiable Simulator's Model launches through ``TapedLauncher`` instead (``Model.make_differentiable``).
Two launches need more than ``wp.launch``:

- the guard's checks stay off the tape (``off_tape``): they have no adjoint and change nothing the loss reads;
- a kernel that overwrites one of its inputs in place (the renormalisation of the orientations) would have its
  adjoint replay it on its own results: ``launch_in_place`` records, around it, the restoring of what it read
  (before its adjoint runs) and of what it wrote (after), as functions on the tape.

Warp's adjoint of an array store takes the element's gradient and zeroes it (``retain_grad`` aside), so a kernel
that writes each element once, and reads it before, gets the right gradient in place; what it must not meet is a
value overwritten after it was read, which the differentiable mode avoids with fresh states and accumulators.
"""
from __future__ import annotations

import warp as wp

from .launcher import Launcher


def active_tape():
    """The ``wp.Tape`` recording now, or None (Warp 1.19 keeps it on its runtime)."""
    runtime = getattr(getattr(getattr(wp, "_src", None), "context", None), "runtime", None)
    return getattr(runtime, "tape", None)


class TapedPrepared:
    """``Launcher.prepare``'s object for the taped launcher: the same ``set``, ``run`` and ``run_pieces``, each run a
    ``wp.launch`` of the current inputs (nothing replayed)."""

    def __init__(self, launcher: "TapedLauncher", kernel, inputs: list):
        self.launcher, self.kernel, self.inputs = launcher, kernel, list(inputs)

    def set(self, i: int, value) -> None:
        """Input i is ``value`` from the next run on."""
        self.inputs[i] = value

    def run(self, dim: int) -> None:
        """Launch over ``dim`` threads."""
        self.launcher.launch(self.kernel, dim, self.inputs)

    def run_pieces(self, dim: int, base: int, pieces: int) -> None:
        """One piece: input ``base`` (a piece's first thread) 0, ``dim`` threads (a tape records one launch)."""
        self.set(base, 0)
        self.run(dim)


class TapedLauncher(Launcher):
    """A Launcher whose every launch is a ``wp.launch`` (recorded by an active ``wp.Tape``), none recorded for
    replay, none split into pieces; ``launches`` counts them as the forward launcher does."""

    def launch(self, kernel, dim: int, inputs: list) -> None:
        """Run ``kernel`` over ``dim`` threads with ``inputs`` through ``wp.launch``."""
        if dim == 0:
            return
        self.launches += 1
        wp.launch(kernel, dim=dim, inputs=inputs, device=self.device)

    def launch_elementwise(self, kernel, dim: int, inputs: list) -> None:
        """launch(): one launch over every element."""
        self.launch(kernel, dim, inputs)

    def prepare(self, kernel, dim: int, inputs: list) -> TapedPrepared:
        """A TapedPrepared of ``kernel`` on ``inputs``."""
        return TapedPrepared(self, kernel, inputs)

    def off_tape(self, kernel, dim: int, inputs: list) -> None:
        """launch() that no tape records (the guard's checks)."""
        if dim:
            wp.launch(kernel, dim=dim, inputs=inputs, device=self.device, record_tape=False)

    def launch_in_place(self, kernel, dim: int, inputs: list, written: wp.array) -> None:
        """launch() of a kernel that reads ``written`` (an array with a gradient among ``inputs``) and overwrites it,
        element by element. On a tape, the values it read are put back into ``written`` just before its adjoint
        replays it, and the values it wrote just after, so that adjoint, and those of the launches before it, see
        what they saw going forward."""
        tape = active_tape()
        if tape is None or dim == 0:
            self.launch(kernel, dim, inputs)
            return
        read = wp.clone(written, requires_grad=False)
        wrote = wp.empty_like(written, requires_grad=False)
        tape.record_func(lambda: wp.copy(written, wrote), [written])   # runs after the kernel's adjoint
        self.launch(kernel, dim, inputs)
        wp.copy(wrote, written)
        tape.record_func(lambda: wp.copy(written, read), [written])    # runs before it

"""The differentiable mode's launcher: every launch through ``wp.launch``, so that an active ``wp.Tape`` records it.

The forward launcher (core.launcher) replays recorded launches by calling compiled entry points, which no tape
sees; a differentiable Simulator's Model launches through ``TapedLauncher`` instead (``Model.make_differentiable``).
Three kinds of launch need more than ``wp.launch``:

- the guard's checks stay off the tape (``off_tape``): they have no adjoint and change nothing the loss reads;
- a kernel that overwrites one of its inputs in place (the renormalisation of the orientations, the plane impacts,
  each colour of the strain limiter's sweeps) would have its adjoint replay it on its own results:
  ``launch_in_place`` records after it the restoring of what it read, a function on the tape that runs just
  before its adjoint (and, at the tape's start, the restoring of what was written last, for after the backward);
- a part whose adjoint is written by hand (implicit Euler's linear solve) runs ``paused``, off the tape, and
  records that adjoint with ``tape.record_func``.

Warp's adjoint of an array store takes the element's gradient and zeroes it (``retain_grad`` aside), so a kernel
that writes each element once, and reads it before, gets the right gradient in place; what it must not meet is a
value overwritten after it was read, which the differentiable mode avoids with fresh states and accumulators.
"""
from __future__ import annotations

from contextlib import contextmanager
from functools import partial

import warp as wp

from .launcher import Launcher


def _runtime():
    return getattr(getattr(getattr(wp, "_src", None), "context", None), "runtime", None)


def active_tape():
    """The ``wp.Tape`` recording now, or None (Warp 1.19 keeps it on its runtime)."""
    return getattr(_runtime(), "tape", None)


@contextmanager
def paused():
    """Launches inside record on no tape; yields the tape that was recording (or None), which records again after.
    For a part whose adjoint is recorded by hand (``tape.record_func``: implicit Euler's linear solve)."""
    runtime, tape = _runtime(), active_tape()
    if tape is not None:
        runtime.tape = None
    try:
        yield tape
    finally:
        if tape is not None:
            runtime.tape = tape


def copies(*arrays) -> list:
    """A copy of each array, on the tape where one records (its adjoint adds the copy's gradient into the
    original's): the outputs of an update that writes some elements of its inputs and leaves the rest."""
    return [wp.clone(array, requires_grad=True) for array in arrays]


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

    def launch_in_place(self, kernel, dim: int, inputs: list, written) -> None:
        """launch() of a kernel that reads ``written`` (an array among ``inputs``, or a list of them) and overwrites
        it, element by element. On a tape, the values it read are put back into ``written`` just before its adjoint
        replays it; a replay stores nothing, so they stay there for the adjoints of the launches before it, which
        saw them going forward. When the tape's whole backward is done, ``written`` holds what the forward left in
        it again (``_restore_at_end``)."""
        tape = active_tape()
        if tape is None or dim == 0:
            self.launch(kernel, dim, inputs)
            return
        arrays = list(written) if isinstance(written, (list, tuple)) else [written]
        read = [wp.clone(array, requires_grad=False) for array in arrays]
        self.launch(kernel, dim, inputs)
        tape.record_func(lambda: _copy_all(arrays, read), arrays)    # runs just before its adjoint
        _restore_at_end(tape, arrays)


def _copy_all(destinations: list, sources: list) -> None:
    for destination, source in zip(destinations, sources):
        wp.copy(destination, source)


def _put_back(final: dict) -> None:
    for array, values in final.values():
        wp.copy(array, values)


def _restore_at_end(tape, arrays: list) -> None:
    """Keep a copy of each of ``arrays`` as written now, the latest per array (an earlier one is dropped), for a
    function at the start of ``tape``, the last its backward runs, which puts them back in the order written."""
    held = getattr(tape, "_warp_sim_written", None)
    if held is None or not tape.launches or tape.launches[0] is not held[0]:
        final = {}
        restore = partial(_put_back, final)
        tape.launches.insert(0, restore)
        held = tape._warp_sim_written = (restore, final)
    final = held[1]
    for array in arrays:
        key = (array.ptr, array.shape, array.strides)
        final.pop(key, None)
        final[key] = (array, wp.clone(array, requires_grad=False))

"""The trajectory a loss reads: the state at every frame, as (frames + 1, count) Warp arrays, which are also the
checkpoints' stored states (gradients.checkpoints: no second copy), with gradients only for what the loss reads."""
from __future__ import annotations

import warp as wp

from ..core.model import Model
from ..core.state import State

#: the fields a trajectory holds, with their component's count on the model and their element kind
FIELDS = (("particle_x", "particle_count", "vec3"), ("particle_v", "particle_count", "vec3"),
          ("body_x", "body_count", "vec3"), ("body_q", "body_count", "quat"))


def values_of(array: wp.array) -> wp.array:
    """The same memory as ``array``, without its gradient (copies through it move values only)."""
    alias = wp.array(ptr=array.ptr, shape=array.shape, dtype=array.dtype, device=array.device)
    alias._owner_ref = array   # keeps the memory alive as long as the alias
    return alias


def _span(array: wp.array) -> tuple[int, int]:
    """The bytes [first, last) an array's elements lie in (a view's too)."""
    if array.size == 0:
        return array.ptr, array.ptr
    last = array.ptr + sum((n - 1) * s for n, s in zip(array.shape, array.strides))
    return array.ptr, last + wp.types.type_size_in_bytes(array.dtype)


class Trajectory:
    """The states of a run at its frames, row k the state at t = k / fps (row 0: the initial state).

    particle_x [m], particle_v [m/s]: (frames + 1, particles) of the model's vec3 (wp.vec3d in float64)
    body_x [m] (centres of mass): (frames + 1, bodies) of vec3; body_q: (frames + 1, bodies) of quat (x, y, z, w)
    frames: the frames after the initial state; fps [1/s]
    tracked: the names of the fields with a gradient (``.grad``): ``track`` gives them one, by default none; a
    loss computed from them by Warp kernels on a wp.Tape sends its adjoint into those. A component the scene lacks
    has arrays of zero columns.
    """

    def __init__(self, model: Model, frames: int, fps: float):
        self.frames, self.fps = frames, fps
        kinds = {"vec3": model.vec3, "quat": model.quat}
        self._present = [name for name, count, _ in FIELDS if getattr(model, count)]
        for name, count, kind in FIELDS:
            setattr(self, name, wp.zeros((frames + 1, getattr(model, count)), dtype=kinds[kind], device=model.device))
        self._values = {name: values_of(getattr(self, name)) for name in self._present}
        self.tracked: list[str] = []

    def store(self, frame: int, state: State) -> None:
        """Copy ``state``'s fields into row ``frame`` (values only)."""
        for name, values in self._values.items():
            wp.copy(values[frame], getattr(state, name))

    def restore(self, frame: int, state: State) -> None:
        """Copy row ``frame`` into ``state``'s fields (values only: no gradient moves with them)."""
        for name, values in self._values.items():
            wp.copy(getattr(state, name), values[frame])

    def read_by(self, tape: wp.Tape) -> list[str]:
        """The fields whose memory a launch or function on ``tape`` reads or writes (whole, a row or any view)."""
        arrays = [a for launch in tape.launches if not callable(launch) for group in launch[3:5] for a in group
                  if isinstance(a, wp.array)] + [a for a in tape.gradients if isinstance(a, wp.array)]
        spans = [_span(a) for a in arrays]
        read = []
        for name in self._present:
            first, last = _span(getattr(self, name))
            if any(start < last and end > first for start, end in spans):
                read.append(name)
        return read

    def track(self, names) -> None:
        """Give the fields ``names`` zeroed gradients and every other field none (the memory of a gradient only for
        what the loss reads); ``names`` empty or None: none."""
        self.tracked = [name for name in self._present if name in (names or ())]
        for name in self._present:
            array = getattr(self, name)
            array.requires_grad = False           # drops a probe's gradient
            array.requires_grad = name in self.tracked   # a new zeroed one

    def probe(self) -> None:
        """Give every field a gradient that is allocated but not written (its pages not touched), for a loss's
        trial call on a tape that ``read_by`` then inspects."""
        for name in self._present:
            array = getattr(self, name)
            array.grad = wp.empty_like(array, requires_grad=False)
        self.tracked = list(self._present)

    def watch(self, state: State, frame: int) -> list:
        """While a frame's tape records: a copy of each of ``state``'s tracked fields into an array of its own, whose
        gradient ``seed`` sets to row ``frame`` of this trajectory's gradient; the tape's backward then adds that row
        into ``state``'s gradient. Returns the (copy, row) pairs for ``seed``."""
        pairs = []
        for name in self.tracked:
            field = getattr(state, name)
            sink = wp.empty(field.shape[0], dtype=field.dtype, device=field.device, requires_grad=True)
            wp.copy(sink, field)
            pairs.append((sink, getattr(self, name).grad[frame]))
        return pairs

    @staticmethod
    def seed(pairs: list) -> None:
        """After the tape of ``watch``'s copies stopped recording: their gradients the trajectory's rows."""
        for sink, row in pairs:
            wp.copy(sink.grad, row)

"""The trajectory a loss reads: the state at every frame, as (frames + 1, count) Warp arrays with gradients."""
from __future__ import annotations

import warp as wp

from ..core.model import Model
from ..core.state import State

#: the fields a trajectory holds, with their component's count on the model and their element kind
FIELDS = (("particle_x", "particle_count", "vec3"), ("particle_v", "particle_count", "vec3"),
          ("body_x", "body_count", "vec3"), ("body_q", "body_count", "quat"))


class Trajectory:
    """The states of a run at its frames, row k the state at t = k / fps (row 0: the initial state).

    particle_x [m], particle_v [m/s]: (frames + 1, particles) of the model's vec3 (wp.vec3d in float64)
    body_x [m] (centres of mass): (frames + 1, bodies) of vec3; body_q: (frames + 1, bodies) of quat (x, y, z, w)
    frames: the frames after the initial state; fps [1/s]

    Every array has a gradient (``.grad``): a loss computed from them by Warp kernels on a wp.Tape sends its adjoint
    into them. A component the scene lacks has arrays of zero columns.
    """

    def __init__(self, model: Model, frames: int, fps: float):
        self.frames, self.fps = frames, fps
        kinds = {"vec3": model.vec3, "quat": model.quat}
        self._fields = [(name, kinds[kind]) for name, count, kind in FIELDS if getattr(model, count)]
        for name, count, kind in FIELDS:
            setattr(self, name, wp.zeros((frames + 1, getattr(model, count)), dtype=kinds[kind], device=model.device,
                                         requires_grad=True))

    def store(self, frame: int, state: State) -> None:
        """Copy ``state``'s fields into row ``frame``, going forward (no tape records; the gradients copied with
        them are zeros then)."""
        for name, _ in self._fields:
            wp.copy(getattr(self, name)[frame], getattr(state, name))

    def watch(self, state: State, frame: int) -> list:
        """While a frame's tape records: a copy of each of ``state``'s fields into an array of its own, whose gradient
        ``seed`` sets to row ``frame`` of this trajectory's gradient; the tape's backward then adds that row into
        ``state``'s gradient. Returns the (copy, row) pairs for ``seed``."""
        pairs = []
        for name, dtype in self._fields:
            field = getattr(state, name)
            sink = wp.empty(field.shape[0], dtype=dtype, device=field.device, requires_grad=True)
            wp.copy(sink, field)
            pairs.append((sink, getattr(self, name).grad[frame]))
        return pairs

    @staticmethod
    def seed(pairs: list) -> None:
        """After the tape of ``watch``'s copies stopped recording: their gradients the trajectory's rows."""
        for sink, row in pairs:
            wp.copy(sink.grad, row)

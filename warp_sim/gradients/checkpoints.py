"""A differentiable run checkpointed per frame: the state stored at every frame, each frame's substeps recomputed
on a tape of its own in the backward pass, so memory follows the frames, not the substeps.

Going forward nothing is recorded: frame by frame the Simulator steps, and its state (the flat buffer, every
field) is copied into row k of ``states``. Going back, from the last frame to the first, frame k is stepped again
from a copy of row k - 1 while a new wp.Tape records it; the tape's backward takes the adjoint of its last state
(the first state's of frame k + 1, plus the loss's adjoint of trajectory row k) to its first state's, adding into
the gradients of the model's arrays and the controls on the way; then the tape and every state of the frame are
dropped. Peak memory: the stored states (frames + 1 of them), the trajectory with its gradient, and one frame's
tape (its substeps' states and scratch states, with their gradients).
"""
from __future__ import annotations

import warp as wp

from ..core.state import State
from .controls import Controls
from .trajectory import Trajectory


class Checkpoints:
    """The run of ``frames`` frames of 1 / fps seconds, ``substeps`` steps each, of a differentiable Simulator.

    states: the stored states, (frames + 1, state size) of the model's scalar, row k the flat state at frame k
    times: the simulator's time at each frame [s] (what a recomputed frame starts from)
    count: the number of stored states (frames + 1)
    """

    def __init__(self, sim, frames: int, fps: float, substeps: int, controls: Controls):
        self.sim, self.frames, self.fps, self.substeps, self.controls = sim, frames, fps, substeps, controls
        self.states = wp.zeros((frames + 1, sim.dynamics.layout.size), dtype=sim.model.scalar, device=sim.device)
        self.times = [0.0] * (frames + 1)

    @property
    def count(self) -> int:
        return self.states.shape[0]

    def _store(self, frame: int, traj: Trajectory) -> None:
        state = self.sim.state
        wp.copy(self.states[frame], state.y)   # no gradient: a row holds values only
        self.times[frame] = self.sim.time
        traj.store(frame, state)

    def _step(self, frame: int) -> None:
        """Frame ``frame`` (1 to frames): the controls of the interval before it held, a step of 1 / fps seconds in
        ``substeps`` equal pieces (``Simulator.step(1 / fps, substeps=substeps)``)."""
        self.controls.apply(self.sim, frame - 1)
        self.sim.step(1.0 / self.fps, substeps=self.substeps)

    def forward(self, traj: Trajectory) -> None:
        """Run every frame from the simulator's state, storing it (and recording it into ``traj``) at each."""
        self._store(0, traj)
        for frame in range(1, self.frames + 1):
            self._step(frame)
            self._store(frame, traj)

    def restore(self, frame: int) -> State:
        """A new State (with a gradient) holding stored frame ``frame``; the simulator starts from it, at its time."""
        state = self.sim.dynamics.new_state()
        wp.copy(state.y, self.states[frame])
        self.sim.state, self.sim.time = state, self.times[frame]
        return state

    def backward(self, traj: Trajectory, on_frame=None) -> State:
        """The backward pass, after the loss's adjoint reached ``traj``'s gradient: the frames from the last, each
        recomputed on its own tape. Returns frame 0's state, whose gradient is d loss / d (initial state); the
        model's arrays and the controls hold theirs. ``on_frame(frame, tape)``, if given, is called after each
        frame's backward, before its tape is dropped (for inspection)."""
        carry = None   # d loss / d (state at the frame's end), from the frames after it
        for frame in range(self.frames, 0, -1):
            start = self.restore(frame - 1)
            with wp.Tape() as tape:
                watched = traj.watch(start, 0) if frame == 1 else []
                self._step(frame)
                end = self.sim.state
                watched += traj.watch(end, frame)
            traj.seed(watched)
            tape.backward(grads=None if carry is None else {end.y: carry})
            carry = start.y.grad
            if on_frame is not None:
                on_frame(frame, tape)
            del tape, end, watched
        return start

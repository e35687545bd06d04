"""A differentiable run checkpointed per frame: the state stored at every frame, each frame's substeps recomputed
on a tape of its own in the backward pass, so memory follows the frames, not the substeps.

The stored states are the trajectory's arrays (gradients.trajectory: particle_x, particle_v, body_x, body_q, row
k at frame k) and, for the rest of the state (the bodies' momenta), arrays of the same form here: one copy of
each state, which the loss reads as it is. Going forward nothing is recorded: frame by frame the Simulator steps
and its state is copied into row k. Going back, from the last frame to the first, frame k is stepped again from
row k - 1 while a new wp.Tape records it; the tape's backward takes the adjoint of its last state (the first
state's of frame k + 1, plus the loss's adjoint of the tracked trajectory rows k) to its first state's, adding
into the gradients of the model's arrays and the controls on the way; then the tape is dropped. Every state a
frame makes (its steps' ends, the solver's stages) comes from one frame's pool (gradients.pool), reused frame
after frame, forward and back. Peak memory: the stored states (frames + 1 of them), the gradients of the fields
the loss reads, and one frame's pool and tape (its states with their gradients, accumulators, copies).

What a pass carries from step to step outside the state on the tape (``Pass.carried``: the joints' impulses,
which warm-start the next step) is stored at each frame too, a recomputed frame starts from it (``Pass.carry``),
and its adjoint is carried from frame to frame with the state's.
"""
from __future__ import annotations

import warp as wp

from ..core.state import State
from .controls import Controls
from .pool import StatePool
from .trajectory import FIELDS, Trajectory, values_of


class Checkpoints:
    """The run of ``frames`` frames of 1 / fps seconds, ``substeps`` steps each, of a differentiable Simulator.

    rest: the stored rows of the state's fields a trajectory does not hold (body_P, body_L): name -> (frames + 1,
    count) array; times: the simulator's time at each frame [s] (what a recomputed frame starts from)
    count: the number of stored states (frames + 1); stored_bytes: their size, trajectory rows included [bytes]
    pool: the frame's scratch states (gradients.pool.StatePool)
    """

    def __init__(self, sim, frames: int, fps: float, substeps: int, controls: Controls):
        self.sim, self.frames, self.fps, self.substeps, self.controls = sim, frames, fps, substeps, controls
        held = {name for name, _, _ in FIELDS}
        self.rest = {}
        for field in sim.dynamics.layout.fields:
            if field.name not in held:
                like = getattr(sim.state, field.name)
                self.rest[field.name] = values_of(wp.zeros((frames + 1, field.count), dtype=like.dtype,
                                                           device=sim.device))
        self.times = [0.0] * (frames + 1)
        self.carried = [[] for _ in range(frames + 1)]   # per frame, copies of the passes' carried arrays
        self.pool = StatePool(sim.dynamics)
        self._start = None   # the state a forward frame starts from (not the pool's: the pool is reused)

    @property
    def count(self) -> int:
        return self.frames + 1

    @property
    def stored_bytes(self) -> int:
        return self.count * self.sim.dynamics.layout.size * wp.types.type_size_in_bytes(self.sim.model.scalar)

    def _store(self, frame: int, traj: Trajectory) -> None:
        state = self.sim.state
        traj.store(frame, state)
        for name, rows in self.rest.items():
            wp.copy(rows[frame], getattr(state, name))
        self.times[frame] = self.sim.time
        self.carried[frame] = [wp.clone(array, requires_grad=False) for array in self._carried()]

    def _carried(self) -> list:
        """What the simulator's passes carry to the next step now (Pass.carried), in pass order."""
        return [array for part in self.sim.passes for array in part.carried()]

    def _carry(self, arrays: list) -> None:
        """Each pass starts its next step from its share of ``arrays`` (as _carried() lists them)."""
        for part in self.sim.passes:
            count = len(part.carried())
            if count:
                part.carry(arrays[:count])
                arrays = arrays[count:]

    def _step(self, frame: int) -> None:
        """Frame ``frame`` (1 to frames): the controls of the interval before it held, a step of 1 / fps seconds in
        ``substeps`` equal pieces (``Simulator.step(1 / fps, substeps=substeps)``), its states from the pool."""
        self.controls.apply(self.sim, frame - 1)
        with self.pool:
            self.sim.step(1.0 / self.fps, substeps=self.substeps)

    def forward(self, traj: Trajectory) -> None:
        """Run every frame from the simulator's state, storing it into ``traj`` (and ``rest``) at each."""
        self._start = self.sim.dynamics.fresh_state()
        self._store(0, traj)
        for frame in range(1, self.frames + 1):
            if self.sim.state is not self._start:   # a pooled state of the frame before: the pool reuses it
                wp.copy(self._start.y, self.sim.state.y)
                self.sim.state = self._start
            self._step(frame)
            self._store(frame, traj)

    def restore(self, frame: int, traj: Trajectory) -> State:
        """A new State (with a gradient) holding stored frame ``frame``; the simulator starts from it, at its time."""
        state = self.sim.dynamics.fresh_state()
        traj.restore(frame, state)
        for name, rows in self.rest.items():
            wp.copy(getattr(state, name), rows[frame])
        self.sim.state, self.sim.time = state, self.times[frame]
        self._carry([wp.clone(array, requires_grad=True) for array in self.carried[frame]])
        return state

    def backward(self, traj: Trajectory, on_frame=None) -> State:
        """The backward pass, after the loss's adjoint reached ``traj``'s gradient: the frames from the last, each
        recomputed on its own tape. Returns frame 0's state, whose gradient is d loss / d (initial state); the
        model's arrays and the controls hold theirs. ``on_frame(frame, tape)``, if given, is called after each
        frame's backward, before its tape is dropped (for inspection)."""
        carry = None   # d loss / d (state at the frame's end), from the frames after it
        carried = []   # d loss / d (what the passes carried at the frame's end), likewise
        for frame in range(self.frames, 0, -1):
            start = self.restore(frame - 1, traj)
            first = self._carried()
            with wp.Tape() as tape:
                watched = traj.watch(start, 0) if frame == 1 else []
                self._step(frame)
                end = self.sim.state
                watched += traj.watch(end, frame)
            traj.seed(watched)
            grads = {} if carry is None else {end.y: carry}
            grads.update(zip(self._carried(), carried))
            tape.backward(grads=grads or None)
            carry, carried = start.y.grad, [array.grad for array in first]
            if on_frame is not None:
                on_frame(frame, tape)
            del tape, end, watched
        return start

"""Exact gradients through a whole run: ``ws.gradient`` over a differentiable Simulator, checkpointed per frame.

- ``run``: ws.gradient itself, its arguments checked before anything runs;
- ``trajectory``: the (frames + 1, count) arrays a loss reads;
- ``controls``: per-frame forces and torques held over each frame;
- ``parameters``: the names of ``wrt`` and each gradient from the adjoint;
- ``checkpoints``: the forward run storing a state per frame, and the backward pass recomputing each frame on a
  tape of its own;
- ``pool``: one frame's scratch states, reused frame after frame.
"""
from .run import gradient
from .trajectory import Trajectory

__all__ = ["gradient", "Trajectory"]

"""Control: what the user sets while a simulation runs, apart from the Model (constant) and the State."""
from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import blocks
from .model import Model
from .persistence import Persistent


class Control(Persistent):
    """Inputs held from when they are set until changed, on the model's device.

    body_force: per body, a force held on its centre of mass [N], world frame (vec3); None without bodies
    body_torque: per body, a held torque about its centre of mass [N m], world frame (vec3); None without bodies
    held: body_force and body_torque as a kernels.blocks Wrench (None without bodies)

    The arrays are captured in ``held``: change their values in place (set_body_wrench), never replace them; a
    differentiable run may hold other arrays instead (``hold``).
    """

    persistent = ("body_force", "body_torque")

    def __init__(self, model: Model):
        self.model = model
        self.body_force = model.zeros(model.body_count, model.vec3) if model.body_count else None
        self.body_torque = model.zeros(model.body_count, model.vec3) if model.body_count else None
        self.held = blocks.fill(blocks.of(model.scalar).Wrench, force=self.body_force, torque=self.body_torque) \
            if model.body_count else None

    def set_body_wrench(self, index: int, force: np.ndarray, torque: np.ndarray) -> None:
        """Hold ``force`` [N] and ``torque`` [N m] (world frame, about the centre of mass) on body ``index``."""
        m = self.model
        wp.copy(self.body_force, wp.array([force], dtype=m.vec3, device=m.device), dest_offset=index, count=1)
        wp.copy(self.body_torque, wp.array([torque], dtype=m.vec3, device=m.device), dest_offset=index, count=1)

    def hold(self, force, torque) -> None:
        """Hold ``force`` [N] and ``torque`` [N m] (vec3 arrays, one per body, world frame) instead, from the next
        launch on: a differentiable run's per-frame controls, rows of (frames, bodies, 3) arrays whose gradients a
        wp.Tape's adjoint fills. Only there: the forward launcher records launches by their structs' identity."""
        self.held = blocks.fill(blocks.of(self.model.scalar).Wrench, force=force, torque=torque)

    def make_differentiable(self) -> None:
        """Give the held inputs gradients (``body_force.grad``, ``body_torque.grad``: what a tape's adjoint sends
        them), before anything launches."""
        if self.held is not None:
            self.body_force.requires_grad = self.body_torque.requires_grad = True
            self.hold(self.body_force, self.body_torque)

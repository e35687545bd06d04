"""Kinematic bodies: bodies that follow their keyframed tracks (scene.tracks), pushing others without being pushed.

A kinematic body is simulated as a body 10^6 times heavier than the heaviest dynamic one (core.model), so the
contact response treats it as immovable; this pass then sets its end-of-step pose from its track and its momenta
from the track's mean velocities over the step, once before the contact response (which sees it move) and once
after (which undoes the 10^-6 it was pushed), so its motion is exactly the track.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..kernels import rigid as rigid_kernels


class KinematicBodies(Pass):
    """Sets the kinematic bodies' state from their tracks (see the module docstring); tracks: (body index, Track)."""

    kernels = ("rigid",)

    def __init__(self, model: Model, scene):
        self.model = model
        self.tracks = [(index, body.track) for index, body in enumerate(scene.bodies) if body.track is not None]
        count = len(self.tracks)
        self.index = wp.array(np.array([index for index, _ in self.tracks], dtype=np.int32), dtype=wp.int32,
                              device=model.device)
        self.x, self.v, self.omega = (model.zeros(count, model.vec3) for _ in range(3))
        self.q = model.zeros(count, model.quat)

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        poses = [track.pose(t + h) for _, track in self.tracks]
        moves = [track.velocities(t, t + h) for _, track in self.tracks]
        dtype = self.model.numpy_scalar
        self.x.assign(np.array([x for x, _ in poses], dtype=dtype))
        self.q.assign(np.array([q for _, q in poses], dtype=dtype))
        self.v.assign(np.array([v for v, _ in moves], dtype=dtype))
        self.omega.assign(np.array([w for _, w in moves], dtype=dtype))
        m = self.model
        m.launch(rigid_kernels.set_kinematic, len(self.tracks),
                 [self.index, self.x, self.q, self.v, self.omega, m.body_mass, end.bodies])

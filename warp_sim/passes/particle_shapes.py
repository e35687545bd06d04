"""Particles (and cloth and soft-body vertices) pushed by bodies and static colliders, a pass after each step."""
from __future__ import annotations

import warp as wp

from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..detection import ContactGeometry, Detection
from ..kernels import blocks
from ..kernels import particle_shapes as shape_kernels


class ParticleShapeContacts(Pass):
    """Particles (and cloth and soft-body vertices) against bodies and static colliders, one way: shapes push
    particles, at the end of each step (see kernels.particle_shapes.push_particles).

    geometry: the scene's shapes on the device; detection: the bodies' broad phase whose hash grid it reuses,
    or None (colliders only); touched: per-particle int32 flags set to 1 on contact (empty unless an
    emitter kills on contact)
    """

    kernels = ("particle_shapes", "detection")

    def __init__(self, model: Model, geometry: ContactGeometry, detection: Detection | None):
        self.model = model
        self.geometry = geometry
        self.detection = detection
        if detection is not None and model.body_count:
            detection.use_grid()   # the bodies near a particle come from the detection's hash grid
        self.touched = model.empty(wp.int32)
        empty, vec3 = model.empty, model.vec3
        self.no_bodies = (blocks.fill(model.blocks.Bodies, x=empty(vec3), q=empty(model.quat), P=empty(vec3),
                                      L=empty(vec3)),
                          blocks.fill(model.blocks.BodyMass, inv_mass=empty(), inv_inertia=empty(model.mat33)))

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        m = self.model
        grid = self.detection.grid.id if self.detection is not None and self.detection.grid is not None else 0
        bodies, mass = (end.bodies, m.body_mass) if m.body_count else self.no_bodies
        m.launch(shape_kernels.push_particles, m.particle_count, [
            self.geometry.geoms, wp.uint64(grid), self.geometry.static_count, self.geometry.max_reach, bodies, mass,
            end.particle_x, end.particle_v, m.particle_material, self.touched])

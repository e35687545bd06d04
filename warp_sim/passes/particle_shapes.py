"""Particles (and cloth and soft-body vertices) pushed by bodies and static colliders, a pass after each step."""
from __future__ import annotations

import warp as wp

from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..detection import ContactGeometry, Detection
from ..kernels import particle_shapes as shape_kernels


class ParticleShapeContacts(Pass):
    """Particles (and cloth and soft-body vertices) against bodies and static colliders, one way: shapes push
    particles, at the end of each step (see kernels.particle_shapes.push_particles).

    geometry: the scene's shapes on the device; detection: the bodies' broad phase whose hash grid it reuses,
    or None (colliders only); touched: per-particle int32 flags set to 1 on contact (empty unless an
    emitter kills on contact)
    """

    def __init__(self, model: Model, geometry: ContactGeometry, detection: Detection | None):
        self.model = model
        self.geometry = geometry
        self.detection = detection
        self.touched = model.empty(wp.int32)

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        m = self.model
        grid = self.detection.grid.id if self.detection is not None and self.detection.grid is not None else 0
        empty_vec, empty_q = m.empty(m.vec3), m.empty(wp.types.quaternion(m.scalar))
        bodies = [end.body_x, end.body_q, end.body_P, end.body_L, m.body_inv_mass, m.body_inv_inertia] \
            if m.body_count else [empty_vec, empty_q, empty_vec, empty_vec, m.empty(), m.empty(m.mat33)]
        m.launch(shape_kernels.push_particles, m.particle_count, [
            self.geometry.geoms, wp.uint64(grid), self.geometry.static_count, self.geometry.max_reach, *bodies,
            end.particle_x, end.particle_v, m.particle_inv_mass, m.particle_radius, m.particle_restitution,
            m.particle_friction, self.touched])

"""Particles (and cloth and soft-body vertices) against bodies and static colliders, a pass after each step."""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..detection import ContactGeometry, Detection
from ..kernels import blocks
from ..kernels import particle_shapes as shape_kernels


class ParticleShapeContacts(Pass):
    """Particles (and cloth and soft-body vertices) against bodies and static colliders, one way: shapes push
    particles. Each particle's motion over the step is swept against the static colliders (continuous collision:
    the first hit's time of impact, response there, the rest of the step travelled; see
    kernels.particle_shapes), then every particle is projected out of every shape at the end of the step
    (resting contact, and the bodies, which are not swept: see kernels.particle_shapes.push_particles).

    geometry: the scene's shapes on the device; detection: the bodies' broad phase whose hash grid it reuses,
    or None (colliders only); colliders: the scene's static colliders (open surfaces, ``MeshShape(solid=False)``,
    hold particles on both sides); continuous: False for the end-of-step projection alone, as before the sweep
    (open surfaces then push as terrains, inside below them: a benchmark's baseline); touched: per-particle
    int32 flags set to 1 on contact (empty unless an emitter kills on contact)
    """

    kernels = ("particle_shapes", "detection")

    def __init__(self, model: Model, geometry: ContactGeometry, detection: Detection | None, colliders=(),
                 continuous: bool = True):
        self.model = model
        self.geometry = geometry
        self.detection = detection
        self.continuous = bool(continuous)
        if detection is not None and model.body_count:
            detection.use_grid()   # the bodies near a particle come from the detection's hash grid
        self.touched = model.empty(wp.int32)
        sides = [int(c.shape.kind == "mesh" and not c.shape.solid) for c in colliders]
        if len(sides) != geometry.static_count:
            raise ValueError(f"colliders={len(sides)} colliders; expected the geometry's {geometry.static_count}")
        self.double_sided = wp.array(np.asarray(sides, dtype=np.int32), dtype=wp.int32, device=model.device)
        self.terrains = model.empty(wp.int32)   # no flags: every open surface a terrain (continuous=False)
        empty, vec3 = model.empty, model.vec3
        self.no_bodies = (blocks.fill(model.blocks.Bodies, x=empty(vec3), q=empty(model.quat), P=empty(vec3),
                                      L=empty(vec3)),
                          blocks.fill(model.blocks.BodyMass, inv_mass=empty(), inv_inertia=empty(model.mat33)))

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        """Sweep every particle from ``start`` to ``end`` (h seconds) against the static colliders and project it
        out of every shape; ``end`` is corrected in place."""
        m, g = self.model, self.geometry
        grid = self.detection.grid.id if self.detection is not None and self.detection.grid is not None else 0
        bodies, mass = (end.bodies, m.body_mass) if m.body_count else self.no_bodies
        if self.continuous:
            m.launch(shape_kernels.collide_particles, m.particle_count, [
                g.geoms, wp.uint64(grid), g.static_count, g.max_reach, self.double_sided, bodies, mass,
                start.particle_x, start.particle_v, end.particle_x, end.particle_v, m.particle_material, m.scalar(h),
                self.touched])
        else:
            m.launch(shape_kernels.push_particles, m.particle_count, [
                g.geoms, wp.uint64(grid), g.static_count, g.max_reach, self.terrains, bodies, mass,
                end.particle_x, end.particle_v, m.particle_material, self.touched])

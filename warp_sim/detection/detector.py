"""Broad and narrow phase over a step: the contacts that exist or could close within it.

A hash grid over the bodies' centres (rebuilt every step, linear in the body count) gives
the pairs whose bounding spheres, grown by how far each body moves over the step and the
contact margin, overlap; static colliders and planes are tested per body. The narrow
phase then tests, at the start poses, sample points (box corners, capsule and sphere
centres with their radius, cylinder rims, mesh vertices) against the other shape's signed
distance, and box-box contact polygons by separating axes.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..core.state import State
from ..kernels import detection as detection_kernels
from .buffers import GrowableBuffer
from .geometry import ContactGeometry


class Detection:
    """Broad and narrow phase over a pose pair (start, end) of the bodies: ``detect`` fills ``contacts``."""

    def __init__(self, model: Model, geometry: ContactGeometry, planes: list, margin: float):
        self.model = model
        self.geometry = geometry
        self.margin = float(margin)
        device = model.device
        self.pairs = GrowableBuffer(device, max(64, 8 * model.body_count), with_points=False)
        self.contacts = GrowableBuffer(device, max(256, 16 * model.body_count), with_points=True)
        dim = int(min(128, max(8, 2.0 * model.body_count ** (1.0 / 3.0))))   # cells hash into dim^3 buckets
        self.grid = wp.HashGrid(dim, dim, dim, device=device) if model.body_count else None
        self.cell = max(2.0 * geometry.body_bound + self.margin, 1e-3)
        self.planes_normal = wp.array(np.array([p.normal for p in planes]).reshape(-1, 3),
                                      dtype=wp.vec3f, device=device)
        self.planes_offset = wp.array([p.offset for p in planes], dtype=wp.float32, device=device)
        self.planes_restitution = wp.array([p.restitution for p in planes], dtype=wp.float32,
                                           device=device)
        self.planes_friction = wp.array([p.friction for p in planes], dtype=wp.float32, device=device)
        self.pair_count = 0
        self.count = 0

    def detect(self, start: State, end: State) -> int:
        """Contacts at the start poses that could close before the end poses; returns their count."""
        m = self.model
        geoms = self.geometry.geoms
        B = m.body_count
        self.geometry.max_reach.zero_()
        m.launch(detection_kernels.gather_poses, B, [start.body_x, start.body_q, end.body_x, end.body_q, self.margin,
                                                   geoms, self.geometry.max_reach])
        self.grid.build(geoms.x[:B], self.cell)
        statics = self.geometry.static_count

        def pairs(buffer):
            m.launch(detection_kernels.find_pairs, B, [geoms, self.grid.id, statics, self.planes_normal,
                                                     self.planes_offset, self.geometry.max_reach, buffer])

        self.pair_count = self.pairs.fill(pairs)

        def contacts(buffer):
            m.launch(detection_kernels.narrow_phase, self.pair_count, [self.pairs.buffer, geoms, self.planes_normal,
                                                                     self.planes_offset, self.margin, buffer])

        self.count = self.contacts.fill(contacts) if self.pair_count else 0
        return self.count

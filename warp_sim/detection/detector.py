"""Broad and narrow phase over a step: the contacts that exist or could close within it.

A hash grid over the bodies' centres (rebuilt every step, linear in the body count) gives
the pairs whose bounding spheres, grown by how far each body moves over the step and the
contact margin, overlap; static colliders and planes are tested per body. The narrow
phase then tests, at the start poses, sample points (box corners, capsule and sphere
centres with their radius, cylinder rims, mesh vertices) against the other shape's signed
distance, and box-box contact polygons by separating axes.
"""
from __future__ import annotations

import warp as wp

from ..core.model import Model
from ..core.state import State
from ..kernels import detection as detection_kernels
from .buffers import GrowableBuffer
from .geometry import ContactGeometry


class Detection:
    """Broad and narrow phase over a pose pair (start, end) of the bodies: ``detect`` fills ``contacts``.

    geometry: the shapes (ContactGeometry); margin: the gap below which shapes count as touching [m]
    pairs, contacts: growable buffers of candidate pairs and contacts; grid: the bodies' hash grid
    cell: its cell size [m]; pair_count, count: pairs and contacts found by the last detect (the last one not
        captured: a captured step reads nothing back, and its launches run over the buffers' capacities)
    """

    def __init__(self, model: Model, geometry: ContactGeometry, margin: float):
        self.model = model
        self.geometry = geometry
        self.margin = float(margin)
        device = model.device
        self.pairs = GrowableBuffer(device, max(64, 8 * model.body_count), with_points=False)
        self.contacts = GrowableBuffer(device, max(256, 16 * model.body_count), with_points=True)
        dim = int(min(128, max(8, 2.0 * model.body_count ** (1.0 / 3.0))))   # cells hash into dim^3 buckets
        self.grid = wp.HashGrid(dim, dim, dim, device=device) if model.body_count else None
        self.cell = max(2.0 * geometry.body_bound + self.margin, 1e-3)
        self.pair_count = 0
        self.count = 0

    def detect(self, start: State, end: State) -> int | None:
        """Contacts at the start poses that could close before the end poses; returns their count (None while a
        step is captured: the count stays on the device)."""
        m = self.model
        capturing = m.launcher.capturing
        geoms = self.geometry.geoms
        B = m.body_count
        self.geometry.max_reach.zero_()
        m.launch(detection_kernels.gather_poses, B, [start.bodies, end.bodies, self.margin, geoms,
                                                   self.geometry.max_reach])
        self.grid.build(geoms.x[:B], self.cell)
        statics = self.geometry.static_count

        def pairs(buffer):
            m.launch(detection_kernels.find_pairs, B, [geoms, self.grid.id, statics, self.geometry.max_reach, buffer])

        pair_count = self.pairs.fill(pairs, capturing)

        def contacts(buffer):
            m.launch(detection_kernels.narrow_phase, self.pairs.capacity if capturing else pair_count,
                     [self.pairs.buffer, geoms, self.geometry.max_reach, buffer])

        if capturing:
            return self.contacts.fill(contacts, capturing)
        self.pair_count = pair_count
        self.count = self.contacts.fill(contacts) if pair_count else 0
        return self.count

"""Broad and narrow phase over a step: the contacts that exist or could close within it.

Every pair up to ``Detection.all_pairs`` bodies (a CPU builds a hash grid in some 50 us whatever the
count), beyond that a hash grid over the bodies' centres (rebuilt every step, linear in the body count), gives
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
from .buffers import GrowableBuffer, launch_threads
from .geometry import ContactGeometry


class Detection:
    """Broad and narrow phase over a pose pair (start, end) of the bodies: ``detect`` fills ``contacts``.

    geometry: the shapes (ContactGeometry); margin: the gap below which shapes count as touching [m]
    pairs, contacts: growable buffers of candidate pairs and contacts; grid: the bodies' hash grid (None up to
        ``all_pairs`` bodies, unless particles query it: every pair is tested); cell: its cell size [m]
    pair_count, count: pairs and contacts found by the last detect (the last one not captured: a captured step
        reads nothing back); captured: the threads a captured step launches over the pairs and the contacts
    """

    all_pairs = 128   # bodies up to which every pair is tested instead of building the hash grid

    def __init__(self, model: Model, geometry: ContactGeometry, margin: float):
        self.model = model
        self.geometry = geometry
        self.margin = float(margin)
        device = model.device
        self.pairs = GrowableBuffer(device, max(64, 8 * model.body_count), with_points=False)
        self.contacts = GrowableBuffer(device, max(256, 16 * model.body_count), with_points=True)
        self.grid = None
        if model.body_count > self.all_pairs:
            self.use_grid()
        self.cell = max(2.0 * geometry.body_bound + self.margin, 1e-3)
        self.pair_count = 0
        self.count = 0
        self.captured = (0, 0)

    def before_capture(self) -> None:
        """Before a step is recorded: the threads its launches run over the pairs and the contacts (``captured``),
        the last uncaptured counts with headroom (buffers.launch_threads), at most the capacities."""
        self.captured = (launch_threads(self.pair_count, self.pairs.capacity),
                         launch_threads(self.count, self.contacts.capacity))

    def threads(self) -> tuple[int, int]:
        """Threads of a launch over the pairs and over the contacts: the counts found by the last detect, or while
        a step is captured those of ``captured`` (the kernels exit past the device's counts; the step's gate,
        kernels.manifolds.gate_response, says whether the counts outgrew them)."""
        return self.captured if self.model.launcher.capturing else (self.pair_count, self.count)

    def use_grid(self) -> None:
        """Build the bodies' hash grid every step whatever their count (particles against shapes query it)."""
        if self.grid is None:
            dim = int(min(128, max(8, 2.0 * self.model.body_count ** (1.0 / 3.0))))   # cells hash into dim^3 buckets
            self.grid = wp.HashGrid(dim, dim, dim, device=self.model.device)

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
        statics = self.geometry.static_count
        if self.grid is not None:
            self.grid.build(geoms.x[:B], self.cell)

        def pairs(buffer):
            if self.grid is None:
                m.launch(detection_kernels.find_all_pairs, B, [geoms, statics, self.geometry.max_reach, buffer])
            else:
                m.launch(detection_kernels.find_pairs, B, [geoms, self.grid.id, statics, self.geometry.max_reach,
                                                          buffer])

        pair_count = self.pairs.fill(pairs, capturing)

        def contacts(buffer):
            m.launch(detection_kernels.narrow_phase, self.captured[0] if capturing else pair_count,
                     [self.pairs.buffer, geoms, self.geometry.max_reach, buffer])

        if capturing:
            self.contacts.fill(contacts, capturing)
            return None
        self.pair_count = pair_count
        self.count = self.contacts.fill(contacts) if pair_count else 0
        return self.count

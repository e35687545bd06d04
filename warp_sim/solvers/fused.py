"""The fused step of particles (and cloth) under semi-implicit Euler: the generic path's work in one launch.

The generic path of a step is the solver's stages (forces, the particle accelerations, a kick over the velocity
block, the position rates, a drift over the position block), then the passes (the plane impulses), then the guard:
six launches, each reading and writing whole arrays. ``FusedParticleStep`` accumulates the force terms (springs,
fields, aerodynamics) as the generic path does, then launches kernels.fused.symplectic_euler_particles, which
reads x and v once and writes them once, with the same Warp functions in the same order: the states are equal
bit for bit. assembly.fused_step says when it applies (docs/architecture.md: the rule).
"""
from __future__ import annotations

import warp as wp

from ..core.cpu_threads import chunked_launch
from ..core.dynamics import Dynamics
from ..kernels import fused as fused_kernels
from ..kernels.guards import GuardRecord


class FusedParticleStep:
    """One launch per step for a particles-only Dynamics under symplectic_euler.

    impacts: whether the plane impulses are folded in (the scene's impulse plane contacts); touched: their
    per-particle contact flags (int32, empty unless a kill-on-contact emitter reads them); record, max_speed:
    the particles' guard record and bound, once the Simulator folds the guard in (``set_guard``; else a record the
    kernel never writes, as it is launched with step 0).
    """

    kernels = ("fused",)
    capturable = True
    BASE = 16   # the kernel's input that is a piece's first thread (core.cpu_threads)

    def __init__(self, dynamics: Dynamics, impacts: bool, touched: wp.array):
        self.dynamics = dynamics
        model = self.model = dynamics.model
        self.impacts = int(impacts)
        self.touched = touched
        self.planes = model.planes if model.planes is not None else model.no_planes()
        record = GuardRecord()
        record.first_step = record.first_key = wp.empty(1, dtype=wp.int32, device=model.device)
        self.set_guard(record, model.scalar(0.0))
        #: particles a thread steps, threads, pieces at most (core.cpu_threads.chunked_launch)
        self.chunk, self.threads, self.pieces = chunked_launch(model.device, model.particle_count)

    def set_guard(self, record: GuardRecord, max_speed) -> None:
        """Fold the guard's check of the particles (its record, its bound [m/s] in the model's scalar) in."""
        self.record, self.max_speed = record, max_speed
        #: the record as numpy views on the CPU (its arrays' memory), else None
        self._record_view = ((record.first_step.numpy(), record.first_key.numpy()) if record.first_step.device.is_cpu
                             else None)

    def step(self, start, end, t: float, h: float, check: int) -> None:
        """``end`` from ``start`` over h seconds from time t; check > 0: record the guard's check as that step."""
        m, forces = self.model, self.dynamics.forces
        self.dynamics.accumulate_forces(start, t)
        launch = m.launcher.prepare(
            fused_kernels.symplectic_euler_particles, self.threads,
            [start.particle_x, start.particle_v, forces.particle_f, m.gravity, m.drag, m.wind, m.particle_material,
             self.planes, m.scalar(h), self.impacts, end.particle_x, end.particle_v, self.touched, self.max_speed,
             check, self.record, 0, self.chunk])
        if self.pieces == 1 or check == 0 or self._record_view is None:
            launch.run_pieces(self.threads, self.BASE, self.pieces)
            return
        # Warp's CPU atomics are plain reads and writes, so pieces that record bad particles at once may keep a
        # higher one: a step that records one is taken again as one piece (it writes end from start only), so the
        # record names its lowest bad particle, as on one thread
        first_step, first_key = self._record_view
        before = int(first_step[0]), int(first_key[0])
        launch.run_pieces(self.threads, self.BASE, self.pieces)
        if int(first_step[0]) != before[0]:
            first_step[0], first_key[0] = before
            launch.run_pieces(self.threads, self.BASE, 1)

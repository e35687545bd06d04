"""Particles against planes: detection over the step's interval and the time-of-impact impulse response.

Each crossing is backed up to its time of impact, the velocity reflected with restitution
and Coulomb friction there, and the rest of the step travelled; a particle pressed onto a
plane is in resting contact. The alternative, penalty forces, is ``forces.penalty.PlanePenalty``.
"""
from __future__ import annotations

import warp as wp

from ..core.cpu_threads import chunked_launch
from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..kernels import planes as plane_kernels


class PlaneImpacts(Pass):
    """The time-of-impact response pass, run after the solver on (start, end) of a step.

    touched: per-particle int32 flags set to 1 on contact (empty unless a kill-on-contact emitter asks)
    hold_impact_time: in a differentiable run, drop the impact times' gradients (the naive adjoint, which holds
    each impact's time fixed; for comparison only: False, the exact adjoint, by default)
    """

    hold_impact_time = False

    kernels = ("planes",)
    capturable = True
    BASE = 8   # the kernel's input that is a piece's first thread (core.cpu_threads)

    def __init__(self, model: Model):
        self.model = model
        self.touched = model.empty(wp.int32)
        #: particles a thread takes, threads, pieces at most (core.cpu_threads.chunked_launch)
        self.chunk, self.threads, self.pieces = chunked_launch(model.device, model.particle_count)

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        """Correct ``end`` in place for every plane crossed between ``start`` and ``end`` (h seconds)."""
        m = self.model
        if m.differentiable:   # one particle a thread, its adjoint exact; end corrected in place on the tape
            m.launcher.launch_in_place(plane_kernels.resolve_plane_impacts_differentiable, m.particle_count, [
                start.particle_x, start.particle_v, end.particle_x, end.particle_v, m.particle_material, m.planes,
                m.scalar(h), int(self.hold_impact_time), self.touched], [end.particle_x, end.particle_v])
            return
        m.launcher.prepare(plane_kernels.resolve_plane_impacts_chunked, self.threads, [
            start.particle_x, start.particle_v, end.particle_x, end.particle_v, m.particle_material, m.planes,
            m.scalar(h), self.touched, 0, self.chunk]).run_pieces(self.threads, self.BASE, self.pieces)

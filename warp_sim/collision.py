"""Particle-plane collision detection and response, as a pass after each step or as forces.

Two responses, chosen per simulator:
- "impulse" (default): detection over the step's interval; each crossing is backed
  up to its time of impact, the velocity reflected with restitution and Coulomb
  friction there, and the rest of the step travelled (``PlaneImpacts``).
- "penalty": a spring and damper on the penetration depth, a force every
  integrator sees (``PlanePenalty``).
"""
from __future__ import annotations

import warp as wp

from .dynamics import Forces, ForceTerm
from .kernels import planes as plane_kernels
from .model import Model, State

RESPONSES = ("impulse", "penalty")


def _material_inputs(model: Model) -> list:
    return [model.particle_restitution, model.particle_friction, model.plane_normal,
            model.plane_offset, model.plane_restitution, model.plane_friction]


class PlaneImpacts:
    """The time-of-impact response pass, run after the solver on (start, end) of a step."""

    def __init__(self, model: Model):
        self.model = model
        #: per-particle int32 flags set to 1 on contact, for those who ask (kill-on-contact emitters)
        self.touched = model.empty(wp.int32)

    def apply(self, start: State, end: State, h: float) -> None:
        """Correct ``end`` in place for every plane crossed between ``start`` and ``end`` (h seconds)."""
        m = self.model
        m.launch(plane_kernels.resolve_plane_impacts, m.particle_count,
                 [start.particle_x, start.particle_v, end.particle_x, end.particle_v, m.particle_inv_mass,
                  m.particle_radius, *_material_inputs(m), m.scalar(h), self.touched])


class PlanePenalty(ForceTerm):
    """Penalty forces on particles inside planes: stiffness [N/m], damper from restitution."""

    def __init__(self, model: Model, stiffness: float):
        self.model = model
        self.stiffness = model.scalar(stiffness)

    def apply(self, state: State, t: float, forces: Forces) -> None:
        m = self.model
        m.launch(plane_kernels.plane_penalty_forces, m.particle_count,
                 [state.particle_x, state.particle_v, m.particle_inv_mass, m.particle_radius,
                  *_material_inputs(m), self.stiffness, forces.particle_f])

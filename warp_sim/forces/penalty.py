"""Penalty contacts as force terms: a spring on the penetration depth and a damper chosen so that the
contact rebounds with its restitution. One damping model for particles and bodies (kernels.penalty)."""
from __future__ import annotations

from ..core.model import Model
from ..core.protocols import Forces, ForceTerm
from ..core.state import State
from ..detection import Detection
from ..kernels import penalty as penalty_kernels


class PlanePenalty(ForceTerm):
    """Particles inside planes pushed out: stiffness [N/m], the damper of kernels.penalty.penalty_damping."""

    kernels = ("penalty",)

    def __init__(self, model: Model, stiffness: float):
        self.model = model
        self.stiffness = model.scalar(stiffness)

    def apply(self, state: State, t: float, forces: Forces) -> None:
        m = self.model
        m.launch(penalty_kernels.plane_penalty_forces, m.particle_count,
                 [state.particle_x, state.particle_v, m.particle_material, m.planes, self.stiffness,
                  forces.particle_f])


class BodyPenalty(ForceTerm):
    """Each overlap of bodies, colliders and planes pushes the bodies apart: stiffness [N/m], the damper of
    kernels.penalty.penalty_damping for the pair's reduced mass, Coulomb friction capped by the damper.

    detection: the broad and narrow phase, run on the state each evaluation (contacts at that instant)
    """

    targets = frozenset({"bodies"})
    kernels = ("penalty", "detection")
    capturable = False   # the detection reads its contact counts back

    def __init__(self, model: Model, stiffness: float, detection: Detection):
        self.model = model
        self.stiffness = model.scalar(stiffness)
        self.detection = detection

    def apply(self, state: State, t: float, forces: Forces) -> None:
        m = self.model
        count = self.detection.detect(state, state)
        if count:
            d = self.detection
            m.launch(penalty_kernels.body_penalty_forces, count, [d.contacts.buffer, d.geometry.geoms, state.bodies,
                                                                   m.body_mass, self.stiffness, forces.body_wrench])

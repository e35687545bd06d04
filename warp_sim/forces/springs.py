"""Damped Hooke springs between particle pairs, as a force term."""
from __future__ import annotations

from ..core.model import Model
from ..core.protocols import Forces, ForceTerm
from ..core.state import State
from ..kernels import springs as spring_kernels


class Springs(ForceTerm):
    """f2 = (-ks (L - L0) - kd (v2 - v1) . d) d, f1 = -f2 on every spring of the model (one launch)."""

    kernels = ("springs",)

    def __init__(self, model: Model):
        self.model = model

    def apply(self, state: State, t: float, forces: Forces) -> None:
        m, springs = self.model, self.model.springs
        m.launch(spring_kernels.spring_forces_unpacked, m.spring_count,
                 [state.particle_x, state.particle_v, springs.pairs, springs.stiffness, springs.damping,
                  springs.rest_length, forces.particle_f])

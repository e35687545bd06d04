"""The partitioned (symplectic) solvers: kicks of the velocity block, drifts of the position block.

A kick and a drift write their rates into ``scratch`` states (new ones in a differentiable run); velocity Verlet's
half step is a state of its own there, since the drift reads its velocities and the second kick replaces them.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.state import State
from .base import Integrator


class Partitioned(Integrator):
    """Base of the symplectic schemes: kicks (velocities from forces) and drifts
    (positions from velocities), on the two blocks of the state."""

    def allocate(self, dynamics):
        self.k = dynamics.new_state()
        self.mid = dynamics.new_state() if dynamics.position_rates_need_positions else None

    def kick(self, forces_at: State, velocities: State, out: State, t: float, h: float) -> State:
        """out.velocity = velocities.velocity + h * (velocity rates at ``forces_at``); returns the state holding
        those rates."""
        k = self.scratch(self.k)
        self.dynamics.velocity_derivative(forces_at, t, k)
        self.axpy(velocities.velocity, h, k.velocity, out.velocity)
        return k

    def drift(self, state_in: State, state_out: State, h: float) -> None:
        """out.position = in.position + h * (position rates from in's positions and out's velocities).

        Where position rates depend on positions (a body's spin omega = R I_body^-1 R^T L depends on
        its orientation), the rates are taken at the half-drifted positions (a midpoint drift), so the
        drift stays second order; for particles (x' = v) this extra stage would change nothing and is skipped.
        """
        k = self.scratch(self.k)
        self.dynamics.position_derivative(state_in, state_out, k)
        if self.mid is not None:
            mid = self.scratch(self.mid)
            self.axpy(state_in.position, 0.5 * h, k.position, mid.position)
            k = self.scratch(self.k)
            self.dynamics.position_derivative(mid, state_out, k)
        self.axpy(state_in.position, h, k.position, state_out.position)


class SymplecticEuler(Partitioned):
    """Semi-implicit Euler: velocities from forces at the old positions, then positions
    from the new velocities. First order, symplectic: bounded energy error."""

    name, order = "symplectic_euler", 1
    position_response = 1.0
    differentiable = True

    def step(self, state_in, state_out, t, h):
        self.kick(state_in, state_in, state_out, t, h)
        self.drift(state_in, state_out, h)

    def amplification(self, h, w2, c, stiff=True):
        """v1 = v + h (-w2 x - c v), then x1 = x + h v1 (Integrator.amplification)."""
        kick = np.array([[1.0, 0.0], [-h * w2, 1.0 - h * c]])
        return np.array([[1.0, h], [0.0, 1.0]]) @ kick


class VelocityVerlet(Partitioned):
    """Velocity Verlet: half kick, drift, half kick with the forces at the new positions.
    Second order, symplectic; velocity-dependent forces use the half-step velocity."""

    name, order = "verlet", 2
    differentiable = True

    def step(self, state_in, state_out, t, h):
        half = self.scratch(state_out)   # state_out itself, but in a differentiable run
        self.kick(state_in, state_in, half, t, 0.5 * h)
        self.drift(state_in, half, h)
        self.kick(half, half, state_out, t + h, 0.5 * h)
        if half is not state_out:
            wp.copy(state_out.position, half.position)   # recorded by an active tape

    def amplification(self, h, w2, c, stiff=True):
        """A half kick at (x, v), a drift with the half-step velocity, a half kick at (x1, v_half): the
        damper sees the half-step velocity both times (Integrator.amplification)."""
        half_kick = np.array([[1.0, 0.0], [-0.5 * h * w2, 1.0 - 0.5 * h * c]])
        drift = np.array([[1.0, h], [0.0, 1.0]])
        return half_kick @ drift @ half_kick

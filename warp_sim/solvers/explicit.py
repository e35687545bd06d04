"""The explicit Runge-Kutta solvers: Euler (order 1), midpoint (2), classical RK4 (4).

Each stage writes its slope and its trial state into ``scratch`` states: the ones allocated at ``bind``, or new
ones in a differentiable run.
"""
from __future__ import annotations

from ..kernels import integrate
from .base import Integrator


class Euler(Integrator):
    """Explicit Euler: y1 = y0 + h f(t, y0). First order."""

    name, order = "euler", 1
    position_response = 0.0
    differentiable = True

    def allocate(self, dynamics):
        self.k = dynamics.new_state()

    def step(self, state_in, state_out, t, h):
        k = self.scratch(self.k)
        self.dynamics.derivative(state_in, t, k)
        self.axpy(state_in.y, h, k.y, state_out.y)


class Midpoint(Integrator):
    """Midpoint (second-order Runge-Kutta): an Euler half step, then a full step with the slope there."""

    name, order = "midpoint", 2
    differentiable = True

    def allocate(self, dynamics):
        self.k = dynamics.new_state()
        self.mid = dynamics.new_state()

    def step(self, state_in, state_out, t, h):
        k, mid = self.scratch(self.k), self.scratch(self.mid)
        self.dynamics.derivative(state_in, t, k)
        self.axpy(state_in.y, 0.5 * h, k.y, mid.y)
        k = self.scratch(self.k)
        self.dynamics.derivative(mid, t + 0.5 * h, k)
        self.axpy(state_in.y, h, k.y, state_out.y)


class RK4(Integrator):
    """Classical fourth-order Runge-Kutta: four slopes, weighted 1/6, 1/3, 1/3, 1/6."""

    name, order = "rk4", 4
    differentiable = True

    def allocate(self, dynamics):
        self.k = [dynamics.new_state() for _ in range(4)]
        self.trial = dynamics.new_state()

    def step(self, state_in, state_out, t, h):
        k1, k2, k3, k4 = (self.scratch(k) for k in self.k)
        f = self.dynamics.derivative
        f(state_in, t, k1)
        trial = self.scratch(self.trial)
        self.axpy(state_in.y, 0.5 * h, k1.y, trial.y)
        f(trial, t + 0.5 * h, k2)
        trial = self.scratch(self.trial)
        self.axpy(state_in.y, 0.5 * h, k2.y, trial.y)
        f(trial, t + 0.5 * h, k3)
        trial = self.scratch(self.trial)
        self.axpy(state_in.y, h, k3.y, trial.y)
        f(trial, t + h, k4)
        self.launch_elementwise(integrate.rk4_combine, state_in.y.shape[0],
                    [state_in.y, self.scalar(h), k1.y, k2.y, k3.y, k4.y, state_out.y])

"""The explicit Runge-Kutta solvers: Euler (order 1), midpoint (2), classical RK4 (4)."""
from __future__ import annotations

from ..kernels import integrate
from .base import Integrator


class Euler(Integrator):
    """Explicit Euler: y1 = y0 + h f(t, y0). First order."""

    name, order = "euler", 1
    position_response = 0.0

    def allocate(self, dynamics):
        self.k = dynamics.new_state()

    def step(self, state_in, state_out, t, h):
        self.dynamics.derivative(state_in, t, self.k)
        self.axpy(state_in.y, h, self.k.y, state_out.y)


class Midpoint(Integrator):
    """Midpoint (second-order Runge-Kutta): an Euler half step, then a full step with the slope there."""

    name, order = "midpoint", 2

    def allocate(self, dynamics):
        self.k = dynamics.new_state()
        self.mid = dynamics.new_state()

    def step(self, state_in, state_out, t, h):
        self.dynamics.derivative(state_in, t, self.k)
        self.axpy(state_in.y, 0.5 * h, self.k.y, self.mid.y)
        self.dynamics.derivative(self.mid, t + 0.5 * h, self.k)
        self.axpy(state_in.y, h, self.k.y, state_out.y)


class RK4(Integrator):
    """Classical fourth-order Runge-Kutta: four slopes, weighted 1/6, 1/3, 1/3, 1/6."""

    name, order = "rk4", 4

    def allocate(self, dynamics):
        self.k = [dynamics.new_state() for _ in range(4)]
        self.trial = dynamics.new_state()

    def step(self, state_in, state_out, t, h):
        k1, k2, k3, k4 = self.k
        f = self.dynamics.derivative
        f(state_in, t, k1)
        self.axpy(state_in.y, 0.5 * h, k1.y, self.trial.y)
        f(self.trial, t + 0.5 * h, k2)
        self.axpy(state_in.y, 0.5 * h, k2.y, self.trial.y)
        f(self.trial, t + 0.5 * h, k3)
        self.axpy(state_in.y, h, k3.y, self.trial.y)
        f(self.trial, t + h, k4)
        self.launch_elementwise(integrate.rk4_combine, state_in.y.shape[0],
                    [state_in.y, self.scalar(h), k1.y, k2.y, k3.y, k4.y, state_out.y])

"""The ODE solvers, written once over the flat state and the Dynamics derivative.

Each solver advances ``state_in`` at time t by h seconds into ``state_out``
(a different State of the same layout). Scratch states are allocated once, when
the solver is made, never per step.
"""
from __future__ import annotations

from . import checks
from .dynamics import Dynamics
from .kernels import integrate
from .model import State


class Integrator:
    """Base class: ``step(state_in, state_out, t, h)``; ``order`` is the global order of accuracy."""

    name = ""
    order = 0
    #: beta: a force held over a step moves the end position by beta h times the end velocity change it causes
    #: (1/2 for the trapezoid-like solvers, 1 for symplectic and implicit Euler, 0 for explicit Euler)
    position_response = 0.5

    def __init__(self, dynamics: Dynamics):
        self.dynamics = dynamics
        self.scalar = dynamics.model.scalar
        self.launch = dynamics.model.launch

    def axpy(self, y, h: float, dy, out) -> None:
        """out = y + h dy over flat buffers (or blocks) of equal length."""
        self.launch(integrate.axpy, y.shape[0], [y, self.scalar(h), dy, out])

    def step(self, state_in: State, state_out: State, t: float, h: float) -> None:
        raise NotImplementedError


class Euler(Integrator):
    """Explicit Euler: y1 = y0 + h f(t, y0). First order."""
    position_response = 0.0

    name, order = "euler", 1

    def __init__(self, dynamics):
        super().__init__(dynamics)
        self.k = dynamics.new_state()

    def step(self, state_in, state_out, t, h):
        self.dynamics.derivative(state_in, t, self.k)
        self.axpy(state_in.y, h, self.k.y, state_out.y)


class Midpoint(Integrator):
    """Midpoint (second-order Runge-Kutta): an Euler half step, then a full step with the slope there."""

    name, order = "midpoint", 2

    def __init__(self, dynamics):
        super().__init__(dynamics)
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

    def __init__(self, dynamics):
        super().__init__(dynamics)
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
        self.launch(integrate.rk4_combine, state_in.y.shape[0],
                    [state_in.y, self.scalar(h), k1.y, k2.y, k3.y, k4.y, state_out.y])


class Partitioned(Integrator):
    """Base of the symplectic schemes: kicks (velocities from forces) and drifts
    (positions from velocities), on the two blocks of the state."""

    def __init__(self, dynamics):
        super().__init__(dynamics)
        self.k = dynamics.new_state()
        self.mid = dynamics.new_state() if dynamics.position_rates_need_positions else None

    def kick(self, forces_at: State, velocities: State, out: State, t: float, h: float) -> None:
        """out.velocity = velocities.velocity + h * (velocity rates at ``forces_at``)."""
        self.dynamics.velocity_derivative(forces_at, t, self.k)
        self.axpy(velocities.velocity, h, self.k.velocity, out.velocity)

    def drift(self, state_in: State, state_out: State, h: float) -> None:
        """out.position = in.position + h * (position rates from in's positions and out's velocities).

        Where position rates depend on positions (a body's spin omega = R I_body^-1 R^T L depends on
        its orientation), the rates are taken at the half-drifted positions (a midpoint drift), so the
        drift stays second order; for particles (x' = v) this extra stage would change nothing and is skipped.
        """
        self.dynamics.position_derivative(state_in, state_out, self.k)
        if self.mid is not None:
            self.axpy(state_in.position, 0.5 * h, self.k.position, self.mid.position)
            self.dynamics.position_derivative(self.mid, state_out, self.k)
        self.axpy(state_in.position, h, self.k.position, state_out.position)


class SymplecticEuler(Partitioned):
    """Semi-implicit Euler: velocities from forces at the old positions, then positions
    from the new velocities. First order, symplectic: bounded energy error."""
    position_response = 1.0

    name, order = "symplectic_euler", 1

    def step(self, state_in, state_out, t, h):
        self.kick(state_in, state_in, state_out, t, h)
        self.drift(state_in, state_out, h)


class VelocityVerlet(Partitioned):
    """Velocity Verlet: half kick, drift, half kick with the forces at the new positions.
    Second order, symplectic; velocity-dependent forces use the half-step velocity."""

    name, order = "verlet", 2

    def step(self, state_in, state_out, t, h):
        self.kick(state_in, state_in, state_out, t, 0.5 * h)
        self.drift(state_in, state_out, h)
        self.kick(state_out, state_out, state_out, t + h, 0.5 * h)


INTEGRATORS = {cls.name: cls for cls in (Euler, Midpoint, RK4, SymplecticEuler, VelocityVerlet)}


def make_integrator(name: str, dynamics: Dynamics) -> Integrator:
    """The solver called ``name`` (one of INTEGRATORS) for ``dynamics``."""
    return INTEGRATORS[checks.choice("integrator", name, tuple(INTEGRATORS))](dynamics)


# registered last: warp_sim.implicit imports Partitioned from this module
from .implicit import ImplicitEuler  # noqa: E402

INTEGRATORS[ImplicitEuler.name] = ImplicitEuler

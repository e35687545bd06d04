"""The solver protocol: an ODE solver made with its options, then bound to one simulation's Dynamics.

A solver advances ``state_in`` at time t by h seconds into ``state_out`` (a different
State of the same layout), written once over the flat state and the Dynamics derivative,
so every component runs under every solver. Scratch states are allocated once, at
``bind``, never per step; in a differentiable run (``differentiable`` solvers only) each stage
writes a new one instead (``scratch``), so no value a wp.Tape's adjoint reads is overwritten.
"""
from __future__ import annotations

import numpy as np

from ..core.dynamics import Dynamics
from ..core.persistence import Persistent
from ..core.state import State
from ..kernels import integrate
from ..util import checks


class Integrator(Persistent):
    """Base of the ODE solvers: ``Integrator(**options)``, then ``bind(dynamics)``, then ``step``.

    name: the registry name ("rk4", ...); order: the global order of accuracy
    position_response: beta, how far a velocity change moves a position over a step: a force held over a
        step moves the end position by beta h times the end velocity change it causes (1/2 for the
        trapezoid-like solvers, 1 for symplectic and implicit Euler, 0 for explicit Euler)
    dynamics: the Dynamics it is bound to (None before ``bind``)
    persistent: what it carries from one step to the next (a step size, a warm start, counters), for checkpoints
    kernels: the kernel modules (names in warp_sim.kernels) it launches
    capturable: whether its launches are the same every step (a fixed step: core.capture)
    differentiable: whether its step has an adjoint on a wp.Tape (its stages write ``scratch`` states: a
        Simulator(differentiable=True) refuses the others)
    """

    name = ""
    kernels: tuple[str, ...] = ("integrate",)
    capturable = True
    differentiable = False
    order = 0
    position_response = 0.5

    def __init__(self):
        self.dynamics: Dynamics | None = None

    def bind(self, dynamics: Dynamics) -> "Integrator":
        """Attach to one simulation's Dynamics and allocate the scratch states; returns self."""
        if self.dynamics is not None:
            raise checks.fail("integrator", self, "this solver instance is already bound to a simulator; "
                                                  "make a new one for each Simulator")
        self.scalar = dynamics.model.scalar
        self.use_launcher(dynamics.model.launcher)
        self.allocate(dynamics)        # may refuse the dynamics (ValueError): the solver stays unbound then
        self.dynamics = dynamics
        return self

    def use_launcher(self, launcher) -> None:
        """Launch through ``launcher`` (core.launcher; a differentiable Simulator's core.tape one) from now on."""
        self.launch = launcher.launch
        self.launch_elementwise = launcher.launch_elementwise

    def scratch(self, state: State) -> State:
        """``state`` (one of the scratch states of ``allocate``), or in a differentiable run a new State of its
        layout: each stage that writes it gets its own, so no value the adjoint reads is overwritten."""
        return self.dynamics.new_state() if self.dynamics.model.differentiable else state

    def allocate(self, dynamics: Dynamics) -> None:
        """Allocate what the solver needs for this Dynamics (scratch states, solver buffers)."""

    def axpy(self, y, h: float, dy, out) -> None:
        """out = y + h dy over flat buffers (or blocks) of equal length."""
        self.launch_elementwise(integrate.axpy, y.shape[0], [y, self.scalar(h), dy, out])

    def step(self, state_in: State, state_out: State, t: float, h: float) -> None:
        raise NotImplementedError

    def amplification(self, h: float, w2: float, c: float, stiff: bool = True) -> np.ndarray | None:
        """The 2 x 2 matrix one step of h [s] applies to (x, v) of the test oscillator x'' = -w2 x - c x'
        (w2 [1/s^2], c [1/s]); stiff: the force is a spring or drag (what implicit Euler takes implicitly), not a
        penalty contact. None: the solver picks its own steps (no fixed-step limit). Here: an explicit Runge-Kutta
        method of ``order`` stages at most 4, whose step is the Taylor polynomial of e^(hA) of that degree."""
        A = h * np.array([[0.0, 1.0], [-w2, -c]])
        term = total = np.eye(2)
        for k in range(1, self.order + 1):
            term = term @ A / k
            total = total + term
        return total

    def stats(self) -> dict:
        """The solver's counters (empty for a fixed-step explicit solver)."""
        return {}

    def pending_warning(self) -> str | None:
        """A warning about the steps since the last call (e.g. solves that stopped unconverged), or None; the
        Simulator issues it once per step() or run() call."""
        return None

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

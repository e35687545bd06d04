"""Adaptive stepping: Dormand-Prince 5(4) with error control, landing exactly on each step's end."""
from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..core.guards import SimulationDiverged
from ..core.state import State
from ..kernels import integrate
from ..util import checks
from .base import Integrator


class AdaptiveStepFailed(SimulationDiverged):
    """An adaptive solver could not meet its tolerance: its step size fell below its floor, or it
    needed more internal steps than allowed in one call. A SimulationDiverged (so ``Simulator.run``
    keeps every frame written before it); ``time`` [s] is where it stopped, ``step`` is None,
    ``component`` is "integrator", ``element`` is -1."""

    def __init__(self, time: float, reason: str):
        self.step, self.time, self.component, self.element, self.reason = None, time, "integrator", -1, reason
        RuntimeError.__init__(self, f"adaptive step failed at t = {time:.9g} s: {reason}")


# Dormand-Prince 5(4) (Dormand and Prince 1980; Hairer, Norsett and Wanner, Solving ODEs I, II.5):
# the nodes; the stage weights are written out in the kernels (warp_sim.kernels.integrate.dp_*).
#: the smallest relative tolerance at any precision: 4 float64 machine epsilons
RTOL_FLOOR = 4.0 * float(np.finfo(np.float64).eps)
DP_NODES = (0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0)


class RK45(Integrator):
    """Adaptive Dormand-Prince 5(4): an embedded Runge-Kutta pair with step-size control.

    ``step(state_in, state_out, t, h)`` integrates from t to exactly t + h with as many internal
    steps as the tolerance needs, so ``Simulator.step(dt)`` and ``Simulator.run(fps=...)`` land
    exactly on their times (with ``run``, pass ``substeps=1``: each substep is its own call).
    Each internal step takes the fifth-order solution (local extrapolation) and the 7-stage
    Dormand-Prince slopes, the last of which is the first of the next internal step (first same
    as last: 6 derivative evaluations per step, plus one at the start of every call, since the
    simulator may change the state between calls: contacts, projections, emitters).

    Error control, per trial step of size s: err = max_i |y5_i - y4_i| / (atol + rtol max(|y_i|,
    |y5_i|)) over the whole flat state (every component: positions, velocities, orientations,
    momenta), reduced on the device (one scalar read back per trial). err <= 1 accepts; err > 1
    (or a non-finite trial) rejects and retries. The next size is s clamp(0.9 err^(-1/5), 0.2, 5)
    (no growth right after a rejection). What remains of the span is split into equal steps no
    longer than that size, so the last one lands on t + h without a sliver. The
    proposed size is kept between calls (``step_size``; a step shortened to fit the span does not
    lower it unless its error asks for that), so the next call starts where the last one left off;
    the first call tries the whole span, or ``first_step`` if given.

    Options (``Simulator(scene, integrator=RK45(rtol=1e-8, atol=1e-10))``):
    rtol: relative tolerance, 4 machine epsilons of the precision <= rtol < 1 (default 1e-6, which float32
        allows too)
    atol: absolute tolerance in the state's units (m, m/s, kg m/s, ...), > 0 (default 1e-9)
    max_steps: internal trial steps allowed per call, >= 1 (default 100000)
    first_step: the first trial step [s], > 0, or None (the whole span)
    A step size below 1e-12 of the call's span, or more than max_steps trials, raises AdaptiveStepFailed (a
    SimulationDiverged) naming the time.

    Counters, cumulative since the solver was made (also ``stats()``):
    accepted, rejected: internal steps
    evaluations: derivative evaluations, the cost to compare with fixed-step solvers
    """

    name, order = "rk45", 5
    capturable = False   # its step size and the steps it takes follow an error read back
    min_step_fraction = 1.0e-12
    persistent = ("step_size", "accepted", "rejected", "evaluations")
    safety, min_factor, max_factor = 0.9, 0.2, 5.0

    def __init__(self, rtol: float = 1.0e-6, atol: float = 1.0e-9, max_steps: int = 100_000,
                 first_step: float | None = None):
        super().__init__()
        self.rtol = checks.scalar("rtol", rtol)
        if not RTOL_FLOOR <= self.rtol < 1.0:   # the precision's own floor is checked at bind
            raise checks.fail("rtol", rtol, f"must be >= {RTOL_FLOOR:.3g} (4 machine epsilons of a float64 state) "
                                            "and < 1")
        self.atol = checks.scalar("atol", atol, low=0.0, low_open=True)
        self.max_steps = checks.count("max_steps", max_steps)
        self.step_size = None if first_step is None else checks.scalar("first_step", first_step, low=0.0,
                                                                          low_open=True)
        self.accepted = 0
        self.rejected = 0
        self.evaluations = 0

    def allocate(self, dynamics):
        model = dynamics.model
        rtol_low = 4.0 * float(np.finfo(model.numpy_scalar).eps)
        if self.rtol < rtol_low:
            raise checks.fail("rtol", self.rtol, f"must be >= {rtol_low:.3g} (4 machine epsilons of the "
                                                 f"{model.precision} state) and < 1")
        self.k = [dynamics.new_state() for _ in range(7)]
        self.stage = dynamics.new_state()
        self.spare = dynamics.new_state()
        self.err = wp.zeros(1, dtype=model.scalar, device=model.device)
        self._atol, self._rtol = model.scalar(self.atol), model.scalar(self.rtol)

    def amplification(self, h, w2, c, stiff=True):
        """None: it chooses its own steps from its tolerances (Integrator.amplification)."""
        return None

    def stats(self) -> dict:
        """accepted and rejected internal steps, and derivative evaluations, since the solver was made."""
        return {"accepted": self.accepted, "rejected": self.rejected, "evaluations": self.evaluations}

    def __repr__(self) -> str:
        return f"RK45(rtol={self.rtol:g}, atol={self.atol:g})"

    def _f(self, state: State, t: float, out: State) -> None:
        self.dynamics.derivative(state, t, out)
        self.evaluations += 1

    def _trial(self, y: State, t: float, s: float, out: State) -> float:
        """One Dormand-Prince trial step of size s from (t, y) with k[0] = f(t, y) given: the
        fifth-order solution into ``out``, k[6] = f(t + s, out); returns the scaled error."""
        (k1, k2, k3, k4, k5, k6, k7), stage, n = self.k, self.stage, y.y.shape[0]
        f, c, h = self._f, DP_NODES, self.scalar(s)
        self.launch(integrate.axpy, n, [y.y, self.scalar(0.2 * s), k1.y, stage.y])
        f(stage, t + c[1] * s, k2)
        self.launch(integrate.dp_stage3, n, [y.y, h, k1.y, k2.y, stage.y])
        f(stage, t + c[2] * s, k3)
        self.launch(integrate.dp_stage4, n, [y.y, h, k1.y, k2.y, k3.y, stage.y])
        f(stage, t + c[3] * s, k4)
        self.launch(integrate.dp_stage5, n, [y.y, h, k1.y, k2.y, k3.y, k4.y, stage.y])
        f(stage, t + c[4] * s, k5)
        self.launch(integrate.dp_stage6, n, [y.y, h, k1.y, k2.y, k3.y, k4.y, k5.y, stage.y])
        f(stage, t + s, k6)
        self.launch(integrate.dp_solution, n, [y.y, h, k1.y, k3.y, k4.y, k5.y, k6.y, out.y])
        f(out, t + s, k7)
        self.err.zero_()
        self.launch(integrate.dp_error_max, n, [y.y, out.y, h, k1.y, k3.y, k4.y, k5.y, k6.y, k7.y, self._atol,
                                                self._rtol, self.err])
        return float(self.err.numpy()[0])

    def step(self, state_in, state_out, t, h):
        span = float(h)
        h_min = self.min_step_fraction * span
        wanted = span if self.step_size is None else self.step_size   # the controller's size, unclipped
        current, done, trials, just_rejected = state_in, 0.0, 0, False
        self._f(state_in, t, self.k[0])
        while True:
            remaining = span - done
            # split what remains into equal steps no longer than wanted: no sliver at the end
            pieces = math.ceil(remaining / wanted - 1e-9)
            last = pieces <= 1
            s = remaining if last else remaining / pieces
            if s < h_min:
                raise AdaptiveStepFailed(t + done, f"the step size {s:.3g} s fell below {h_min:.3g} s "
                                                   f"({self.min_step_fraction:g} of the step {span:.6g} s) at "
                                                   f"rtol={self.rtol:g}, atol={self.atol:g}; the solution may be "
                                                   f"singular there")
            if trials >= self.max_steps:
                raise AdaptiveStepFailed(t + done, f"{trials} internal steps (max_steps) did not reach "
                                                   f"t = {t + span:.9g} s at rtol={self.rtol:g}, atol={self.atol:g}")
            trials += 1
            out = state_out if current is not state_out else self.spare
            err = self._trial(current, t + done, s, out)
            if err == 0.0:
                factor = self.max_factor
            elif math.isfinite(err):
                factor = min(self.max_factor, max(self.min_factor, self.safety * err ** -0.2))
            else:
                factor = self.min_factor
            if not err <= 1.0:                        # also a NaN error: reject
                self.rejected += 1
                just_rejected = True
                wanted = s * min(factor, 1.0)
                continue
            self.accepted += 1
            current = out
            self.k[0], self.k[6] = self.k[6], self.k[0]     # first same as last
            if just_rejected:
                factor = min(factor, 1.0)
            just_rejected = False
            # a step shortened to land on the end says nothing against the longer size wanted before
            wanted = max(s * factor, wanted) if s < wanted and factor >= 1.0 else s * factor
            if last:
                break
            done += s
        self.step_size = wanted
        if current is not state_out:
            wp.copy(state_out.y, current.y)

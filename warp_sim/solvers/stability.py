"""The longest step a solver takes stably on a scene, and so the substeps a step of dt needs.

A fixed-step solver applied to the test oscillator x'' = -w^2 x - c x' multiplies (x, v) by a 2 x 2 matrix each
step (``Integrator.amplification``). A step h is stable when the spectral radius rho of that matrix lets the
amplitude grow by at most GROWTH_PER_SECOND per simulated second: rho^(1/h) <= 1 + GROWTH_PER_SECOND. Inside a
solver's stability region (rho <= 1: rk4 up to w h = 2.83, symplectic Euler and Verlet up to 2) that changes nothing;
for explicit Euler and midpoint, which grow an undamped oscillator at any step, it is the step at which that growth
stays that small (very short: they are not for stiff springs, and the Simulator says so).

The oscillators are a scene's stiffest modes: its springs' (``scene.stiffness``, with their dampers and the linear
drag) and, with penalty contacts, the contact spring on the lightest particle (k / m) or body (2 k / m, two bodies)
with a critical damper. The step limit is the shortest of their stable steps times SAFETY (the springs are
linearised at the initial positions; a stretched spring is a little stiffer across).
"""
from __future__ import annotations

import contextlib
import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..scene.stiffness import stiffest_mode
from .base import Integrator

GROWTH_PER_SECOND = 0.01   # a step is stable while the stiffest mode's amplitude grows at most 1 % per second
SAFETY = 0.95              # the step limit is this fraction of the longest stable step of the linearised scene
MAX_AUTO_SUBSTEPS = 4096   # substeps="auto" takes at most this many pieces per step (and warns if it needs more)
#: the Simulator's warnings about steps longer than the stable one, and about euler and midpoint on springs
STEP_WARNINGS = r"substeps=|integrator='\w+' grows"


@contextlib.contextmanager
def unchecked_steps():
    """Silence the warnings about too long steps inside the block: for studies that measure such steps."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=STEP_WARNINGS)
        yield


@dataclass(frozen=True)
class StepLimit:
    """The longest step [s] a solver takes stably on a scene (math.inf: none binds), and why.

    step: SAFETY times the longest stable step of the stiffest mode [s]; longest: that longest stable step itself
    [s] (a step beyond it grows the mode); omega: that mode's angular frequency [rad/s] (0 without one); cause:
    what it is, in words ("the springs' stiffest mode, omega = 471 rad/s, at particle 1197"); grows_at_any_step:
    the solver grows an undamped oscillator at any step (euler, midpoint) and the scene has one."""
    step: float
    longest: float = math.inf
    omega: float = 0.0
    cause: str = "nothing stiff"
    grows_at_any_step: bool = False

    def pieces(self, h: float) -> int:
        """The fewest equal pieces of a step of h seconds that are each no longer than ``step``."""
        if not math.isfinite(self.step):
            return 1
        return max(1, math.ceil(h / self.step * (1.0 - 1e-12)))


def spectral_radius(integrator: Integrator, h: float, omega: float, c: float, stiff: bool = True) -> float:
    """rho of one step of h [s] of ``integrator`` on x'' = -omega^2 x - c x' (0 for a solver without a fixed step)."""
    matrix = integrator.amplification(h, omega * omega, c, stiff)
    return 0.0 if matrix is None else float(np.max(np.abs(np.linalg.eigvals(matrix))))


def stable_step(integrator: Integrator, omega: float, c: float, stiff: bool = True) -> float:
    """The longest step h [s] at which ``integrator`` lets the oscillator x'' = -omega^2 x - c x' grow by at most
    GROWTH_PER_SECOND a second (math.inf: any step). omega [rad/s], c [1/s]."""
    rate = max(omega, c)
    if rate <= 0.0:
        return math.inf
    allowed = math.log1p(GROWTH_PER_SECOND)

    def stable(h: float) -> bool:
        rho = spectral_radius(integrator, h, omega, c, stiff)
        return rho == 0.0 or math.log(rho) <= h * allowed

    low = 1.0 / rate
    while not stable(low):
        low *= 0.5
        if low * rate < 1e-12:
            return 0.0
    high = 2.0 * low
    while stable(high):
        low, high = high, 2.0 * high
        if high * rate > 1e12:
            return math.inf
    for _ in range(60):   # bisection to a relative bracket of 2^-60 of a factor 2
        middle = 0.5 * (low + high)
        low, high = (middle, high) if stable(middle) else (low, middle)
    return low


def grows_at_any_step(integrator: Integrator) -> bool:
    """Whether ``integrator`` grows an undamped oscillator at any fixed step (explicit Euler and midpoint do)."""
    return spectral_radius(integrator, 0.01, 1.0, 0.0) > 1.0 + 1e-12


def step_limit(scene, integrator: Integrator, penalty_stiffness: float | None = None,
               collisions: bool = True) -> StepLimit:
    """The StepLimit of ``integrator`` on ``scene``: its springs' stiffest mode and, where penalty_stiffness is
    given (contact="penalty"), the penalty contacts of particles on planes and of bodies."""
    modes = []   # (omega, c, stiff, cause)
    springs = stiffest_mode(scene)
    if springs is not None:
        modes.append((springs.omega, springs.damping, True,
                      f"the springs' stiffest mode, omega = {springs.omega:.4g} rad/s, at particle {springs.particle}"))
    if penalty_stiffness is not None:
        modes.extend(_penalty_modes(scene, penalty_stiffness, collisions))
    best = StepLimit(math.inf)
    for omega, c, stiff, cause in modes:
        longest = stable_step(integrator, omega, c, stiff)
        if SAFETY * longest < best.step:
            best = StepLimit(SAFETY * longest, longest, omega, cause, stiff and grows_at_any_step(integrator))
    return best


def _penalty_modes(scene, k: float, collisions: bool) -> list:
    """The penalty contact springs (critically damped, the most a contact's damper is): on the lightest particle
    that meets a plane, and between the lightest bodies."""
    modes = []
    masses = [scene.particle_array("mass")[~scene.particle_array("pinned").astype(bool)]]
    masses += [np.array([emitter.mass[0]]) for emitter in scene.emitters]
    particles = np.concatenate(masses) if masses else np.zeros(0)
    if scene.planes and len(particles):
        omega = math.sqrt(k / float(particles.min()))
        modes.append((omega, 2.0 * omega, False, f"the penalty contacts of particles, omega = {omega:.4g} rad/s"))
    if scene.body_count and collisions and (scene.planes or scene.colliders or scene.body_count > 1):
        omega = math.sqrt(2.0 * k / float(scene.body_array("mass").min()))
        modes.append((omega, 2.0 * omega, False, f"the penalty contacts of bodies, omega = {omega:.4g} rad/s"))
    return modes

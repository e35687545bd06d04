"""Each solver's longest stable step on the damped test oscillator (solvers.stability) against closed forms."""
import math

import pytest

import warp_sim as ws
from warp_sim.solvers import INTEGRATORS
from warp_sim.solvers.stability import GROWTH_PER_SECOND, grows_at_any_step, stable_step

OMEGA = 1.0e3   # [rad/s]: fast enough that the 1 %-a-second allowance moves the edge of a region by under 1e-5


@pytest.mark.parametrize("name, omega_h", [("rk4", 2.0 * math.sqrt(2.0)), ("symplectic_euler", 2.0), ("verlet", 2.0)])
def test_undamped_limits_are_the_stability_intervals(name, omega_h):
    assert stable_step(INTEGRATORS[name](), OMEGA, 0.0) * OMEGA == pytest.approx(omega_h, rel=1e-5)


@pytest.mark.parametrize("c", [10.0, 300.0, 3000.0])
def test_damped_symplectic_euler_matches_its_closed_form(c):
    """v1 = v + h(-w^2 x - c v), x1 = x + h v1 is stable while h^2 w^2 <= 4 - 2 h c: h = (sqrt(c^2 + 4 w^2) - c) / w^2
    (an overdamped mode, c >> w, is held by the damper: h <= 2 / c as c grows)."""
    exact = (math.sqrt(c * c + 4.0 * OMEGA**2) - c) / OMEGA**2
    assert stable_step(ws.SymplecticEuler(), OMEGA, c) == pytest.approx(exact, rel=1e-5)


def test_explicit_euler_and_midpoint_keep_their_growth_to_one_percent_a_second():
    """Undamped, explicit Euler grows the amplitude by sqrt(1 + (wh)^2) a step and midpoint by sqrt(1 + (wh)^4/4):
    the step where that is 1 % a second; with damping c, Euler's region |1 + h lambda| <= 1 gives h <= c / w^2."""
    rate = math.log1p(GROWTH_PER_SECOND)
    euler = stable_step(ws.Euler(), OMEGA, 0.0)
    assert 0.5 * math.log1p((OMEGA * euler) ** 2) / euler == pytest.approx(rate, rel=1e-6)
    midpoint = stable_step(ws.Midpoint(), OMEGA, 0.0)
    assert 0.5 * math.log1p((OMEGA * midpoint) ** 4 / 4.0) / midpoint == pytest.approx(rate, rel=1e-6)
    assert stable_step(ws.Euler(), OMEGA, 200.0) == pytest.approx(200.0 / OMEGA**2, rel=1e-3)
    assert grows_at_any_step(ws.Euler()) and grows_at_any_step(ws.Midpoint())
    assert not any(grows_at_any_step(INTEGRATORS[n]()) for n in ("rk4", "symplectic_euler", "verlet", "implicit_euler"))


def test_implicit_euler_and_rk45_have_no_limit_but_implicit_euler_steps_penalty_contacts_explicitly():
    assert stable_step(ws.ImplicitEuler(), OMEGA, 0.0) == math.inf
    assert stable_step(ws.RK45(), OMEGA, 0.0) == math.inf
    assert stable_step(ws.ImplicitEuler(), OMEGA, 0.0, stiff=False) * OMEGA == pytest.approx(2.0, rel=1e-5)

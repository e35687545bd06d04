"""The ODE solvers against closed forms: projectile, harmonic oscillator orders, stability limit."""
import math

import numpy as np
import pytest
from helpers import G, oscillator, particle, run_steps

import warp_sim as ws

EXPECTED_ORDER = {"euler": 1, "midpoint": 2, "rk4": 4, "symplectic_euler": 1, "verlet": 2, "implicit_euler": 1}
# adaptive solvers: the error follows the tolerance, not the step, so no fixed-step order (tests/test_rk45.py)
ADAPTIVE = {"rk45"}


def test_every_integrator_has_an_expected_order():
    assert set(EXPECTED_ORDER) | ADAPTIVE == set(ws.INTEGRATORS)


def projectile(integrator, device, T=2.0, h=0.01):
    scene = ws.Scene(precision="float64")
    x0, v0 = np.array([0.0, 1.0, 0.0]), np.array([3.0, 10.0, -1.0])
    scene.add_particles([x0], [v0])
    sim = ws.Simulator(scene, integrator=integrator, device=device)
    run_steps(sim, round(T / h), h)
    exact = x0 + v0 * T + 0.5 * np.array([0.0, -G, 0.0]) * T**2
    x, v = particle(sim)
    return x, exact, v, v0 + np.array([0.0, -G, 0.0]) * T


@pytest.mark.parametrize("integrator", ["midpoint", "rk4", "verlet"])
def test_projectile_exact_for_second_order_and_above(integrator, device):
    x, exact, v, v_exact = projectile(integrator, device)
    assert np.abs(x - exact).max() < 1e-9
    assert np.abs(v - v_exact).max() < 1e-9


@pytest.mark.parametrize("integrator, sign", [("euler", +1), ("symplectic_euler", -1)])
def test_projectile_first_order_error_is_g_T_h_over_2(integrator, sign, device):
    T, h = 2.0, 0.01
    x, exact, _, _ = projectile(integrator, device, T, h)
    # Euler lags the parabola by |g| T h / 2 (it misses the h^2/2 term each step);
    # symplectic Euler leads it by the same amount.
    error = x[1] - exact[1]
    assert error == pytest.approx(sign * G * T * h / 2, rel=0.01)
    assert abs(x[0] - exact[0]) < 1e-9


def oscillator_error(integrator, h, device, T=2.0, k=4.0, m=1.0, amplitude=0.1):
    sim = ws.Simulator(oscillator(k, m, amplitude), integrator=integrator, device=device)
    run_steps(sim, round(T / h), h)
    x, v = particle(sim, 1)
    omega = math.sqrt(k / m)
    exact_x = 1.0 + amplitude * math.cos(omega * T)
    exact_v = -amplitude * omega * math.sin(omega * T)
    return math.hypot(x[0] - exact_x, (v[0] - exact_v) / omega)


@pytest.mark.parametrize("integrator", sorted(EXPECTED_ORDER))
def test_oscillator_observed_order(integrator, device):
    steps = np.array([0.02, 0.01, 0.005, 0.0025])
    errors = np.array([oscillator_error(integrator, h, device) for h in steps])
    order = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    print(f"{integrator}: errors {errors}, observed order {order:.3f}")
    assert order == pytest.approx(EXPECTED_ORDER[integrator], abs=0.2)


@pytest.mark.filterwarnings("error::RuntimeWarning")
@pytest.mark.parametrize("integrator", ["symplectic_euler", "verlet"])
def test_stiff_spring_stability_limit_of_symplectic_schemes(integrator):
    """ks/m = 1e6: stable below h = 2 sqrt(m/k), diverges (and says so) above it."""
    k, m = 1.0e6, 1.0
    limit = 2.0 * math.sqrt(m / k)
    sim = ws.Simulator(oscillator(k, m, amplitude=0.01, precision="float32"), integrator=integrator, device="cpu")
    peak = 0.0
    for _ in range(10_000):
        sim.step(0.98 * limit, substeps=1)   # just inside the limit: no warning (the filter makes one an error)
        peak = max(peak, abs(float(sim.state.particle_x.numpy()[1, 0]) - 1.0))
    # bounded: the modified energy keeps |x| below A / sqrt(1 - (h w / 2)^2) = 5.03 A
    assert peak < 0.01 / math.sqrt(1.0 - 0.98**2) * 1.01
    sim = ws.Simulator(oscillator(k, m, amplitude=0.01, precision="float32"), integrator=integrator, device="cpu")
    with pytest.raises(ws.SimulationDiverged) as caught, \
            pytest.warns(RuntimeWarning, match=r"substeps=1 gives steps of .* longer than .* 2 substeps"):
        for _ in range(10_000):
            sim.step(1.05 * limit, substeps=1)
    assert caught.value.component == "particles" and caught.value.element == 1
    assert 1 <= caught.value.step < 10_000


def test_damped_spring_loses_energy_at_the_closed_form_rate(device):
    """The damper opposes the rate of change of length: amplitude decays as exp(-kd t / 2m)."""
    k, m, kd, T = 100.0, 1.0, 0.4, 3.0
    sim = ws.Simulator(oscillator(k, m, amplitude=0.1, damping=kd), integrator="rk4", device=device)
    run_steps(sim, 3000, T / 3000)
    x, v = particle(sim, 1)
    gamma = kd / (2 * m)
    omega_d = math.sqrt(k / m - gamma**2)
    exact = 0.1 * math.exp(-gamma * T) * (math.cos(omega_d * T) + gamma / omega_d * math.sin(omega_d * T))
    assert x[0] - 1.0 == pytest.approx(exact, abs=1e-9)

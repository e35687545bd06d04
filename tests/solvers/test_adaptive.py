"""The adaptive Dormand-Prince 5(4) solver "rk45": accuracy per derivative evaluation on an
eccentric Kepler orbit, exact landing on the requested times, step rejection and growth,
a torque-free rigid body, every component in one scene, and bad input."""
import math

import numpy as np
import pytest
from helpers import G, oscillator, particle

import warp_sim as ws
from warp_sim import RK45, AdaptiveStepFailed
from warp_sim.solvers import make_integrator

# point masses in the xy-plane with I_body = diag(1, 2, 3) kg m^2, spun near the intermediate axis
LAMINA = ws.PointMasses([[math.sqrt(2.0), 0, 0], [-math.sqrt(2.0), 0, 0], [0, 1, 0], [0, -1, 0]], 0.5)
OMEGA0 = (0.1, 1.0, 0.1)   # [rad/s]


class RecordingRK45(RK45):
    """RK45 that records every trial step: (t, size, scaled error)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.trials = []

    def _trial(self, y, t, s, out):
        err = super()._trial(y, t, s, out)
        self.trials.append((t, s, err))
        return err


def kepler(integrator, e=0.99, GM=1.0, a=1.0, **options):
    """A particle on a Kepler ellipse of eccentricity e and semi-major axis a [m] around the inverse-square
    attractor at the origin, started at apoapsis. Returns (simulator, start position, period)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_field(ws.Attractor(position=(0.0, 0.0, 0.0), strength=GM))   # min_distance 1e-3 < periapsis 0.01
    r_apo = a * (1.0 + e)
    v_apo = math.sqrt(GM * (1.0 - e) / (a * (1.0 + e)))                      # vis-viva at apoapsis
    scene.add_particles([[r_apo, 0.0, 0.0]], [[0.0, v_apo, 0.0]])
    sim = ws.Simulator(scene, integrator=make_integrator(integrator, **options), device="cpu")
    return sim, np.array([r_apo, 0.0, 0.0]), 2.0 * math.pi * math.sqrt(a**3 / GM)


def test_kepler_orbit_e099_beats_rk4_at_equal_cost(capsys):
    """e = 0.99: after one period rk45 is back at the start within 1e-6 a; rk4 with the same number of
    derivative evaluations (fixed steps) misses by far more than 10 times that."""
    sim, x0, T = kepler("rk45", rtol=1e-10, atol=1e-12)
    sim.step(T)                                      # one call: as many internal steps as needed
    assert sim.time == T
    error45 = float(np.linalg.norm(particle(sim)[0] - x0))      # a = 1 m: absolute = relative to a
    rk45 = sim.integrator
    assert rk45.evaluations == 1 + 6 * (rk45.accepted + rk45.rejected)
    steps = rk45.evaluations // 4
    sim4, _, _ = kepler("rk4")
    sim4.step(T / steps, steps)
    error4 = float(np.linalg.norm(particle(sim4)[0] - x0))
    with capsys.disabled():
        print(f"\n  Kepler e = 0.99, one period: rk45 error {error45:.3e} a with {rk45.evaluations} evaluations "
              f"({rk45.accepted} accepted, {rk45.rejected} rejected steps); rk4 error {error4:.3e} a with "
              f"{4 * steps} evaluations ({steps} steps of {T / steps:.3e} s)")
    assert error45 < 1e-6
    assert error4 > 10.0 * error45


def test_step_lands_exactly_and_projectile_is_exact():
    """sim.step(0.1) leaves time 0.1 and the projectile's closed form to 1e-12, for any step sizes inside."""
    scene = ws.Scene(precision="float64")
    x0, v0 = np.array([0.0, 1.0, 0.0]), np.array([3.0, 10.0, -1.0])
    scene.add_particles([x0], [v0])
    solver = RecordingRK45(rtol=1e-8, first_step=0.03)
    sim = ws.Simulator(scene, integrator=solver, device="cpu")
    sim.step(0.1)
    assert sim.time == 0.1
    x, v = particle(sim)
    g = np.array([0.0, -G, 0.0])
    np.testing.assert_allclose(x, x0 + v0 * 0.1 + 0.5 * g * 0.1**2, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(v, v0 + g * 0.1, rtol=0.0, atol=1e-12)
    # 0.1 s split into equal steps no longer than 0.03 s; the first, exact, grows the next 5x: the rest in one
    assert [s for _, s, _ in solver.trials] == pytest.approx([0.025, 0.075], rel=1e-12)


def test_run_lands_on_frame_times():
    scene = ws.Scene(precision="float64")
    x0, v0 = np.array([0.0, 1.0, 0.0]), np.array([1.0, 2.0, 0.0])
    scene.add_particles([x0], [v0])
    sim = ws.Simulator(scene, integrator="rk45", device="cpu")
    sim.run(seconds=0.5, fps=10, substeps=1, progress=False)     # frames 0 .. 4: the last at 0.4 s
    assert sim.time == pytest.approx(0.4, abs=1e-15)
    x, _ = particle(sim)
    np.testing.assert_allclose(x, x0 + v0 * 0.4 + 0.5 * np.array([0.0, -G, 0.0]) * 0.4**2, rtol=0.0, atol=1e-12)


def test_damped_oscillator_matches_closed_form_to_the_tolerance():
    """A particle on a damped spring to a pinned particle, 30 calls of 0.1 s at rtol 1e-8, atol 1e-10:
    position within the tolerance scale (atol + rtol |x|, |x| ~ 1 m), velocity within 20 times it."""
    k, m, kd, T, amplitude, rtol, atol = 100.0, 1.0, 0.4, 3.0, 0.1, 1e-8, 1e-10
    sim = ws.Simulator(oscillator(k, m, amplitude=amplitude, damping=kd), integrator=ws.RK45(rtol=rtol, atol=atol),
                       device="cpu")
    for _ in range(30):
        sim.step(0.1)
    x, v = particle(sim, 1)
    gamma = kd / (2 * m)
    omega_d = math.sqrt(k / m - gamma**2)
    decay = amplitude * math.exp(-gamma * T)
    exact_x = 1.0 + decay * (math.cos(omega_d * T) + gamma / omega_d * math.sin(omega_d * T))
    exact_v = -decay * (k / m) / omega_d * math.sin(omega_d * T)
    scale = atol + rtol * 1.0
    assert abs(x[0] - exact_x) < scale
    assert abs(v[0] - exact_v) < 20.0 * scale
    assert particle(sim, 0)[0].tolist() == [0.0, 0.0, 0.0]       # the pinned end stays put


def test_rejections_are_counted_and_the_step_recovers():
    """Tight tolerance and a first try of the whole 1 s span on w = 10 rad/s: rejected, shrunk by at
    most 5x per try, then accepted; the counters add up."""
    solver = RecordingRK45(rtol=1e-10, atol=1e-12)
    sim = ws.Simulator(oscillator(k=100.0), integrator=solver, device="cpu")
    sim.step(1.0)
    assert sim.time == 1.0
    assert solver.rejected >= 1 and solver.trials[0][2] > 1.0
    assert solver.accepted + solver.rejected == len(solver.trials)
    assert solver.evaluations == 1 + 6 * len(solver.trials)
    for (_, s0, e0), (_, s1, _) in zip(solver.trials, solver.trials[1:]):
        if e0 > 1.0:                                    # after a rejection: smaller, by at most 5x
            assert 0.2 * s0 * (1 - 1e-12) <= s1 < s0


def test_step_grows_on_a_smooth_problem_within_the_growth_limit():
    """From a 1e-6 s first step on a slow oscillator (w = 1 rad/s) the step grows, by at most 5x per
    accepted step, and the last size is kept for the next call."""
    solver = RecordingRK45(rtol=1e-6, atol=1e-9, first_step=1e-6)
    sim = ws.Simulator(oscillator(k=1.0), integrator=solver, device="cpu")
    sim.step(2.0)
    sizes = [s for _, s, _ in solver.trials]
    accepted = [e <= 1.0 for _, _, e in solver.trials]
    ratios = [b / a for a, b, ok in zip(sizes, sizes[1:], accepted) if ok]
    assert max(ratios) <= 5.0 * (1 + 1e-12)
    assert max(ratios) == pytest.approx(5.0)          # the growth limit is what holds it at first
    assert sizes[0] == 1e-6 and max(sizes) > 1e-2
    assert solver.accepted < 40
    kept = solver.step_size
    assert kept > 1e-2
    before = len(solver.trials)
    sim.step(2.0)
    # it starts where it left off: the 2 s split into equal steps no longer than the kept size
    assert solver.trials[before][1] == pytest.approx(2.0 / math.ceil(2.0 / kept), rel=1e-12)


def test_torque_free_body_conserves_L_and_energy_to_the_tolerance():
    """I_body = diag(1, 2, 3) point masses tumbling about the intermediate axis for 25 s (through the flip):
    L exact to 1e-12, kinetic energy to 10 rtol = 1e-9 relative at rtol 1e-10, unit quaternion."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_rigid_body(LAMINA, angular_velocity=OMEGA0)
    sim = ws.Simulator(scene, integrator=ws.RK45(rtol=1e-10, atol=1e-12), device="cpu")

    def energy_and_L():
        _, omega = (a.numpy()[0] for a in sim.body_velocities())
        L = sim.state.body_L.numpy()[0]
        return 0.5 * float(omega @ L), L

    E0, L0 = energy_and_L()
    for _ in range(50):
        sim.step(0.5)
    E, L = energy_and_L()
    q = sim.state.body_q.numpy()[0]
    drift = abs(E - E0) / E0
    print(f"rk45 torque-free body, 25 s: energy drift {drift:.3e}, {sim.integrator.evaluations} evaluations")
    assert np.linalg.norm(L - L0) <= 1e-12 * np.linalg.norm(L0)
    assert drift < 1e-9
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12
    assert sim.time == pytest.approx(25.0, abs=1e-12)


def test_every_component_in_one_scene():
    """Cloth (springs), a body on the ground, an emitter and a field together: runs, stays finite."""
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=0.3, friction=0.5)
    scene.add_cloth_grid(resolution=(4, 4), size=(0.5, 0.5), position=(0.0, 1.0, 0.0), mass=0.2,
                         stiffness=(1e3, 1e3, 1e2), damping=(0.5, 0.5, 0.1), pinned=(0, 3))
    scene.add_rigid_body(ws.Sphere(radius=0.1), density=500.0, position=(1.0, 0.5, 0.0),
                         angular_velocity=(0.0, 1.0, 2.0))
    scene.add_emitter(rate=50.0, lifetime=0.5, position=(-1.0, 0.5, 0.0), speed=(1.0, 2.0), seed=1)
    scene.add_field(ws.Vortex(position=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0), strength=0.5))
    sim = ws.Simulator(scene, integrator=ws.RK45(rtol=1e-6, atol=1e-8), device="cpu")
    sim.run(seconds=0.45, fps=20, substeps=1, progress=False)     # frames 0 .. 8: the last at 0.4 s
    assert sim.time == pytest.approx(0.4, abs=1e-12)
    for name in ("particle_x", "particle_v", "body_x", "body_q", "body_P", "body_L"):
        assert np.all(np.isfinite(getattr(sim.state, name).numpy()))
    assert sim.integrator.accepted >= 8 and sim.integrator.evaluations > 0
    assert sim.state.body_x.numpy()[0, 1] >= 0.1 - 1e-6                  # the sphere rests on the ground


@pytest.mark.parametrize("name, value", [("rtol", 0.0), ("rtol", -1e-6), ("rtol", float("nan")), ("rtol", 1.0),
                                         ("rtol", 1e-17), ("atol", 0.0), ("atol", -1e-9), ("atol", float("nan")),
                                         ("atol", float("inf"))])
def test_bad_tolerances_name_the_argument(name, value):
    with pytest.raises(ValueError, match=f"^{name}=") as caught:
        ws.RK45(**{name: value})
    message = str(caught.value)
    assert "must be" in message


def test_float32_runs_at_the_default_tolerance_and_rejects_a_tighter_rtol_than_it_can_hold():
    sim = ws.Simulator(oscillator(k=4.0, precision="float32"), integrator="rk45", device="cpu")
    for _ in range(10):
        sim.step(0.1)
    x, _ = particle(sim, 1)
    assert x[0] == pytest.approx(1.0 + 0.1 * math.cos(2.0 * 1.0), abs=1e-5)
    with pytest.raises(ValueError, match="rtol=1e-07 is invalid.*float32"):
        ws.Simulator(oscillator(precision="float32"), integrator=ws.RK45(rtol=1e-7), device="cpu")


@pytest.mark.parametrize("integrator", ["rk4", "verlet", "implicit_euler"])
def test_tolerances_for_a_fixed_step_integrator_raise(integrator):
    with pytest.raises(ValueError, match="rtol=1e-06 is invalid.*'rk45' only"):
        make_integrator(integrator, rtol=1e-6)
    with pytest.raises(ValueError, match="atol=1e-09 is invalid.*'rk45' only"):
        make_integrator(integrator, atol=1e-9)


def test_make_integrator_options():
    solver = make_integrator("rk45", rtol=1e-7, atol=1e-10, max_steps=50)
    assert (solver.rtol, solver.atol, solver.max_steps) == (1e-7, 1e-10, 50)
    assert make_integrator("implicit_euler", tolerance=1e-8).tolerance == 1e-8
    with pytest.raises(ValueError, match="tolerance=.*'implicit_euler' only"):
        make_integrator("rk45", tolerance=1e-8)
    with pytest.raises(ValueError, match="bogus=1 is invalid.*no integrator takes 'bogus'"):
        make_integrator("rk45", bogus=1)
    with pytest.raises(ValueError, match="integrator='rk54'.*'rk45'"):
        ws.Simulator(oscillator(), integrator="rk54", device="cpu")


def test_too_many_steps_and_step_underflow_raise_naming_the_time():
    sim = ws.Simulator(oscillator(k=100.0), integrator=RK45(rtol=1e-10, max_steps=5), device="cpu")
    with pytest.raises(AdaptiveStepFailed, match=r"at t = [0-9.e-]+ s: 5 internal steps \(max_steps\)"):
        sim.step(1.0)
    sim = ws.Simulator(oscillator(k=100.0), integrator=RK45(rtol=1e-10), device="cpu")
    sim.integrator.min_step_fraction = 0.5            # a floor the tolerance cannot meet
    with pytest.raises(ws.SimulationDiverged, match="adaptive step failed at t = 0 s: the step size") as caught:
        sim.step(1.0)
    assert caught.value.time == 0.0 and caught.value.component == "integrator"

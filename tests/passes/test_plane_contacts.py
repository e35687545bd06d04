"""Particle-plane contacts: time-of-impact bounces, friction, resting, any plane, penalty mode."""
import math

import numpy as np
import pytest
from helpers import G, particle

import warp_sim as ws


def dropped_ball(integrator, device, restitution=0.8, friction=0.0, height=1.0, contact="impulse", **kwargs):
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=restitution, friction=friction)
    scene.add_particles([[0.0, height, 0.0]], radius=0.0)
    return ws.Simulator(scene, integrator=integrator, device=device, contact=contact, **kwargs)


@pytest.mark.parametrize("integrator", ["rk4", "verlet"])
def test_bounce_apexes_follow_restitution_squared(integrator, device):
    """Dropped from 1 m with e = 0.8 at dt = 1/60: apex n is 0.8^(2n) m; never below ground, never gains energy."""
    sim = dropped_ball(integrator, device)
    apexes, rising, energy = [], False, G * 1.0
    for _ in range(60 * 6):
        sim.step(1.0 / 60.0)
        x, v = particle(sim)
        assert x[1] >= 0.0
        e_now = G * x[1] + 0.5 * v @ v
        assert e_now <= energy + 1e-12
        energy = e_now
        if v[1] > 0 and not rising:          # first step after a bounce: apex of the ballistic arc
            apexes.append(x[1] + v[1] ** 2 / (2 * G))
        rising = v[1] > 0
    expected = 0.8 ** (2 * np.arange(1, 6))
    print(f"{integrator}: apexes {np.array(apexes[:5])}")
    np.testing.assert_allclose(apexes[:5], expected, rtol=1e-4)


@pytest.mark.parametrize("integrator", sorted(ws.INTEGRATORS))
def test_zero_restitution_leaves_no_upward_speed(integrator, device):
    sim = dropped_ball(integrator, device, restitution=0.0)
    for _ in range(120):
        sim.step(1.0 / 60.0)
        x, v = particle(sim)
        assert x[1] >= 0.0 and v[1] < 1e-3
    assert x[1] == pytest.approx(0.0, abs=1e-12) and abs(v[1]) < 1e-9


@pytest.mark.parametrize("integrator", sorted(ws.INTEGRATORS))
def test_sliding_particle_stops_after_v0_squared_over_2_mu_g(integrator, device):
    """5 m/s, mu = 0.5, dt = 1e-3: stops after v0^2 / (2 mu g) = 2.548 m and then stays put."""
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=0.5, friction=0.5)
    scene.add_particles([[0.0, 0.0, 0.0]], [[5.0, 0.0, 0.0]], radius=0.0)
    sim = ws.Simulator(scene, integrator=integrator, device=device)
    for _ in range(1500):
        sim.step(1e-3)
    x, v = particle(sim)
    assert np.linalg.norm(v) == 0.0                      # static friction holds it: no chatter
    assert x[0] == pytest.approx(5.0**2 / (2 * 0.5 * G), rel=0.01)
    assert x[1] == pytest.approx(0.0, abs=1e-12)
    for _ in range(100):
        sim.step(1e-3)
    x_after, v_after = particle(sim)
    np.testing.assert_array_equal(x_after, x)
    assert np.linalg.norm(v_after) == 0.0


def test_wall_reflects_at_the_time_of_impact(device):
    """No gravity, towards the wall x = -2 at 3 m/s, e = 0.5: closed-form position after the bounce."""
    scene = ws.Scene(gravity=(0, 0, 0), precision="float64")
    scene.add_plane(normal=(1, 0, 0), offset=-2.0, restitution=0.5, friction=0.4)
    scene.add_particles([[0.0, 0.5, 0.0]], [[-3.0, 0.0, 0.0]], radius=0.1)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
    for _ in range(10):
        sim.step(0.1)
    x, v = particle(sim)
    impact = (2.0 - 0.1) / 3.0
    assert v[0] == pytest.approx(1.5, rel=1e-12)
    assert x[0] == pytest.approx(-1.9 + 1.5 * (1.0 - impact), rel=1e-12)


def test_tilted_plane_reflects_normal_component_only(device):
    n = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    scene = ws.Scene(gravity=(0, 0, 0), precision="float64")
    scene.add_plane(normal=n, offset=0.0, restitution=1.0, friction=0.0)
    v0 = np.array([-1.0, -0.5, 0.25])
    scene.add_particles([[1.0, 1.0, 0.0]], [v0], radius=0.0)
    sim = ws.Simulator(scene, integrator="rk4", device=device)
    for _ in range(100):
        sim.step(0.05)
    x, v = particle(sim)
    np.testing.assert_allclose(v, v0 - 2 * (v0 @ n) * n, atol=1e-12)
    assert x @ n >= 0.0


def test_corner_of_two_planes_keeps_particle_outside_both(device):
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=0.3, friction=0.2)
    scene.add_plane(normal=(1, 0, 0), offset=-1.0, restitution=0.3, friction=0.2, name="Wall")
    scene.add_particles([[-0.9, 0.3, 0.0]], [[-20.0, -20.0, 0.0]], radius=0.05)
    sim = ws.Simulator(scene, integrator="verlet", device=device)
    for _ in range(300):
        sim.step(1.0 / 60.0)
        x, v = particle(sim)
        assert x[1] >= 0.05 - 1e-12 and x[0] >= -0.95 - 1e-12
    assert np.linalg.norm(v) < 1e-3


def test_particle_restitution_is_averaged_with_the_plane(device):
    """particle e = 0.6, ground e = 1.0: contact e = 0.8, so the first apex is 0.64 m."""
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=1.0, friction=0.0)
    scene.add_particles([[0.0, 1.0, 0.0]], radius=0.0, restitution=0.6)
    sim = ws.Simulator(scene, integrator="rk4", device=device)
    while particle(sim)[1][1] <= 0.0:
        sim.step(1.0 / 60.0)
    x, v = particle(sim)
    assert x[1] + v[1] ** 2 / (2 * G) == pytest.approx(0.64, rel=1e-9)


def test_penalty_contact_rests_at_m_g_over_k(device):
    k, m = 1.0e4, 2.0
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=0.5, friction=0.5)
    scene.add_particles([[0.0, 0.2, 0.0]], mass=m, radius=0.1)
    sim = ws.Simulator(scene, integrator="rk4", device=device, contact="penalty", penalty_stiffness=k)
    for _ in range(3000):
        sim.step(1e-3)
    x, v = particle(sim)
    assert 0.1 - x[1] == pytest.approx(m * G / k, rel=1e-3)
    assert np.linalg.norm(v) < 1e-4


def test_penalty_bounce_loses_energy_as_restitution_says(device):
    """The damper is set from e: an impact at 4.43 m/s rebounds to e^2 of the drop height."""
    sim = dropped_ball("rk4", device, restitution=0.5, contact="penalty", penalty_stiffness=1e6)
    rising, apex = False, None
    for _ in range(20000):
        sim.step(1e-4)
        x, v = particle(sim)
        if v[1] > 0:
            rising = True
        elif rising:
            apex = x[1]
            break
    print(f"penalty apex {apex:.4f} m (e^2 = 0.25)")
    assert apex == pytest.approx(0.25, rel=0.02)


def incline(mu, theta_degrees, device, integrator="symplectic_euler"):
    """A particle at rest on the plane through the origin tilted by theta about z."""
    theta = math.radians(theta_degrees)
    n = np.array([-math.sin(theta), math.cos(theta), 0.0])
    scene = ws.Scene(precision="float64")
    scene.add_plane(normal=n, offset=0.0, restitution=0.0, friction=mu)
    scene.add_particles([[0.0, 0.0, 0.0]], radius=0.0)
    return ws.Simulator(scene, integrator=integrator, device=device), theta


@pytest.mark.parametrize("integrator", ["symplectic_euler", "rk4"])
def test_static_friction_holds_on_an_incline_without_creep(integrator, device):
    """mu = 0.5 > tan 20 deg = 0.364: the particle stays exactly where it is."""
    sim, _ = incline(0.5, 20.0, device, integrator)
    for _ in range(2000):
        sim.step(1e-3)
    x, v = particle(sim)
    assert np.abs(x).max() < 1e-12 and np.abs(v).max() < 1e-12


@pytest.mark.parametrize("integrator", ["symplectic_euler", "verlet", "rk4"])
def test_kinetic_friction_on_an_incline(integrator, device):
    """mu = 0.2 < tan 30 deg: slides down the slope with a = g (sin t - mu cos t), on the plane."""
    sim, theta = incline(0.2, 30.0, device, integrator)
    T, h = 1.0, 1e-3
    for _ in range(round(T / h)):
        sim.step(h)
    x, v = particle(sim)
    a = G * (math.sin(theta) - 0.2 * math.cos(theta))
    down = -np.array([math.cos(theta), math.sin(theta), 0.0])
    assert x @ down == pytest.approx(0.5 * a * T**2, rel=2e-3)
    assert v @ down == pytest.approx(a * T, rel=2e-3)
    n = np.array([-math.sin(theta), math.cos(theta), 0.0])
    assert abs(x @ n) < 1e-12

"""Force fields (attractor, vortex, turbulence) against closed forms, through the real simulator."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import warp as wp

import warp_sim as ws
from warp_sim import Attractor, Turbulence, Vortex
from warp_sim.kernels import blocks
from warp_sim.kernels import fields as field_kernels

GM = 2.0                                    # [m^3/s^2]
CENTER = np.array([0.3, -0.2, 0.1])         # [m], off the origin on purpose
NORMAL = np.array([1.0, 2.0, 2.0]) / 3.0    # orbital plane normal, tilted on purpose
IN_PLANE = np.array([2.0, -1.0, 0.0]) / math.sqrt(5.0)


def simulator(positions, fields, device, velocities=None, mass=1.0, pinned=None, integrator="rk4",
              precision="float64"):
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision=precision)
    scene.add_particles(positions, velocities, mass=mass, pinned=pinned)
    for field in fields:
        scene.add_field(field)
    return ws.Simulator(scene, integrator=integrator, device=device)


def xv(sim):
    """Copies (the CPU arrays alias the state) of all positions [m] and velocities [m/s], float64."""
    return (sim.state.particle_x.numpy().astype(np.float64), sim.state.particle_v.numpy().astype(np.float64))


def one_euler_step_accelerations(points, fields, device, h=1e-3, mass=1.0):
    """The acceleration [m/s^2] at each point: explicit Euler from rest gives v1 = h a(x0) (and x1 = x0)."""
    sim = simulator(points, fields, device, mass=mass, integrator="euler")
    sim.step(h)
    return xv(sim)[1] / h


# --- attractor ----------------------------------------------------------------------------------

def test_circular_kepler_orbit_keeps_its_radius_over_ten_orbits(device):
    r = 1.5
    r0 = r * IN_PLANE
    v0 = math.sqrt(GM / r) * np.cross(NORMAL, IN_PLANE)
    period = 2.0 * math.pi * math.sqrt(r**3 / GM)
    sim = simulator([CENTER + r0], [Attractor(CENTER, GM)], device, [v0])
    radii = []
    for _ in range(100):                                    # 10 orbits, sampled every tenth of one
        sim.step(period / 1000, steps=100)
        radii.append(np.linalg.norm(xv(sim)[0][0] - CENTER))
    assert np.abs(np.array(radii) / r - 1.0).max() < 1e-6  # rk4 at 1000 steps/orbit: ~1e-10
    x = xv(sim)[0]
    assert np.linalg.norm(x[0] - CENTER - r0) < 1e-5 * r   # back at the start after 10 periods
    assert abs(np.dot(x[0] - CENTER, NORMAL)) < 1e-12      # never leaves its plane


def test_eccentric_orbit_returns_after_one_period_conserving_energy_and_angular_momentum(device):
    a, e = 1.2, 0.5
    r_peri, r_apo = a * (1 - e), a * (1 + e)
    v_peri = math.sqrt(GM * (1 + e) / r_peri)
    r0, v0 = r_peri * IN_PLANE, v_peri * np.cross(NORMAL, IN_PLANE)
    period = 2.0 * math.pi * math.sqrt(a**3 / GM)
    energy0, momentum0 = 0.5 * v_peri**2 - GM / r_peri, np.cross(r0, v0)
    assert energy0 == pytest.approx(-GM / (2 * a))
    sim = simulator([CENTER + r0], [Attractor(CENTER, GM)], device, [v0])
    radii = []
    for _ in range(10):
        sim.step(period / 1000, steps=100)
        x, v = xv(sim)
        r, u = x[0] - CENTER, v[0]
        radii.append(np.linalg.norm(r))
        energy = 0.5 * u @ u - GM / np.linalg.norm(r)
        assert abs(energy / energy0 - 1.0) < 1e-7                                       # observed ~2e-9
        assert np.linalg.norm(np.cross(r, u) - momentum0) < 1e-9 * np.linalg.norm(momentum0)  # ~5e-11
    assert radii[4] == pytest.approx(r_apo, rel=1e-6)        # apoapsis a (1 + e) at T / 2
    assert np.linalg.norm(r - r0) < 1e-6 * a                 # Kepler's third law: back after 2 pi sqrt(a^3 / GM)
    assert np.linalg.norm(u - v0) < 1e-6 * v_peri            # observed ~4e-8 for both


def test_attractor_is_mass_independent_and_spares_pinned_particles(device):
    start = CENTER + np.array([1.0, 0.2, -0.3])
    velocity = np.array([0.1, 1.1, 0.4])
    pinned_at = CENTER + np.array([-0.5, 0.0, 0.0])
    sim = simulator([start, start, pinned_at], [Attractor(CENTER, GM)], device,
                    [velocity, velocity, (0.0, 0.0, 0.0)], mass=[1e-3, 1e3, 1.0], pinned=[2])
    sim.step(0.01, steps=200)
    x, v = xv(sim)
    assert np.linalg.norm(x[0] - start) > 0.5                 # it did move
    np.testing.assert_allclose(x[1], x[0], rtol=0, atol=1e-12)  # a / inv_mass * inv_mass: rounding only
    np.testing.assert_allclose(v[1], v[0], rtol=0, atol=1e-12)
    assert np.array_equal(x[2], pinned_at) and not v[2].any()


def test_attractor_acceleration_is_newton_outside_and_a_uniform_ball_inside(device):
    d = 0.25                                                   # min_distance [m]
    offsets = np.array([[1.0, 0.0, 0.0], [0.0, -0.3, 0.4], [0.2, 0.2, 0.2], [0.0, 0.0, 0.1], [0.0, 0.0, 0.0]])
    for strength in (GM, -GM):                                # negative strength repels
        a = one_euler_step_accelerations(CENTER + offsets, [Attractor(CENTER, strength, d)], device)
        r = np.linalg.norm(offsets, axis=1, keepdims=True)
        expected = -strength * offsets / np.maximum(r, d) ** 3
        np.testing.assert_allclose(a, expected, rtol=1e-12, atol=1e-12)
    assert not a[-1].any()                                    # at the centre itself: zero, no singularity


# --- vortex -------------------------------------------------------------------------------------

def vortex_formula(points, center, axis, strength, core):
    n = np.asarray(axis) / np.linalg.norm(axis)
    d = points - center
    r = d - np.outer(d @ n, n)
    return strength * np.cross(n, r) / (np.sum(r * r, axis=1, keepdims=True) + core**2)


def test_vortex_acceleration_matches_the_formula(device):
    rng = np.random.default_rng(3)
    points = rng.uniform(-2.0, 2.0, (32, 3))
    center, axis, strength, core = np.array([0.1, 0.5, -0.2]), np.array([1.0, 1.0, 0.5]), 0.8, 0.3
    a = one_euler_step_accelerations(points, [Vortex(center, axis, strength, core)], device, mass=2.5)
    expected = vortex_formula(points, center, axis, strength, core)
    np.testing.assert_allclose(a, expected, rtol=1e-12, atol=1e-12)
    assert np.abs(a @ (axis / np.linalg.norm(axis))).max() < 1e-12     # no push along the axis


def test_vortex_swirls_counter_clockwise_about_its_axis(device):
    a = one_euler_step_accelerations([[1.0, 0.0, 0.0]], [Vortex((0.0, 0.0, 0.0), (0.0, 0.0, 3.0), 2.0, 1.0)],
                                     device)
    np.testing.assert_allclose(a[0], [0.0, 1.0, 0.0], atol=1e-12)   # 2 * (z x x) / (1 + 1) = +y


# --- turbulence ---------------------------------------------------------------------------------

def sample_turbulence(points, device, t=0.0, strength=1.0, scale=1.0, frequency=0.5, seed=0, octaves=1,
                      precision=np.float64):
    """The turbulence acceleration [m/s^2] at points, through the public kernel (unit mass)."""
    scalar, vec3 = (wp.float64, wp.vec3d) if precision == np.float64 else (wp.float32, wp.vec3f)
    n = len(points)

    def one(value):
        return wp.array(np.array([value], dtype=precision), dtype=scalar, device=device)

    force = wp.zeros(n, dtype=vec3, device=device)
    fields = blocks.fill(blocks.of(scalar).Turbulences, strength=one(strength), inv_scale=one(1.0 / scale),
                         frequency=one(frequency), seed=wp.array([seed], dtype=wp.int32, device=device),
                         octaves=wp.array([octaves], dtype=wp.int32, device=device))
    wp.launch(field_kernels.turbulence_forces, n,
              [wp.array(np.asarray(points, dtype=precision), dtype=vec3, device=device),
               wp.ones(n, dtype=scalar, device=device), scalar(t), fields, force], device=device)
    return force.numpy().astype(np.float64)


@pytest.mark.parametrize("octaves", [1, 3])
def test_turbulence_is_divergence_free(octaves, device):
    rng = np.random.default_rng(1)
    points = rng.uniform(-2.0, 2.0, (400, 3))
    scale, t = 0.7, 1.3
    h = 3e-3 * scale                                 # float32 noise: rounding ~1e-4, truncation ~1e-5 at this h
    J = np.zeros((len(points), 3, 3))                # J[:, i, k] = d a_i / d x_k, central differences
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        plus = sample_turbulence(points + step, device, t, scale=scale, octaves=octaves)
        minus = sample_turbulence(points - step, device, t, scale=scale, octaves=octaves)
        J[:, :, k] = (plus - minus) / (2 * h)
    size = np.linalg.norm(J, axis=(1, 2))
    divergence = np.trace(J, axis1=1, axis2=2)
    assert np.abs(divergence / size).max() < 5e-3    # observed <= 1e-3
    assert np.abs(divergence / size).mean() < 5e-4   # observed ~1e-4
    # the same differences detect the divergence of a field that has one: flip a_z
    flipped = J[:, 0, 0] + J[:, 1, 1] - J[:, 2, 2]
    assert np.abs(flipped / size).mean() > 0.1       # observed ~0.4


def test_turbulence_is_deterministic_seeded_time_varying_and_bounded(device):
    rng = np.random.default_rng(2)
    points = rng.uniform(-20.0, 20.0, (20000, 3))
    a = sample_turbulence(points, device, t=0.4, strength=2.0, seed=7)
    assert np.array_equal(a, sample_turbulence(points, device, t=0.4, strength=2.0, seed=7))
    assert np.abs(a - sample_turbulence(points, device, t=0.4, strength=2.0, seed=8)).mean() > 0.5
    assert np.abs(a - sample_turbulence(points, device, t=3.4, strength=2.0, seed=7)).mean() > 0.5
    steady = sample_turbulence(points, device, t=0.4, strength=2.0, seed=7, frequency=0.0)
    assert np.array_equal(steady, sample_turbulence(points, device, t=9.0, strength=2.0, seed=7, frequency=0.0))
    np.testing.assert_allclose(sample_turbulence(points, device, t=0.4, strength=6.0, seed=7), 3.0 * a, rtol=1e-12)
    for octaves in (1, 4):                 # |a| / strength: mean ~1, max observed 3.1 (1 octave), 3.6 (many)
        magnitude = np.linalg.norm(sample_turbulence(points, device, 0.4, 2.0, seed=7, octaves=octaves), axis=1)
        assert magnitude.max() <= 4.0 * 2.0
        assert 0.5 * 2.0 < magnitude.mean() < 1.5 * 2.0


def test_turbulence_float32_and_float64_agree(device):
    points = np.random.default_rng(4).uniform(-3.0, 3.0, (100, 3))
    a64 = sample_turbulence(points, device, t=0.25, scale=0.5)
    a32 = sample_turbulence(points, device, t=0.25, scale=0.5, precision=np.float32)
    np.testing.assert_allclose(a32, a64, rtol=0, atol=1e-5)   # the noise is float32 in both


# --- superposition ------------------------------------------------------------------------------

def test_fields_of_one_and_of_different_kinds_add_up(device):
    rng = np.random.default_rng(5)
    points = rng.uniform(-1.5, 1.5, (8, 3))
    mass = rng.uniform(0.5, 2.0, 8)
    fields = [Attractor((0.2, 0.0, 0.0), 1.0), Attractor((-0.5, 0.5, 0.1), -0.4, 0.2),
              Vortex((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.7), Vortex((0.3, 0.0, 0.3), (1.0, 0.0, 0.0), -0.5, 0.05),
              Turbulence(0.8, scale=0.6, seed=1), Turbulence(0.3, scale=2.0, seed=2, octaves=3)]
    together = one_euler_step_accelerations(points, fields, device, mass=mass)
    alone = [one_euler_step_accelerations(points, [field], device, mass=mass) for field in fields]
    assert all(np.abs(a).max() > 1e-3 for a in alone)
    np.testing.assert_allclose(together, np.sum(alone, axis=0), rtol=0, atol=1e-12)
    vortices = vortex_formula(points, np.zeros(3), (0.0, 1.0, 0.0), 0.7, 0.1) + vortex_formula(
        points, np.array([0.3, 0.0, 0.3]), (1.0, 0.0, 0.0), -0.5, 0.05)
    np.testing.assert_allclose(alone[2] + alone[3], vortices, rtol=1e-12, atol=1e-12)


# --- validation ---------------------------------------------------------------------------------

BAD = [
    ("position", lambda: Attractor((math.nan, 0.0, 0.0), 1.0)),
    ("position", lambda: Attractor((0.0, 0.0), 1.0)),
    ("strength", lambda: Attractor((0.0, 0.0, 0.0), math.inf)),
    ("strength", lambda: Attractor((0.0, 0.0, 0.0), "big")),
    ("min_distance", lambda: Attractor((0.0, 0.0, 0.0), 1.0, 0.0)),
    ("min_distance", lambda: Attractor((0.0, 0.0, 0.0), 1.0, -1.0)),
    ("position", lambda: Vortex((0.0, math.inf, 0.0), (0.0, 1.0, 0.0), 1.0)),
    ("axis", lambda: Vortex((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0)),
    ("axis", lambda: Vortex((0.0, 0.0, 0.0), (0.0, math.nan, 1.0), 1.0)),
    ("strength", lambda: Vortex((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), math.nan)),
    ("core_radius", lambda: Vortex((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 1.0, 0.0)),
    ("strength", lambda: Turbulence(-1.0)),
    ("scale", lambda: Turbulence(1.0, scale=-1.0)),
    ("scale", lambda: Turbulence(1.0, scale=0.0)),
    ("frequency", lambda: Turbulence(1.0, frequency=-0.5)),
    ("frequency", lambda: Turbulence(1.0, frequency=math.nan)),
    ("seed", lambda: Turbulence(1.0, seed=1.5)),
    ("seed", lambda: Turbulence(1.0, seed=True)),
    ("seed", lambda: Turbulence(1.0, seed=-1)),
    ("seed", lambda: Turbulence(1.0, seed=2**31)),
    ("octaves", lambda: Turbulence(1.0, octaves=0)),
    ("octaves", lambda: Turbulence(1.0, octaves=17)),
    ("octaves", lambda: Turbulence(1.0, octaves=2.0)),
]


@pytest.mark.parametrize("name, make", BAD, ids=[f"{name}{i}" for i, (name, _) in enumerate(BAD)])
def test_bad_field_input_raises_naming_the_argument(name, make):
    with pytest.raises(ValueError, match=rf"^{name}=.* is invalid: "):
        make()


def test_add_field_rejects_non_fields_and_fields_normalise_their_inputs():
    scene = ws.Scene()
    with pytest.raises(ValueError, match=r"^field='x' is invalid: expected a warp_sim force field"):
        scene.add_field("x")
    vortex = Vortex([0, 0, 0], np.array([0.0, 0.0, 2.0]), 1)
    assert vortex.axis == (0.0, 0.0, 1.0) and isinstance(vortex.strength, float)
    assert Turbulence(1.0, seed=np.int64(3)).seed == 3
    assert scene.add_field(vortex) == 0 and scene.add_field(Attractor((0, 1, 0), 1.0)) == 1


# --- leave out ----------------------------------------------------------------------------------

PROBE = r"""
import json, sys
import warp as wp
wp.config.log_level = wp.LOG_WARNING
import warp_sim as ws
scene = ws.Scene()
scene.add_particles([[0.0, 1.0, 0.0]])
if sys.argv[1] == "field":
    from warp_sim import Vortex
    scene.add_field(Vortex((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 1.0))
sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
sim.step(0.01, steps=3)
print(json.dumps({"loaded": bool(wp.get_module("warp_sim.kernels.fields").execs),
                  "terms": [type(term).__name__ for term in sim.dynamics.force_terms]}))
"""


@pytest.mark.parametrize("kind", ["none", "field"])
def test_fields_module_is_loaded_only_by_scenes_with_fields(kind):
    out = subprocess.run([sys.executable, "-c", PROBE, kind], capture_output=True, text=True, check=True)
    result = json.loads(out.stdout.strip().splitlines()[-1])
    with_field = kind == "field"
    assert result == {"loaded": with_field, "terms": ["FieldForces"] if with_field else []}

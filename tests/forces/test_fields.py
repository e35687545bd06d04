"""Force fields (attractor, vortex, turbulence) against closed forms, through the real simulator."""
import itertools
import json
import math
import subprocess
import sys

import numpy as np
import pytest
import warp as wp

import warp_sim as ws
from warp_sim import Attractor, Turbulence, Vortex
from warp_sim.forces.turbulence import PERIOD, TurbulenceGrids, grid_size
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
# The field is strength x curl of a quadratic B-spline potential on a periodic grid (warp_sim.forces.turbulence).

GAUSS = 0.5 * math.sqrt(0.6) * np.array([-1.0, 0.0, 1.0])   # 3-point Gauss-Legendre rule on [-1/2, 1/2]
GAUSS_WEIGHTS = np.array([5.0, 8.0, 5.0]) / 18.0


def turbulence_grids(device, strength=1.0, scale=1.0, frequency=0.5, seed=0, octaves=1, precision=np.float64):
    scalar = wp.float64 if precision == np.float64 else wp.float32
    return TurbulenceGrids([Turbulence(strength, scale, frequency, seed, octaves)], scalar, device)


def sample_turbulence(points, device, t=0.0, grids=None, precision=np.float64, **field):
    """The turbulence acceleration [m/s^2] at points [m] and time t [s], through the public kernel (unit mass)."""
    grids = grids or turbulence_grids(device, precision=precision, **field)
    scalar, vec3 = (wp.float64, wp.vec3d) if precision == np.float64 else (wp.float32, wp.vec3f)
    n = len(points)
    force = wp.zeros(n, dtype=vec3, device=device)
    wp.launch(field_kernels.turbulence_forces, n,
              [wp.array(np.asarray(points, dtype=precision), dtype=vec3, device=device),
               wp.ones(n, dtype=scalar, device=device), grids.block, grids.at(t), force], device=device)
    return force.numpy().astype(np.float64)


def reference_spline(grids, points, scale):
    """psi and curl psi (grid units) of field 0 at points [m], in numpy float64 from the block's grid: an independent
    implementation of the quadratic B-spline the kernel reads."""
    n = grids.nodes[0]
    stride = n + 3
    grid = grids.potential.numpy()[:stride**3].astype(np.float64).reshape(stride, stride, stride, 3)
    g = (np.asarray(points) / (PERIOD * scale)) % 1.0 * n
    m = np.floor(g + 0.5).astype(int)
    f = g - m
    w = np.stack([0.5 * (0.5 - f) ** 2, 0.75 - f * f, 0.5 * (0.5 + f) ** 2], -1)   # (points, axis, node)
    d = np.stack([f - 0.5, -2.0 * f, 0.5 + f], -1)
    psi, curl = np.zeros((len(g), 3)), np.zeros((len(g), 3))
    for i, j, k in itertools.product(range(3), repeat=3):
        node = grid[m[:, 0] + i, m[:, 1] + j, m[:, 2] + k]
        psi += (w[:, 0, i] * w[:, 1, j] * w[:, 2, k])[:, None] * node
        gradient = np.stack([d[:, 0, i] * w[:, 1, j] * w[:, 2, k], w[:, 0, i] * d[:, 1, j] * w[:, 2, k],
                             w[:, 0, i] * w[:, 1, j] * d[:, 2, k]], -1)
        curl += np.cross(gradient, node)
    return psi, curl


def period_quadrature(nodes, scale):
    """Points [m] and weights (summing to 1) of the 3-point Gauss rule in every spline cell of one period (cells
    centred on the nodes). Per cell the field is a polynomial of degree <= 2 in each coordinate, so the rule gives
    the mean of |a|^2 and of a . b over the period exactly."""
    g = (np.arange(nodes)[:, None] + GAUSS).ravel()
    w = np.tile(GAUSS_WEIGHTS, nodes) / nodes
    points = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) * (PERIOD * scale / nodes)
    return points, np.einsum("i,j,k->ijk", w, w, w).ravel()


def jacobian(field, points, h):
    """J[:, i, k] = d field_i / d x_k by central differences of step h [m]."""
    J = np.zeros((len(points), 3, 3))
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        J[:, :, k] = (field(points + step) - field(points - step)) / (2 * h)
    return J


@pytest.mark.parametrize("octaves, frequency, precision", [(1, 0.0, np.float64), (1, 0.5, np.float32),
                                                           (3, 0.5, np.float64)])
def test_turbulence_is_divergence_free(octaves, frequency, precision, device):
    """mean |div a| / mean |J|_F over 400 random points, J by central differences with h = cell / 100: the field
    is solenoidal in each spline cell and continuous across cells, so only rounding and the few stencils that
    straddle a cell face remain. The same measure on the potential psi itself (not solenoidal) is large."""
    rng = np.random.default_rng(1)
    points = rng.uniform(-2.0, 2.0, (400, 3))
    scale, t = 0.7, 1.3
    grids = turbulence_grids(device, scale=scale, frequency=frequency, octaves=octaves, precision=precision)
    h = 1e-2 * PERIOD * scale / grids.nodes[0]
    J = jacobian(lambda p: sample_turbulence(p, device, t, grids, precision), points, h)
    size, divergence = np.linalg.norm(J, axis=(1, 2)), np.abs(np.trace(J, axis1=1, axis2=2))
    assert divergence.mean() / size.mean() < 2e-4    # observed 1e-5 .. 3e-5
    assert np.max(divergence / size) < 5e-3          # observed <= 1.2e-3
    control = jacobian(lambda p: reference_spline(grids, p, scale)[0], points, h)
    ratio = np.abs(np.trace(control, axis1=1, axis2=2)).mean() / np.linalg.norm(control, axis=(1, 2)).mean()
    assert ratio > 0.3                               # observed 0.47 .. 0.49


def test_turbulence_kernel_is_the_curl_of_the_spline_potential(device):
    """The kernel's analytic curl against a numpy float64 evaluation of the same B-spline: float32 rounding only."""
    points = np.random.default_rng(6).uniform(-3.0, 3.0, (500, 3))
    grids = turbulence_grids(device, strength=2.5, scale=0.8, octaves=2)
    a = sample_turbulence(points, device, 0.6, grids)
    np.testing.assert_allclose(a, 2.5 * reference_spline(grids, points, 0.8)[1], rtol=0, atol=2.5 * 1e-5)


def test_turbulence_is_reproducible_and_seeded(device):
    """Two Simulators with one seed give bit-identical forces; another seed gives another field."""
    points = np.random.default_rng(2).uniform(-5.0, 5.0, (2000, 3))
    a = one_euler_step_accelerations(points, [Turbulence(2.0, seed=7)], device)
    assert np.array_equal(a, one_euler_step_accelerations(points, [Turbulence(2.0, seed=7)], device))
    assert np.abs(a - one_euler_step_accelerations(points, [Turbulence(2.0, seed=8)], device)).mean() > 1.0
    np.testing.assert_allclose(one_euler_step_accelerations(points, [Turbulence(6.0, seed=7)], device), 3.0 * a,
                               rtol=1e-12)


def test_turbulence_is_periodic_and_stretches_with_scale(device):
    """a(x + P L e_i) = a(x), and a_2L(2 x) = a_L(x): the same grid read at the same grid coordinates."""
    points = np.random.default_rng(3).uniform(-2.0, 2.0, (500, 3))
    scale = 0.6
    grids = turbulence_grids(device, scale=scale, octaves=2)
    a = sample_turbulence(points, device, 0.8, grids)
    for axis in range(3):
        shift = np.zeros(3)
        shift[axis] = PERIOD * scale
        np.testing.assert_allclose(sample_turbulence(points + shift, device, 0.8, grids), a, rtol=0, atol=1e-5)
    stretched = sample_turbulence(2.0 * points, device, 0.8, turbulence_grids(device, scale=2 * scale, octaves=2))
    np.testing.assert_allclose(stretched, a, rtol=0, atol=1e-5)
    assert np.abs(sample_turbulence(points + 0.5 * scale, device, 0.8, grids) - a).mean() > 0.3  # not trivially so


@pytest.mark.parametrize("octaves, frequency", [(1, 0.0), (1, 0.5), (2, 2.0)])
def test_turbulence_rms_is_strength_at_every_time(octaves, frequency, device):
    """The RMS of |a| over one period (exact quadrature) is strength at every instant, to float32 rounding;
    |a| averages about 0.9 strength, and at most 8 MiB of grids per field."""
    strength, scale = 2.0, 0.5
    grids = turbulence_grids(device, strength=strength, scale=scale, frequency=frequency, octaves=octaves)
    points, weights = period_quadrature(grids.nodes[0], scale)
    for t in (0.0, 0.37, 1.5, 2.9, 7.25):
        a = sample_turbulence(points, device, t, grids)
        rms = math.sqrt(weights @ np.sum(a * a, axis=1))
        assert abs(rms / strength - 1.0) < 2e-5                              # observed <= 3e-8
        assert 0.85 < weights @ np.linalg.norm(a, axis=1) / strength < 0.97  # observed ~0.92
    assert grids.bytes <= 8 * 2**20


def test_turbulence_moves_through_orthonormal_slices_and_never_repeats(device):
    """f > 0: at t = j / f the field is one slice of random sign; slices j and j + 1 are orthogonal over the
    period; 3 passages later it is the same slice, of either sign (so no period); between, it changes smoothly.
    f = 0: the same field at every time."""
    f, scale = 0.5, 0.5
    grids = turbulence_grids(device, scale=scale, frequency=f)
    points, weights = period_quadrature(grids.nodes[0], scale)
    at = [sample_turbulence(points, device, j / f, grids) for j in range(12)]
    for j in range(11):
        assert abs(weights @ np.sum(at[j] * at[j + 1], axis=1)) < 1e-5      # observed <= 4e-9
    signs = set()
    for j in range(9):
        if np.array_equal(at[j + 3], at[j]):
            signs.add(1)
        else:
            assert np.array_equal(at[j + 3], -at[j])
            signs.add(-1)
    assert signs == {1, -1}
    step = sample_turbulence(points, device, 1.3 + 1e-3 / f, grids) - sample_turbulence(points, device, 1.3, grids)
    assert math.sqrt(weights @ np.sum(step * step, axis=1)) < 2e-3          # (pi / 2) 1e-3 at most
    steady = turbulence_grids(device, frequency=0.0)
    assert np.array_equal(sample_turbulence(points, device, 0.4, steady),
                          sample_turbulence(points, device, 9.0, steady))


def test_turbulence_at_non_finite_positions_is_nan_not_a_crash(device):
    """A diverged particle (NaN or inf position) reads the grid in bounds and gets a NaN acceleration, for the guard
    to report."""
    a = sample_turbulence([[math.nan, 0.0, 0.0], [0.0, math.inf, 1.0], [0.3, 0.2, 0.1]], device)
    assert np.isnan(a[:2]).all() and np.isfinite(a[2]).all()


def test_turbulence_float32_and_float64_agree(device):
    points = np.random.default_rng(4).uniform(-3.0, 3.0, (100, 3))
    a64 = sample_turbulence(points, device, t=0.25, scale=0.5)
    a32 = sample_turbulence(points, device, t=0.25, scale=0.5, precision=np.float32)
    np.testing.assert_allclose(a32, a64, rtol=0, atol=1e-5)   # the grid is float32 in both


def test_turbulence_grid_resolves_three_octaves_and_warns_beyond():
    """16, 32, 52 nodes per axis for 1, 2, 3 octaves (4 per lattice cell of the finest, 52 at most); a fourth
    octave would have 1.6 nodes per cell: left out, with a warning, and the field is that of 3 octaves."""
    assert [grid_size(octaves) for octaves in (1, 2, 3, 4, 16)] == [(16, 1), (32, 2), (52, 3), (52, 3), (52, 3)]
    points = np.random.default_rng(5).uniform(-1.0, 1.0, (50, 3))
    with pytest.warns(UserWarning, match=r"^Turbulence octaves=4: its grid resolves 3; the finer 1 are left out"):
        four = turbulence_grids("cpu", frequency=0.0, octaves=4)
    assert four.octaves == [3]
    assert np.array_equal(sample_turbulence(points, "cpu", 0.0, four),
                          sample_turbulence(points, "cpu", 0.0, turbulence_grids("cpu", frequency=0.0, octaves=3)))


# --- superposition ------------------------------------------------------------------------------

def test_fields_of_one_and_of_different_kinds_add_up(device):
    rng = np.random.default_rng(5)
    points = rng.uniform(-1.5, 1.5, (8, 3))
    mass = rng.uniform(0.5, 2.0, 8)
    fields = [Attractor((0.2, 0.0, 0.0), 1.0), Attractor((-0.5, 0.5, 0.1), -0.4, 0.2),
              Vortex((0.0, 0.0, 0.0), (0.0, 1.0, 0.0), 0.7), Vortex((0.3, 0.0, 0.3), (1.0, 0.0, 0.0), -0.5, 0.05),
              Turbulence(0.8, scale=0.6, seed=1), Turbulence(0.3, scale=2.0, seed=2, octaves=2)]
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

"""Implicit Euler (linearised backward Euler, Baraff and Witkin 1998) against closed forms.

Backward Euler for the linear oscillator x'' = -w^2 x: with u = w x + i v, one step is
(1 + h^2 w^2) v1 = v0 - h w^2 x0, x1 = x0 + h v1, which is exactly u1 = u0 / (1 + i h w):
the amplitude |u| shrinks by 1 / sqrt(1 + h^2 w^2) per step and the phase turns by
-atan(h w). A spring along its own axis is a linear force, so the linearised step is
exact backward Euler there and these closed forms hold to rounding.
"""
import math
import time

import numpy as np
import pytest
from helpers import G, oscillator, particle, run_steps

import warp_sim as ws
from warp_sim import ImplicitEuler


def implicit(scene, device="cpu", **options):
    """A Simulator on ``scene`` stepping with ImplicitEuler(**options)."""
    return ws.Simulator(scene, integrator=ImplicitEuler(**options), device=device)


def test_registered_and_first_order():
    assert ws.INTEGRATORS["implicit_euler"] is ImplicitEuler
    assert ImplicitEuler.order == 1 and ImplicitEuler.name == "implicit_euler"


# -- the reference: the linear system assembled densely in numpy ---------------------------------------------

def reference_step(scene, x0, v0, h):
    """(x1, v1) of one linearised backward Euler step, assembled and solved densely (float64).

    A = M + h c I + sum over springs of the blocks +-B, B = h kd d d^T + h^2 ks (d d^T + max(0, 1 - L0/L)(I - d d^T));
    b = h F + h^2 dF/dx v0; pinned particles' rows and columns removed (their dv is 0)."""
    n = len(x0)
    m = scene.particle_array("mass")
    free = ~scene.particle_array("pinned")
    g, c, wind = np.asarray(scene.gravity), scene.drag, np.asarray(scene.wind)
    A = np.zeros((3 * n, 3 * n))
    F = np.zeros((n, 3))
    Kv = np.zeros((n, 3))
    for i in range(n):
        A[3 * i:3 * i + 3, 3 * i:3 * i + 3] = (m[i] + h * c) * np.eye(3)
        F[i] = m[i] * g + c * (wind - v0[i])
    pairs = scene.spring_array("pairs")
    for (i, j), ks, kd, L0 in zip(pairs, scene.spring_array("stiffness"), scene.spring_array("damping"),
                                  scene.spring_array("rest_length")):
        delta = x0[j] - x0[i]
        L = np.linalg.norm(delta)
        d = delta / L
        f = (-ks * (L - L0) - kd * np.dot(v0[j] - v0[i], d)) * d
        F[j] += f
        F[i] -= f
        P = np.outer(d, d)
        S = ks * (P + max(0.0, 1.0 - L0 / L) * (np.eye(3) - P))
        B = h * kd * P + h * h * S
        for a, b_, sign in ((i, i, 1), (j, j, 1), (i, j, -1), (j, i, -1)):
            A[3 * a:3 * a + 3, 3 * b_:3 * b_ + 3] += sign * B
        Kv[j] -= S @ (v0[j] - v0[i])
        Kv[i] += S @ (v0[j] - v0[i])
    rhs = (h * F + h * h * Kv).ravel()
    keep = np.repeat(free, 3)
    dv = np.zeros(3 * n)
    dv[keep] = np.linalg.solve(A[np.ix_(keep, keep)], rhs[keep])
    v1 = v0 + dv.reshape(n, 3)
    return x0 + h * v1, v1


def test_one_step_of_the_oscillator_from_rest_is_the_hand_solved_system(device):
    """From rest at displacement a: (m + h^2 k) v1 = -h k a, x1 = x0 + h v1 (1e-12, float64)."""
    k, m, a, h = 4.0, 1.5, 0.1, 0.1
    sim = implicit(oscillator(k, m, a), device)
    sim.step(h)
    x, v = particle(sim, 1)
    v_exact = -h * k * a / (m + h * h * k)
    assert v == pytest.approx([v_exact, 0.0, 0.0], abs=1e-12)
    assert x == pytest.approx([1.0 + a + h * v_exact, 0.0, 0.0], abs=1e-12)
    assert sim.integrator.last_iterations == 1     # block Jacobi is the exact inverse of one free particle


@pytest.mark.parametrize("rest", [1.4, 0.6], ids=["compressed", "stretched"])
def test_one_step_in_3d_matches_the_dense_reference(rest, device):
    """Two free particles and a pinned one, off-axis springs with dampers, initial velocities,
    gravity, drag and wind: the step equals the dense numpy solve of the same system (1e-12).
    Compressed springs exercise the clamp of the geometric term at 0."""
    scene = ws.Scene(gravity=(0.0, -G, 0.0), precision="float64", drag=0.3, wind=(0.5, 0.0, -0.2))
    x0 = np.array([[0.0, 0.0, 0.0], [0.8, 0.5, -0.3], [1.1, -0.4, 0.6]])
    v0 = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.5], [-0.7, 0.1, 0.2]])
    scene.add_particles(x0, v0, mass=[1.0, 2.0, 0.5], pinned=[0])
    scene.add_springs([[0, 1], [1, 2], [0, 2]], stiffness=[50.0, 80.0, 20.0], damping=[0.7, 0.2, 0.0],
                      rest_length=rest)
    h = 0.05
    sim = implicit(scene, device, tolerance=1e-15, max_iterations=50)
    sim.step(h)
    x_ref, v_ref = reference_step(scene, x0, scene.particle_array("velocity"), h)
    x, v = sim.state.particle_x.numpy(), sim.state.particle_v.numpy()
    assert np.abs(v - v_ref).max() < 1e-12
    assert np.abs(x - x_ref).max() < 1e-12
    assert np.all(v[0] == 0.0) and np.all(x[0] == x0[0])


# -- the oscillator: amplification factor, stability ----------------------------------------------------------

@pytest.mark.parametrize("h", [0.01, 0.1, 1.0])
def test_amplitude_decays_by_the_backward_euler_factor(h, device):
    """u = w x + i v after n steps is u0 / (1 + i h w)^n: |u| shrinks by 1 / sqrt(1 + h^2 w^2) per step,
    the phase turns by -atan(h w). x and v match this at every step to 1e-9 (amplitude 0.1, float64)."""
    k, m, a = 4.0, 1.0, 0.1
    w = math.sqrt(k / m)
    sim = implicit(oscillator(k, m, a), device)
    u = complex(w * a, 0.0)
    factor = 1.0 / complex(1.0, h * w)
    ratios = []
    for _ in range(200):
        previous = abs(u)
        sim.step(h)
        u *= factor
        x, v = particle(sim, 1)
        assert abs(x[0] - 1.0 - u.real / w) < 1e-9 and abs(v[0] - u.imag) < 1e-9
        assert np.all(x[1:] == 0.0) and np.all(v[1:] == 0.0)
        ratios.append(math.hypot(w * (x[0] - 1.0), v[0]) / previous)
    if abs(u) > 1e-6:      # the measured per-step ratio while the amplitude is well above rounding
        assert np.allclose(ratios, 1.0 / math.sqrt(1.0 + (h * w) ** 2), rtol=1e-6, atol=0.0)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_stiff_spring_is_stable_at_large_steps_and_loses_energy_every_step(precision, device):
    """ks/m = 1e6 at h = 1/60 (h w = 16.7, ten times explicit schemes' limit h w < 2): 10 s stay finite,
    and E = m v^2 / 2 + k (L - L0)^2 / 2 never grows: E(n+1) <= E(n) + 1e-12 E(0) (float64; 1e-6 E(0) in
    float32, whose positions near x = 1 m resolve displacements of 6e-8 m only)."""
    k, m, a, h = 1.0e6, 1.0, 0.01, 1.0 / 60.0
    sim = implicit(oscillator(k, m, a, precision=precision), device)
    slack = (1e-12 if precision == "float64" else 1e-6) * 0.5 * k * a * a

    def energy():
        x, v = particle(sim, 1)
        return 0.5 * m * v @ v + 0.5 * k * (np.linalg.norm(x) - 1.0) ** 2

    energies = [energy()]
    for _ in range(600):
        sim.step(h)
        energies.append(energy())
    energies = np.array(energies)
    assert np.all(np.isfinite(sim.state.y.numpy()))
    assert np.all(np.diff(energies) <= slack)
    assert energies[1] < energies[0] / (1.0 + (h * h * k / m)) * 1.001   # the first step alone: factor 1/(1 + h^2 w^2)


# -- a cloth: stiff springs at a frame rate step ----------------------------------------------------------------

def cloth(n, k=1.0e4, size=1.0, mass=1.0, precision="float32"):
    """An n x n sheet, horizontal at y = 1 m, total mass [kg] spread evenly, structural, shear and bend
    springs of stiffness k (no dampers), the two corners of one edge pinned, gravity -Y.
    Returns (scene, indices of the pinned particles)."""
    scene = ws.Scene(gravity=(0.0, -G, 0.0), precision=precision)
    s = size / (n - 1)
    rows, cols = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    index = rows * n + cols
    positions = np.stack([rows.ravel() * s, np.ones(n * n), cols.ravel() * s], axis=1)
    pairs = [np.stack([index[:-1, :].ravel(), index[1:, :].ravel()], 1),       # structural
             np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], 1),
             np.stack([index[:-1, :-1].ravel(), index[1:, 1:].ravel()], 1),    # shear
             np.stack([index[1:, :-1].ravel(), index[:-1, 1:].ravel()], 1),
             np.stack([index[:-2, :].ravel(), index[2:, :].ravel()], 1),       # bend
             np.stack([index[:, :-2].ravel(), index[:, 2:].ravel()], 1)]
    pinned = [index[0, 0], index[0, n - 1]]
    scene.add_particles(positions, mass=mass / (n * n), pinned=pinned)
    scene.add_springs(np.concatenate(pairs), stiffness=k)
    return scene, np.array(pinned)


def cloth_energy(scene, sim):
    """Kinetic + gravitational (zero at y = 0) + spring energy [J], in float64."""
    x = sim.state.particle_x.numpy().astype(np.float64)
    v = sim.state.particle_v.numpy().astype(np.float64)
    m = scene.particle_array("mass")
    pairs = scene.spring_array("pairs")
    stretch = np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1) - scene.spring_array("rest_length")
    return (0.5 * np.sum(m * np.sum(v * v, axis=1)) - np.sum(m * (x @ np.asarray(scene.gravity)))
            + 0.5 * np.sum(scene.spring_array("stiffness") * stretch**2))


def run_cloth(n, capsys, seconds=10.0, h=1.0 / 60.0, rise_tolerance=1e-6, **options):
    """Hang the n x n cloth for `seconds`; check it and report the CG iterations per step.

    Criteria: finite throughout; the pinned corners' velocity change exactly 0 and their positions
    unchanged at every step; after the first second, the energy never rises from one step to the next
    by more than rise_tolerance of its initial magnitude (1e-6: float32 rounding of positions near 1 m),
    and it ends below where it started."""
    scene, pinned = cloth(n)
    sim = implicit(scene, **options)
    x_pinned = sim.state.particle_x.numpy()[pinned].copy()
    energies, iterations = [cloth_energy(scene, sim)], []
    steps = round(seconds / h)
    start = time.perf_counter()
    for _ in range(steps):
        v_before = sim.state.particle_v.numpy()[pinned].copy()
        sim.step(h)
        iterations.append(sim.integrator.last_iterations)
        assert np.all(sim.state.particle_v.numpy()[pinned] - v_before == 0.0)
        assert np.all(sim.state.particle_x.numpy()[pinned] == x_pinned)
        energies.append(cloth_energy(scene, sim))
    elapsed = time.perf_counter() - start
    energies, iterations = np.array(energies), np.array(iterations)
    with capsys.disabled():
        print(f"\n{n}x{n} cloth, k = 1e4 N/m, h = 1/60 s, {seconds:g} s: CG iterations per step "
              f"min {iterations.min()}, mean {iterations.mean():.1f}, max {iterations.max()} "
              f"(cap {sim.integrator.max_iterations}, {sim.integrator.unconverged_solves} solves at the cap); "
              f"energy {energies[0]:.4f} -> {energies[-1]:.4f} J; {elapsed:.1f} s")
    assert np.all(np.isfinite(sim.state.y.numpy()))
    after_first_second = np.diff(energies[round(1.0 / h):])
    assert after_first_second.max() <= rise_tolerance * abs(energies[0])
    assert energies[-1] < energies[0]
    return iterations


def test_small_cloth_stays_finite_and_loses_energy(capsys):
    """A 16 x 16 version of the 64 x 64 test below, for 3 s, with the default CG settings."""
    run_cloth(16, capsys, seconds=3.0)


@pytest.mark.slow   # about a minute
def test_64x64_cloth_stays_finite_and_loses_energy(capsys):
    """64 x 64 particles, 24 000 springs of k = 1e4 N/m, 600 steps of 1/60 s. This system needs over
    200 CG iterations a step for a 1e-6 residual (h^2 k / m is about 3e3: badly conditioned), at ~3.5 ms
    each on the CPU, so the test caps CG at 40 iterations (relative tolerance 1e-3): the step stays
    stable and loses energy with inexact solves too (a capped solve may let the energy rise by a few
    1e-4 of E0 in a step, so the per-step bound is 1e-3 here; the 16 x 16 test holds the tight one),
    and the run takes about a minute and a half."""
    with pytest.warns(RuntimeWarning, match="stopped at the cap of 40 iterations"):
        run_cloth(64, capsys, rise_tolerance=1e-3, tolerance=1e-3, max_iterations=40, check_every=10)


# -- fixed points and conservation ------------------------------------------------------------------------------

def test_hanging_chain_settles_to_the_static_stretches():
    """N masses m below a pinned top on springs k: spring j (j = 1 at the top) carries the N - j + 1
    masses below it, so it stretches by (N - j + 1) m g / k. Large steps (h = 0.25 s, h w = 25 for the
    stiffest mode) settle to that fixed point; started off the vertical line so pendulum modes are damped
    too. Checked to 1e-6 relative (float64)."""
    N, k, m, L0, h = 10, 1000.0, 0.1, 0.1, 0.25
    scene = ws.Scene(gravity=(0.0, -G, 0.0), precision="float64")
    x = np.zeros((N + 1, 3))
    x[:, 1] = -L0 * np.arange(N + 1)
    x[1:, 0] = 0.02 * np.sin(np.arange(1, N + 1))      # a kinked start, off the vertical
    scene.add_particles(x, mass=[1.0] + [m] * N, pinned=[0])
    scene.add_springs([[j - 1, j] for j in range(1, N + 1)], stiffness=k, damping=2.0, rest_length=L0)
    sim = implicit(scene, tolerance=1e-10)
    run_steps(sim, 200, h)
    x = sim.state.particle_x.numpy()
    stretch = np.linalg.norm(np.diff(x, axis=0), axis=1) - L0
    expected = (N - np.arange(1, N + 1) + 1) * m * G / k
    assert stretch == pytest.approx(expected, rel=1e-6)
    assert np.abs(x[:, [0, 2]]).max() < 1e-9              # hanging straight down
    assert np.abs(sim.state.particle_v.numpy()).max() < 1e-9


def test_momentum_changes_by_the_impulse_of_gravity_alone(device):
    """Nothing pinned, springs (internal: each spring's blocks sum to zero over its two particles, in both
    the matrix and the right-hand side): the total momentum changes by exactly M g t. 1e-10 relative,
    float64, with a CG tolerance of 1e-13 (the residual's sum is what a loose solve would leak)."""
    rng = np.random.default_rng(7)
    n = 8
    scene = ws.Scene(gravity=(0.0, -G, 0.0), precision="float64")
    scene.add_particles(rng.uniform(-1.0, 1.0, (n, 3)), rng.normal(0.0, 2.0, (n, 3)), mass=rng.uniform(0.5, 2.0, n))
    pairs = [[i, j] for i in range(n) for j in range(i + 1, n) if rng.random() < 0.5]
    scene.add_springs(pairs, stiffness=rng.uniform(100.0, 1000.0, len(pairs)),
                      damping=rng.uniform(0.0, 2.0, len(pairs)), rest_length=rng.uniform(0.2, 1.5, len(pairs)))
    m = scene.particle_array("mass")
    sim = implicit(scene, device, tolerance=1e-13)
    p0 = m @ sim.state.particle_v.numpy()
    h, steps = 0.02, 100
    run_steps(sim, steps, h)
    impulse = m.sum() * np.array([0.0, -G, 0.0]) * h * steps
    p1 = m @ sim.state.particle_v.numpy()
    assert np.abs(p1 - p0 - impulse).max() < 1e-10 * np.linalg.norm(impulse)


def test_pinned_particles_never_move(device):
    """Pinned particles in the middle of a stretched, swinging net keep their positions and zero velocities
    bit for bit (their velocity change is written as exactly 0)."""
    scene = ws.Scene(gravity=(0.0, -G, 0.0), precision="float32")
    grid = np.array([[i * 0.1, 0.0, j * 0.1] for i in range(5) for j in range(5)])
    pinned = [0, 4, 12]
    scene.add_particles(grid, rng_velocities(len(grid)), mass=0.05, pinned=pinned)
    pairs = [[a, b] for a in range(25) for b in range(a + 1, 25) if np.linalg.norm(grid[a] - grid[b]) < 0.15]
    scene.add_springs(pairs, stiffness=500.0, damping=0.1, rest_length=0.08)
    sim = implicit(scene, device)
    x0 = sim.state.particle_x.numpy()[pinned].copy()
    for _ in range(120):
        sim.step(1.0 / 60.0)
        assert np.all(sim.state.particle_x.numpy()[pinned] == x0)
        assert np.all(sim.state.particle_v.numpy()[pinned] == 0.0)
    assert np.abs(sim.state.particle_x.numpy() - grid).max() > 0.05      # the rest did move


def rng_velocities(n):
    return np.random.default_rng(3).normal(0.0, 0.5, (n, 3))


# -- other components: emitters and rigid bodies -----------------------------------------------------------------

def test_without_springs_or_drag_it_is_symplectic_euler_for_particles_and_bodies(device):
    """With no spring and no drag the system is M dv = h F: implicit Euler is then symplectic Euler, for
    emitted particles (dead slots have inverse mass 0, like pinned ones) and for rigid bodies, which this
    step always advances by symplectic Euler. The two runs agree to 1e-12 (float64)."""
    def scene():
        s = ws.Scene(gravity=(0.0, -G, 0.0), precision="float64")
        s.add_particles([[0.0, 1.0, 0.0], [1.0, 2.0, 0.0]], [[1.0, 3.0, 0.0], [0.0, 0.0, 0.0]], pinned=[1])
        s.add_emitter(rate=50.0, lifetime=0.3, speed=2.0, spread=30.0, seed=3)
        s.add_rigid_body(ws.Box((0.1, 0.2, 0.3)), mass=2.0, linear_velocity=(0.5, 2.0, 0.0),
                         angular_velocity=(1.0, 2.0, 3.0))
        return s

    runs = []
    for integrator in ("implicit_euler", "symplectic_euler"):
        sim = ws.Simulator(scene(), integrator=integrator, device=device)
        run_steps(sim, 60, 1.0 / 60.0)
        runs.append(sim.state.y.numpy())
    assert sim.emitter_stats()[0]["live"] > 0
    assert np.abs(runs[0] - runs[1]).max() < 1e-12


# -- options -----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("options, name", [
    ({"tolerance": 0.0}, "tolerance"), ({"tolerance": -1e-6}, "tolerance"), ({"tolerance": 1.0}, "tolerance"),
    ({"tolerance": float("nan")}, "tolerance"), ({"max_iterations": 0}, "max_iterations"),
    ({"max_iterations": 2.5}, "max_iterations"), ({"max_iterations": True}, "max_iterations"),
    ({"preconditioner": "ilu"}, "preconditioner"), ({"check_every": 0}, "check_every"),
    ({"absolute_tolerance": -1.0}, "absolute_tolerance")])
def test_bad_options_raise_value_error_naming_the_argument(options, name):
    with pytest.raises(ValueError, match=f"^{name}="):
        ImplicitEuler(**options)


@pytest.mark.parametrize("preconditioner", ["block_jacobi", "diag", "none"])
def test_every_preconditioner_gives_the_same_step(preconditioner):
    scene, _ = cloth(6, precision="float64")
    sim = implicit(scene, preconditioner=preconditioner, tolerance=1e-12)
    reference = implicit(scene, tolerance=1e-12)
    run_steps(sim, 10, 1.0 / 60.0)
    run_steps(reference, 10, 1.0 / 60.0)
    assert np.abs(sim.state.y.numpy() - reference.state.y.numpy()).max() < 1e-9
    assert sim.integrator.last_converged and sim.integrator.last_iterations > 0
    assert sim.integrator.last_residual <= sim.integrator.last_tolerance

"""Mass-spring-damper bodies and cloth against closed forms: the hanging chain, the elastic
catenary, momentum conservation of a free cloth, and the explicit stability limit."""
import numpy as np
import pytest
from helpers import G

import warp_sim as ws


def chain_scene(n, m, k, rest, drag, start, end=None):
    """n + 1 particles from `start` (pinned) in a straight line to `end` (pinned when given, else
    the chain hangs free below start), n springs of stiffness k and rest length `rest`."""
    scene = ws.Scene(precision="float64", drag=drag)
    start = np.asarray(start, dtype=float)
    stop = start + np.array([0.0, -n * rest, 0.0]) if end is None else np.asarray(end, dtype=float)
    points = start + np.linspace(0.0, 1.0, n + 1)[:, None] * (stop - start)
    pinned = [0] if end is None else [0, n]
    ids = scene.add_particles(points, mass=m, pinned=pinned)
    scene.add_springs(np.stack([ids[:-1], ids[1:]], axis=1), stiffness=k, rest_length=rest)
    return scene


def test_hanging_chain_stretches_by_the_weight_below():
    """N masses hanging from a pinned top, damped to rest: spring j (from the top) carries the
    N - j + 1 masses below it, so it is stretched by (N - j + 1) m g / k (1e-6 relative)."""
    n, m, k = 10, 0.1, 100.0
    sim = ws.Simulator(chain_scene(n, m, k, 0.1, drag=1.0, start=(0.0, 2.0, 0.0)),
                       integrator="symplectic_euler", device="cpu")
    sim.step(1e-3, 15_000)
    x = sim.state.particle_x.numpy()
    stretch = np.linalg.norm(np.diff(x, axis=0), axis=1) - 0.1
    expected = (n - np.arange(1, n + 1) + 1) * m * G / k
    assert np.allclose(stretch, expected, rtol=1e-6, atol=0.0)
    assert np.abs(sim.state.particle_v.numpy()).max() < 1e-7


def test_elastic_catenary_tension_and_sag():
    """20 links, 0.05 kg masses, k = 200 N/m, rest 0.06 m, ends level 1 m apart, settled:
    horizontal tension 2.00941 N and sag 0.52580 m within 0.5 % (the closed form of the
    discrete elastic catenary; a Newton solve of the statics gives 2.0094105 N, 0.5258019 m)."""
    k, rest = 200.0, 0.06
    sim = ws.Simulator(chain_scene(20, 0.05, k, rest, drag=0.2, start=(0.0, 1.0, 0.0), end=(1.0, 1.0, 0.0)),
                       integrator="symplectic_euler", device="cpu")
    sim.step(2e-3, 10_000)
    x = sim.state.particle_x.numpy()
    d = x[1] - x[0]
    length = np.linalg.norm(d)
    horizontal_tension = k * (length - rest) * d[0] / length
    sag = 1.0 - x[:, 1].min()
    assert horizontal_tension == pytest.approx(2.00941, rel=5e-3)
    assert sag == pytest.approx(0.52580, rel=5e-3)


def uniform_grid_scene(n, spacing, m, k):
    """An n x n grid of particles of mass m each in the x-y plane, with structural, shear and bend
    springs of one stiffness k (no damping, no gravity): the lattice whose highest in-plane mode
    has omega^2 = 10.125 k / m (the maximum over wave vectors of its dynamical matrix)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    scene.add_particles(np.stack([i.ravel() * spacing, j.ravel() * spacing, 0.0 * i.ravel()], axis=1), mass=m)
    index = np.arange(n * n).reshape(n, n)
    offsets = [(1, 0), (0, 1), (1, 1), (1, -1), (2, 0), (0, 2)]
    pairs = []
    for di, dj in offsets:
        a = index[max(0, -di):n - max(0, di), max(0, -dj):n - max(0, dj)]
        b = index[max(0, di):n + min(0, di) or None, max(0, dj):n + min(0, dj) or None]
        pairs.append(np.stack([a.ravel(), b.ravel()], axis=1))
    scene.add_springs(np.concatenate(pairs), stiffness=k)
    return scene


def is_stable(scene, integrator, h, steps=3000, seed=0):
    """True when a small random perturbation of the grid stays below ten times its size."""
    sim = ws.Simulator(scene, integrator=integrator, device="cpu", guard=False)
    x0 = sim.state.particle_x.numpy().copy()
    kick = np.random.default_rng(seed).normal(0.0, 1e-4, size=x0.shape)
    sim.state.particle_x.assign(x0 + kick)
    sim.step(h, steps, substeps=1)
    drift = np.abs(sim.state.particle_x.numpy() - x0)
    return bool(np.all(np.isfinite(drift)) and drift.max() < 10.0 * np.abs(kick).max())


@pytest.mark.parametrize("integrator, theory", [("symplectic_euler", 0.6285), ("rk4", 0.889)])
def test_explicit_stability_limit_of_a_cloth_by_bisection(integrator, theory):
    """The largest stable step of a cloth with structural = shear = bend stiffness k, in units of
    sqrt(m/k): 2 / sqrt(10.125) = 0.6285 for symplectic Euler and 2 sqrt(2) / sqrt(10.125) = 0.889
    for rk4. Bisection on a 12 x 12 grid matches within 5 %."""
    m, k = 0.01, 100.0
    unit = np.sqrt(m / k)
    scene = uniform_grid_scene(12, 0.05, m, k)
    low, high = 0.5 * theory, 1.5 * theory
    assert is_stable(scene, integrator, low * unit) and not is_stable(scene, integrator, high * unit)
    for _ in range(8):
        middle = 0.5 * (low + high)
        if is_stable(scene, integrator, middle * unit):
            low = middle
        else:
            high = middle
    assert 0.5 * (low + high) == pytest.approx(theory, rel=0.05)


def free_cloth(integrator):
    """A 10 x 10 cloth with all spring families and dampers, no gravity, thrown spinning and
    tumbling (random vertex velocities): internal forces only."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_cloth_grid(resolution=(10, 10), size=(1.0, 1.0), position=(0.0, 1.0, 0.0), mass=0.5,
                         stiffness=(500.0, 300.0, 50.0), damping=(0.2, 0.1, 0.05))
    sim = ws.Simulator(scene, integrator=integrator, device="cpu")
    spin = np.cross([0.0, 0.0, 3.0], scene.particle_array("position"))
    v = np.random.default_rng(1).normal(0.0, 0.5, size=(100, 3)) + spin
    sim.state.particle_v.assign(v)
    return sim, scene.particle_array("mass")


def momenta(sim, mass):
    x, v = sim.state.particle_x.numpy(), sim.state.particle_v.numpy()
    return (mass[:, None] * v).sum(axis=0), np.cross(x, mass[:, None] * v).sum(axis=0)


@pytest.mark.parametrize("integrator", sorted(set(ws.INTEGRATORS) - {"implicit_euler"}))
def test_free_cloth_conserves_momentum(integrator):
    """Linear momentum to 1e-12 relative with every explicit integrator over 500 steps of 0.1 ms
    (explicit Euler grows the fastest modes by 1.01 per two steps there, but stays bounded);
    angular momentum to 1e-10 with symplectic Euler and Verlet (exact for central pair forces)."""
    sim, mass = free_cloth(integrator)
    P0, L0 = momenta(sim, mass)
    sim.step(1e-4, 500)
    P, L = momenta(sim, mass)
    assert np.linalg.norm(P - P0) <= 1e-12 * np.linalg.norm(P0)
    if integrator in ("symplectic_euler", "verlet"):
        assert np.linalg.norm(L - L0) <= 1e-10 * np.linalg.norm(L0)

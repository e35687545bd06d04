"""Provot strain limiting against its closed forms: limits, untouched springs, momentum, colouring."""
import numpy as np
import pytest
from helpers import add_grid, add_mesh, host

import warp_sim as ws
from warp_sim.passes import StrainLimiter, colour_springs


def spring_strains(sim, springs, families=("structural", "shear")):
    """L / L0 - 1 of the given spring families in the current state."""
    scene = sim.scene
    ids = np.concatenate([springs[f] for f in families])
    pairs, rest = scene.spring_array("pairs")[ids], scene.spring_array("rest_length")[ids]
    x = host(sim.state.particle_x).astype(np.float64)
    return np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1) / rest - 1.0


@pytest.mark.parametrize("precision, tolerance, rounding", [("float64", 1e-6, 1e-12), ("float32", 1e-4, 1e-5)])
def test_strain_limiting_keeps_every_structural_spring_under_the_configured_elongation(precision, tolerance, rounding,
                                                                                         device):
    """A soft 8 x 8 cloth hanging from its pinned top row stretches to 78 % without limiting; with
    max_stretch 0.1 no structural or shear spring ever exceeds 1.1 (1 + tolerance) L0 (the limiter's
    default tolerance; rounding: a float32 length 2 m from the origin is good to about 4e-6 of 0.11 m)."""
    bound = (1.0 + 0.1) * (1.0 + tolerance) - 1.0 + rounding
    strains = {}
    for max_stretch in (None, 0.1):
        scene = ws.Scene(precision=precision)
        _, springs = add_grid(scene, max_stretch=max_stretch)
        sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
        x0 = host(sim.state.particle_x)
        worst, iterations = -1.0, []
        for _ in range(300):
            sim.step(5e-3)
            strain = spring_strains(sim, springs)
            worst = max(worst, strain.max())
            if max_stretch is not None:
                limiter = sim.strain_limiter
                iterations.append(limiter.last_iterations)
                assert limiter.converged
                assert strain.max() <= bound
                assert limiter.max_strain == pytest.approx(strain.max(), abs=rounding)
                x, v = host(sim.state.particle_x), host(sim.state.particle_v)
                assert np.array_equal(x[:8], x0[:8]) and not np.any(v[:8])      # the pinned row
        strains[max_stretch] = worst
        if max_stretch is not None:
            print(f"{precision}: sweeps per step max {max(iterations)}, mean {np.mean(iterations):.2f}")
            assert max(iterations) < limiter.max_iterations
    assert strains[None] > 0.5                                     # the test can fail: unlimited, it stretches
    assert strains[0.1] <= bound


def free_cloth(device, scale=1.0, max_stretch=0.1, seed=0, noise=0.0, velocity_noise=0.0):
    """A free 6 x 6 cloth (no gravity, no pins, equal masses) with its positions scaled about the
    first particle and jittered: its springs stretched (scale > 1) or compressed (scale < 1)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    _, springs = add_grid(scene, n=6, hanging=False, pin_top=False, max_stretch=max_stretch)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
    rng = np.random.default_rng(seed)
    x = host(sim.state.particle_x)
    x = x[0] + scale * (x - x[0]) + noise * rng.normal(size=x.shape)
    sim.state.particle_x.assign(x)
    sim.state.particle_v.assign(velocity_noise * rng.normal(size=x.shape))
    return sim, springs


@pytest.mark.parametrize("scale", [0.8, 1.0, 1.05])
def test_springs_within_the_limit_and_compressed_ones_are_untouched(scale, device):
    sim, springs = free_cloth(device, scale=scale, velocity_noise=0.3)
    x, v = host(sim.state.particle_x), host(sim.state.particle_v)
    sim.strain_limiter.apply(sim.state, sim.state, sim.time, 1e-3)
    assert np.array_equal(host(sim.state.particle_x), x) and np.array_equal(host(sim.state.particle_v), v)
    assert sim.strain_limiter.last_iterations == 0 and sim.strain_limiter.converged
    assert sim.strain_limiter.max_strain == pytest.approx(spring_strains(sim, springs).max(), abs=1e-12)


def test_limiter_conserves_the_linear_momentum_of_a_free_cloth(device):
    sim, springs = free_cloth(device, scale=1.25, noise=0.01, velocity_noise=0.5, seed=4)
    mass, h = 0.01, 1e-2
    x, v = host(sim.state.particle_x), host(sim.state.particle_v)
    before = spring_strains(sim, springs)
    assert before.max() > 0.2
    sim.strain_limiter.apply(sim.state, sim.state, sim.time, h)
    x1, v1 = host(sim.state.particle_x), host(sim.state.particle_v)
    assert sim.strain_limiter.converged
    assert spring_strains(sim, springs).max() <= 1.1 * (1.0 + 1e-6) - 1.0
    assert np.abs(v1 - v).max() > 1.0                              # it did move things (dx / h)
    assert np.allclose(v1 - v, (x1 - x) / h, rtol=0.0, atol=1e-10)  # v += dx / h
    assert np.abs(mass * (v1.sum(axis=0) - v.sum(axis=0))).max() <= 1e-12
    assert np.abs(mass * (x1.sum(axis=0) - x.sum(axis=0))).max() <= 1e-12
    assert (before > 0.1).sum() > 100                              # most springs started over their limit


def test_limiter_in_the_simulator_conserves_momentum(device):
    sim, springs = free_cloth(device, scale=1.0, velocity_noise=2.0, seed=5)
    p0 = host(sim.state.particle_v).sum(axis=0)
    for _ in range(50):
        sim.step(5e-3)
        assert spring_strains(sim, springs).max() <= 1.1 * (1.0 + 1e-6) - 1.0
    assert np.abs(host(sim.state.particle_v).sum(axis=0) - p0).max() <= 1e-11


def test_spring_between_two_pinned_particles_is_left_alone():
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    ids = scene.add_particles([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], pinned=[0, 1])
    pinned_spring = scene.add_springs([[0, 1]], 1.0, rest_length=0.5)
    free_spring = scene.add_springs([[1, 2]], 1.0, rest_length=0.5)
    add_mesh(scene, [ids], 0, 3, {"structural": np.concatenate([pinned_spring, free_spring])}, max_stretch=0.1)
    sim = ws.Simulator(scene, integrator="euler", device="cpu")
    assert sim.strain_limiter.constraint_count == 1
    sim.step(1e-2)
    x = host(sim.state.particle_x)
    assert np.array_equal(x[:2], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    assert x[2, 0] == pytest.approx(1.55, abs=1e-12)             # the free end comes to 1.1 L0
    assert sim.strain_limiter.last_iterations == 1


def test_colouring_never_gives_one_colour_two_springs_at_a_particle():
    rows = np.arange(64).reshape(8, 8)
    grid = np.concatenate([np.stack([rows[:, :-1].ravel(), rows[:, 1:].ravel()], 1),
                           np.stack([rows[:-1].ravel(), rows[1:].ravel()], 1),
                           np.stack([rows[:-1, :-1].ravel(), rows[1:, 1:].ravel()], 1),
                           np.stack([rows[:-1, 1:].ravel(), rows[1:, :-1].ravel()], 1)])
    rng = np.random.default_rng(0)
    random = rng.integers(0, 40, size=(400, 2))
    random = random[random[:, 0] != random[:, 1]]
    for pairs, count in ((grid, 64), (random, 40)):
        colours = colour_springs(pairs, count)
        for c in np.unique(colours):
            ends = pairs[colours == c].ravel()
            assert len(np.unique(ends)) == len(ends)
        degree = np.bincount(pairs.ravel(), minlength=count).max()
        assert colours.max() + 1 <= 2 * degree - 1
    assert colour_springs(grid, 64).max() + 1 == 8


# validation ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("options, argument", [
    ({"max_iterations": 0}, "max_iterations=0"), ({"max_iterations": 2.5}, "max_iterations=2.5"),
    ({"max_iterations": True}, "max_iterations=True"), ({"tolerance": -1e-6}, "tolerance=-1e-06"),
    ({"relaxation": 2.0}, "relaxation=2.0"), ({"relaxation": 0.5}, "relaxation=0.5"),
])
def test_bad_limiter_options_are_rejected(options, argument):
    scene = ws.Scene()
    add_grid(scene, n=3, max_stretch=0.1)
    with pytest.raises(ValueError, match=argument):
        StrainLimiter(ws.Model(scene, "cpu"), scene, **options)


@pytest.mark.parametrize("h", [1 / 60, 1 / 24])
@pytest.mark.parametrize("integrator", ["symplectic_euler", "implicit_euler"])
def test_a_cpu_sweep_in_one_launch_is_the_sweep_colour_by_colour(integrator, h):
    """On the CPU a sweep is one launch over every spring (stored colour by colour; a CPU launch runs its threads in
    order): the states are those of one launch per colour bit for bit, at frame-rate steps, with fewer launches, and
    every limited spring within 1.1 (1 + tolerance) L0."""
    sims = []
    for one_launch in (True, False):
        scene = ws.Scene(precision="float64")
        _, springs = add_grid(scene, stiffness=50.0, max_stretch=0.1)
        sim = ws.Simulator(scene, integrator=integrator, device="cpu")
        limiter = sim.strain_limiter
        assert limiter.colour_count > 1 and len(limiter.sweep_launches) == 1
        if not one_launch:
            limiter.sweep_launches = limiter.colours
        sims.append((sim, springs))
    launches = []
    for sim, springs in sims:
        start = sim.model.launcher.launches
        for _ in range(round(2.0 / h)):
            sim.step(h)
            assert sim.strain_limiter.converged
            assert spring_strains(sim, springs).max() <= 1.1 * (1.0 + 1e-6) - 1.0 + 1e-12
        launches.append(sim.model.launcher.launches - start)
    (one, _), (per_colour, _) = sims
    assert np.array_equal(host(one.state.particle_x), host(per_colour.state.particle_x))
    assert np.array_equal(host(one.state.particle_v), host(per_colour.state.particle_v))
    assert launches[0] < launches[1]

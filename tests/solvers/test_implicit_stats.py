"""Implicit Euler's statistics are running aggregates (count, iterations min/mean/max, mean and worst relative
residual, unconverged count): a fixed handful of numbers however long the run, so a checkpoint does not grow with
the steps, and stats() keeps its documented keys."""
import numpy as np
import pytest

import warp_sim as ws
from warp_sim.core import persistence

H = 1.0 / 60.0
KEYS = {"solves", "iterations", "residuals", "unconverged", "max_iterations", "tolerance"}


def cloth_sim(max_iterations=None):
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(6, 6), size=(1.0, 1.0), position=(0, 1, 0), pinned=["top_corners"])
    return ws.Simulator(scene, integrator=ws.ImplicitEuler(max_iterations=max_iterations), device="cpu")


def checkpoint_size(sim):
    arrays, values = persistence.save(sim)
    return sorted((key, value.shape) for key, value in arrays.items()), sorted(values)


def test_a_checkpoint_does_not_grow_with_the_steps():
    sim = cloth_sim()
    sim.step(H, steps=2, substeps=1)
    early = checkpoint_size(sim)
    sim.step(H, steps=30, substeps=1)
    assert checkpoint_size(sim) == early
    assert not any(isinstance(getattr(sim.integrator, name), list) for name in sim.integrator.persistent)


def test_the_aggregates_follow_every_solve():
    sim = cloth_sim()
    seen = []
    for _ in range(5):
        sim.step(H, substeps=1)
        seen.append(sim.integrator.last_iterations)
    stats = sim.integrator.stats()
    assert set(stats) == KEYS and stats["solves"] == 5 and stats["unconverged"] == 0
    assert stats["iterations"] == (min(seen), pytest.approx(np.mean(seen)), max(seen))
    mean, worst = stats["residuals"]
    assert 0.0 <= mean <= worst <= stats["tolerance"]


def test_unconverged_solves_are_counted_with_the_worst_residual():
    sim = cloth_sim(max_iterations=1)
    with pytest.warns(RuntimeWarning, match="stopped at the cap of 1"):
        sim.step(H, steps=3, substeps=1)
    stats = sim.integrator.stats()
    assert stats["unconverged"] == 3 and stats["iterations"] == (1, 1.0, 1)
    assert stats["residuals"][1] > stats["tolerance"]


def test_a_restored_checkpoint_gives_the_same_stats():
    sim = cloth_sim()
    sim.step(H, steps=4, substeps=1)
    arrays, values = persistence.save(sim)
    other = cloth_sim()
    persistence.restore(other, arrays, values)
    assert other.integrator.stats() == sim.integrator.stats()
    sim.step(H, substeps=1)
    other.step(H, substeps=1)
    assert other.integrator.stats() == sim.integrator.stats()
    assert np.array_equal(other.state.particle_x.numpy(), sim.state.particle_x.numpy())


def test_no_solve_yet():
    stats = cloth_sim().integrator.stats()
    assert stats["solves"] == 0 and stats["iterations"] == (0, 0.0, 0) and stats["residuals"] == (0.0, 0.0)

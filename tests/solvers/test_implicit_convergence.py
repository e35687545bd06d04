"""Implicit Euler converges at frame rate with its defaults, and says so when it does not.

The cloth is the cloth benchmark's (benchmarks/cloth.py): 1 m x 1 m, 0.2 kg/m^2, structural and shear
springs of 1e4 N/m and bend springs of 1e3 N/m, pinned at its top corners, from rest under gravity, at
h = 1/60 s. Every solve is reported (sim.integrator.stats()): at 32^2, 64^2 and 128^2 at least 95 % of
them reach the tolerance within the cap."""
import warnings

import numpy as np
import pytest

import warp_sim as ws

pytestmark = pytest.mark.slow   # CG solves to tight tolerances at 128^2: about 25 s

H = 1.0 / 60.0
CLOTH = {"size": (1.0, 1.0), "position": (0.0, 1.0, 0.0), "density": 0.2, "pinned": ["top_corners"],
         "stiffness": (1.0e4, 1.0e4, 1.0e3), "damping": (0.01, 0.01, 0.001)}


def cloth(n, precision="float32"):
    scene = ws.Scene(precision=precision)
    scene.add_cloth_grid(resolution=(n, n), **CLOTH)
    return scene


@pytest.mark.parametrize("n, steps", [(32, 30), (64, 30), (128, 12)])
def test_defaults_converge_within_the_cap(n, steps):
    sim = ws.Simulator(cloth(n), integrator="implicit_euler")
    with warnings.catch_warnings():
        warnings.simplefilter("error")   # a converged run issues no warning
        sim.step(H, steps=steps)
    stats = sim.integrator.stats()
    print(f"{n}^2: {stats}")
    assert stats["solves"] == steps
    assert stats["unconverged"] <= 0.05 * steps
    assert stats["residuals"][0] <= stats["tolerance"]
    assert stats["iterations"][2] <= stats["max_iterations"]


def test_default_tolerance_moves_nothing_visible():
    """At 32^2 the default tolerance (1e-3) ends 30 steps within 1e-6 m of solves to 1e-7 in float64 (measured:
    1e-14 m; the bound is a thousandth of a millimetre, far below what a user could see)."""
    loose = ws.Simulator(cloth(32, "float64"), integrator="implicit_euler")
    tight = ws.Simulator(cloth(32, "float64"), integrator=ws.ImplicitEuler(tolerance=1e-7, max_iterations=5000))
    loose.step(H, steps=30)
    tight.step(H, steps=30)
    assert tight.integrator.stats()["unconverged"] == 0
    error = np.abs(loose.state.particle_x.numpy() - tight.state.particle_x.numpy()).max()
    print(f"default tolerance against 1e-7: {error:.2e} m")
    assert error < 1e-6


def test_unconverged_solves_warn_once_per_call_with_count_and_worst_residual():
    sim = ws.Simulator(cloth(32), integrator=ws.ImplicitEuler(max_iterations=5))
    with pytest.warns(RuntimeWarning) as caught:
        sim.step(H, steps=4)
    messages = [str(w.message) for w in caught if "implicit_euler" in str(w.message)]
    assert len(messages) == 1 and "4 conjugate gradient solve(s) stopped at the cap of 5" in messages[0]
    worst = sim.integrator.stats()["residuals"][1]   # every solve stopped at the cap: the worst of them all
    assert f"{worst:.2e}" in messages[0]
    with pytest.warns(RuntimeWarning, match="1 conjugate gradient solve"):   # frames 0 and 1: one step
        sim.run(2.0 / 60.0, fps=60, substeps=1, progress=False)
    stats = sim.integrator.stats()
    assert stats["unconverged"] == 5 and stats["iterations"] == (5, 5.0, 5)


def test_stats_record_every_solve():
    sim = ws.Simulator(cloth(16), integrator="implicit_euler")
    assert sim.integrator.stats()["solves"] == 0
    seen = []
    for _ in range(3):
        sim.step(H)
        seen.append(sim.integrator.last_iterations)
    stats = sim.integrator.stats()
    assert stats["solves"] == 3
    assert stats["iterations"] == (min(seen), pytest.approx(sum(seen) / 3), max(seen)) and min(seen) > 0
    mean, worst = stats["residuals"]
    assert 0.0 <= mean <= worst <= stats["tolerance"]
    assert sim.integrator.max_iterations == 200   # max(200, 4 sqrt(256))

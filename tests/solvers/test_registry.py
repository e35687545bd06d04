"""Solvers by name or as instances with their options: the wiring is the same, options are honoured, and bad
options are ValueErrors naming them."""
import math

import numpy as np
import pytest
from helpers import oscillator

import warp_sim as ws
from warp_sim.solvers import make_integrator


def hanging_cloth(n=8, k=1.0e4):
    """An n x n cloth of k N/m springs pinned at its top corners, 0.5 kg, float64."""
    scene = ws.Scene(precision="float64")
    scene.add_cloth_grid(resolution=(n, n), size=(0.5, 0.5), position=(0.0, 1.0, 0.0), mass=0.5,
                         stiffness=(k, k, k / 10.0), damping=(1.0, 1.0, 0.1), pinned=["top_corners"])
    return scene


@pytest.mark.parametrize("tolerance", [1e-4, 1e-8])
def test_implicit_euler_instance_solves_to_its_tolerance(tolerance):
    """Each CG solve of a stiff cloth at h = 1/60 s ends with |b - A dv| <= tolerance |b| (the relative
    residual asked for), and the Simulator uses the instance it was given."""
    solver = ws.ImplicitEuler(tolerance=tolerance, max_iterations=2000)
    sim = ws.Simulator(hanging_cloth(), integrator=solver, device="cpu")
    assert sim.integrator is solver
    for _ in range(5):
        sim.step(1.0 / 60.0)
        rhs = float(np.linalg.norm(solver.rhs.numpy().astype(np.float64)))
        assert solver.last_converged
        assert solver.last_residual <= tolerance * rhs * (1.0 + 1e-9)
        assert solver.last_tolerance == pytest.approx(tolerance * rhs, rel=1e-6)
    assert solver.unconverged_solves == 0


def test_rk45_instance_honours_its_tolerances():
    """An undamped oscillator (w = 2 rad/s) over 3 s: the error against the closed form stays within a few
    times the tolerance scale atol + rtol |x|, and tightening rtol by 1e4 tightens the error."""
    errors = {}
    for rtol in (1e-5, 1e-9):
        solver = ws.RK45(rtol=rtol, atol=rtol * 1e-2)
        sim = ws.Simulator(oscillator(k=4.0), integrator=solver, device="cpu")
        sim.step(3.0)
        x = sim.state.particle_x.numpy()[1, 0]
        errors[rtol] = abs(x - (1.0 + 0.1 * math.cos(2.0 * 3.0)))
        assert solver.rtol == rtol and solver.stats()["accepted"] > 0
    assert errors[1e-5] < 50 * (1e-7 + 1e-5 * 1.1)
    assert errors[1e-9] < 1e-3 * errors[1e-5]


def test_a_name_and_an_instance_give_the_same_step():
    by_name = ws.Simulator(hanging_cloth(), integrator="implicit_euler", device="cpu")
    by_instance = ws.Simulator(hanging_cloth(), integrator=ws.ImplicitEuler(), device="cpu")
    for sim in (by_name, by_instance):
        sim.step(1.0 / 60.0, steps=3)
    np.testing.assert_array_equal(by_name.state.particle_x.numpy(), by_instance.state.particle_x.numpy())


def test_a_solver_instance_serves_one_simulator():
    solver = ws.RK4()
    ws.Simulator(oscillator(), integrator=solver, device="cpu")
    with pytest.raises(ValueError, match="^integrator=.*already bound"):
        ws.Simulator(oscillator(), integrator=solver, device="cpu")


@pytest.mark.parametrize("make, name", [
    (lambda: ws.ImplicitEuler(tolerance=2.0), "tolerance"),
    (lambda: ws.ImplicitEuler(max_iterations=0), "max_iterations"),
    (lambda: ws.ImplicitEuler(warm_start="yes"), "warm_start"), (lambda: ws.RK45(atol=-1.0), "atol"),
    (lambda: ws.RK45(rtol=0.0), "rtol"), (lambda: ws.RK45(max_steps=1.5), "max_steps"),
    (lambda: make_integrator(42), "integrator"), (lambda: make_integrator("rk5"), "integrator"),
    (lambda: make_integrator(ws.RK4(), rtol=1e-6), "rtol")])
def test_bad_solver_arguments_name_themselves(make, name):
    with pytest.raises(ValueError, match=f"^{name}="):
        make()

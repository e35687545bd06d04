"""Gradients against closed forms, exact to 1e-9 in float64: a projectile's final position against its initial
position and velocity under every explicit solver (dx(T)/dx0 = I, dx(T)/dv0 = T I: each solver's discrete map is
x0 + N h v0 + terms in g), a body pushed from rest by per-frame forces (dx(T)/dF_k = dt (T - (k + 1/2) dt) / m,
which rk4 integrates exactly, the force being constant over each frame), the same body's mass under a constant
force, and gravity on the projectile (T^2 / 2 with a second-order solver)."""
import numpy as np
import pytest
from gradient_scenes import WEIGHTS, final_position_loss, projectile

import warp_sim as ws

EXPLICIT = ["euler", "midpoint", "rk4", "symplectic_euler", "verlet"]
SECONDS, FPS, SUBSTEPS = 0.5, 60.0, 4


@pytest.mark.parametrize("integrator", EXPLICIT)
def test_projectile_gradient_is_exact(integrator):
    value, grads = ws.gradient(projectile(), final_position_loss(), ["particle_x", "particle_v"], seconds=SECONDS,
                               fps=FPS, substeps=SUBSTEPS, integrator=integrator)
    w = np.array(WEIGHTS)
    x_error = np.abs(grads["particle_x"] - w).max()
    v_error = np.abs(grads["particle_v"] - SECONDS * w).max()
    print(f"{integrator}: loss {value:.12g}, max |error| d/dx0 {x_error:.2e}, d/dv0 {v_error:.2e}")
    assert grads["particle_x"].shape == grads["particle_v"].shape == (1, 3)
    assert x_error < 1e-9 and v_error < 1e-9


@pytest.mark.parametrize("integrator", ["midpoint", "rk4", "verlet"])
def test_gravity_gradient_of_a_projectile_is_half_t_squared(integrator):
    _, grads = ws.gradient(projectile(), final_position_loss(), ["gravity"], seconds=SECONDS, fps=FPS,
                           substeps=SUBSTEPS, integrator=integrator)
    assert np.abs(grads["gravity"] - 0.5 * SECONDS ** 2 * np.array(WEIGHTS)).max() < 1e-9


def pushed_ball(mass: float = 2.0) -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_rigid_body(ws.Sphere(0.1), mass=mass, position=(0.0, 1.0, 0.0))
    return scene


def test_per_frame_forces_on_a_body_from_rest():
    fps, seconds, mass = 30.0, 0.5, 2.0
    frames, dt = int(round(seconds * fps)), 1.0 / fps
    force = np.tile([1.0, 2.0, -1.0], (frames, 1, 1))
    _, grads = ws.gradient(pushed_ball(mass), final_position_loss("body_x"), ["body_force", "body_torque"],
                           seconds=seconds, fps=fps, substeps=4, integrator="rk4", controls={"body_force": force})
    k = np.arange(frames)
    expected = (dt * (seconds - (k + 0.5) * dt) / mass)[:, None] * np.array(WEIGHTS)
    error = np.abs(grads["body_force"][:, 0] - expected).max()
    print(f"d x(T) / d F_k: max |error| {error:.2e} over {frames} frames")
    assert grads["body_force"].shape == (frames, 1, 3) and error < 1e-9
    assert np.abs(grads["body_torque"]).max() < 1e-12   # a torque turns the ball, which the loss does not see


def test_body_mass_under_a_constant_force():
    """x(T) = x0 + (g + F / M) T^2 / 2, so d (w . x(T)) / dM = -(w . F) T^2 / (2 M^2)."""
    fps, seconds, mass = 30.0, 0.5, 2.0
    frames = int(round(seconds * fps))
    force = np.tile([1.0, 2.0, -1.0], (frames, 1, 1))
    _, grads = ws.gradient(pushed_ball(mass), final_position_loss("body_x"), ["body_mass"], seconds=seconds,
                           fps=fps, substeps=4, integrator="rk4", controls={"body_force": force})
    expected = -np.dot(WEIGHTS, force[0, 0]) * seconds ** 2 / (2.0 * mass ** 2)
    assert abs(grads["body_mass"][0] - expected) < 1e-9


def test_an_empty_wrt_returns_the_value_alone():
    value = ws.gradient(projectile(), final_position_loss(), [], seconds=SECONDS, fps=FPS, substeps=SUBSTEPS)
    x0, v0, g, T = np.array([0.0, 1.0, 0.0]), np.array([1.0, 2.0, 0.5]), np.array([0.0, -9.81, 0.0]), SECONDS
    assert isinstance(value, float)
    assert abs(value - np.dot(WEIGHTS, x0 + v0 * T + 0.5 * g * T ** 2)) < 1e-9   # rk4: exact on a parabola

"""Gradients with respect to restitution (wrt "restitution", per body, and "plane_restitution", per plane) through
the taped body-contact response at the time of impact, against closed forms.

A contact's restitution is the mean of its two sides' (kernels.contacts.pair_material), so with both sides set to
the same e the pair's is e and d/d e_body = d/d e_plane = 1/2 d/d e_pair. Float64, rk4, 60 fps, 8 substeps.
"""
import numpy as np
import pytest
import warp as wp

import warp_sim as ws

G = 9.81
RADIUS = 0.125


@wp.kernel
def body_coordinate(x: wp.array2d(dtype=wp.vec3d), frame: int, body: int, axis: int,
                    out: wp.array(dtype=wp.float64)):
    """out = x[frame, body][axis]."""
    out[0] = x[frame, body][axis]


def coordinate_loss(body: int, axis: int):
    def loss(traj):
        out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
        wp.launch(body_coordinate, 1, [traj.body_x, traj.frames, body, axis, out])
        return out
    return loss


def dropped(e: float, height: float) -> ws.Scene:
    scene = ws.Scene(precision="float64", gravity=(0.0, -G, 0.0))
    scene.add_ground(restitution=e, friction=0.0)   # the ball's own: the pair's is e
    scene.add_rigid_body(ws.Sphere(RADIUS), mass=1.0, position=(0.0, height, 0.0), restitution=e, friction=0.0)
    return scene


def test_a_bounce_on_the_ground_has_the_closed_form_restitution_gradient():
    """Dropped from rest at centre height h, the ball lands at t1 = s / g with s = sqrt(2 g (h - r)), whatever e;
    it rebounds at e s, so before its second impact y(T) = r + e s (T - t1) - g (T - t1)^2 / 2 and
    dy/de_pair = s (T - t1); the ball's own e and the ground's each give half of it. Within 2e-4 relative;
    measured 4e-15."""
    e, height, T = 0.5, 1.0, 0.7
    s = np.sqrt(2.0 * G * (height - RADIUS))
    tau = T - s / G
    assert 0.0 < tau < 2.0 * e * s / G   # after the bounce, before the next
    value, grads = ws.gradient(dropped(e, height), coordinate_loss(0, 1), ["restitution", "plane_restitution"],
                               seconds=T, fps=60.0, substeps=8, integrator="rk4")
    assert value == pytest.approx(RADIUS + e * s * tau - 0.5 * G * tau * tau, abs=1e-9)
    expected = 0.5 * s * tau
    assert grads["restitution"].shape == (1,) and grads["restitution"].dtype == np.float64
    assert grads["restitution"][0] == pytest.approx(expected, rel=2e-4)
    assert grads["plane_restitution"][0] == pytest.approx(expected, rel=2e-4)
    assert grads["restitution"][0] + grads["plane_restitution"][0] == pytest.approx(2.0 * expected, rel=1e-12)
    assert abs(grads["restitution"][0] / expected - 1.0) < 1e-12   # what it measures


def head_on(e: float, x=(0.0, 0.5), v=(1.0, 0.0)) -> ws.Scene:
    scene = ws.Scene(precision="float64", gravity=(0.0, 0.0, 0.0))
    for xk, vk in zip(x, v):
        scene.add_rigid_body(ws.Sphere(RADIUS), mass=1.0, position=(xk, 1.0, 0.0), linear_velocity=(vk, 0.0, 0.0),
                             restitution=e, friction=0.0)
    return scene


def test_a_head_on_collision_has_the_closed_form_restitution_gradient():
    """Equal spheres, the second at rest: they meet at t_c = (x2 - x1 - 2 r) / v1 and the second leaves at
    v2' = (1 + e) / 2 v1, so x2(T) = x2 + v2' (T - t_c) and dx2/de_pair = v1 / 2 (T - t_c), half of it from each
    ball's own e (e = 0.8). Within 1e-3 relative; measured 1.5e-14."""
    e, T = 0.8, 1.0
    t_c = (0.5 - 0.0 - 2.0 * RADIUS) / 1.0
    value, grads = ws.gradient(head_on(e), coordinate_loss(1, 0), ["restitution"], seconds=T, fps=60.0,
                               substeps=8, integrator="rk4")
    assert value == pytest.approx(0.5 + 0.5 * (1.0 + e) * (T - t_c), abs=1e-9)
    pair = 0.5 * (T - t_c)
    np.testing.assert_allclose(grads["restitution"], [0.5 * pair, 0.5 * pair], rtol=1e-3)
    assert grads["restitution"].sum() == pytest.approx(pair, rel=1e-3)
    np.testing.assert_allclose(grads["restitution"], [0.5 * pair, 0.5 * pair], rtol=1e-12)   # what it measures


def test_plane_restitution_needs_a_plane():
    with pytest.raises(ValueError, match="plane_restitution.*has none"):
        ws.gradient(head_on(0.8), coordinate_loss(1, 0), ["plane_restitution"], seconds=0.1)

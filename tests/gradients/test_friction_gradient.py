"""Gradients through Coulomb friction in body contacts (passes.contact_adjoint): a box sliding to a stop and a
sphere sliding into rolling on the ground, against their closed forms and central differences; the gradient
with respect to each side's friction coefficient (a contact takes the mean of the body's and the plane's).

Every scene is float64, inelastic (e = 0) and starts in contact at rest on the ground, sliding along +x.
"""
import numpy as np
import pytest
from test_body_contacts_gradient import body_loss

import warp_sim as ws

G = 9.81
HALF, RADIUS = 0.1, 0.125   # [m] the box's half extent, the sphere's radius
V0, MU = 1.0, 0.4            # [m/s] the initial sliding speed, [1] the friction coefficient of both sides


def sliding(shape: str, v0: float = V0, mu: float = MU) -> ws.Scene:
    """A box or a sphere of 1 kg resting on the ground and sliding along +x at v0, friction mu on both sides."""
    scene = ws.Scene(precision="float64", gravity=(0.0, -G, 0.0))
    scene.add_ground(restitution=0.0, friction=mu)
    body, height = (ws.Box((HALF, HALF, HALF)), HALF) if shape == "box" else (ws.Sphere(RADIUS), RADIUS)
    scene.add_rigid_body(body, mass=1.0, position=(0.0, height, 0.0), linear_velocity=(v0, 0.0, 0.0),
                         restitution=0.0, friction=mu)
    return scene


LOSS = body_loss(0, (1.0, 0.0, 0.0))   # x(T)


def distance_gradients(shape: str, seconds: float):
    """(x(T), dx/dv0, dx/dmu with mu the pair's coefficient: the body's and the plane's summed)."""
    value, grads = ws.gradient(sliding(shape), LOSS, ["body_v", "friction", "plane_friction"], seconds=seconds)
    assert grads["friction"][0] == pytest.approx(grads["plane_friction"][0], rel=1e-12)   # each half the pair's
    return value, grads["body_v"][0, 0], grads["friction"][0] + grads["plane_friction"][0]


def central(shape: str, seconds: float, step: float = 1e-5):
    """(dx/dv0, dx/dmu) by central differences of forward runs."""
    def x(**change):
        return ws.gradient(sliding(shape, **change), LOSS, [], seconds=seconds)
    return ((x(v0=V0 + step) - x(v0=V0 - step)) / (2 * step), (x(mu=MU + step) - x(mu=MU - step)) / (2 * step))


def test_a_sphere_sliding_into_rolling_has_the_closed_form_gradients():
    """A sphere sliding at v0 without spin rolls from t1 = 2 v0 / (7 mu g) at 5/7 v0 (friction slows the centre
    and spins the ball up), so x(T) = 2 v0^2 / (49 mu g) + 5/7 v0 T for T > t1 (t1 = 0.073 s here):
    dx/dv0 = 4 v0 / (49 mu g) + 5 T / 7 and dx/dmu = -2 v0^2 / (49 mu^2 g). Against central differences within
    1e-5 relative (measured 1e-9); against the closed form within 1e-3 (dx/dv0, measured 4e-4) and 5e-2 (dx/dmu,
    measured 2.6 %: the sliding phase is a whole number of steps, 35 at 1/480 s, and the gradient is the run's,
    whose last sliding step ends in sticking, which mu does not enter)."""
    T = 1.0
    value, dv, dmu = distance_gradients("sphere", T)
    assert value == pytest.approx(2 * V0**2 / (49 * MU * G) + 5 / 7 * V0 * T, rel=1e-5)
    np.testing.assert_allclose([dv, dmu], central("sphere", T), rtol=1e-5)
    assert dv == pytest.approx(4 * V0 / (49 * MU * G) + 5 * T / 7, rel=1e-3)
    assert dmu == pytest.approx(-2 * V0**2 / (49 * MU**2 * G), rel=5e-2)


@pytest.mark.slow   # 25 s: four corners of resting contact, every sweep in full
def test_a_box_sliding_to_a_stop_has_the_closed_form_gradients():
    """A box sliding at v0 stops after v0^2 / (2 mu g) (T = 0.5 s is past its stop at 0.25 s): dx/dv0 = v0 /
    (mu g) and dx/dmu = -v0^2 / (2 mu^2 g). Against central differences within 1e-6 relative (measured 4e-12 and
    1.5e-9); against the closed form within 1e-2 (measured: x 1.5e-5, dx/dv0 1.4e-3, dx/dmu 2.9e-3, the stop
    falling inside a step of 1/480 s)."""
    T = 0.5
    value, dv, dmu = distance_gradients("box", T)
    np.testing.assert_allclose([dv, dmu], central("box", T), rtol=1e-6)
    assert value == pytest.approx(V0**2 / (2 * MU * G), rel=1e-3)
    assert dv == pytest.approx(V0 / (MU * G), rel=1e-2)
    assert dmu == pytest.approx(-V0**2 / (2 * MU**2 * G), rel=1e-2)


def test_friction_needs_a_body_and_plane_friction_a_plane():
    scene = ws.Scene(precision="float64")
    scene.add_particles([(0.0, 1.0, 0.0)])
    with pytest.raises(ValueError, match="friction.*has none"):
        ws.gradient(scene, body_loss(0, (1.0, 0.0, 0.0)), ["friction"], seconds=0.1)
    with pytest.raises(ValueError, match="plane_friction.*has none"):
        ws.gradient(scene, body_loss(0, (1.0, 0.0, 0.0)), ["plane_friction"], seconds=0.1)

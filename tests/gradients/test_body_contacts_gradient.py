"""Gradients through rigid-body impacts with restitution (passes.contact_adjoint): two spheres meeting head on, a
sphere bouncing on the ground against the closed form (and the naive gradient, the impact time held, against it),
an off-centre billiards hit and a box landing and coming to rest against central differences; what stays refused.

Every scene is float64 and frictionless, with radii that float32 (the narrow phase's precision) holds exactly.
"""
import numpy as np
import pytest
import warp as wp
from gradient_scenes import forward_value

import warp_sim as ws
from warp_sim.adjoints import NoAdjoint
from warp_sim.passes import BodyContacts

G = 9.81


@wp.kernel
def weighted_body(x: wp.array2d(dtype=wp.vec3d), q: wp.array2d(dtype=wp.quatd), frame: int, body: int,
                  w: wp.vec3d, turned: float, out: wp.array(dtype=wp.float64)):
    """out = w . x[frame, body] + turned * w . R(q[frame, body]) e_x."""
    axis = wp.quat_rotate(q[frame, body], wp.vec3d(wp.float64(1.0), wp.float64(0.0), wp.float64(0.0)))
    out[0] = wp.dot(w, x[frame, body]) + wp.float64(turned) * wp.dot(w, axis)


def body_loss(body: int, weights, turned: float = 0.0):
    """loss(traj) = w . x_body(T) (+ turned w . R_body(T) e_x)."""
    def loss(traj):
        out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
        wp.launch(weighted_body, 1, [traj.body_x, traj.body_q, traj.frames, body, wp.vec3d(*weights), turned, out])
        return out
    return loss


def head_on(x=(0.0, 0.5), v=(1.0, -0.5), radius=0.125) -> ws.Scene:
    scene = ws.Scene(precision="float64", gravity=(0.0, 0.0, 0.0))
    for xk, vk in zip(x, v):
        scene.add_rigid_body(ws.Sphere(radius), mass=1.0, position=(xk, 1.0, 0.0), linear_velocity=(vk, 0.0, 0.0),
                             restitution=1.0, friction=0.0)
    return scene


def test_equal_spheres_meeting_head_on_swap_their_gradients():
    """Equal spheres in an elastic head-on collision swap velocities at t* = (x2 - x1 - 2r) / (v1 - v2), so after it
    x2(T) = x2 + v2 t* + v1 (T - t*) = x1 + 2 r + v1 T: d x2(T) / d (x1, x2, v1, v2) = (1, 0, T, 0), (1, 0, 1, 0)
    at T = 1 s (Nimble returns (0.75, 0.25, 0.91, 0.08)). Measured: exact to 1e-14."""
    value, grads = ws.gradient(head_on(), body_loss(1, (1.0, 0.0, 0.0)), ["body_x", "body_v"], seconds=1.0)
    assert value == pytest.approx(0.0 + 0.25 + 1.0, abs=1e-12)
    along = [grads["body_x"][0, 0], grads["body_x"][1, 0], grads["body_v"][0, 0], grads["body_v"][1, 0]]
    np.testing.assert_allclose(along, [1.0, 0.0, 1.0, 0.0], atol=0.02)
    np.testing.assert_allclose(along, [1.0, 0.0, 1.0, 0.0], atol=1e-9)   # what it measures


RADIUS, E = 0.125, 0.5


def dropped(height: float, v0: float) -> ws.Scene:
    scene = ws.Scene(precision="float64", gravity=(0.0, -G, 0.0))
    scene.add_ground(restitution=E, friction=0.0)
    scene.add_rigid_body(ws.Sphere(RADIUS), mass=1.0, position=(0.0, height, 0.0), linear_velocity=(0.0, v0, 0.0),
                         restitution=E, friction=0.0)
    return scene


def bounce(height: float, v0: float, T: float) -> tuple[float, float, float]:
    """(y(T), dy/dh, dy/dv0) of a ball of radius r dropped from centre height h with upward speed v0, after one
    bounce of restitution e on the ground.

    It falls D = h - r to the impact: h + v0 t - g t^2 / 2 = r at t* = (v0 + s) / g, arriving at -s with
    s = sqrt(v0^2 + 2 g D). It rebounds at e s and flies for tau = T - t*: y(T) = r + e s tau - g tau^2 / 2. With
    ds/dh = g / s, dt*/dh = 1 / s, ds/dv0 = v0 / s and dt*/dv0 = (1 + v0 / s) / g, and dy/dt* = -(e s - g tau):
    dy/dh = e g tau / s - (e s - g tau) / s = (1 + e) g tau / s - e and
    dy/dv0 = e v0 tau / s - (e s - g tau)(1 + v0 / s) / g.
    """
    s = np.sqrt(v0 * v0 + 2.0 * G * (height - RADIUS))
    tau = T - (v0 + s) / G
    assert 0.0 < tau < 2.0 * E * s / G   # after the bounce, before the next
    return (RADIUS + E * s * tau - 0.5 * G * tau * tau, (1.0 + E) * G * tau / s - E,
            E * v0 * tau / s - (E * s - G * tau) * (1.0 + v0 / s) / G)


HEIGHT, V0, T_BOUNCE = 1.0, 0.3, 0.7
HEIGHT_LOSS = body_loss(0, (0.0, 1.0, 0.0))


def test_a_bounce_on_the_ground_has_the_closed_form_gradient():
    """d y(T) / d h and d y(T) / d v0 through one bounce (e = 0.5, rk4) against bounce(): within 2e-4; measured
    6e-15 (the time of impact, its post-impact velocity -e u and the flight after all move with the drop)."""
    y, dh, dv = bounce(HEIGHT, V0, T_BOUNCE)
    value, grads = ws.gradient(dropped(HEIGHT, V0), HEIGHT_LOSS, ["body_x", "body_v"], seconds=T_BOUNCE)
    assert value == pytest.approx(y, abs=1e-12)
    assert grads["body_x"][0, 1] == pytest.approx(dh, abs=2e-4)
    assert grads["body_v"][0, 1] == pytest.approx(dv, abs=2e-4)
    assert abs(grads["body_x"][0, 1] - dh) < 1e-12 and abs(grads["body_v"][0, 1] - dv) < 1e-12   # measured


def test_the_naive_gradient_with_the_impact_time_held_differs(monkeypatch):
    """Holding the time of impact (BodyContacts.hold_impact_time, the naive discrete gradient) the
    bounce only flips the velocity where it was: a higher drop lands the same height higher, dy/dh = 1 exactly,
    against (1 + e) g tau / s - e = 0.371; dy/dv0 is 0.331 against 0.046. The same forward run."""
    y, dh, dv = bounce(HEIGHT, V0, T_BOUNCE)
    monkeypatch.setattr(BodyContacts, "hold_impact_time", True)
    value, grads = ws.gradient(dropped(HEIGHT, V0), HEIGHT_LOSS, ["body_x", "body_v"], seconds=T_BOUNCE)
    assert value == pytest.approx(y, abs=1e-12)
    assert grads["body_x"][0, 1] == pytest.approx(1.0, abs=1e-9)
    assert abs(grads["body_x"][0, 1] - dh) > 0.5 and abs(grads["body_v"][0, 1] - dv) > 0.2


def billiards(cue_velocity, masses=(0.17, 0.17)) -> ws.Scene:
    """A cue ball sent at a second one 0.6 m away, 45 mm off the line of centres (radii 50 mm, e = 0.95)."""
    scene = ws.Scene(precision="float64", gravity=(0.0, 0.0, 0.0))
    for position, velocity, mass in (((0.0, 0.5, 0.0), tuple(cue_velocity), masses[0]),
                                     ((0.6, 0.5, 0.045), (0.0, 0.0, 0.0), masses[1])):
        scene.add_rigid_body(ws.Sphere(0.05), mass=float(mass), position=position, linear_velocity=velocity,
                             restitution=0.95, friction=0.0)
    return scene


def central_differences(value, x: np.ndarray, step: float, entries) -> np.ndarray:
    result = []
    for k in entries:
        up, down = x.copy(), x.copy()
        up[k] += step
        down[k] -= step
        result.append((value(up) - value(down)) / (2.0 * step))
    return np.array(result)


def test_billiards_cue_velocity_gradient_matches_central_differences():
    """The second ball's final position, weighted, against the cue ball's velocity in the table's plane and the
    balls' masses: the gradient matches central differences of the same runs (steps 1e-5 m/s, 1e-6 kg) within 1e-3
    relative; measured 2e-9 and 1e-9."""
    cue, masses = np.array([1.2, 0.0, 0.02]), np.array([0.17, 0.17])
    loss = body_loss(1, (0.6, 0.0, -0.9))
    value, grads = ws.gradient(billiards(cue), loss, ["body_v", "body_mass"], seconds=1.0)
    assert value == pytest.approx(forward_value(billiards(cue), loss, 1.0), abs=1e-6)   # the forward run's
    numeric = central_differences(lambda v: ws.gradient(billiards(v), loss, seconds=1.0), cue, 1e-5, (0, 2))
    np.testing.assert_allclose(grads["body_v"][0, [0, 2]], numeric, rtol=1e-3)
    assert abs(numeric[1]) > 1.0   # the offset matters: a sideways push turns the second ball's path
    numeric = central_differences(lambda m: ws.gradient(billiards(cue, m), loss, seconds=1.0), masses, 1e-6, (0, 1))
    np.testing.assert_allclose(grads["body_mass"], numeric, rtol=1e-3)


def landing_box(height: float, speed: float) -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=0.0, friction=0.0)
    q = np.array([0.2, 0.1, 0.05, 1.0])
    scene.add_rigid_body(ws.Box((0.2, 0.1, 0.15)), mass=1.0, position=(0.0, height, 0.0),
                         orientation=tuple(q / np.linalg.norm(q)), linear_velocity=(speed, 0.0, 0.0),
                         angular_velocity=(0.3, 0.0, 0.5), restitution=0.0, friction=0.0)
    return scene


@pytest.mark.slow   # 30 s: resting contact solves every sweep
def test_a_box_landing_and_resting_on_the_ground_matches_central_differences():
    """A tilted, spinning box dropped on the ground (e = 0, frictionless): its corners' impacts, then resting
    contact and the position projection, with the choices of the run held (passes.contact_adjoint). Its final pose
    against the drop height and sliding speed matches central differences within 1e-3 relative (measured 8e-5
    and 5e-10: the resting iterations make the run a fine staircase of the inputs, of steps below 1e-4)."""
    start = np.array([0.6, 0.4])
    loss = body_loss(0, (0.6, 0.8, -0.9), turned=1.0)
    value, grads = ws.gradient(landing_box(*start), loss, ["body_x", "body_v"], seconds=1.0)
    numeric = central_differences(lambda p: ws.gradient(landing_box(*p), loss, seconds=1.0), start, 1e-5, (0, 1))
    np.testing.assert_allclose([grads["body_x"][0, 1], grads["body_v"][0, 0]], numeric, rtol=1e-3)


def two_boxes() -> ws.Scene:
    scene = ws.Scene(precision="float64")
    for x in (0.0, 0.5):
        scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), mass=1.0, position=(x, 1.0, 0.0), friction=0.0)
    return scene


def sphere_on_a_box_collider() -> ws.Scene:
    scene = dropped(1.0, 0.0)
    scene.add_collider(ws.Box((0.5, 0.1, 0.5)), position=(0.0, -1.0, 0.0), friction=0.0)
    return scene


@pytest.mark.parametrize("make", [two_boxes, sphere_on_a_box_collider])
def test_what_the_taped_response_does_not_cover_is_refused(make):
    """Body pairs other than two spheres and static colliders other than spheres: a NoAdjoint before anything
    runs, naming the body contacts and what they cover."""
    with pytest.raises(NoAdjoint, match="body contacts.*between spheres.*collisions=False"):
        ws.Simulator(make(), differentiable=True)


def test_a_box_on_the_ground_and_spheres_are_covered():
    """A box of any shape on a plane and spheres among themselves run differentiably, contacts included."""
    assert ws.Simulator(landing_box(0.6, 0.0), differentiable=True).body_contacts is not None
    assert ws.Simulator(head_on(), differentiable=True).body_contacts is not None

"""Gradients through joints (passes.joint_adjoint): a pendulum against the small-angle closed form, a chain of
ball joints and a hinge stopped by its limit against central differences (the impulses that warm-start each step
carried across the frames of a checkpointed gradient), an arm steered by per-frame torques.

Every scene is float64, collisions off (joints alone), run through ws.gradient's defaults (60 fps, 8 substeps,
each split to the joint step of 1/480 s).
"""
import math

import numpy as np
import pytest
from test_body_contacts_gradient import body_loss

import warp_sim as ws

G = 9.81
LENGTH, RADIUS = 1.0, 0.05   # [m] the pendulum's arm and its bob's radius


def pendulum(theta0: float = 0.0, v0: float = 0.0, limits=None) -> ws.Scene:
    """A 1 kg sphere on a 1 m arm, hinged about z at (0, 2, 0) (within ``limits`` [rad], if given), from angle
    theta0 with tangential speed v0."""
    scene = ws.Scene(precision="float64")
    along = (math.cos(theta0), math.sin(theta0), 0.0)
    scene.add_rigid_body(ws.Sphere(RADIUS), mass=1.0,
                         position=(LENGTH * math.sin(theta0), 2.0 - LENGTH * math.cos(theta0), 0.0),
                         linear_velocity=tuple(v0 * a for a in along))
    scene.add_joint("revolute", None, 0, anchor=(0.0, 2.0, 0.0), axis=(0.0, 0.0, 1.0), limits=limits)
    return scene


def central(make, loss, step: float, seconds: float, **gradient) -> float:
    """d loss / d p by central differences of ``make(p)``'s forward runs about p = 0."""
    return (ws.gradient(make(step), loss, [], seconds=seconds, **gradient)
            - ws.gradient(make(-step), loss, [], seconds=seconds, **gradient)) / (2 * step)


def test_a_pendulum_has_the_small_angle_closed_form_gradient():
    """Pushed at the bottom with v0 and no spin, the bob swings with the angular momentum about the hinge it had,
    m L v0 = I_hinge theta'(0) (I_hinge = m L^2 + 2/5 m r^2: the joint's first step spins the ball up), so for
    small v0 theta(t) = theta'(0) / omega sin(omega t), omega^2 = m g L / I_hinge, and x(T) = L theta(T):
    d x(T) / d v0 = sin(omega T) / (omega (1 + 2/5 r^2 / L^2)) (T = 0.7 s, past a quarter period; v0 = 1 cm/s).
    Within 1e-4 relative of it (measured 3.6e-6), and of central differences within 1e-6 (measured 2e-11).
    (From exact rest, v0 = 0, the run's rows and projection see exact zeros whose branches the gradient holds:
    3e-4 off central differences there.)"""
    T, v0 = 0.7, 0.01
    spun = 1.0 + 0.4 * RADIUS**2 / LENGTH**2
    omega = math.sqrt(G / (LENGTH * spun))
    loss = body_loss(0, (1.0, 0.0, 0.0))
    value, grads = ws.gradient(pendulum(v0=v0), loss, ["body_v"], seconds=T)
    assert value == pytest.approx(v0 * math.sin(omega * T) / (omega * spun), rel=1e-4)
    dx = grads["body_v"][0, 0]
    assert dx == pytest.approx(central(lambda e: pendulum(v0=v0 + e), loss, 1e-6, T), rel=1e-6)
    assert dx == pytest.approx(math.sin(omega * T) / (omega * spun), rel=1e-4)


def chain(links: int = 4, speed: float = 0.0, mass: float = 0.2) -> ws.Scene:
    """``links`` boxes of 0.2 m on ball joints from a world pivot at (0, 2, 0), released horizontally along +x, the
    last one's mass ``mass``, the first pushed along z at ``speed``."""
    scene = ws.Scene(precision="float64")
    for k in range(links):
        scene.add_rigid_body(ws.Box((0.1, 0.02, 0.02)), mass=mass if k == links - 1 else 0.2,
                             position=(0.2 * k + 0.1, 2.0, 0.0),
                             linear_velocity=(0.0, 0.0, speed if k == 0 else 0.0))
        scene.add_joint("ball", k - 1 if k else None, k, anchor=(0.2 * k, 2.0, 0.0))
    return scene


@pytest.mark.slow   # 40 s: a chain's every sweep on the tape, and four forward runs
def test_a_falling_chain_matches_central_differences():
    """A chain of four ball-jointed links released horizontally, its tip's position at 0.5 s against the first
    link's initial z speed and the tip's mass: the gradient through the warm-started sweeps (not converged in a
    step, so the impulses carried from step to step and frame to frame enter it) matches central differences
    within 1e-5 relative (measured 1.7e-8 and 2.8e-9)."""
    T = 0.5
    loss = body_loss(3, (0.4, 1.0, 0.7))
    value, grads = ws.gradient(chain(speed=0.3), loss, ["body_v", "body_mass"], seconds=T, collisions=False)
    by_speed = central(lambda e: chain(speed=0.3 + e), loss, 1e-6, T, collisions=False)
    by_mass = central(lambda e: chain(speed=0.3, mass=0.2 + e), loss, 1e-6, T, collisions=False)
    np.testing.assert_allclose([grads["body_v"][0, 2], grads["body_mass"][3]], [by_speed, by_mass], rtol=1e-5)


def limited(v0: float = 0.0) -> ws.Scene:
    """The pendulum with its hinge limited to +-0.3 rad, released at the bottom at 1.5 m/s + v0: it would swing
    to 0.49 rad, so it stops at the limit and swings back from there."""
    return pendulum(v0=1.5 + v0, limits=(-0.3, 0.3))


def test_a_pendulum_stopped_by_its_limit_matches_central_differences():
    """The bob reaches the limit at a time that depends on its speed, stops there (the limit row inelastic) and
    swings back under gravity: its position at T = 0.8 s against the initial speed, through the limit row, whose
    impulse grows with the speed, and the projection that holds it. Within 1e-4 relative of central differences
    (measured 6e-6)."""
    T = 0.8
    loss = body_loss(0, (1.0, 0.5, 0.0), turned=0.5)
    value, grads = ws.gradient(limited(), loss, ["body_v"], seconds=T)
    along = grads["body_v"][0, 0]   # the bob starts at the bottom moving along +x
    assert along == pytest.approx(central(limited, loss, 1e-6, T), rel=1e-4)


def test_per_frame_torques_steer_a_hinged_arm():
    """An arm on a vertical hinge (no gravity) turned by per-frame torques about the hinge: its angle after the
    last frame against each frame's torque, theta(T) = sum_k tau_k dt (T - (k + 1/2) dt) / I_hinge with I_hinge =
    m (a^2 + b^2) / 3 + m d^2 the arm's inertia about the hinge (a box of half extents a, b at d): the torques
    about other axes, which the hinge holds, get nothing. Against central differences within 1e-6 (frames 0 and
    11; measured 4e-11 and 4e-10); against the closed form within 1e-4 absolute (measured 5.2e-5, the same for
    every frame: the jointed bodies' drift is first order in the step, 1/480 s)."""
    fps, frames = 60.0, 12
    scene = ws.Scene(precision="float64", gravity=(0.0, 0.0, 0.0))
    scene.add_rigid_body(ws.Box((0.25, 0.02, 0.02)), mass=1.0, position=(0.25, 1.0, 0.0))
    scene.add_joint("revolute", None, 0, anchor=(0.0, 1.0, 0.0), axis=(0.0, 1.0, 0.0))
    torque = np.zeros((frames, 1, 3))
    torque[:, 0, 1] = 0.01
    loss = body_loss(0, (0.0, 0.0, -1.0))   # -z of the centre: d sin(theta) for small theta
    value, grads = ws.gradient(scene, loss, ["body_torque"], seconds=frames / fps, controls={"body_torque": torque})
    dt, T = 1.0 / fps, frames / fps
    inertia = 1.0 * (0.25**2 + 0.02**2) / 3.0 + 1.0 * 0.25**2
    expected = 0.25 * dt * (T - (np.arange(frames) + 0.5) * dt) / inertia
    np.testing.assert_allclose(grads["body_torque"][:, 0, 1], expected, atol=1e-4)
    np.testing.assert_allclose(grads["body_torque"][:, 0, [0, 2]], 0.0, atol=1e-9)

    def pushed(frame, step):
        more = torque.copy()
        more[frame, 0, 1] += step
        return ws.gradient(scene, loss, [], seconds=T, controls={"body_torque": more})
    for frame in (0, frames - 1):
        numeric = (pushed(frame, 1e-6) - pushed(frame, -1e-6)) / 2e-6
        assert grads["body_torque"][frame, 0, 1] == pytest.approx(numeric, rel=1e-6)


def hinged_arm(v: float = 0.0) -> ws.Scene:
    """A 0.5 m box arm (1 kg) hinged about z at 0.3 m above the ground, swung down at 1 m/s + v: its tip lands on
    the ground (e = 0, friction 0.5), slides and sticks, the hinge holding the other end."""
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=0.0, friction=0.5)
    scene.add_rigid_body(ws.Box((0.25, 0.02, 0.02)), mass=1.0, position=(0.25, 0.3, 0.0),
                         linear_velocity=(0.0, -1.0 - v, 0.0))
    scene.add_joint("revolute", None, 0, anchor=(0.0, 0.3, 0.0), axis=(0.0, 0.0, 1.0))
    return scene


@pytest.mark.slow   # 30 s: the joint's rows inside the contact solve's sweeps, on the tape
def test_a_hinged_arm_landing_on_the_ground_matches_central_differences():
    """Joints and contacts in one coloured solve: the arm's tip lands at 0.15 s and comes to rest where friction
    stops it; its pose at 0.3 s against the speed it was swung at, through the contact's impact and friction and
    the hinge's rows swept with them (the joint's impulses carried from frame to frame). Within 1e-5 relative of
    central differences (measured 4e-8)."""
    T = 0.3
    loss = body_loss(0, (0.3, 1.0, 0.0), turned=0.5)
    value, grads = ws.gradient(hinged_arm(), loss, ["body_v"], seconds=T)
    assert -grads["body_v"][0, 1] == pytest.approx(central(hinged_arm, loss, 1e-6, T), rel=1e-5)


@pytest.mark.parametrize("integrator", ["euler", "midpoint", "rk4", "symplectic_euler", "verlet", "implicit_euler"])
def test_a_hinged_pendulum_has_its_gradient_under_every_solver(integrator):
    """The joint pass plugs into every fixed-step solver unchanged: the pendulum pushed at 0.3 m/s, its pose at
    0.3 s against the push, within 1e-7 relative of central differences under each (measured 5e-11 to 3e-10)."""
    loss = body_loss(0, (1.0, 0.5, 0.0), turned=0.5)
    value, grads = ws.gradient(pendulum(v0=0.3), loss, ["body_v"], seconds=0.3, integrator=integrator)
    numeric = central(lambda e: pendulum(v0=0.3 + e), loss, 1e-6, 0.3, integrator=integrator)
    assert grads["body_v"][0, 0] == pytest.approx(numeric, rel=1e-7)

"""Joints in the coloured solve (passes.joints): each kind against its closed form at sim.step(1/60) and run()."""
import math

import numpy as np
import pytest
from helpers import turn_between

import warp_sim as ws
from warp_sim.util.rotations import matrix_to_quat, quat_to_matrix

G = 9.81
Z_TURN = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))   # a capsule's y axis onto x


def pendulum(theta0: float, precision: str = "float32"):
    """A 1 kg sphere (r = 0.05 m) hanging 1 m below a world pivot at (0, 2, 0) on a hinge about z, at theta0."""
    scene = ws.Scene(precision=precision)
    body = scene.add_rigid_body(ws.Sphere(0.05), mass=1.0, position=(math.sin(theta0), 2.0 - math.cos(theta0), 0.0))
    scene.add_joint("revolute", None, body, anchor=(0.0, 2.0, 0.0), axis=(0.0, 0.0, 1.0))
    return scene


def physical_period(theta0: float, length: float = 1.0, mass: float = 1.0, radius: float = 0.05) -> float:
    """The physical pendulum's period with the amplitude correction (to theta0^4)."""
    inertia = mass * length ** 2 + 0.4 * mass * radius ** 2
    t0 = 2.0 * math.pi * math.sqrt(inertia / (mass * G * length))
    return t0 * (1.0 + theta0 ** 2 / 16.0 + 11.0 * theta0 ** 4 / 3072.0)


def swing(positions: np.ndarray) -> np.ndarray:
    return np.arctan2(positions[:, 0], 2.0 - positions[:, 1])


def period_of(angles: np.ndarray, fps: float) -> float:
    """The mean period between upward zero crossings (linear interpolation)."""
    t = np.arange(len(angles)) / fps
    up = [t[i] - angles[i] * (t[i + 1] - t[i]) / (angles[i + 1] - angles[i])
          for i in range(len(angles) - 1) if angles[i] < 0.0 <= angles[i + 1]]
    return float(np.mean(np.diff(up)))


def anchor_gap(positions: np.ndarray) -> np.ndarray:
    return np.abs(np.linalg.norm(positions - np.array([0.0, 2.0, 0.0]), axis=1) - 1.0)


def test_pendulum_period_swing_and_gap_through_run():
    """run()'s defaults (60 fps): the period within 0.5 %, 95 % of the swing kept over 10 s, the gap under 2 mm."""
    theta0 = math.radians(10.0)
    sim = ws.Simulator(pendulum(theta0))
    x = np.array([arrays["body_x"][0] for _, _, arrays in sim.frames(10.0, fps=60.0)])
    angles = swing(x)
    assert abs(period_of(angles, 60.0) / physical_period(theta0) - 1.0) < 0.005
    assert np.max(np.abs(angles[-120:])) > 0.95 * theta0
    assert anchor_gap(x).max() < 2e-3


@pytest.mark.parametrize("integrator", ["rk4", "symplectic_euler", "verlet", "euler", "midpoint", "implicit_euler",
                                        "rk45"])
def test_pendulum_through_step_every_integrator(integrator):
    """sim.step(1/60) under every solver, the adaptive rk45 included: each holds the period and the swing
    (jointed bodies drift as symplectic Euler does: finish_response)."""
    theta0 = math.radians(10.0)
    sim = ws.Simulator(pendulum(theta0), integrator=integrator)
    x = [sim.state.body_x.numpy()[0].copy()]
    for _ in range(600):
        sim.step(1.0 / 60.0)
        x.append(sim.state.body_x.numpy()[0].copy())
    angles = swing(np.array(x))
    assert abs(period_of(angles, 60.0) / physical_period(theta0) - 1.0) < 0.005
    assert 0.95 * theta0 < np.max(np.abs(angles[-120:])) < 1.02 * theta0
    assert anchor_gap(np.array(x)).max() < 2e-3


def capsule_chain(scene, links: int, top, mass: float = 0.1, link: float = 0.1, kind: str = "ball"):
    """``links`` capsule links of ``link`` m along +x from ``top``, the first on a world pivot; their indices."""
    top = np.asarray(top, float)
    bodies, parent = [], None
    for k in range(links):
        body = scene.add_rigid_body(ws.Capsule(0.01, link - 0.02), mass=mass, position=top + (k + 0.5) * link *
                                    np.array([1.0, 0.0, 0.0]), orientation=Z_TURN)
        scene.add_joint(kind, parent, body, anchor=top + k * link * np.array([1.0, 0.0, 0.0]), axis=(0, 0, 1))
        bodies.append(body)
        parent = body
    return bodies


def test_chain_of_twenty_ball_joints_holds_every_frame():
    scene = ws.Scene()
    capsule_chain(scene, 20, (0.0, 3.0, 0.0))
    sim = ws.Simulator(scene)
    worst = 0.0
    for _ in range(180):
        sim.step(1.0 / 60.0)
        worst = max(worst, float(sim.joints.gaps(sim.state).max()))
    tip = sim.state.body_x.numpy()[-1]
    assert worst < 2e-3
    assert np.linalg.norm(tip - np.array([0.0, 3.0, 0.0])) < 2.0   # it swung, in one piece
    assert sim.state.body_x.numpy()[:, 1].min() < 2.5


def test_heavy_ball_on_a_light_chain_stretches_it_less_than_one_percent():
    """A 10 kg ball on 10 links of 0.1 kg (100:1), released 60 degrees from the vertical."""
    scene = ws.Scene()
    top, link, down = np.array([0.0, 3.0, 0.0]), 0.1, np.array([math.sin(math.pi / 3), -math.cos(math.pi / 3), 0.0])
    across = np.cross(down, (0.0, 0.0, 1.0))
    orientation = matrix_to_quat(np.stack([across, down, np.cross(across, down)], axis=1))
    parent = None
    for k in range(10):
        body = scene.add_rigid_body(ws.Capsule(0.01, link - 0.02), mass=0.1, position=top + down * link * (k + 0.5),
                                    orientation=orientation)
        scene.add_joint("ball", parent, body, anchor=top + down * link * k)
        parent = body
    ball = scene.add_rigid_body(ws.Sphere(0.05), mass=10.0, position=top + down * (10 * link + 0.05))
    scene.add_joint("ball", parent, ball, anchor=top + down * 10 * link)
    sim = ws.Simulator(scene)
    worst = 0.0
    for _ in range(180):
        sim.step(1.0 / 60.0)
        reach = np.linalg.norm(sim.state.body_x.numpy()[-1] - top) - 0.05
        worst = max(worst, reach / (10 * link) - 1.0)
    assert worst < 0.01


def test_hinge_limit_holds_a_fast_spin():
    """A hinge limited to +-45 degrees, spun at 180 degrees/s (no gravity), stays within 46.5 degrees."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0))
    body = scene.add_rigid_body(ws.Box((0.25, 0.02, 0.02)), mass=1.0, position=(0.25, 1.0, 0.0),
                                angular_velocity=(0.0, 0.0, math.pi))
    scene.add_joint("revolute", None, body, anchor=(0.0, 1.0, 0.0), axis=(0.0, 0.0, 1.0),
                    limits=(-math.pi / 4, math.pi / 4))
    # the spin about the hinge's pivot: v = omega x r
    sim = ws.Simulator(scene)
    angles = []
    for _ in range(120):
        sim.step(1.0 / 60.0)
        x = sim.state.body_x.numpy()[0]
        angles.append(math.degrees(math.atan2(x[1] - 1.0, x[0])))
    assert max(np.abs(angles)) < 46.5
    assert max(angles) > 44.0   # it reached the limit


def test_a_long_pendulum_stops_on_its_limit_with_its_anchor_held():
    """A 1 m pendulum released at 20 degrees swings under gravity onto a limit at 15 degrees (the hinge's -5):
    it stops there (a limit is inelastic: it climbs back less than 0.5 degrees) with the anchor gap under 2 mm
    (the limit's torque acts about the hinge, not the bob's centre of mass: kernels.joints.held_spin)."""
    start = math.radians(20.0)
    scene = ws.Scene()
    bob = scene.add_rigid_body(ws.Sphere(0.05), mass=1.0, position=(math.sin(start), 2.0 - math.cos(start), 0.0))
    scene.add_joint("revolute", None, bob, anchor=(0.0, 2.0, 0.0), axis=(0.0, 0.0, 1.0),
                    limits=(math.radians(-5.0), math.radians(20.0)))
    sim = ws.Simulator(scene)
    x = []
    for _ in range(120):
        sim.step(1.0 / 60.0)
        x.append(sim.state.body_x.numpy()[0].copy())
        assert sim.joints.gaps(sim.state).max() < 2e-3
    angles = np.degrees(swing(np.array(x)))
    assert angles.min() > 15.0 - 0.5 and angles[30:].max() < 15.5


def test_slider_keeps_to_its_rail_orientation_and_limits():
    scene = ws.Scene(gravity=(0.0, -9.81, 0.0))
    body = scene.add_rigid_body(ws.Box((0.1, 0.05, 0.05)), mass=1.0, position=(0.0, 1.0, 0.0),
                                linear_velocity=(2.0, 1.5, -1.0), angular_velocity=(3.0, -2.0, 4.0))
    scene.add_joint("prismatic", None, body, anchor=(0.0, 1.0, 0.0), axis=(1.0, 0.0, 0.0), limits=(-0.3, 0.5))
    sim = ws.Simulator(scene)
    for _ in range(120):
        sim.step(1.0 / 60.0)
        x, q = sim.state.body_x.numpy()[0], sim.state.body_q.numpy()[0]
        assert np.hypot(x[1] - 1.0, x[2]) < 2e-3
        assert math.degrees(2.0 * math.acos(min(1.0, abs(float(q[3]))))) < 0.5
        assert -0.302 < x[0] < 0.502
    assert sim.state.body_x.numpy()[0][0] > 0.49   # it ran up to the upper limit and stayed


def relative_pose(x, q, a: int, b: int):
    Ra, Rb = quat_to_matrix(q[a]), quat_to_matrix(q[b])
    return Ra.T @ (x[b] - x[a]), Ra.T @ Rb


def test_welded_boxes_thrown_on_the_ground_keep_their_pose():
    scene = ws.Scene()
    scene.add_ground(restitution=0.3, friction=0.6)
    a = scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), density=500.0, position=(0.0, 1.0, 0.0),
                             linear_velocity=(2.0, 1.0, 0.0), angular_velocity=(1.0, 3.0, 2.0))
    b = scene.add_rigid_body(ws.Box((0.05, 0.05, 0.15)), density=500.0, position=(0.15, 1.0, 0.0),
                             linear_velocity=(2.0, 1.0, 0.0))
    scene.add_joint("fixed", a, b, anchor=(0.1, 1.0, 0.0))
    sim = ws.Simulator(scene)
    offset0, turn0 = relative_pose(sim.state.body_x.numpy(), sim.state.body_q.numpy(), a, b)
    for _ in range(180):
        sim.step(1.0 / 60.0)
        offset, turn = relative_pose(sim.state.body_x.numpy(), sim.state.body_q.numpy(), a, b)
        assert np.linalg.norm(offset - offset0) < 2e-3
        cosine = np.clip((np.trace(turn0.T @ turn) - 1.0) / 2.0, -1.0, 1.0)
        assert math.degrees(math.acos(cosine)) < 1.0
    assert sim.state.body_x.numpy()[:, 1].max() < 0.3   # landed


def test_drive_settles_an_arm_on_its_target():
    """A 0.5 m arm (1 kg) on a vertical hinge, driven to 90 degrees by stiffness 0.05 N m per degree and damping
    0.017 N m per degree/s (the USD values, in SI here), is within 1 degree of 90 after 3 s."""
    per_degree = 180.0 / math.pi
    scene = ws.Scene()
    arm = scene.add_rigid_body(ws.Box((0.25, 0.02, 0.02)), mass=1.0, position=(0.25, 1.0, 0.0))
    drive = ws.Drive(target=math.pi / 2, stiffness=0.05 * per_degree, damping=0.017 * per_degree)
    scene.add_joint("revolute", None, arm, anchor=(0.0, 1.0, 0.0), axis=(0.0, 1.0, 0.0), drive=drive)
    sim = ws.Simulator(scene)
    sim.step(1.0 / 60.0, steps=180)
    x = sim.state.body_x.numpy()[0]
    angle = math.degrees(math.atan2(-x[2], x[0]))   # about +y, x turns towards -z
    assert abs(angle - 90.0) < 1.0


@pytest.mark.parametrize("mass", [1.0, 10.0])
def test_acceleration_drive_rings_at_its_own_frequency_whatever_it_moves(mass):
    """An acceleration drive's stiffness is per unit of the axis's effective inertia, here the arm's about its
    hinge (I_c + m r^2, not I_c alone): undamped, without gravity, a 0.5 m arm of 1 or 10 kg pulled from 0 to
    0.1 rad rings with period 2 pi / sqrt(stiffness) (1 s) within 2 %."""
    stiffness = (2.0 * math.pi) ** 2
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0))
    arm = scene.add_rigid_body(ws.Box((0.25, 0.02, 0.02)), mass=mass, position=(0.25, 1.0, 0.0))
    drive = ws.Drive(target=0.1, stiffness=stiffness, acceleration=True)
    scene.add_joint("revolute", None, arm, anchor=(0.0, 1.0, 0.0), axis=(0.0, 1.0, 0.0), drive=drive)
    sim = ws.Simulator(scene)
    angles = []
    for _ in range(600):
        sim.step(1.0 / 240.0)
        x = sim.state.body_x.numpy()[0]
        angles.append(math.atan2(-x[2], x[0]) - 0.1)
    assert abs(period_of(np.array(angles), 240.0) - 1.0) < 0.02


def overlapping_boxes(collide: bool):
    """Two 0.2 m boxes 0.1 m apart (half overlapping), hinged at their middle, no gravity."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0))
    a = scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), mass=1.0, position=(0.0, 1.0, 0.0))
    b = scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), mass=1.0, position=(0.1, 1.0, 0.0))
    scene.add_joint("revolute", a, b, anchor=(0.05, 1.0, 0.0), axis=(0.0, 0.0, 1.0), collide=collide)
    return scene


def test_jointed_bodies_do_not_push_each_other_apart():
    """Hinged, the overlapping boxes stay as they are and no pair reaches the narrow phase; with collide=True the
    pair is found and the contacts turn them about the hinge."""
    sim = ws.Simulator(overlapping_boxes(False))
    sim.step(1.0 / 60.0, steps=30)
    x, q = sim.state.body_x.numpy(), sim.state.body_q.numpy()
    assert abs(np.linalg.norm(x[1] - x[0]) - 0.1) < 1e-5 and np.abs(q[:, 3]).min() > 1.0 - 1e-6
    assert sim.body_contacts.detection.pair_count == 0
    sim = ws.Simulator(overlapping_boxes(True))
    sim.step(1.0 / 60.0, steps=30)
    assert sim.body_contacts.detection.pair_count == 1
    assert np.abs(sim.state.body_q.numpy()[:, 3]).min() < 0.999   # pushed: they turned


def test_d6_velocity_drive_turns_at_its_rate_about_its_axis():
    """A generic joint with every axis locked but rotX, driven at 1 rad/s about the world's (0, 1, 1) axis."""
    axis = np.array([0.0, 1.0, 1.0]) / math.sqrt(2.0)
    scene = ws.Scene()
    wheel = scene.add_rigid_body(ws.Cylinder(0.2, 0.05), mass=2.0, position=(0.0, 1.0, 0.0))
    d6 = ws.D6(locked=("transX", "transY", "transZ", "rotY", "rotZ"),
               drives={"rotX": ws.Drive(velocity=1.0, damping=50.0)})
    scene.add_joint(d6, None, wheel, anchor=(0.0, 1.0, 0.0), axis=axis)
    sim = ws.Simulator(scene)
    sim.step(1.0 / 60.0, steps=60)
    q0 = sim.state.body_q.numpy()[0].astype(float)
    sim.step(1.0 / 60.0, steps=60)
    q1 = sim.state.body_q.numpy()[0].astype(float)
    angle, spin_axis = turn_between(q0, q1)
    assert abs(angle - 1.0) < 0.02
    assert np.dot(spin_axis, axis) > 0.999
    assert np.linalg.norm(sim.state.body_x.numpy()[0] - np.array([0.0, 1.0, 0.0])) < 2e-3


def test_a_joint_breaks_and_is_reported():
    scene = ws.Scene()
    body = scene.add_rigid_body(ws.Sphere(0.05), mass=1.0, position=(0.0, 1.0, 0.0))
    scene.add_joint("ball", None, body, anchor=(0.0, 1.05, 0.0), break_force=5.0, name="weak")
    sim = ws.Simulator(scene)
    with pytest.warns(RuntimeWarning, match="'weak'.*broke"):
        sim.step(1.0 / 60.0, steps=30)
    assert sim.joint_breaks[0][:2] == (0, "weak")
    assert sim.state.body_x.numpy()[0][1] < 0.9   # it fell once free
    strong = ws.Scene()
    body = strong.add_rigid_body(ws.Sphere(0.05), mass=1.0, position=(0.0, 1.0, 0.0))
    strong.add_joint("ball", None, body, anchor=(0.0, 1.05, 0.0), break_force=15.0)
    sim = ws.Simulator(strong)
    sim.step(1.0 / 60.0, steps=30)   # 9.81 N held: it does not break
    assert sim.joint_breaks == []


def test_distance_joint_is_a_rope():
    """A ball on a 1 m rope from the world falls freely until taut, then hangs at 1 m."""
    scene = ws.Scene()
    ball = scene.add_rigid_body(ws.Sphere(0.05), mass=1.0, position=(0.5, 2.0, 0.0))
    scene.add_joint("distance", None, ball, anchor=((0.0, 2.0, 0.0), (0.5, 2.0, 0.0)), limits=(0.0, 1.0))
    sim = ws.Simulator(scene)
    sim.step(1.0 / 60.0, steps=6)   # 0.1 s of free fall: 4.9 cm, still slack
    assert abs(sim.state.body_x.numpy()[0][1] - (2.0 - 0.5 * G * 0.1 ** 2)) < 2e-3
    for _ in range(240):
        sim.step(1.0 / 60.0)
        assert np.linalg.norm(sim.state.body_x.numpy()[0] - np.array([0.0, 2.0, 0.0])) < 1.002


def test_a_distance_joint_with_only_a_minimum_is_a_strut():
    """limits (0.5, inf): a ball thrown at its anchor at 2 m/s (no gravity) moves freely, then comes no nearer
    than 0.5 m (2 mm) and stays there (a limit is inelastic)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0))
    ball = scene.add_rigid_body(ws.Sphere(0.05), mass=1.0, position=(1.0, 2.0, 0.0), linear_velocity=(-2.0, 0.0, 0.0))
    scene.add_joint("distance", None, ball, anchor=((0.0, 2.0, 0.0), (1.0, 2.0, 0.0)), limits=(0.5, math.inf))
    sim = ws.Simulator(scene)
    distances = []
    for _ in range(60):
        sim.step(1.0 / 60.0)
        distances.append(np.linalg.norm(sim.state.body_x.numpy()[0] - np.array([0.0, 2.0, 0.0])))
    assert abs(distances[5] - (1.0 - 2.0 * 6 / 60.0)) < 1e-6   # free before it reaches 0.5 m
    assert min(distances) > 0.5 - 2e-3 and abs(distances[-1] - 0.5) < 2e-3


def test_a_scene_without_joints_launches_no_joint_kernel():
    scene = ws.Scene()
    scene.add_ground()
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), mass=1.0, position=(0.0, 0.5, 0.0))
    sim = ws.Simulator(scene)
    assert sim.joints is None and "joints" not in sim.kernel_modules()
    assert "joints" in ws.Simulator(pendulum(0.1)).kernel_modules()


def creature(scene, legs_per_side: int = 3, height: float = 0.5):
    """A capsule torso along x with legs_per_side legs a side, each a thigh on a driven hinge (about x, limits
    +-60 degrees) and a shin on a knee hinge (limits 0 to 90 degrees), its centre ``height`` m up."""
    r = 0.04
    torso = scene.add_rigid_body(ws.Capsule(0.06, 0.5), density=500.0, position=(0.0, height, 0.0),
                                 orientation=Z_TURN, name="torso")
    hip_drive = ws.Drive(target=0.0, stiffness=40.0, damping=2.0, max_force=30.0)
    for k in range(legs_per_side):
        x = -0.25 + 0.5 * k / max(1, legs_per_side - 1)
        for side in (-1.0, 1.0):
            hip = np.array([x, height, side * 0.06])
            thigh = scene.add_rigid_body(ws.Capsule(r, 0.12), density=500.0, position=hip + (0.0, -0.1, 0.0))
            scene.add_joint("revolute", torso, thigh, anchor=hip, axis=(1.0, 0.0, 0.0),
                            limits=(-math.pi / 3, math.pi / 3), drive=hip_drive)
            knee = hip + (0.0, -0.2, 0.0)
            shin = scene.add_rigid_body(ws.Capsule(r, 0.12), density=500.0, position=knee + (0.0, -0.1, 0.0))
            scene.add_joint("revolute", thigh, shin, anchor=knee, axis=(0.0, 0.0, 1.0), limits=(0.0, math.pi / 2))
    return torso


def test_many_legged_creature_lands_in_one_piece_and_rests():
    scene = ws.Scene()
    scene.add_ground(restitution=0.2, friction=0.8)
    creature(scene, height=0.7)
    sim = ws.Simulator(scene)
    x = sim.state.body_x.numpy().copy()
    for _ in range(240):
        sim.step(1.0 / 60.0)
        now = sim.state.body_x.numpy().copy()
        assert sim.joints.gaps(sim.state).max() < 0.01
        assert np.linalg.norm(now - x, axis=1).max() < 0.1   # no teleports: at most 6 m/s for a frame
        x = now
    assert x[:, 1].min() > 0.02   # on the ground, not through it (capsule radii 0.04)
    P = sim.state.body_P.numpy()
    masses = scene.body_array("mass")
    assert np.abs(P / masses[:, None]).max() < 0.05   # at rest

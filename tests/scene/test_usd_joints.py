"""UsdPhysics joints read by Scene.from_usd (scene/usd_joints.py) and written by Scene.to_usd: every stage authored
here with pxr as a DCC tool saves it, each checked by the motion it gives (units, degrees, per-degree drives, sides
and frames), the round trip, the overlay leaving the joints alone, and bad joints refused naming the prim."""
import math
import warnings

import numpy as np
import pytest
from helpers import turn_between
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics

import warp_sim as ws
from warp_sim.scene.joints import LIMITED, LOCKED
from warp_sim.util.rotations import matrix_to_quat, quat_to_matrix

G = 9.81
THETA0 = math.radians(10.0)


def new_stage(path, meters=1.0, up="Y", gravity=G):
    """A stage in ``meters`` per unit with a physics scene pulling ``gravity`` [m/s^2] against the up axis."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, meters)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    physics = UsdPhysics.Scene.Define(stage, "/World/physicsScene")
    physics.CreateGravityDirectionAttr(Gf.Vec3f(0, 0, -1) if up == "Z" else Gf.Vec3f(0, -1, 0))
    physics.CreateGravityMagnitudeAttr(gravity / meters)
    return stage


def body(stage, path, geom, at, mass=1.0, collider=False, **sizes):
    """A rigid body (or with ``collider`` a static collider) of UsdGeom class ``geom`` at ``at`` [stage units]."""
    prim = geom.Define(stage, path)
    for name, value in sizes.items():
        getattr(prim, f"Create{name}Attr")(value)
    prim.AddTranslateOp().Set(Gf.Vec3d(*at))
    UsdPhysics.CollisionAPI.Apply(prim.GetPrim())
    if not collider:
        UsdPhysics.RigidBodyAPI.Apply(prim.GetPrim())
        UsdPhysics.MassAPI.Apply(prim.GetPrim()).CreateMassAttr(mass)
    return prim


def joint(stage, schema, path, body0=None, body1=None, pos0=(0, 0, 0), pos1=(0, 0, 0), rot=None, **values):
    """A joint prim of ``schema`` between the prims at body0 and body1 (None: the world); ``values``: its
    attributes by their Create*Attr names (Axis="Z", LowerLimit=-5, ...)."""
    usd = schema.Define(stage, path)
    if body0:
        usd.CreateBody0Rel().SetTargets([body0])
    if body1:
        usd.CreateBody1Rel().SetTargets([body1])
    usd.CreateLocalPos0Attr(Gf.Vec3f(*pos0))
    usd.CreateLocalPos1Attr(Gf.Vec3f(*pos1))
    if rot is not None:
        usd.CreateLocalRot0Attr(rot)
        usd.CreateLocalRot1Attr(rot)
    for name, value in values.items():
        getattr(usd, f"Create{name}Attr")(value)
    return usd.GetPrim()


def drive(prim, instance, **values):
    api = UsdPhysics.DriveAPI.Apply(prim, instance)
    for name, value in values.items():
        getattr(api, f"Create{name}Attr")(value)


def motion(scene, seconds, fps=60.0):
    """(times [s], body positions (frames, B, 3) [m], orientations (frames, B, 4)) of the frames of a run."""
    frames = list(ws.Simulator(scene).frames(seconds, fps=fps))
    return (np.array([t for _, t, _ in frames]), *(np.array([arrays[key] for _, _, arrays in frames], dtype=np.float64)
                                                   for key in ("body_x", "body_q")))


def positions(scene, seconds, fps=60.0):
    return motion(scene, seconds, fps)[1]


# ---- a pendulum in centimetres -----------------------------------------------------------------------------------
def pendulum_stage(path, swapped=False, limits=None, target=None):
    """A 1 kg sphere (r = 5 cm) 100 cm below a world pivot at (0, 200, 0) cm on a hinge about z, at 10 degrees;
    ``swapped``: the sphere is body0 and the world body1 (the same joint, so limits and target negated)."""
    stage = new_stage(path, meters=0.01)
    at = (100.0 * math.sin(THETA0), 200.0 - 100.0 * math.cos(THETA0), 0.0)
    body(stage, "/World/ball", UsdGeom.Sphere, at, Radius=5.0)
    pivot, lever = (0.0, 200.0, 0.0), (-at[0], 200.0 - at[1], 0.0)
    sign = -1.0 if swapped else 1.0
    values = {} if limits is None else {"LowerLimit": min(sign * limits[0], sign * limits[1]),
                                        "UpperLimit": max(sign * limits[0], sign * limits[1])}
    sides = dict(body0="/World/ball", pos0=lever, pos1=pivot) if swapped else dict(body1="/World/ball", pos0=pivot,
                                                                                   pos1=lever)
    hinge = joint(stage, UsdPhysics.RevoluteJoint, "/World/hinge", Axis="Z", **sides, **values)
    if target is not None:
        drive(hinge, "angular", TargetPosition=sign * target, Stiffness=0.005 * 1e4)
    stage.Save()
    return path


def physical_period(theta0, length=1.0, mass=1.0, radius=0.05):
    """The physical pendulum's period with the amplitude correction (to theta0^4)."""
    inertia = mass * length ** 2 + 0.4 * mass * radius ** 2
    return 2.0 * math.pi * math.sqrt(inertia / (mass * G * length)) * (1.0 + theta0 ** 2 / 16.0 +
                                                                       11.0 * theta0 ** 4 / 3072.0)


def period_of(angles, fps):
    """The mean period between upward zero crossings (linear interpolation)."""
    t = np.arange(len(angles)) / fps
    up = [t[i] - angles[i] * (t[i + 1] - t[i]) / (angles[i + 1] - angles[i])
          for i in range(len(angles) - 1) if angles[i] < 0.0 <= angles[i + 1]]
    return float(np.mean(np.diff(up)))


def swing(x):
    return np.arctan2(x[:, 0], 2.0 - x[:, 1])


def test_revolute_pendulum_in_centimetres_has_the_physical_period(tmp_path):
    """Authored in centimetres (metersPerUnit 0.01), the hinge's pivot and lever convert to metres: over 10 s the
    period is the physical pendulum's with the amplitude correction within 0.5 % (measured: 4e-6), the pivot held."""
    scene = ws.Scene.from_usd(pendulum_stage(tmp_path / "pendulum.usda"))
    hinge = scene.joints[0]
    assert (hinge.name, hinge.kind, hinge.parent, hinge.child) == ("/World/hinge", "revolute", -1, 0)
    np.testing.assert_allclose(hinge.parent_anchor, (0.0, 2.0, 0.0), atol=1e-6)
    np.testing.assert_allclose(quat_to_matrix(hinge.parent_frame)[:, 0], (0.0, 0.0, 1.0), atol=1e-7)   # axis Z
    x = positions(scene, 10.0)[:, 0]
    error = period_of(swing(x), 60.0) / physical_period(THETA0) - 1.0
    assert abs(error) < 0.005, error
    assert np.abs(np.linalg.norm(x - (0.0, 2.0, 0.0), axis=1) - 1.0).max() < 2e-3


def test_a_swapped_joint_moves_as_the_unswapped_one(tmp_path):
    """body0 the sphere and body1 the world: the sides swap (the child is the dynamic body), the authored limits
    (-20, 5) degrees and drive target -3 degrees of the swapped hinge are the unswapped (-5, 20) and 3: the same
    joint, the same motion (released at the hinge's angle 0, it swings to the -5 degree limit and back)."""
    plain = ws.Scene.from_usd(pendulum_stage(tmp_path / "plain.usda", limits=(-5.0, 20.0), target=3.0))
    swapped = ws.Scene.from_usd(pendulum_stage(tmp_path / "swapped.usda", True, limits=(-5.0, 20.0), target=3.0))
    a, b = plain.joints[0], swapped.joints[0]
    assert (b.parent, b.child) == (-1, 0)
    np.testing.assert_allclose((b.lower[3], b.upper[3]), np.radians((-5.0, 20.0)), atol=1e-7)
    assert b.drives[3].target == pytest.approx(math.radians(3.0))
    for name in ("parent_anchor", "child_anchor"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), atol=1e-6)
    (_, x, q), (_, y, r) = motion(plain, 2.0), motion(swapped, 2.0)
    assert np.abs(x - y).max() < 1e-6 and np.abs(q - r).max() < 1e-6
    turn = np.degrees(2.0 * np.arctan2(q[:, 0, 2], q[:, 0, 3]))   # the hinge's angle from the start, about z
    assert -5.1 < turn.min() < -4.9   # it swung down to the lower limit and was held there


def test_body0_that_is_not_a_body_is_refused_naming_the_joint(tmp_path):
    stage = new_stage(tmp_path / "bad.usda")
    body(stage, "/World/ball", UsdGeom.Sphere, (0.0, 1.0, 0.0), Radius=0.05)
    UsdGeom.Xform.Define(stage, "/World/empty")
    joint(stage, UsdPhysics.RevoluteJoint, "/World/hinge", body0="/World/empty", body1="/World/ball")
    stage.Save()
    with pytest.raises(ValueError, match=r"^/World/hinge: physics:body0='/World/empty' is invalid: .*rigid body"):
        ws.Scene.from_usd(tmp_path / "bad.usda")


# ---- a generic joint (D6) ----------------------------------------------------------------------------------------
def test_d6_velocity_drive_turns_the_body_about_its_world_axis(tmp_path):
    """A UsdPhysics.Joint with transX/Y/Z, rotX and rotZ locked (low > high) and rotY free, driven by
    PhysicsDriveAPI:rotY at 90 degrees/s (damping 10 N m per degree/s): after 1 s the box turns at pi/2 rad/s
    about the joint frame's y axis, here the world's (1, 1, 0)/sqrt(2) (measured error 4e-7), and stays put."""
    stage = new_stage(tmp_path / "d6.usda")
    body(stage, "/World/box", UsdGeom.Cube, (0.0, 1.0, 0.0), mass=2.0, Size=0.2)
    axis = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    turn = np.stack([np.cross(axis, (0.0, 0.0, 1.0)), axis, (0.0, 0.0, 1.0)], axis=1)   # y onto the axis
    q = matrix_to_quat(turn)
    prim = joint(stage, UsdPhysics.Joint, "/World/d6", body1="/World/box", pos0=(0.0, 1.0, 0.0),
                 rot=Gf.Quatf(*map(float, (q[3], *q[:3]))))
    for name in ("transX", "transY", "transZ", "rotX", "rotZ"):
        limit = UsdPhysics.LimitAPI.Apply(prim, name)
        limit.CreateLowAttr(1.0)
        limit.CreateHighAttr(-1.0)
    drive(prim, "rotY", TargetVelocity=90.0, Damping=10.0)
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "d6.usda")
    d6 = scene.joints[0]
    assert d6.kind == "d6" and list(d6.modes) == [LOCKED] * 4 + [0, LOCKED]
    assert d6.drives[4].velocity == pytest.approx(math.pi / 2) and d6.drives[4].damping == pytest.approx(
        10.0 * 180.0 / math.pi)
    sim = ws.Simulator(scene)
    sim.step(1.0 / 60.0, steps=60)
    q0 = sim.state.body_q.numpy()[0].astype(float)
    sim.step(1.0 / 60.0, steps=30)
    q1 = sim.state.body_q.numpy()[0].astype(float)
    angle, about = turn_between(q0, q1)
    assert abs(angle / 0.5 / (math.pi / 2) - 1.0) < 0.02, angle
    assert np.dot(about, axis) > 0.999
    assert np.linalg.norm(sim.state.body_x.numpy()[0] - (0.0, 1.0, 0.0)) < 2e-3


# ---- prismatic, spherical, fixed, distance -----------------------------------------------------------------------
def test_prismatic_limits_in_millimetres_hold_the_slider(tmp_path):
    """A slider along x limited to (-300, 500) mm, the box thrown along and across it: it keeps to its rail and
    turns not at all, runs up to 0.5 m and stays within the limits."""
    stage = new_stage(tmp_path / "slider.usda", meters=0.001)
    box = body(stage, "/World/box", UsdGeom.Cube, (0.0, 1000.0, 0.0), Size=100.0)
    UsdPhysics.RigidBodyAPI(box.GetPrim()).CreateVelocityAttr(Gf.Vec3f(2000.0, 1500.0, -1000.0))
    UsdPhysics.RigidBodyAPI(box.GetPrim()).CreateAngularVelocityAttr(Gf.Vec3f(170.0, -115.0, 230.0))
    joint(stage, UsdPhysics.PrismaticJoint, "/World/slider", body1="/World/box", pos0=(0.0, 1000.0, 0.0), Axis="X",
          LowerLimit=-300.0, UpperLimit=500.0)
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "slider.usda")
    slider = scene.joints[0]
    assert slider.modes[0] == LIMITED and (slider.lower[0], slider.upper[0]) == pytest.approx((-0.3, 0.5))
    sim = ws.Simulator(scene)
    for _ in range(120):
        sim.step(1.0 / 60.0)
        x, q = sim.state.body_x.numpy()[0], sim.state.body_q.numpy()[0]
        assert np.hypot(x[1] - 1.0, x[2]) < 2e-3
        assert math.degrees(2.0 * math.acos(min(1.0, abs(float(q[3]))))) < 0.5
        assert -0.302 < x[0] < 0.502
    assert sim.state.body_x.numpy()[0][0] > 0.49


def test_spherical_cone_holds_the_swing_of_a_z_up_stage(tmp_path):
    """A capsule hanging from a ball joint on a Z-up stage, the cone about Z (physics:axis) of 30 and 45 degrees:
    warned as elliptical, the smaller is kept; spun at 300 degrees/s (enough for a 50 degree swing) it swings to
    30 degrees and no further."""
    stage = new_stage(tmp_path / "ball.usda", up="Z")
    capsule = body(stage, "/World/link", UsdGeom.Capsule, (0.0, 0.0, 1.75), Radius=0.05, Height=0.4, Axis="Z")
    rigid = UsdPhysics.RigidBodyAPI(capsule.GetPrim())
    rigid.CreateAngularVelocityAttr(Gf.Vec3f(300.0, 0.0, 0.0))
    rigid.CreateVelocityAttr(Gf.Vec3f(0.0, math.radians(300.0) * 0.25, 0.0))
    joint(stage, UsdPhysics.SphericalJoint, "/World/ball", body1="/World/link", pos0=(0.0, 0.0, 2.0),
          pos1=(0.0, 0.0, 0.25), Axis="Z", ConeAngle0Limit=30.0, ConeAngle1Limit=45.0)
    stage.Save()
    with pytest.warns(UserWarning, match=r"elliptical cones.*/World/ball"):
        scene = ws.Scene.from_usd(tmp_path / "ball.usda")
    assert scene.joints[0].cone == pytest.approx(math.radians(30.0))
    x = positions(scene, 1.0)[:, 0]
    hang = x - (0.0, 2.0, 0.0)
    tilt = np.degrees(np.arccos(-hang[:, 1] / np.linalg.norm(hang, axis=1)))
    assert 28.0 < tilt.max() < 31.5


def weld_stage(path):
    """A box welded under a static collider slab whose prim is scaled (localPos0 in its scaled frame), overlapping
    it by 5 cm."""
    stage = new_stage(path)
    slab = body(stage, "/World/slab", UsdGeom.Cube, (0.0, 1.0, 0.0), collider=True, Size=1.0)
    slab.AddScaleOp().Set(Gf.Vec3f(0.5, 0.1, 0.5))
    body(stage, "/World/box", UsdGeom.Cube, (0.0, 0.9, 0.0), Size=0.2)
    joint(stage, UsdPhysics.FixedJoint, "/World/weld", body0="/World/slab", body1="/World/box", pos0=(0.0, -0.5, 0.0),
          pos1=(0.0, 0.05, 0.0))
    stage.Save()
    return path


def test_fixed_joint_to_a_scaled_static_collider_holds_the_body(tmp_path):
    """The weld is to the world with parent_collider set, the two do not collide, and the box hangs in place
    for 1 s."""
    scene = ws.Scene.from_usd(weld_stage(tmp_path / "weld.usda"))
    weld = scene.joints[0]
    assert (weld.parent, weld.parent_collider) == (-1, scene.usd_paths["/World/slab"][1])
    np.testing.assert_allclose(weld.parent_anchor, (0.0, 0.95, 0.0), atol=1e-6)
    x = positions(scene, 1.0)[:, 0]
    assert np.linalg.norm(x - (0.0, 0.9, 0.0), axis=1).max() < 2e-3


def test_distance_joint_with_max_distance_is_a_rope(tmp_path):
    """A ball on a 1 m rope (maxDistance; minDistance unset) falls freely until taut, then stays within 1 m."""
    stage = new_stage(tmp_path / "rope.usda")
    body(stage, "/World/ball", UsdGeom.Sphere, (0.5, 2.0, 0.0), Radius=0.05)
    joint(stage, UsdPhysics.DistanceJoint, "/World/rope", body1="/World/ball", pos0=(0.0, 2.0, 0.0), MaxDistance=1.0)
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "rope.usda")
    assert scene.joints[0].distance == (0.0, 1.0)
    x = positions(scene, 3.0)[:, 0]
    assert abs(x[6, 1] - (2.0 - 0.5 * G * 0.1 ** 2)) < 2e-3   # slack for 0.1 s
    reach = np.linalg.norm(x - (0.0, 2.0, 0.0), axis=1)
    assert reach.max() < 1.002 and reach[-60:].min() > 0.98


# ---- drives, filtering, enabling, breaking ---------------------------------------------------------------------
def test_angular_drive_per_degree_settles_the_arm_on_its_target(tmp_path):
    """A 50 cm arm (1 kg) on a vertical hinge in a centimetre stage, PhysicsDriveAPI:angular to 90 degrees with
    stiffness 0.05 N m per degree and damping 0.017 N m per degree/s (x 1e4 in kg cm^2): within 1 degree in 3 s."""
    stage = new_stage(tmp_path / "door.usda", meters=0.01)
    arm = body(stage, "/World/arm", UsdGeom.Cube, (25.0, 100.0, 0.0), Size=1.0)
    arm.AddScaleOp().Set(Gf.Vec3f(50.0, 4.0, 4.0))
    hinge = joint(stage, UsdPhysics.RevoluteJoint, "/World/hinge", body1="/World/arm", pos0=(0.0, 100.0, 0.0),
                  pos1=(-0.5, 0.0, 0.0), Axis="Y")   # localPos1 in the arm's scaled frame: -25 cm
    drive(hinge, "angular", TargetPosition=90.0, Stiffness=0.05e4, Damping=0.017e4)
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "door.usda")
    servo = scene.joints[0].drives[3]
    assert (servo.target, servo.stiffness, servo.damping) == pytest.approx(
        (math.pi / 2, 0.05 * 180 / math.pi, 0.017 * 180 / math.pi))
    sim = ws.Simulator(scene)
    sim.step(1.0 / 60.0, steps=180)
    x = sim.state.body_x.numpy()[0]
    assert abs(math.degrees(math.atan2(-x[2], x[0])) - 90.0) < 1.0


def overlapping_boxes(path, collide):
    """Two 0.2 m boxes 0.1 m apart (half overlapping), hinged at their middle about z, no gravity."""
    stage = new_stage(path, gravity=0.0)
    body(stage, "/World/a", UsdGeom.Cube, (0.0, 1.0, 0.0), Size=0.2)
    body(stage, "/World/b", UsdGeom.Cube, (0.1, 1.0, 0.0), Size=0.2)
    values = {} if collide is None else {"CollisionEnabled": collide}
    joint(stage, UsdPhysics.RevoluteJoint, "/World/hinge", body0="/World/a", body1="/World/b", pos0=(0.05, 0, 0),
          pos1=(-0.05, 0, 0), Axis="Z", **values)
    stage.Save()
    return path


@pytest.mark.parametrize("collide", [None, True])
def test_collision_enabled_decides_whether_jointed_bodies_collide(tmp_path, collide):
    """collisionEnabled unset (the schema's false): the overlapping boxes stay as they are, no pair found; true:
    the pair is found and the contacts turn them about the hinge."""
    sim = ws.Simulator(ws.Scene.from_usd(overlapping_boxes(tmp_path / "boxes.usda", collide)))
    sim.step(1.0 / 60.0, steps=30)
    x, q = sim.state.body_x.numpy(), sim.state.body_q.numpy()
    if collide:
        assert sim.body_contacts.detection.pair_count == 1 and np.abs(q[:, 3]).min() < 0.999
    else:
        assert sim.body_contacts.detection.pair_count == 0 and np.abs(q[:, 3]).min() > 1.0 - 1e-6
        assert abs(np.linalg.norm(x[1] - x[0]) - 0.1) < 1e-5


def hanging_ball(path, **values):
    """A 1 kg ball hung by a ball joint 5 cm above its centre, in a centimetre stage."""
    stage = new_stage(path, meters=0.01)
    body(stage, "/World/ball", UsdGeom.Sphere, (0.0, 100.0, 0.0), Radius=5.0)
    joint(stage, UsdPhysics.SphericalJoint, "/World/joint", body1="/World/ball", pos0=(0.0, 105.0, 0.0),
          pos1=(0.0, 5.0, 0.0), **values)
    stage.Save()
    return path


def test_a_disabled_joint_lets_the_body_fall(tmp_path):
    scene = ws.Scene.from_usd(hanging_ball(tmp_path / "off.usda", JointEnabled=False))
    assert scene.joints[0].enabled is False
    t, x, _ = motion(scene, 0.5)
    assert np.abs(x[:, 0, 1] - (1.0 - 0.5 * G * t ** 2)).max() < 2e-3


def test_break_force_in_stage_units_breaks_the_joint_and_is_reported(tmp_path):
    """breakForce 500 kg cm/s^2 (5 N) under 9.81 N of weight breaks, reported and warned; 1500 (15 N) holds."""
    weak = ws.Scene.from_usd(hanging_ball(tmp_path / "weak.usda", BreakForce=500.0))
    assert weak.joints[0].break_force == pytest.approx(5.0)
    sim = ws.Simulator(weak)
    with pytest.warns(RuntimeWarning, match="'/World/joint'.*broke"):
        sim.step(1.0 / 60.0, steps=30)
    assert sim.joint_breaks[0][:2] == (0, "/World/joint")
    assert sim.state.body_x.numpy()[0][1] < 0.9
    sim = ws.Simulator(ws.Scene.from_usd(hanging_ball(tmp_path / "strong.usda", BreakForce=1500.0)))
    sim.step(1.0 / 60.0, steps=30)
    assert sim.joint_breaks == [] and abs(sim.state.body_x.numpy()[0][1] - 1.0) < 2e-3


# ---- the way back ------------------------------------------------------------------------------------------------
def jointed_scene():
    """A limited, driven hinge pendulum and a 3-link capsule chain (a coned ball joint, a limited hinge and a D6)
    swinging from world pivots, float64."""
    scene = ws.Scene(precision="float64")
    ball = scene.add_rigid_body(ws.Sphere(0.05), mass=1.0, position=(math.sin(0.3), 2.0 - math.cos(0.3), 0.0))
    scene.add_joint("revolute", None, ball, anchor=(0.0, 2.0, 0.0), axis=(0.0, 0.0, 1.0), limits=(-0.2, 0.5),
                    drive=ws.Drive(target=0.1, stiffness=2.0, damping=0.1))
    turn = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))   # a capsule's y axis onto x
    top, parent = np.array([1.0, 3.0, 0.0]), None
    kinds = ("ball", "revolute", ws.D6(locked=("transX", "transY", "transZ", "rotX"), limits={"rotY": (-0.3, 0.2)}))
    for k, kind in enumerate(kinds):
        link = scene.add_rigid_body(ws.Capsule(0.02, 0.08), mass=0.2, position=top + (k + 0.5) * np.array(
            [0.12, -0.05, 0.03]), orientation=turn, angular_velocity=(0.5, 0.0, 1.0))
        limits = {"ball": 1.0, "revolute": (-0.8, 0.8)}.get(kind) if isinstance(kind, str) else None
        scene.add_joint(kind, parent, link, anchor=top + k * np.array([0.12, -0.05, 0.03]), axis=(0.0, 0.3, 1.0),
                        limits=limits)
        parent = link
    return scene


def test_round_trip_through_to_usd_moves_the_same(tmp_path):
    """A jointed scene through Scene.to_usd and back (float64) holds the same joints and moves the same over 1 s
    within 1e-6 m (measured: 1.1e-7 m; USD keeps localPos, localRot and the bodies' orientations in float32)."""
    scene = jointed_scene()
    path = scene.to_usd(tmp_path / "jointed.usda")
    stage = Usd.Stage.Open(str(path))
    assert [str(p.GetTypeName()) for p in stage.GetPrimAtPath("/World/Joints").GetChildren()] == [
        "PhysicsRevoluteJoint", "PhysicsSphericalJoint", "PhysicsRevoluteJoint", "PhysicsJoint"]
    back = ws.Scene.from_usd(path, precision="float64")
    for a, b in zip(scene.joints, back.joints):
        assert (a.kind, a.parent, a.child) == (b.kind, b.parent, b.child)
        assert list(a.modes) == list(b.modes) and a.cone == pytest.approx(b.cone)
        np.testing.assert_allclose(b.lower, a.lower, atol=1e-6)
        np.testing.assert_allclose(b.upper, a.upper, atol=1e-6)
    servo = back.joints[0].drives[3]
    assert (servo.target, servo.stiffness, servo.damping) == pytest.approx((0.1, 2.0, 0.1), rel=1e-6)
    x, y = positions(scene, 1.0), positions(back, 1.0)
    assert np.abs(x - y).max() < 1e-6, np.abs(x - y).max()


def test_a_weld_to_a_static_collider_round_trips(tmp_path):
    """The weld to a collider goes out with body0 the collider's collision prim (localPos0 in its scaled frame)
    and comes back with parent_collider set, holding the box as before."""
    scene = ws.Scene.from_usd(weld_stage(tmp_path / "weld.usda"))
    back = ws.Scene.from_usd(scene.to_usd(tmp_path / "out.usda"))
    weld = back.joints[0]
    assert (weld.kind, weld.parent, weld.parent_collider) == ("fixed", -1, 0)
    np.testing.assert_allclose(weld.parent_anchor, scene.joints[0].parent_anchor, atol=1e-6)
    assert np.abs(positions(back, 0.5) - positions(scene, 0.5)).max() < 1e-5


def test_what_is_read_but_not_honoured_is_warned_once_per_kind(tmp_path):
    """A joint state, a drive on an axis the joint does not move, a LimitAPI on a typed joint, PhysX's joint
    schema: one warning each, naming the prims; a distance joint with only a minDistance (a strut the ball may not
    come nearer than) is honoured, without a warning."""
    stage = new_stage(tmp_path / "odd.usda")
    body(stage, "/World/ball", UsdGeom.Sphere, (0.0, 1.0, 0.0), Radius=0.05)
    hinge = joint(stage, UsdPhysics.RevoluteJoint, "/World/hinge", body1="/World/ball", pos0=(0.0, 1.0, 0.0))
    drive(hinge, "linear", Stiffness=1.0)
    hinge.AddAppliedSchema("PhysicsJointStateAPI:angular")   # PhysX's, unknown to usd-core
    hinge.AddAppliedSchema("PhysxJointAPI")
    UsdPhysics.LimitAPI.Apply(hinge, "rotY")
    joint(stage, UsdPhysics.DistanceJoint, "/World/strut", body1="/World/ball", pos0=(0.0, 1.0, 0.0),
          MinDistance=0.5)
    stage.Save()
    with pytest.warns(UserWarning) as caught:
        scene = ws.Scene.from_usd(tmp_path / "odd.usda")
    messages = [str(w.message) for w in caught]
    for what, path in (("joint states", "/World/hinge"), ("drives on axes", "/World/hinge"),
                       ("limits warp_sim does not have", "/World/hinge"),
                       ("other solvers' schemas", "/World/hinge")):
        assert sum(what in m and path in m for m in messages) == 1, (what, messages)
    assert len(scene.joints) == 2 and scene.joints[0].drives[3] is None
    assert not any("minDistance" in m for m in messages) and scene.joints[1].distance == (0.5, math.inf)


@pytest.mark.parametrize("name, value, text", [
    ("drive:angular:physics:stiffness", -1.0, "expected a number >= 0, finite"),
    ("drive:angular:physics:maxForce", -5.0, "expected a number >= 0"),
    ("physics:breakTorque", 0.0, "expected a torque .* > 0"),
    ("physics:lowerLimit", 30.0, "expected at most physics:upperLimit"),
])
def test_a_bad_joint_value_is_refused_naming_prim_and_attribute(tmp_path, name, value, text):
    stage = new_stage(tmp_path / "bad.usda")
    body(stage, "/World/ball", UsdGeom.Sphere, (0.0, 1.0, 0.0), Radius=0.05)
    hinge = joint(stage, UsdPhysics.RevoluteJoint, "/World/hinge", body1="/World/ball", pos0=(0.0, 1.0, 0.0),
                  UpperLimit=20.0)
    drive(hinge, "angular", Stiffness=1.0)
    hinge.GetAttribute(name).Set(value)
    stage.Save()
    with pytest.raises(ValueError, match=rf"^/World/hinge: {name}={value:g} is invalid: {text}"):
        ws.Scene.from_usd(tmp_path / "bad.usda")


def authored(stage, path) -> dict:
    """Every authored attribute value and relationship target of the prim at ``path``."""
    prim = stage.GetPrimAtPath(path)
    values = {a.GetName(): a.Get() for a in prim.GetAttributes() if a.HasAuthoredValue()}
    values.update({r.GetName(): list(r.GetTargets()) for r in prim.GetRelationships()})
    values["apiSchemas"] = list(prim.GetAppliedSchemas())
    return values


def test_the_overlay_of_a_run_leaves_the_joint_prims_as_authored(tmp_path):
    source = pendulum_stage(tmp_path / "pendulum.usda", limits=(-5.0, 20.0), target=3.0)
    before = authored(Usd.Stage.Open(str(source)), "/World/hinge")
    out = ws.Simulator(ws.Scene.from_usd(source)).run(0.5, fps=24, usd=tmp_path / "anim.usda", over=source,
                                                     progress=False)
    assert Sdf.Layer.FindOrOpen(str(out)).GetPrimAtPath("/World/hinge") is None
    assert authored(Usd.Stage.Open(str(out)), "/World/hinge") == before
    assert Sdf.Layer.FindOrOpen(str(out)).ListTimeSamplesForPath("/World/ball.xformOp:translate")


def test_joints_and_an_articulation_root_read_without_a_warning(tmp_path):
    """Joints are simulated now (no "not simulated" warning), and PhysicsArticulationRootAPI and
    excludeFromArticulation need nothing in maximal coordinates: no warning at all."""
    stage = new_stage(tmp_path / "robot.usda")
    root = UsdGeom.Xform.Define(stage, "/World/robot").GetPrim()
    UsdPhysics.ArticulationRootAPI.Apply(root)
    body(stage, "/World/robot/base", UsdGeom.Cube, (0.0, 1.0, 0.0), Size=0.2)
    body(stage, "/World/robot/arm", UsdGeom.Cube, (0.3, 1.0, 0.0), Size=0.2)
    joint(stage, UsdPhysics.FixedJoint, "/World/robot/anchor", body1="/World/robot/base", pos0=(0.0, 1.0, 0.0))
    joint(stage, UsdPhysics.RevoluteJoint, "/World/robot/elbow", body0="/World/robot/base",
          body1="/World/robot/arm", pos0=(0.15, 0.0, 0.0), pos1=(-0.15, 0.0, 0.0), Axis="Z",
          ExcludeFromArticulation=True)
    stage.Save()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = ws.Scene.from_usd(tmp_path / "robot.usda")
    assert [(j.kind, j.parent, j.child) for j in scene.joints] == [("fixed", -1, 0), ("revolute", 0, 1)]

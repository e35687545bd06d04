"""Scene.add_joint and ws.Drive / ws.D6: what each kind holds, in the bodies' frames, and every bad value refused
with a ValueError naming the argument (scene/joints.py)."""
import math

import numpy as np
import pytest

import warp_sim as ws
from warp_sim.scene.joints import FREE, LIMITED, LOCKED
from warp_sim.util.rotations import quat_to_matrix


def two_bodies():
    scene = ws.Scene()
    a = scene.add_rigid_body(ws.Sphere(0.1), mass=1.0, position=(0.0, 1.0, 0.0))
    turned = (0.0, 0.0, math.sin(math.pi / 6), math.cos(math.pi / 6))   # 60 degrees about z
    b = scene.add_rigid_body(ws.Sphere(0.1), mass=1.0, position=(1.0, 1.0, 0.0), orientation=turned)
    return scene, a, b


def test_anchor_and_axis_are_kept_in_each_bodys_frame():
    """A world anchor and axis at the call land, through each body's pose, back on the same world point (1e-12 m)
    and axis (1e-12): the joint frame's x axis is the joint axis."""
    scene, a, b = two_bodies()
    axis = np.array([0.0, 0.6, 0.8])
    scene.add_joint("revolute", a, b, anchor=(0.5, 1.2, 0.1), axis=axis, limits=(-0.5, 0.25))
    joint = scene.joints[0]
    for index, anchor, frame in ((a, joint.parent_anchor, joint.parent_frame),
                                 (b, joint.child_anchor, joint.child_frame)):
        body = scene.bodies[index]
        R = quat_to_matrix(np.asarray(body.orientation, float))
        np.testing.assert_allclose(np.asarray(body.position) + R @ anchor, (0.5, 1.2, 0.1), atol=1e-12)
        np.testing.assert_allclose(R @ quat_to_matrix(frame)[:, 0], axis, atol=1e-12)
    assert list(joint.modes) == [LOCKED] * 3 + [LIMITED, LOCKED, LOCKED]
    assert (joint.lower[3], joint.upper[3]) == (-0.5, 0.25)


@pytest.mark.parametrize("kind, modes", [
    ("revolute", [LOCKED] * 3 + [FREE, LOCKED, LOCKED]), ("prismatic", [FREE, LOCKED, LOCKED] + [LOCKED] * 3),
    ("ball", [LOCKED] * 3 + [FREE] * 3), ("fixed", [LOCKED] * 6), ("distance", [FREE] * 6)])
def test_each_kind_is_its_preset_of_six_axes(kind, modes):
    scene, a, b = two_bodies()
    scene.add_joint(kind, None, b, anchor=(1.0, 1.5, 0.0))
    assert list(scene.joints[0].modes) == modes and scene.joints[0].parent == -1


def test_a_distance_joint_defaults_to_a_rod_of_the_anchors_distance():
    scene, a, b = two_bodies()
    scene.add_joint("distance", a, b, anchor=((0.0, 1.0, 0.0), (1.0, 1.0, 0.0)))
    assert scene.joints[0].distance == (1.0, 1.0)


def test_a_d6_locks_limits_and_drives_axis_by_axis():
    """low > high locks an axis, as in UsdPhysics; an axis not named is free."""
    scene, a, b = two_bodies()
    d6 = ws.D6(locked=("transX", "transY", "transZ"), limits={"rotX": (1.0, -1.0), "rotY": (-0.3, 0.3)},
               drives={"rotZ": ws.Drive(velocity=2.0, damping=5.0)})
    scene.add_joint(d6, a, b, anchor=(0.5, 1.0, 0.0))
    joint = scene.joints[0]
    assert joint.kind == "d6" and list(joint.modes) == [LOCKED] * 4 + [LIMITED, FREE]
    assert joint.drives[5].velocity == 2.0 and joint.drives[3] is None


@pytest.mark.parametrize("call, argument", [
    (lambda s, a, b: s.add_joint("hinge", a, b, anchor=(0, 1, 0)), "kind"),
    (lambda s, a, b: s.add_joint("revolute", a, a, anchor=(0, 1, 0)), "child"),
    (lambda s, a, b: s.add_joint("revolute", a, 7, anchor=(0, 1, 0)), "child"),
    (lambda s, a, b: s.add_joint("revolute", -2, b, anchor=(0, 1, 0)), "parent"),
    (lambda s, a, b: s.add_joint("revolute", a, b, anchor=(0, 1, 0), axis=(0, 0, 0)), "axis"),
    (lambda s, a, b: s.add_joint("revolute", a, b, anchor=(0, float("nan"), 0)), "anchor"),
    (lambda s, a, b: s.add_joint("revolute", a, b, anchor=(0, 1, 0), limits=(0.5, -0.5)), "limits"),
    (lambda s, a, b: s.add_joint("prismatic", a, b, anchor=(0, 1, 0), limits=(0.1,)), "limits"),
    (lambda s, a, b: s.add_joint("fixed", a, b, anchor=(0, 1, 0), limits=(0.0, 1.0)), "limits"),
    (lambda s, a, b: s.add_joint("ball", a, b, anchor=(0, 1, 0), limits=4.0), "limits"),
    (lambda s, a, b: s.add_joint("distance", a, b, anchor=(0, 1, 0), limits=(-1.0, 1.0)), "limits"),
    (lambda s, a, b: s.add_joint("ball", a, b, anchor=(0, 1, 0), drive=ws.Drive(stiffness=1.0)), "drive"),
    (lambda s, a, b: s.add_joint("revolute", a, b, anchor=(0, 1, 0), drive=1.0), "drive"),
    (lambda s, a, b: s.add_joint("revolute", a, b, anchor=(0, 1, 0), break_force=0.0), "break_force"),
    (lambda s, a, b: s.add_joint("revolute", a, b, anchor=(0, 1, 0), break_torque=-1.0), "break_torque"),
    (lambda s, a, b: s.add_joint("ball", a, b, anchor=(0, 1, 0), name="j") + 1
     and s.add_joint("ball", a, b, anchor=(0, 1, 0), name="j"), "name"),   # the same name twice
    (lambda s, a, b: ws.Drive(stiffness=-1.0), "stiffness"),
    (lambda s, a, b: ws.Drive(damping=float("nan")), "damping"),
    (lambda s, a, b: ws.Drive(max_force=0.0), "max_force"),
    (lambda s, a, b: ws.D6(locked=("twist",)), "axis"),
    (lambda s, a, b: ws.D6(limits={"rotX": (0.0,)}), "limits['rotX']"),
    (lambda s, a, b: ws.D6(drives={"rotX": 3.0}), "drives['rotX']"),
    (lambda s, a, b: ws.D6(cone=-0.1), "cone"),
])
def test_bad_values_name_their_argument(call, argument):
    scene, a, b = two_bodies()
    with pytest.raises(ValueError) as error:
        call(scene, a, b)
    assert str(error.value).startswith(argument), str(error.value)
    assert len(scene.joints) <= 1


def test_a_joint_added_after_the_simulator_is_refused_at_the_next_step():
    scene, a, b = two_bodies()
    sim = ws.Simulator(scene)
    scene.add_joint("ball", a, b, anchor=(0.5, 1.0, 0.0))
    with pytest.raises(ValueError, match="changed after its Simulator"):
        sim.step(1.0 / 60.0)

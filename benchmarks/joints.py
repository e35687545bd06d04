"""Joints at frame rate: a 100-link chain and 100 ragdolls in warp_sim, MuJoCo, MuJoCo-Warp and Newton, one table.

    python benchmarks/joints.py [--quick] [--scenes chain ragdolls] [--only warp_sim mujoco ...] [--seconds 2]
                                [--rounds 6] [--budget S] [--timeout S] [--out benchmarks/results/joints.json]

The scenes are described once, engine-neutrally (``JointScene``: bodies with a shape, a mass and a pose; joints with
a kind, two bodies, a world anchor and axis, limits), and translated to each engine:
  chain     CHAIN_LINKS capsule links (radius 0.01 m, 0.1 m tip to tip, 0.1 kg), ball joints tip to tip, the first
            on a world pivot 11 m up, released horizontally (the chain along +x) under gravity; no ground (the
            links still collide with each other, except jointed neighbours, in every engine).
  ragdolls  RAGDOLLS ragdolls of 15 bodies (pelvis, torso, head, upper and lower arms, hands, thighs, shins, feet:
            boxes, capsules, spheres; 67 kg), on a 10 x 10 grid 2.2 m apart, each turned about the vertical and
            tipped 0.3 rad (seeded), dropped from 0.3 m above a ground plane; revolute joints with limits at the
            elbows, knees, wrists and ankles, ball joints with cone limits at the shoulders, hips, neck and spine.
            Friction 0.8, no restitution, on every shape and the ground.
Gravity -9.81 m/s^2 along y (y up) everywhere. Each engine advances in frames of 1/60 s:
  warp_sim  ws.Simulator(scene) with its defaults (rk4, impulse contact, guard on) and sim.step(1/60): its own
            sub-steps (joint_step 1/480 s: eight a frame; ``substeps`` in the JSON).
  MuJoCo    C, one thread, MuJoCo's default solver (Newton, pyramidal cones, Euler integrator), its default timestep
            0.002 s rounded to divide a frame: 1/480 s, mj_step(nstep=8) a frame. The MJCF is built here (bodies
            nested as the joint tree, a freejoint at each ragdoll's pelvis, ball and hinge joints; the geoms' mass
            with their shape's inertia; ``compiler angle="radian"``).
  MuJoCo-Warp  the same MJCF and timestep, mjw.step eight times a frame (run only when its projected run fits
            --budget: on the CPU it is far slower than MuJoCo's C).
  Newton    ModelBuilder (add_link, add_joint_ball / add_joint_revolute / add_joint_free, add_articulation per
            tree), the same shapes (density = mass / volume), CollisionPipeline every substep; SolverXPBD with its
            default 2 iterations and 10 substeps a 1/60 s frame (as Newton's examples step XPBD: 10 substeps a
            frame); and SolverFeatherstone, the same 10 substeps. Newton's ball joint takes no limit: a ball joint
            with a cone is a D6 of three angular axes, each limited to +-cone (Newton's intrinsic Euler angles).
Limits differ in kind between the engines (warp_sim's cone bounds the swing of the limb's axis; MuJoCo's ball range
bounds the whole rotation angle, twist included; Newton's D6 bounds three Euler angles; MuJoCo's and Featherstone's
limits are soft), and so do the contact models; the anchor gap is the same measure everywhere.

Measured: frames of 1/60 s per second over --seconds of simulated time (2 s), and the worst joint gap: after every
frame, each joint's anchor-to-anchor distance [m] from the engine's body poses (position and orientation of every
body; the anchors fixed in each body's frame at the start, ``JointScene.gaps``), the largest over the joints and the
frames. Procedure (benchmarks/rounds.py, as compare.py): each engine is a subprocess of its own; for each scene they
build it, run two frames of a throwaway copy (kernels compiled or loaded; its speed projects the run against
--budget), build it again, then take the run's --rounds rounds (of seconds x 60 / rounds frames) in turn, A B C A B C
..., so that a drift of the shared machine's speed reaches every engine alike. Only the stepping is timed (the poses
are read and the gaps computed between frames, outside the clock). frames/s = frames / the run's summed seconds;
``warp_sim / this`` = the median over rounds of this engine's round time over warp_sim's in the same turn
(rounds.paired_ratio: above 1, warp_sim is faster). Nothing is asserted about times. See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import importlib.util
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import rounds
import warp as wp
from common import device_name, markdown

import warp_sim as ws
from warp_sim.util.rotations import matrix_to_quat, quat_to_matrix

FRAME = 1.0 / 60.0           # [s] one frame: every engine is advanced by this much at a time
GRAVITY = (0.0, -9.81, 0.0)  # [m/s^2]
FRICTION = 0.8
CHAIN_LINKS, LINK, LINK_MASS, LINK_RADIUS = 100, 0.1, 0.1, 0.01   # [-, m, kg, m]
CHAIN_PIVOT = (0.0, 11.0, 0.0)  # [m]
RAGDOLLS, RAGDOLL_PITCH, DROP, TILT = 100, 2.2, 0.3, 0.3   # [-, m, m, rad]
SEED = 0
MUJOCO_DEFAULT_TIMESTEP = 0.002  # [s]
MUJOCO_STEPS = round(FRAME / MUJOCO_DEFAULT_TIMESTEP)  # 8 mj_step a frame: timestep 1/480 s
NEWTON_SUBSTEPS = 10
MJW_MIN_CONTACTS, MJW_JACOBIAN_BYTES = 8192, 2**30
WARMUP_FRAMES = 2

#: engine key -> (label, the module it needs or None, the distribution whose version is reported)
ENGINES = {
    "warp_sim": ("warp_sim (defaults: sim.step(1/60))", None, "warp-sim"),
    "mujoco": (f"MuJoCo C (1 thread, dt 1/{round(1 / (FRAME / MUJOCO_STEPS))} s, {MUJOCO_STEPS} steps a frame)",
               "mujoco", "mujoco"),
    "mujoco_warp": (f"MuJoCo-Warp (dt 1/{round(1 / (FRAME / MUJOCO_STEPS))} s, {MUJOCO_STEPS} steps a frame)",
                    "mujoco_warp", "mujoco-warp"),
    "newton_xpbd": (f"Newton XPBD (2 iterations, {NEWTON_SUBSTEPS} substeps a frame)", "newton", "newton"),
    "newton_featherstone": (f"Newton Featherstone ({NEWTON_SUBSTEPS} substeps a frame)", "newton", "newton"),
}
#: the engines run unless --only says otherwise: Newton's Featherstone goes non-finite within the first frames of
#: these ball-jointed chains (a 6-link chain at its 8th step of 1/600 s, 10 links at its 2nd, without contacts too;
#: float32, no armature), so it runs only when asked for (--only newton_featherstone)
DEFAULT_ENGINES = ("warp_sim", "mujoco", "mujoco_warp", "newton_xpbd")
SCENES = ("chain", "ragdolls")
SETTINGS = {"full": {"seconds": 2.0, "rounds": 6, "links": CHAIN_LINKS, "ragdolls": RAGDOLLS},
            "quick": {"seconds": 0.5, "rounds": 3, "links": 10, "ragdolls": 2}}
BUDGET = {"full": 240.0, "quick": 60.0}     # [s] one engine's projected run of one scene, else "n/a"
TIMEOUT = {"full": 1800.0, "quick": 300.0}  # [s] one answer of a worker (benchmarks/rounds.py)


class OverBudget(Exception):
    """A run that would take too long: its row says "n/a (...)", the message."""


class NonFinite(Exception):
    """A run whose poses went non-finite: its row says "failed: ...", the message."""


# ---------------------------------------------------------------------------------------------------- the scenes

@dataclass
class Body:
    """A rigid body: shape "capsule" (size (radius, half_height), along the body's y axis), "box" (half extents) or
    "sphere" ((radius,)), centred on the body's origin; mass [kg]; position [m]; orientation (x, y, z, w)."""
    name: str
    shape: str
    size: tuple
    mass: float
    position: np.ndarray
    orientation: np.ndarray

    @property
    def volume(self) -> float:
        if self.shape == "capsule":
            r, h = self.size
            return math.pi * r * r * (2.0 * h) + 4.0 / 3.0 * math.pi * r**3
        if self.shape == "box":
            return 8.0 * float(np.prod(self.size))
        return 4.0 / 3.0 * math.pi * self.size[0] ** 3


@dataclass
class Joint:
    """A joint: kind "ball" or "revolute"; parent (-1: the world) and child body indices; the world anchor [m] and
    axis at the start (a ball's axis is its cone's); limits: (lower, upper) [rad] of a hinge, the cone half-angle
    [rad] of a ball, or None."""
    name: str
    kind: str
    parent: int
    child: int
    anchor: np.ndarray
    axis: np.ndarray
    limits: tuple | float | None = None


@dataclass
class JointScene:
    """Bodies and joints (each body the child of at most one joint: a forest), whether there is a ground plane y = 0;
    the anchors in each body's frame (``local_anchors``) and the gap measure (``gaps``) from the start's poses."""
    name: str
    bodies: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    ground: bool = False

    def add_body(self, name, shape, size, mass, position, orientation=(0.0, 0.0, 0.0, 1.0)) -> int:
        self.bodies.append(Body(name, shape, tuple(float(s) for s in size), float(mass),
                                np.asarray(position, float), np.asarray(orientation, float)))
        return len(self.bodies) - 1

    def add_joint(self, kind, parent, child, anchor, axis=(1.0, 0.0, 0.0), limits=None) -> int:
        axis = np.asarray(axis, float)
        self.joints.append(Joint(f"j{len(self.joints)}", kind, parent, child, np.asarray(anchor, float),
                                 axis / np.linalg.norm(axis), limits))
        return len(self.joints) - 1

    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """(positions (B, 3), orientations (B, 4) x y z w) at the start."""
        return (np.array([b.position for b in self.bodies]), np.array([b.orientation for b in self.bodies]))

    def local_anchors(self) -> tuple[np.ndarray, np.ndarray]:
        """Per joint, the anchor in the parent's frame (world coordinates for the world) and in the child's."""
        x, q = self.poses()
        parent, child = [], []
        for j in self.joints:
            parent.append(j.anchor if j.parent < 0 else quat_to_matrix(q[j.parent]).T @ (j.anchor - x[j.parent]))
            child.append(quat_to_matrix(q[j.child]).T @ (j.anchor - x[j.child]))
        return np.array(parent), np.array(child)

    def gaps(self, x: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Per joint, the distance [m] between its anchor on the parent (or the world) and on the child, from body
        positions x (B, 3) and orientations q (B, 4, x y z w): the same measure for every engine."""
        if not hasattr(self, "_gap_rows"):
            a_p, a_c = self.local_anchors()
            self._gap_rows = (np.array([j.parent for j in self.joints]), np.array([j.child for j in self.joints]),
                              a_p, a_c)
        parent, child, a_p, a_c = self._gap_rows
        x, q = np.asarray(x, np.float64), np.asarray(q, np.float64)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        world = parent < 0
        p_world = np.where(world[:, None], a_p, x[parent] + rotate(q[parent], a_p))
        c_world = x[child] + rotate(q[child], a_c)
        return np.linalg.norm(c_world - p_world, axis=1)

    def lowest(self, x: np.ndarray, q: np.ndarray) -> float:
        """The lowest point of any body's shape [m] (box corners, capsule ends less the radius, spheres' bottoms)."""
        low = math.inf
        for k, body in enumerate(self.bodies):
            R = quat_to_matrix(np.asarray(q[k], float) / np.linalg.norm(q[k]))
            if body.shape == "box":
                corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * body.size
                low = min(low, float((x[k] + corners @ R.T)[:, 1].min()))
            elif body.shape == "capsule":
                r, h = body.size
                low = min(low, float(x[k][1] - abs(R[1, 1]) * h - r))
            else:
                low = min(low, float(x[k][1] - body.size[0]))
        return low


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (N, 3) by unit quaternions q (N, 4, x y z w)."""
    u, w = q[:, :3], q[:, 3:4]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def conjugate(q: np.ndarray) -> np.ndarray:
    return np.array([-q[0], -q[1], -q[2], q[3]])


def axis_frame(axis: np.ndarray) -> np.ndarray:
    """A quaternion (x, y, z, w) whose frame's x axis is ``axis`` (the joint frame of a hinge about it)."""
    x = axis / np.linalg.norm(axis)
    helper = np.array([0.0, 1.0, 0.0]) if abs(x[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    z = np.cross(x, helper)
    z /= np.linalg.norm(z)
    return matrix_to_quat(np.stack([x, np.cross(z, x), z], axis=1))


def axis_angle(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([axis * math.sin(angle / 2.0), [math.cos(angle / 2.0)]])


#: capsules along the body's y axis turned onto x (a horizontal chain link)
Y_ONTO_X = axis_angle((0.0, 0.0, 1.0), -math.pi / 2.0)


def chain(links: int = CHAIN_LINKS) -> JointScene:
    """``links`` capsules tip to tip along +x from CHAIN_PIVOT, ball joints at the tips, the first on the world."""
    scene = JointScene("chain")
    top = np.asarray(CHAIN_PIVOT, float)
    along = np.array([1.0, 0.0, 0.0])
    parent = -1
    for k in range(links):
        body = scene.add_body(f"link{k}", "capsule", (LINK_RADIUS, LINK / 2.0 - LINK_RADIUS), LINK_MASS,
                              top + (k + 0.5) * LINK * along, Y_ONTO_X)
        scene.add_joint("ball", parent, body, top + k * LINK * along)
        parent = body
    return scene


#: one ragdoll, facing +z, y up, its pelvis at the origin: name -> (shape, size, mass [kg], centre [m], parent,
#: joint kind, anchor [m], axis, limits [rad]); x mirrored for the left side ("l" names)
RAGDOLL_PARTS = {
    "pelvis": ("box", (0.14, 0.08, 0.09), 10.0, (0.0, 0.0, 0.0), None, None, None, None, None),
    "torso": ("box", (0.16, 0.2, 0.1), 20.0, (0.0, 0.3, 0.0), "pelvis", "ball", (0.0, 0.09, 0.0), (0, 1, 0), 0.5),
    "head": ("sphere", (0.1,), 5.0, (0.0, 0.62, 0.0), "torso", "ball", (0.0, 0.51, 0.0), (0, 1, 0), 0.6),
    "upper_arm_r": ("capsule", (0.04, 0.1), 2.0, (0.22, 0.32, 0.0), "torso", "ball", (0.22, 0.46, 0.0), (0, -1, 0),
                    1.5),
    "lower_arm_r": ("capsule", (0.035, 0.1), 1.5, (0.22, 0.045, 0.0), "upper_arm_r", "revolute", (0.22, 0.18, 0.0),
                    (1, 0, 0), (-2.6, 0.0)),
    "hand_r": ("box", (0.02, 0.05, 0.04), 0.5, (0.22, -0.145, 0.0), "lower_arm_r", "revolute", (0.22, -0.09, 0.0),
               (1, 0, 0), (-0.8, 0.8)),
    "thigh_r": ("capsule", (0.06, 0.14), 7.0, (0.09, -0.28, 0.0), "pelvis", "ball", (0.09, -0.08, 0.0), (0, -1, 0),
                1.2),
    "shin_r": ("capsule", (0.05, 0.15), 4.0, (0.09, -0.68, 0.0), "thigh_r", "revolute", (0.09, -0.48, 0.0), (1, 0, 0),
               (0.0, 2.6)),
    "foot_r": ("box", (0.05, 0.03, 0.11), 1.0, (0.09, -0.915, 0.05), "shin_r", "revolute", (0.09, -0.88, 0.0),
               (1, 0, 0), (-0.6, 0.6)),
}


def ragdoll_parts() -> dict:
    """RAGDOLL_PARTS with the left side ("_l", x mirrored) added: 15 parts, parents before children."""
    parts = {}
    for name, part in RAGDOLL_PARTS.items():
        parts[name] = part
        if name.endswith("_r"):
            shape, size, mass, centre, parent, kind, anchor, axis, limits = part
            mirror = np.array([-1.0, 1.0, 1.0])
            parts[name[:-2] + "_l"] = (shape, size, mass, tuple(np.asarray(centre) * mirror),
                                       parent[:-2] + "_l" if parent.endswith("_r") else parent, kind,
                                       tuple(np.asarray(anchor) * mirror), axis, limits)
    return {name: parts[name] for name in sorted(parts, key=lambda n: _depth(parts, n))}


def _depth(parts: dict, name: str) -> int:
    parent = parts[name][4]
    return 0 if parent is None else 1 + _depth(parts, parent)


def ragdolls(count: int = RAGDOLLS, seed: int = SEED) -> JointScene:
    """``count`` ragdolls on a square grid RAGDOLL_PITCH apart, each turned about y at random and tipped TILT about a
    random horizontal axis, their lowest point DROP above the ground."""
    scene = JointScene("ragdolls", ground=True)
    rng = np.random.default_rng(seed)
    parts = ragdoll_parts()
    side = math.ceil(math.sqrt(count))
    for r in range(count):
        yaw = axis_angle((0.0, 1.0, 0.0), rng.uniform(0.0, 2.0 * math.pi))
        heading = rng.uniform(0.0, 2.0 * math.pi)
        tilt = axis_angle((math.cos(heading), 0.0, math.sin(heading)), TILT)
        turn = quat_multiply(tilt, yaw)
        R = quat_to_matrix(turn)
        origin = np.array([(r % side - (side - 1) / 2.0) * RAGDOLL_PITCH, 0.0,
                           (r // side - (side - 1) / 2.0) * RAGDOLL_PITCH])
        first = len(scene.bodies)
        index = {}
        for name, (shape, size, mass, centre, parent, kind, anchor, axis, limits) in parts.items():
            index[name] = scene.add_body(f"r{r}_{name}", shape, size, mass, origin + R @ np.asarray(centre, float),
                                         turn)
            if parent is not None:
                scene.add_joint(kind, index[parent], index[name], origin + R @ np.asarray(anchor, float),
                                R @ np.asarray(axis, float), limits)
        x, q = scene.poses()
        lift = DROP - JointScene("one", scene.bodies[first:]).lowest(x[first:], q[first:])
        for body in scene.bodies[first:]:
            body.position = body.position + np.array([0.0, lift, 0.0])
        for joint in scene.joints:
            if joint.child >= first:
                joint.anchor = joint.anchor + np.array([0.0, lift, 0.0])
    return scene


def make_scene(name: str, mode: str) -> JointScene:
    cfg = SETTINGS[mode]
    return chain(cfg["links"]) if name == "chain" else ragdolls(cfg["ragdolls"])


# ---------------------------------------------------------------------------------------------------- the engines
# Each has frame() (advance one FRAME), poses() -> numpy (x (B, 3), q (B, 4, x y z w)) in the scene's body order,
# sync(), and info (a dict for the JSON: its time step, sub-steps, solver).

class WarpSimJoints:
    """warp_sim: ws.Scene with the same bodies (add_rigid_body(shape, mass=...), restitution 0, friction 0.8),
    scene.add_joint per joint (kind, parent, child, anchor, axis, limits), add_ground(0, 0.8); ws.Simulator(scene)
    with its defaults, sim.step(FRAME) a frame."""

    def __init__(self, scene: JointScene, device: str = "cpu"):
        s = ws.Scene(gravity=GRAVITY)
        if scene.ground:
            s.add_ground(restitution=0.0, friction=FRICTION)
        for b in scene.bodies:
            shape = {"capsule": lambda size: ws.Capsule(*size), "box": ws.Box,
                     "sphere": lambda size: ws.Sphere(size[0])}[b.shape](b.size)
            s.add_rigid_body(shape, mass=b.mass, position=b.position, orientation=b.orientation, restitution=0.0,
                             friction=FRICTION, name=b.name)
        for j in scene.joints:
            s.add_joint(j.kind, None if j.parent < 0 else j.parent, j.child, anchor=j.anchor, axis=j.axis,
                        limits=j.limits, name=j.name)
        self.sim = ws.Simulator(s, device=device)
        self.info = {"substeps": int(self.sim.substeps(FRAME)), "dt": FRAME / self.sim.substeps(FRAME),
                     "integrator": "rk4 (default; jointed bodies drift as symplectic Euler)"}

    def frame(self) -> None:
        self.sim.step(FRAME)

    def sync(self) -> None:
        wp.synchronize_device(self.sim.device)

    def poses(self):
        return self.sim.state.body_x.numpy(), self.sim.state.body_q.numpy()

    def own_gaps(self) -> np.ndarray:
        """warp_sim's own measure (sim.joints.gaps: along the locked axes, all three here), for the cross-check."""
        return self.sim.joints.gaps(self.sim.state)


def mjcf(scene: JointScene, timestep: float) -> str:
    """The scene as MJCF: y up (gravity -y, the plane's normal +y), bodies nested along the joint tree (body pos and
    quat in the parent body's frame), a freejoint on a root no joint holds, ball joints (range 0..cone) and hinges
    (range lower..upper) at the anchor in the child's frame, one geom per body with its mass (inertia from its
    shape), friction FRICTION (MuJoCo's default torsional and rolling coefficients); MuJoCo's defaults else."""
    x, q = scene.poses()
    children: dict[int, list] = {}
    joint_of = {}
    for j in scene.joints:
        children.setdefault(j.parent, []).append(j.child)
        joint_of[j.child] = j
    roots = [k for k in range(len(scene.bodies)) if k not in joint_of]
    children.setdefault(-1, []).extend(roots)

    def fmt(values) -> str:
        return " ".join(repr(float(v)) for v in values)

    def body(k: int, parent: int) -> str:
        b = scene.bodies[k]
        if parent < 0:
            pos, quat = x[k], q[k]
        else:
            pos = quat_to_matrix(q[parent]).T @ (x[k] - x[parent])
            quat = quat_multiply(conjugate(q[parent]), q[k])
        R = quat_to_matrix(q[k])
        j = joint_of.get(k)
        if j is None:
            joint = "<freejoint/>"
        else:
            at = R.T @ (j.anchor - x[k])
            if j.kind == "ball":
                joint = (f'<joint name="{j.name}" type="ball" pos="{fmt(at)}"'
                         + (f' range="0 {float(j.limits)!r}"' if j.limits is not None else "") + "/>")
            else:
                joint = (f'<joint name="{j.name}" type="hinge" pos="{fmt(at)}" axis="{fmt(R.T @ j.axis)}"'
                         + (f' range="{fmt(j.limits)}"' if j.limits is not None else "") + "/>")
        if b.shape == "capsule":
            geom = f'type="capsule" size="{fmt(b.size)}" zaxis="0 1 0"'
        elif b.shape == "box":
            geom = f'type="box" size="{fmt(b.size)}"'
        else:
            geom = f'type="sphere" size="{fmt(b.size)}"'
        inner = "".join(body(c, k) for c in children.get(k, []))
        return (f'<body name="{b.name}" pos="{fmt(pos)}" quat="{fmt([quat[3], quat[0], quat[1], quat[2]])}">'
                f'{joint}<geom {geom} mass="{b.mass!r}"/>{inner}</body>')

    ground = '<geom name="ground" type="plane" size="0 0 1" zaxis="0 1 0"/>' if scene.ground else ""
    n = len(scene.bodies)
    return (f'<mujoco model="{scene.name}"><compiler angle="radian"/>'
            f'<option timestep="{timestep!r}" gravity="{fmt(GRAVITY)}"/><size memory="{max(64, n // 4)}M"/>'
            f'<default><geom friction="{FRICTION!r} 0.005 0.0001"/></default><worldbody>{ground}'
            + "".join(body(k, -1) for k in children[-1]) + "</worldbody></mujoco>")


class MujocoJoints:
    """MuJoCo (C, one thread) on mjcf(scene): mj_step(nstep=MUJOCO_STEPS) a frame; poses from mj_kinematics (mj_step
    leaves xpos and xquat at the state before its last integration)."""

    def __init__(self, mujoco, scene: JointScene):
        self.mujoco = mujoco
        self.model = mujoco.MjModel.from_xml_string(mjcf(scene, FRAME / MUJOCO_STEPS))
        self.data = mujoco.MjData(self.model)
        self.ids = np.array([mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, b.name) for b in scene.bodies])
        self.info = {"substeps": MUJOCO_STEPS, "dt": self.model.opt.timestep, "solver": "Newton (default)",
                     "integrator": "Euler (default)", "cone": "pyramidal (default)", "nv": int(self.model.nv)}

    def frame(self) -> None:
        self.mujoco.mj_step(self.model, self.data, nstep=MUJOCO_STEPS)

    def sync(self) -> None:
        pass

    def poses(self):
        self.mujoco.mj_kinematics(self.model, self.data)
        return self.data.xpos[self.ids].copy(), self.data.xquat[self.ids][:, [1, 2, 3, 0]].copy()


class MujocoWarpJoints:
    """MuJoCo-Warp on the same MJCF on the CPU: put_model / put_data (room for 16 contacts a body, at least
    MJW_MIN_CONTACTS: a folding chain's broad phase overflows 16 a link; 4 constraint rows a contact, as many as a
    dense Jacobian of MJW_JACOBIAN_BYTES holds), mjw.step MUJOCO_STEPS times a frame; poses from mjw.kinematics."""

    def __init__(self, mujoco, mjw, scene: JointScene, device):
        self.mjw, self.device = mjw, device
        mjm = mujoco.MjModel.from_xml_string(mjcf(scene, FRAME / MUJOCO_STEPS))
        mjd = mujoco.MjData(mjm)
        mujoco.mj_forward(mjm, mjd)
        contacts = max(MJW_MIN_CONTACTS, 16 * mjm.nbody)
        rows = min(4 * contacts, MJW_JACOBIAN_BYTES // (4 * mjm.nv))   # its constraint Jacobian is dense: rows x nv
        with wp.ScopedDevice(device):
            self.m = mjw.put_model(mjm)
            self.d = mjw.put_data(mjm, mjd, nconmax=contacts, njmax=rows)
        self.ids = np.array([mujoco.mj_name2id(mjm, mujoco.mjtObj.mjOBJ_BODY, b.name) for b in scene.bodies])
        self.info = {"substeps": MUJOCO_STEPS, "dt": mjm.opt.timestep, "solver": "Newton (default)",
                     "nv": int(mjm.nv)}

    def frame(self) -> None:
        with wp.ScopedDevice(self.device):
            for _ in range(MUJOCO_STEPS):
                self.mjw.step(self.m, self.d)

    def sync(self) -> None:
        wp.synchronize_device(self.device)

    def poses(self):
        with wp.ScopedDevice(self.device):
            self.mjw.kinematics(self.m, self.d)
        return self.d.xpos.numpy()[0][self.ids], self.d.xquat.numpy()[0][self.ids][:, [1, 2, 3, 0]]


class NewtonJoints:
    """Newton: ModelBuilder(up_axis Y), one add_link per body (xform = its pose) with its shape (ShapeConfig density
    = mass / volume, mu FRICTION, no restitution; a capsule turned from Newton's z onto the body's y), a joint per
    joint with parent_xform and child_xform the anchor and the joint frame (x along the axis) in each body's frame, so
    that the start is joint coordinates 0 (a freejoint at each root, add_articulation per tree); eval_fk, then per
    substep CollisionPipeline.collide and solver.step; solver "xpbd" (SolverXPBD, default iterations) or
    "featherstone" (SolverFeatherstone)."""

    def __init__(self, newton, scene: JointScene, device, solver: str = "xpbd"):
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=GRAVITY)
        if scene.ground:
            builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=FRICTION, restitution=0.0))
        x, q = scene.poses()
        z_onto_y = wp.quat(*axis_angle((1.0, 0.0, 0.0), -math.pi / 2.0))
        for b in scene.bodies:
            link = builder.add_link(xform=wp.transform(wp.vec3(*b.position), wp.quat(*b.orientation)), label=b.name)
            cfg = newton.ModelBuilder.ShapeConfig(density=b.mass / b.volume, mu=FRICTION, restitution=0.0)
            if b.shape == "capsule":
                builder.add_shape_capsule(link, xform=wp.transform(wp.vec3(0.0, 0.0, 0.0), z_onto_y),
                                          radius=b.size[0], half_height=b.size[1], cfg=cfg)
            elif b.shape == "box":
                builder.add_shape_box(link, hx=b.size[0], hy=b.size[1], hz=b.size[2], cfg=cfg)
            else:
                builder.add_shape_sphere(link, radius=b.size[0], cfg=cfg)
        joint_of = {j.child: j for j in scene.joints}
        trees: dict[int, list] = {}   # root body -> its joints, in order

        def root_of(k: int) -> int:
            while k in joint_of and joint_of[k].parent >= 0:
                k = joint_of[k].parent
            return k

        for k in range(len(scene.bodies)):   # bodies come parents first (chain, ragdolls)
            j = joint_of.get(k)
            if j is None:
                index = builder.add_joint_free(k)
            else:
                frame = axis_frame(j.axis)

                def local(body: int):
                    if body < 0:
                        return wp.transform(wp.vec3(*j.anchor), wp.quat(*frame))
                    R = quat_to_matrix(q[body])
                    return wp.transform(wp.vec3(*(R.T @ (j.anchor - x[body]))),
                                        wp.quat(*quat_multiply(conjugate(q[body]), frame)))

                frames = dict(parent_xform=local(j.parent), child_xform=local(k), label=j.name)
                if j.kind == "revolute":
                    lower, upper = j.limits if j.limits is not None else (None, None)
                    index = builder.add_joint_revolute(j.parent, k, axis=(1.0, 0.0, 0.0), limit_lower=lower,
                                                       limit_upper=upper, **frames)
                elif j.limits is None:
                    index = builder.add_joint_ball(j.parent, k, **frames)
                else:
                    cone = float(j.limits)
                    axes = [newton.ModelBuilder.JointDofConfig(axis=a, limit_lower=-cone, limit_upper=cone)
                            for a in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))]
                    index = builder.add_joint_d6(j.parent, k, linear_axes=[], angular_axes=axes, **frames)
            trees.setdefault(root_of(k), []).append(index)
        for root, joints in trees.items():
            builder.add_articulation(joints, label=scene.bodies[root].name)
        self.model = builder.finalize(device=device.alias)
        self.states = [self.model.state(), self.model.state()]
        self.control = self.model.control()
        newton.eval_fk(self.model, self.model.joint_q, self.model.joint_qd, self.states[0])
        if solver == "xpbd":
            self.solver = newton.solvers.SolverXPBD(self.model)
        else:
            self.solver = newton.solvers.SolverFeatherstone(self.model)
        self.pipeline = newton.CollisionPipeline(self.model, broad_phase="sap")
        self.contacts = self.pipeline.contacts()
        self.featherstone = solver == "featherstone"
        self.newton = newton
        self.info = {"substeps": NEWTON_SUBSTEPS, "dt": FRAME / NEWTON_SUBSTEPS,
                     "solver": "SolverXPBD (iterations 2, default)" if solver == "xpbd" else "SolverFeatherstone"}

    def frame(self) -> None:
        h = FRAME / NEWTON_SUBSTEPS
        for _ in range(NEWTON_SUBSTEPS):
            state_in, state_out = self.states
            state_in.clear_forces()
            self.pipeline.collide(state_in, self.contacts)
            self.solver.step(state_in, state_out, self.control, self.contacts, h)
            self.states.reverse()

    def sync(self) -> None:
        wp.synchronize_device(self.model.device)

    def finite(self) -> bool:
        """Whether the velocities are finite too (Featherstone's joint velocities go NaN while its poses stay put)."""
        state = self.states[0]
        return bool(np.isfinite(state.body_qd.numpy()).all() and np.isfinite(state.joint_qd.numpy()).all())

    def poses(self):
        state = self.states[0]
        if self.featherstone:   # Featherstone integrates joint coordinates; body_q is their forward kinematics
            self.newton.eval_fk(self.model, state.joint_q, state.joint_qd, state)
        body_q = state.body_q.numpy()
        return body_q[:, :3], body_q[:, 3:7]


def make_engine(key: str, scene: JointScene, device, modules: dict):
    if key == "warp_sim":
        return WarpSimJoints(scene, device.alias)
    if key == "mujoco":
        return MujocoJoints(modules["mujoco"], scene)
    if key == "mujoco_warp":
        return MujocoWarpJoints(modules["mujoco"], modules["mujoco_warp"], scene, device)
    return NewtonJoints(modules["newton"], scene, device, "xpbd" if key == "newton_xpbd" else "featherstone")


# ---------------------------------------------------------------------------------------------------- the worker

def prepare(key: str, name: str, mode: str, args, device, modules: dict):
    """Build ``name`` for engine ``key``, warm it up on a throwaway copy (OverBudget if its projected run exceeds the
    budget), build it again: (one timed round [s], the result from the rounds' seconds)."""
    scene = make_scene(name, mode)
    frames = round(args.seconds / FRAME)
    per_round = max(1, frames // args.rounds)
    budget = args.budget or BUDGET[mode]
    start = time.perf_counter()
    warm = make_engine(key, scene, device, modules)
    warm.sync()
    first_build_s = time.perf_counter() - start
    frame_s = []
    for _ in range(WARMUP_FRAMES):
        tick = time.perf_counter()
        warm.frame()
        warm.sync()
        frame_s.append(time.perf_counter() - tick)
    projected = frame_s[-1] * per_round * args.rounds
    if projected > budget:
        raise OverBudget(f"n/a (over the {budget:.0f} s budget: {frame_s[-1]:,.2f} s a frame after warm-up, "
                         f"{projected:,.0f} s projected)")
    del warm
    start = time.perf_counter()
    engine = make_engine(key, scene, device, modules)
    engine.sync()
    build_s = time.perf_counter() - start
    x, q = engine.poses()
    start_gap = float(scene.gaps(x, q).max())
    series, lowest = [], []
    own = {}

    def round_() -> float:
        seconds = 0.0
        for _ in range(per_round):
            engine.sync()
            tick = time.perf_counter()
            engine.frame()
            engine.sync()
            seconds += time.perf_counter() - tick
            x, q = engine.poses()   # outside the clock
            if not (np.isfinite(x).all() and np.isfinite(q).all() and getattr(engine, "finite", lambda: True)()):
                before = f"worst gap before: {1e3 * max(series):.3g} mm" if series else "in the first frame"
                raise NonFinite(f"failed: non-finite state at t = {(len(series) + 1) * FRAME:.3f} s ({before})")
            series.append(float(scene.gaps(x, q).max()))
        x, q = engine.poses()
        lowest.append(scene.lowest(x, q) if scene.ground else float(np.asarray(x)[:, 1].min()))
        if key == "warp_sim":
            own["max_difference"] = float(np.abs(engine.own_gaps() - scene.gaps(x, q)).max())
        return seconds

    def finish(seconds: list[float]) -> dict:
        gaps = np.array(series)
        worst = int(np.argmax(gaps))
        return {"status": "ok", "seconds": seconds, "frames": len(series), "simulated_s": len(series) * FRAME,
                "steps_per_s": len(series) / sum(seconds), "worst_gap_m": float(gaps[worst]),
                "worst_gap_at_s": (worst + 1) * FRAME, "final_gap_m": float(gaps[-1]), "start_gap_m": start_gap,
                "gap_per_frame_m": series, "lowest_per_round_m": lowest, "build_s": build_s,
                "first_build_s": first_build_s, "warmup_frame_s": frame_s, "bodies": len(scene.bodies),
                "joints": len(scene.joints), **engine.info,
                **({"own_gaps_vs_this_max_difference_m": own["max_difference"]} if own else {})}

    return round_, finish


def failure(error: Exception) -> dict:
    if isinstance(error, (OverBudget, NonFinite)):
        return {"status": str(error)}
    if isinstance(error, ws.SimulationDiverged):
        return {"status": f"failed: SimulationDiverged at step {error.step}: {error.reason}"}
    text = str(error).splitlines()[0] if str(error) else ""
    return {"status": f"failed: {type(error).__name__}: {text}"[:200]}


def worker(args, device) -> None:
    key = args.worker
    mode = "quick" if args.quick else "full"
    modules = {}
    module = ENGINES[key][1]
    if module is not None:
        modules[module] = importlib.import_module(module)
        if module == "mujoco_warp":
            modules["mujoco"] = importlib.import_module("mujoco")
    rounds.serve(args.scenes, lambda name: prepare(key, name, mode, args, device, modules), failure)


# ---------------------------------------------------------------------------------------------------- the parent

def engine_status() -> dict:
    """Per engine: installed (found, not imported: the imports stay in the workers), its version."""
    status = {}
    for key, (_, module, distribution) in ENGINES.items():
        found = module is None or importlib.util.find_spec(module) is not None
        try:
            version = importlib.metadata.version(distribution) if found else None
        except importlib.metadata.PackageNotFoundError:
            version = "?"
        status[key] = {"installed": found, "version": version}
    return status


def worker_command(key: str, args) -> list[str]:
    return ([sys.executable, str(Path(__file__).resolve()), "--worker", key, "--scenes", *args.scenes,
             "--seconds", repr(args.seconds), "--rounds", str(args.rounds)]
            + (["--quick"] if args.quick else []) + (["--budget", repr(args.budget)] if args.budget else []))


def scene_label(name: str, mode: str) -> str:
    cfg = SETTINGS[mode]
    if name == "chain":
        return f"chain of {cfg['links']} links"
    return f"{cfg['ragdolls']} ragdolls ({15 * cfg['ragdolls']:,} bodies)"


def table(rows: list[dict]) -> str:
    cells = []
    for r in rows:
        rate = r.get("steps_per_s")
        if rate is None:
            cells.append([r["scene_label"], r["label"], r["status"].replace("|", "/"), "-", "-", "-", "-"])
            continue
        ratio = "1.00x (ref)" if r["key"] == "warp_sim" else (
            f"{r['paired_ratio']:.2f}x" if r.get("paired_ratio") else "-")
        cells.append([r["scene_label"], r["label"], f"{r['substeps']} x {1e3 * r['dt']:.3g} ms", f"{rate:,.1f}",
                      ratio, f"{1e3 * r['worst_gap_m']:.3g} mm (t = {r['worst_gap_at_s']:.2f} s)",
                      f"{1e3 * r['final_gap_m']:.3g} mm"])
    return markdown(["scene", "engine", "steps a frame", "frames/s (1/60 s)", "warp_sim / this", "worst gap",
                     "gap at the end"], cells, left=("scene", "engine", "steps a frame"))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 links, 2 ragdolls, 0.5 s (a test-sized run)")
    parser.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES))
    parser.add_argument("--only", nargs="+", choices=list(ENGINES), default=None,
                        help="only these engines (warp_sim always runs: it is the reference; default: "
                             + " ".join(DEFAULT_ENGINES) + ")")
    parser.add_argument("--seconds", type=float, default=None, help="simulated time [s] (default 2, --quick 0.5)")
    parser.add_argument("--rounds", type=int, default=None, help="rounds the run is cut into (default 6, --quick 3)")
    parser.add_argument("--budget", type=float, default=None,
                        help="seconds one engine's run of a scene may be projected to take, else n/a "
                             "(default 240, --quick 60)")
    parser.add_argument("--timeout", type=float, default=None,
                        help="seconds a worker may take for one answer (default 1800, --quick 300)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/joints.json"))
    parser.add_argument("--worker", choices=list(ENGINES), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    mode = "quick" if args.quick else "full"
    args.seconds = args.seconds or SETTINGS[mode]["seconds"]
    args.rounds = args.rounds or SETTINGS[mode]["rounds"]
    if args.seconds < FRAME or args.rounds < 1 or round(args.seconds / FRAME) < args.rounds:
        parser.error("--seconds must hold at least one frame (1/60 s) a round, --rounds >= 1")
    wp.init()
    device = wp.get_device("cpu")   # the joints table is a CPU one (the peers' CPU paths)
    if args.worker:
        worker(args, device)
        return
    timeout = args.timeout or TIMEOUT[mode]
    status = engine_status()
    name = device_name(device)
    print(f"warp {wp.__version__}, warp_sim {ws.__version__} on cpu ({name}), {os.cpu_count()} cores; "
          + "; ".join(f"{key} {s['version'] if s['installed'] else 'not installed'}" for key, s in status.items()
                      if key != "warp_sim"))
    frames = round(args.seconds / FRAME)
    print(f"{mode} run: {frames} frames of 1/60 s ({args.seconds:g} s) in {args.rounds} rounds taken in turn",
          flush=True)
    started = time.perf_counter()
    by_key, commands = {}, {}
    for key in ENGINES:
        if key not in (args.only or DEFAULT_ENGINES) and key != "warp_sim":
            continue
        if not status[key]["installed"]:
            by_key[key] = {s: {"status": "not installed"} for s in args.scenes}
        else:
            by_key[key] = None
            commands[key] = worker_command(key, args)

    def report(key, scene, result):
        line = result["status"] if "steps_per_s" not in result else (
            f"{result['steps_per_s']:,.1f} frames/s, worst gap {1e3 * result['worst_gap_m']:.3g} mm")
        print(f"    {scene} {key}: {line}", flush=True)

    by_key.update(rounds.interleave(commands, args.scenes, args.rounds, timeout, report))
    rows = []
    for scene in args.scenes:
        reference = by_key["warp_sim"][scene]
        for key, results in by_key.items():
            result = results[scene]
            paired = rounds.paired_ratio(result.get("seconds"), reference.get("seconds"))
            overall = (reference["steps_per_s"] / result["steps_per_s"]
                       if "steps_per_s" in result and "steps_per_s" in reference else None)
            rows.append({"scene": scene, "scene_label": scene_label(scene, mode), "key": key,
                         "label": ENGINES[key][0], **result,
                         **({"paired_ratio": paired, "overall_ratio": overall}
                            if key != "warp_sim" and paired is not None else {})})
    print()
    print(table(rows))

    args.out.parent.mkdir(parents=True, exist_ok=True)
    out = {"device": "cpu", "device_name": name, "cpu_count": os.cpu_count(), "warp_version": wp.__version__,
           "warp_sim_version": ws.__version__, "numpy_version": np.__version__, "engines": status, "mode": mode,
           "settings": {**SETTINGS[mode], "seconds": args.seconds, "rounds": args.rounds, "frame_s": FRAME,
                        "mujoco_steps_a_frame": MUJOCO_STEPS, "newton_substeps": NEWTON_SUBSTEPS,
                        "friction": FRICTION, "seed": SEED},
           "budget_s": args.budget or BUDGET[mode], "timeout_s": timeout, "wall_s": time.perf_counter() - started,
           "rows": rows}
    args.out.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""Joints between rigid bodies: the host-side description (numpy), every kind held as six joint-frame axes.

A joint ties a child body to a parent body (or the world) at a frame fixed in each: the anchor (a point) and
an orientation whose x axis is the joint's axis. Each of the frame's six axes, ``AXES`` (translation along
and rotation about x, y and z of the parent's frame), is free, locked, or limited to [lower, upper]; a drive
(a PD servo) may act on any axis that is not locked. The named kinds are presets of that:

- "revolute": a hinge about x; limits (lower, upper) of the angle [rad]
- "prismatic": a slider along x; limits of the offset [m]
- "ball": a ball joint; limits: the cone half-angle [rad] the child's x axis may swing from the parent's
- "fixed": a weld
- "distance": the anchors kept between limits (min, max) apart [m] (a rope, or with min = max a rod)
- a ``D6``: the generic joint, what UsdPhysics.Joint with PhysicsLimitAPI and PhysicsDriveAPI says

Units are SI (radians, metres, N m, N); the USD reader turns the schema's degrees into them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..util import checks
from ..util.rotations import matrix_to_quat, quat_to_matrix

AXES = ("transX", "transY", "transZ", "rotX", "rotY", "rotZ")
KINDS = ("revolute", "prismatic", "ball", "fixed", "distance")
FREE, LOCKED, LIMITED = 0, 1, 2
_UNBOUNDED = math.inf


@dataclass(frozen=True)
class Drive:
    """A PD servo on one axis: force (or torque) = stiffness (target - position) + damping (velocity_target -
    velocity), at most max_force, as PhysX and Newton drive a joint.

    target: the position it pulls to [rad] or [m]
    velocity: the velocity it pulls to [rad/s] or [m/s]
    stiffness: [N m/rad] or [N/m]
    damping: [N m s/rad] or [N s/m]
    max_force: the largest torque [N m] or force [N] it gives (inf: none)
    acceleration: True: stiffness and damping are per unit of the axis's effective inertia or mass, so the
        servo's response does not depend on what it moves (the USD drive type "acceleration")
    """
    target: float = 0.0
    velocity: float = 0.0
    stiffness: float = 0.0
    damping: float = 0.0
    max_force: float = _UNBOUNDED
    acceleration: bool = False

    def __post_init__(self):
        for name in ("target", "velocity"):
            checks.scalar(name, getattr(self, name))
        for name in ("stiffness", "damping"):
            checks.scalar(name, getattr(self, name), low=0.0)
        if not (self.max_force > 0.0):
            raise checks.fail("max_force", self.max_force, "expected a force or torque > 0 (inf: no limit)")


@dataclass(frozen=True)
class D6:
    """The generic joint, axis by axis (AXES): ``locked`` axes do not move, ``limits`` hold an axis within
    (lower, upper) [m or rad] (lower > upper locks it, as in UsdPhysics), every other axis is free; ``drives`` put a
    Drive on an axis; ``cone``: the half-angle [rad] the child's x axis may swing from the parent's (None: no cone)."""
    locked: tuple = ()
    limits: dict = field(default_factory=dict)
    drives: dict = field(default_factory=dict)
    cone: float | None = None

    def __post_init__(self):
        for axis in (*self.locked, *self.limits, *self.drives):
            checks.choice("axis", axis, AXES)
        for axis, drive in self.drives.items():
            if not isinstance(drive, Drive):
                raise checks.fail(f"drives[{axis!r}]", drive, "expected a ws.Drive")
        for axis, pair in self.limits.items():
            _pair(f"limits[{axis!r}]", pair, allow_reversed=True)
        if self.cone is not None:
            checks.scalar("cone", self.cone, low=0.0, high=math.pi)


@dataclass
class Joint:
    """One joint (see the module docstring), in the bodies' own frames.

    name: its USD prim name; kind: one of KINDS, or "d6"
    parent: the parent body's index, -1 for the world (or a static collider); child: the child body's index
    parent_anchor, child_anchor: the anchor in each body's frame (its centre of mass and orientation) [m]; for
        the world, in world coordinates
    parent_frame, child_frame: the joint frame's orientation in each body's frame, quaternion (x, y, z, w)
    modes: per axis of AXES, FREE, LOCKED or LIMITED (6,); lower, upper: the limits (6,) [m, rad]
    cone: the swing half-angle [rad] of a ball joint (inf: none)
    distance: (min, max) anchor distance [m] of a distance joint (inf, inf where none)
    drives: per axis, a Drive or None
    collide: whether the two bodies still collide with each other
    break_force [N], break_torque [N m]: the joint breaks when its force or torque exceeds them (inf: never)
    enabled: False: read but not simulated (UsdPhysics jointEnabled = false)
    parent_collider: where the parent is a static collider (a USD stage's), its index in scene.colliders (the
        joint is then to the world, and the child does not collide with it unless ``collide``), else -1
    """
    name: str
    kind: str
    parent: int
    child: int
    parent_anchor: np.ndarray
    child_anchor: np.ndarray
    parent_frame: np.ndarray
    child_frame: np.ndarray
    modes: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    cone: float = _UNBOUNDED
    distance: tuple = (_UNBOUNDED, _UNBOUNDED)
    drives: tuple = (None,) * 6
    collide: bool = False
    break_force: float = _UNBOUNDED
    break_torque: float = _UNBOUNDED
    enabled: bool = True
    parent_collider: int = -1


def _pair(name: str, value, allow_reversed: bool = False) -> tuple[float, float]:
    """(lower, upper) as floats, each finite or +-inf; lower <= upper unless ``allow_reversed``."""
    try:
        lower, upper = (float(v) for v in value)
    except (TypeError, ValueError):
        raise checks.fail(name, value, "expected (lower, upper)") from None
    if math.isnan(lower) or math.isnan(upper):
        raise checks.fail(name, value, "expected (lower, upper) without NaN")
    if lower > upper and not allow_reversed:
        raise checks.fail(name, value, "expected lower <= upper")
    return lower, upper


def frame_from_axis(axis) -> np.ndarray:
    """A unit quaternion (x, y, z, w) whose frame's x axis is ``axis`` (the same frame for the same axis)."""
    x = checks.unit_vec3("axis", axis) if not isinstance(axis, np.ndarray) else axis / np.linalg.norm(axis)
    helper = np.array([0.0, 1.0, 0.0]) if abs(x[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    z = np.cross(x, helper)
    z /= np.linalg.norm(z)
    y = np.cross(z, x)
    return matrix_to_quat(np.stack([x, y, z], axis=1))


def _quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def _conjugate(q: np.ndarray) -> np.ndarray:
    return np.array([-q[0], -q[1], -q[2], q[3]])


def body_pose(scene, index: int) -> tuple[np.ndarray, np.ndarray]:
    """(centre of mass [m], orientation) of body ``index`` at the start, or the world's (0, identity) for -1."""
    if index < 0:
        return np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])
    body = scene.bodies[index]
    return np.asarray(body.position, float), np.asarray(body.orientation, float)


def to_body_frame(scene, index: int, point, rotation) -> tuple[np.ndarray, np.ndarray]:
    """A world point [m] and a world orientation (x, y, z, w) in body ``index``'s frame (-1: the world)."""
    x, q = body_pose(scene, index)
    R = quat_to_matrix(q)
    return R.T @ (np.asarray(point, float) - x), _quat_multiply(_conjugate(q), np.asarray(rotation, float))


def _modes_of(kind, limits, drive) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, tuple, tuple]:
    """(modes, lower, upper, cone, distance, drives) of a kind and its limits and drive (SI)."""
    modes, lower, upper = np.full(6, LOCKED), np.zeros(6), np.zeros(6)
    cone, distance, drives = _UNBOUNDED, (_UNBOUNDED, _UNBOUNDED), [None] * 6
    if isinstance(kind, D6):
        modes[:] = FREE
        for axis in kind.locked:
            modes[AXES.index(axis)] = LOCKED
        for axis, pair in kind.limits.items():
            k = AXES.index(axis)
            lower[k], upper[k] = _pair(f"limits[{axis!r}]", pair, allow_reversed=True)
            modes[k] = LOCKED if lower[k] > upper[k] else LIMITED
        for axis, axis_drive in kind.drives.items():
            drives[AXES.index(axis)] = axis_drive
        cone = _UNBOUNDED if kind.cone is None else float(kind.cone)
        return modes, lower, upper, cone, distance, tuple(drives)
    free = {"revolute": 3, "prismatic": 0}.get(kind)
    if kind in ("ball", "distance"):
        modes[3:] = FREE
    if kind == "distance":
        modes[:3] = FREE
    if free is not None:
        modes[free] = FREE
        if limits is not None:
            lower[free], upper[free] = _pair("limits", limits)
            modes[free] = LIMITED
        drives[free] = drive
    elif drive is not None:
        raise checks.fail("drive", drive, f"a {kind} joint takes no drive (revolute and prismatic do; or use ws.D6)")
    if kind == "ball" and limits is not None:
        cone = checks.scalar("limits", limits, low=0.0, high=math.pi)
    if kind == "fixed" and limits is not None:
        raise checks.fail("limits", limits, "a fixed joint takes no limits")
    if kind == "distance" and limits is not None:
        distance = _pair("limits", limits)
        if distance[0] < 0.0:
            raise checks.fail("limits", limits, "expected distances (min, max) >= 0 [m]")
    return modes, lower, upper, cone, distance, tuple(drives)


def make_joint(scene, kind, parent, child, *, anchors, frames, limits=None, drive=None, collide=False,
               break_force=None, break_torque=None, name=None, enabled=True, parent_collider=-1) -> Joint:
    """A checked Joint: ``anchors`` and ``frames`` are (parent's, child's), each in its body's own frame;
    parent_collider: the static collider (index into scene.colliders) a world-parented joint is anchored to."""
    if not isinstance(kind, D6):
        kind = checks.choice("kind", kind, KINDS)
    count = scene.body_count
    if parent is not None and not (isinstance(parent, (int, np.integer)) and 0 <= parent < count):
        raise checks.fail("parent", parent, f"expected a body index in [0, {count}) or None for the world")
    if not (isinstance(child, (int, np.integer)) and 0 <= child < count):
        raise checks.fail("child", child, f"expected a body index in [0, {count})")
    if parent is not None and parent == child:
        raise checks.fail("child", child, "expected a body other than the parent")
    if parent_collider != -1 and (parent is not None or not 0 <= parent_collider < len(scene.colliders)):
        raise checks.fail("parent_collider", parent_collider,
                          f"expected a collider index in [0, {len(scene.colliders)}) with parent None, or -1")
    if drive is not None and not isinstance(drive, Drive):
        raise checks.fail("drive", drive, "expected a ws.Drive")
    modes, lower, upper, cone, distance, drives = _modes_of(kind, limits, drive)
    forces = []
    for label, value in (("break_force", break_force), ("break_torque", break_torque)):
        forces.append(_UNBOUNDED if value is None else checks.scalar(label, value, low=0.0, low_open=True))
    label = name or f"joint{len(scene.joints)}"
    if any(joint.name == label for joint in scene.joints):
        raise checks.fail("name", label, "joint names must be unique")
    (parent_anchor, child_anchor), (parent_frame, child_frame) = anchors, frames
    return Joint(name=label, kind=kind if isinstance(kind, str) else "d6",
                 parent=-1 if parent is None else int(parent), child=int(child),
                 parent_anchor=checks.vec3("anchor", parent_anchor), child_anchor=checks.vec3("anchor", child_anchor),
                 parent_frame=checks.unit_quaternion("frame", parent_frame),
                 child_frame=checks.unit_quaternion("frame", child_frame),
                 modes=modes, lower=lower, upper=upper, cone=cone, distance=distance, drives=drives,
                 collide=bool(collide), break_force=forces[0], break_torque=forces[1], enabled=bool(enabled),
                 parent_collider=int(parent_collider))


def world_joint(scene, kind, parent, child, *, anchor, axis=(1.0, 0.0, 0.0), orientation=None, limits=None,
                **options) -> Joint:
    """A Joint from world-space anchor(s) [m] and axis (or the joint frame's world ``orientation``) at the
    bodies' current poses; ``anchor`` is one point or (the parent's, the child's). A distance joint's limits
    default to the anchors' current distance (a rod)."""
    points = np.asarray(anchor, float)
    if points.shape == (3,):
        points = np.stack([points, points])
    if points.shape != (2, 3) or not np.all(np.isfinite(points)):
        raise checks.fail("anchor", anchor, "expected a finite point (x, y, z) [m] or two: (the parent's, the child's)")
    if orientation is None:
        frame = frame_from_axis(checks.unit_vec3("axis", axis))
    else:
        frame = checks.unit_quaternion("orientation", orientation)
    if kind == "distance" and limits is None:
        length = float(np.linalg.norm(points[1] - points[0]))
        limits = (length, length)
    parent_index = -1 if parent is None else parent
    if isinstance(parent_index, (int, np.integer)) and 0 <= parent_index < scene.body_count:
        parent_anchor, parent_frame = to_body_frame(scene, parent_index, points[0], frame)
    else:
        parent_anchor, parent_frame = points[0], frame
    if isinstance(child, (int, np.integer)) and 0 <= child < scene.body_count:
        child_anchor, child_frame = to_body_frame(scene, child, points[1], frame)
    else:
        child_anchor, child_frame = points[1], frame
    return make_joint(scene, kind, parent, child, anchors=(parent_anchor, child_anchor),
                      frames=(parent_frame, child_frame), limits=limits, **options)

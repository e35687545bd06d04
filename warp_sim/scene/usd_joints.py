"""UsdPhysics joints as ``scene.joints`` (Scene.from_usd): each schema's attributes, converted to SI and Y up.

Kinds: ``RevoluteJoint`` (a hinge, "revolute"), ``PrismaticJoint`` (a slider), ``SphericalJoint`` (a ball joint,
one cone), ``FixedJoint``, ``DistanceJoint``, and a plain ``Joint`` as a D6 whose ``PhysicsLimitAPI:<axis>`` lock
(low > high) or limit an axis (an axis without one is free) and whose ``PhysicsDriveAPI:<axis>`` drive it.

Sides: ``physics:body0`` is the parent, ``physics:body1`` the child. A side is a rigid body (the prim with
RigidBodyAPI or one inside it, as usd-core resolves it), a static collider (a CollisionAPI prim without a body, or a
disabled body's: the joint is to the world, ``Joint.parent_collider`` names the collider) or unset (the world).
When only body0 is dynamic the sides are swapped so that the child is the dynamic body: that negates every axis's
coordinate, so limits (l, u) become (-u, -l) and drive targets and velocities change sign.

Frames: ``localPos<i>``/``localRot<i>`` place the joint frame in side i's prim frame (its scale applies to the
position, not the rotation; for the world, world coordinates); ``physics:axis`` turns the frame's x axis (warp_sim's
joint axis) onto X, Y or Z. The frame is taken to world space and into each body's own frame (its centre of mass
and orientation, ``joints.to_body_frame``).

Units: angles in degrees, lengths in stage units (``metersPerUnit``), forces in kilogramsPerUnit x units/s^2 and
torques in kilogramsPerUnit x units^2/s^2; an angular drive's stiffness is per degree and its damping per degree/s
(x 180/pi for SI). What is read but not honoured is warned once per kind, naming the prims (``skipped``).
"""
from __future__ import annotations

import math

import numpy as np
from pxr import Gf, UsdGeom, UsdPhysics

from ..util.rotations import matrix_to_quat, quat_to_matrix
from . import usd_attributes, usd_values
from .joints import AXES, D6, Drive, make_joint, to_body_frame

#: the parser's joint kinds and warp_sim's (a plain UsdPhysics.Joint is usd-core's "D6Joint")
KINDS = {"RevoluteJoint": "revolute", "PrismaticJoint": "prismatic", "SphericalJoint": "ball",
         "FixedJoint": "fixed", "DistanceJoint": "distance", "D6Joint": "d6"}
#: the rotation taking the joint frame's x axis onto the schema's ``physics:axis``
AXIS_TURNS = {"X": np.eye(3), "Y": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
              "Z": np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])}
#: a hinge's and a slider's DriveAPI instance and the one axis it drives
DRIVEN = {"revolute": ("angular", "rotX"), "prismatic": ("linear", "transX")}
SIDES = ("physics:body0", "physics:body1")
VALID_SIDE = ("expected one target: a rigid body (a prim with PhysicsRigidBodyAPI, or a prim inside one), a static "
              "collider (a PhysicsCollisionAPI prim without a rigid body) or none (the world)")
FLT_MAX = float(np.finfo(np.float32).max)   # usd-core's "no limit" for a drive's maxForce


class _Side:
    """One side of a joint: its body index (-1: the world), the static collider it is anchored to (-1: none) and
    the prim whose frame its ``localPos``/``localRot`` are in (None: the world)."""

    def __init__(self, body: int = -1, collider: int = -1, prim=None):
        self.body, self.collider, self.prim = body, collider, prim


class _JointReader:
    """The joints of one stage, read into ``scene.joints`` after its bodies and colliders."""

    def __init__(self, scene, stage, time, units, descs, skipped: dict):
        self.scene, self.stage, self.time, self.units = scene, stage, time, units
        self.descs, self.skipped = descs, skipped

    def read(self) -> None:
        for path in self.descs.get("CustomJoint", {}):
            self.note("custom joints (not simulated)", path)
        joints = sorted((path, KINDS[kind], desc) for kind, descs in self.descs.items() if kind in KINDS
                        for path, desc in descs.items())
        for path, kind, desc in joints:
            self.joint(self.stage.GetPrimAtPath(path), kind, desc)

    def note(self, what: str, path) -> None:
        self.skipped.setdefault(what, []).append(str(path))

    # ---- one joint -------------------------------------------------------------------------------------------
    def joint(self, prim, kind: str, desc) -> None:
        path = prim.GetPath()
        sides = [self.side(prim, k, resolved) for k, resolved in enumerate((desc.body0, desc.body1))]
        if None in sides:
            self.note("joints to rigid bodies that are not simulated (left out)", path)
            return
        if sides[0].body < 0 and sides[1].body < 0:
            self.note("joints without a dynamic body on either side (not simulated)", path)
            return
        if sides[0].body == sides[1].body:
            raise usd_values.error(path, SIDES[1], str(prim.GetRelationship(SIDES[1]).GetTargets()[0]),
                                   "expected a body other than physics:body0's (a joint ties two bodies, or a body "
                                   "to the world)")
        axis = self.token(prim, "physics:axis", "X", tuple(AXIS_TURNS)) if kind in ("revolute", "prismatic",
                                                                                    "ball") else "X"
        frames = [self.frame(prim, k, side, AXIS_TURNS[axis]) for k, side in enumerate(sides)]
        flip = sides[1].body < 0          # swapped: the child is the dynamic body
        if flip:
            sides.reverse()
            frames.reverse()
        self.unhonoured(prim, kind)
        u = self.units
        force = u.kilograms_per_unit * u.meters_per_unit
        with usd_values.named(path):
            shape, limits, drive = self.motion(prim, kind, -1.0 if flip else 1.0)
            joint = make_joint(
                self.scene, shape, None if sides[0].body < 0 else sides[0].body, sides[1].body,
                anchors=(frames[0][0], frames[1][0]), frames=(frames[0][1], frames[1][1]), limits=limits,
                drive=drive, collide=bool(self.get(prim, "physics:collisionEnabled", False)),
                break_force=self.breaking(prim, "physics:breakForce", force, "force [kilogramsPerUnit x units/s^2]"),
                break_torque=self.breaking(prim, "physics:breakTorque", force * u.meters_per_unit,
                                           "torque [kilogramsPerUnit x units^2/s^2]"),
                name=str(path), enabled=bool(self.get(prim, "physics:jointEnabled", True)),
                parent_collider=sides[0].collider)
        self.scene.joints.append(joint)

    def side(self, prim, k: int, resolved) -> _Side | None:
        """Side ``k`` (0 or 1) of joint ``prim``, ``resolved`` being usd-core's body path for it; None for a rigid
        body warp_sim does not simulate (warned about already)."""
        relationship = prim.GetRelationship(SIDES[k])
        targets = relationship.GetTargets() if relationship else []
        if not targets:
            return _Side()
        target = self.stage.GetPrimAtPath(targets[0])
        if len(targets) > 1 or not target or not UsdGeom.Xformable(target):
            raise usd_values.error(prim.GetPath(), SIDES[k], [str(t) for t in targets], VALID_SIDE)
        usd_values.transform(target, self.time, rigid=False)
        links, here = self.scene.usd_paths, str(target.GetPath())
        body = None if resolved.isEmpty else str(resolved)
        if body in links and links[body][0] == "body":
            return _Side(body=int(links[body][1]), prim=target)
        if here in links and links[here][0] in ("collider", "plane"):
            return _Side(collider=int(links[here][1]) if links[here][0] == "collider" else -1, prim=target)
        if body is not None or target.HasAPI(UsdPhysics.RigidBodyAPI):   # a body warp_sim does not simulate
            below = sorted(p for p, (kind, _) in links.items() if kind == "collider" and
                           p.startswith((body or here) + "/"))
            return _Side(collider=int(links[below[0]][1]), prim=target) if below else None   # disabled: static
        raise usd_values.error(prim.GetPath(), SIDES[k], here, VALID_SIDE)

    def frame(self, prim, k: int, side: _Side, turn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Side ``k``'s anchor [m] and joint frame (x, y, z, w) in its body's frame (the world's for -1)."""
        path = prim.GetPath()
        position = self.get(prim, f"physics:localPos{k}", Gf.Vec3f(0.0, 0.0, 0.0))
        if not np.all(np.isfinite(list(position))):
            raise usd_values.error(path, f"physics:localPos{k}", position, "expected a finite point [stage units]")
        local = _rotation(path, f"physics:localRot{k}", self.get(prim, f"physics:localRot{k}", Gf.Quatf(1.0)))
        point = np.array(list(position), dtype=np.float64)
        if side.prim is not None:
            world = UsdGeom.Xformable(side.prim).ComputeLocalToWorldTransform(self.time)
            point = np.array(world.Transform(Gf.Vec3d(*point)))
            local = np.array(world.RemoveScaleShear().ExtractRotationMatrix()).T @ local
        return to_body_frame(self.scene, side.body, self.units.point(point),
                             matrix_to_quat(self.units.rotation(local @ turn)))

    # ---- limits and drives -----------------------------------------------------------------------------------
    def motion(self, prim, kind: str, sign: float):
        """(make_joint's kind or a D6, its limits, its drive) of joint ``prim``; ``sign`` -1: the sides swapped."""
        if kind == "d6":
            return self.d6(prim, sign), None, None
        if kind == "ball":
            return kind, self.cone(prim), None
        if kind == "distance":
            return kind, self.distance(prim), None
        if kind not in DRIVEN:
            return kind, None, None
        instance, axis = DRIVEN[kind]
        low, high = self.number(prim, "physics:lowerLimit", -math.inf), self.number(prim, "physics:upperLimit",
                                                                                    math.inf)
        if low > high:
            raise usd_values.error(prim.GetPath(), "physics:lowerLimit", low,
                                   f"expected at most physics:upperLimit ({usd_values.show(high)})")
        limits = None if (low, high) == (-math.inf, math.inf) else self.bounds(axis, low, high, sign)
        return kind, limits, self.drive(prim, instance, axis, sign)

    def scale(self, axis: str) -> float:
        """SI per schema unit of a coordinate along ``axis``: radians per degree, or metres per stage unit."""
        return math.radians(1.0) if axis.startswith("rot") else self.units.meters_per_unit

    def bounds(self, axis: str, low: float, high: float, sign: float) -> tuple[float, float]:
        """Authored limits (low, high) of ``axis`` in SI, of the coordinate ``sign`` times the authored one."""
        low, high = low * self.scale(axis), high * self.scale(axis)
        return (low, high) if sign > 0.0 else (-high, -low)

    def d6(self, prim, sign: float) -> D6:
        locked, limits, drives = [], {}, {}
        for axis in AXES:
            if prim.HasAPI(UsdPhysics.LimitAPI, axis):
                low = self.number(prim, f"limit:{axis}:physics:low", -math.inf)
                high = self.number(prim, f"limit:{axis}:physics:high", math.inf)
                if low > high:
                    locked.append(axis)
                elif (low, high) != (-math.inf, math.inf):
                    limits[axis] = self.bounds(axis, low, high, sign)
            drive = self.drive(prim, axis, axis, sign)
            if drive is not None:
                drives[axis] = drive
        return D6(locked=tuple(locked), limits=limits, drives=drives)

    def cone(self, prim) -> float | None:
        """A spherical joint's one cone [rad] (None: none); an elliptical one becomes its smaller angle, warned."""
        angles = []
        for name in ("physics:coneAngle0Limit", "physics:coneAngle1Limit"):
            value = self.number(prim, name, -1.0)
            angles.append(math.inf if value < 0.0 or value >= 180.0 else value)   # negative: not limited
        if angles[0] != angles[1]:
            self.note("elliptical cones (coneAngle0Limit and coneAngle1Limit differ: warp_sim keeps the smaller)",
                      prim.GetPath())
        return None if math.isinf(min(angles)) else math.radians(min(angles))

    def distance(self, prim) -> tuple | None:
        """A distance joint's (min, max) [m] (a negative bound is none: max inf, min 0), or None with neither."""
        low, high = (self.number(prim, name, -1.0) for name in ("physics:minDistance", "physics:maxDistance"))
        if high < 0.0 or math.isinf(high):
            return None if low <= 0.0 else (low * self.units.meters_per_unit, math.inf)
        if low > high:
            raise usd_values.error(prim.GetPath(), "physics:minDistance", low,
                                   f"expected at most physics:maxDistance ({usd_values.show(high)})")
        return max(low, 0.0) * self.units.meters_per_unit, high * self.units.meters_per_unit

    def drive(self, prim, instance: str, axis: str, sign: float) -> Drive | None:
        """The Drive of ``PhysicsDriveAPI:<instance>`` on ``axis`` in SI (None: not applied, or a maxForce of 0,
        which gives no force)."""
        if not prim.HasAPI(UsdPhysics.DriveAPI, instance):
            return None
        name = f"drive:{instance}:physics:"
        kind = self.token(prim, name + "type", "force", ("force", "acceleration"))
        target, velocity = (self.number(prim, name + key, 0.0, finite=True) for key in ("targetPosition",
                                                                                         "targetVelocity"))
        stiffness, damping = (self.number(prim, name + key, 0.0, low=0.0, finite=True) for key in ("stiffness",
                                                                                                   "damping"))
        most = self.number(prim, name + "maxForce", math.inf, low=0.0)
        if most == 0.0:
            return None
        u, angular = self.units, axis.startswith("rot")
        force = u.kilograms_per_unit * u.meters_per_unit ** (2 if angular else 1)   # [N] or [N m] per stage unit
        # an acceleration drive's gains are per unit of the axis's inertia (or mass): no mass or length in them
        gain = (u.meters_per_unit ** (0 if angular else 1) if kind == "acceleration" else force) / self.scale(axis)
        step = sign * self.scale(axis)
        return Drive(target=target * step, velocity=velocity * step, stiffness=stiffness * gain,
                     damping=damping * gain, max_force=math.inf if most >= FLT_MAX else most * force,
                     acceleration=kind == "acceleration")

    def unhonoured(self, prim, kind: str) -> None:
        """Note (warned once per kind, naming the prims) what ``prim`` authors that warp_sim does not honour."""
        applied = usd_attributes.applied_schemas(prim)
        drives = {name.split(":", 1)[1] for name in applied if name.startswith("PhysicsDriveAPI:")}
        if drives - (set(AXES) if kind == "d6" else {DRIVEN[kind][0]} if kind in DRIVEN else set()):
            self.note("drives on axes the joint does not move (ignored)", prim.GetPath())
        limits = {name.split(":", 1)[1] for name in applied if name.startswith("PhysicsLimitAPI:")}
        if limits - (set(AXES) if kind == "d6" else set()):
            self.note("limits warp_sim does not have (PhysicsLimitAPI:distance, or a LimitAPI on a revolute, "
                      "prismatic, spherical, fixed or distance joint: ignored)", prim.GetPath())
        if any(name.startswith("PhysicsJointStateAPI") for name in applied):
            self.note("joint states (PhysicsJointStateAPI ignored: the bodies start where the stage puts them)",
                      prim.GetPath())
        if any(name.startswith(usd_attributes.FOREIGN) for name in applied):   # PhysxJointAPI, mimic joints, ...
            self.note(usd_attributes.FOREIGN_NOTE, prim.GetPath())

    # ---- authored values -------------------------------------------------------------------------------------
    def get(self, prim, name: str, default):
        attribute = prim.GetAttribute(name)
        value = attribute.Get(self.time) if attribute else None
        return default if value is None else value

    def number(self, prim, name: str, default: float, low: float | None = None, finite: bool = False) -> float:
        """Attribute ``name`` of ``prim`` as a float (``default`` when unset): not NaN, >= ``low``, finite if asked."""
        value = self.get(prim, name, default)
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        if math.isnan(number) or (finite and math.isinf(number)) or (low is not None and number < low):
            valid = "expected a number" + ("" if low is None else f" >= {low:g}") + (
                ", finite" if finite else " (inf: none)")
            raise usd_values.error(prim.GetPath(), name, value, valid)
        return number

    def token(self, prim, name: str, default: str, allowed: tuple) -> str:
        value = str(self.get(prim, name, default))
        if value not in allowed:
            raise usd_values.error(prim.GetPath(), name, value, "expected one of " + ", ".join(allowed))
        return value

    def breaking(self, prim, name: str, unit: float, what: str) -> float | None:
        """A break force or torque in SI, ``unit`` being SI per stage unit (None: unbreakable, the schema's inf)."""
        value = self.number(prim, name, math.inf)
        if not value > 0.0:
            raise usd_values.error(prim.GetPath(), name, value, f"expected a {what} > 0 (inf: unbreakable)")
        return None if math.isinf(value) else value * unit


def _rotation(path, name: str, quat) -> np.ndarray:
    """A Gf quaternion (w first) as a rotation matrix; a zero or non-finite one is refused."""
    q = np.array([*quat.GetImaginary(), quat.GetReal()], dtype=np.float64)
    norm = float(np.linalg.norm(q)) if np.all(np.isfinite(q)) else math.nan
    if not norm > 1e-6:
        raise usd_values.error(path, name, quat, "expected a finite rotation quaternion (w, x, y, z), not zero")
    return quat_to_matrix(q / norm)


def read(scene, stage, time, units, descs: dict, skipped: dict) -> None:
    """Append the stage's joints to ``scene.joints`` (its bodies and colliders read already). descs: usd-core's
    parsed descriptions, kind -> path -> desc; skipped: what the reader warns of, what -> prim paths."""
    _JointReader(scene, stage, time, units, descs, skipped).read()

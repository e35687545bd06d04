"""Scene.to_usd: a Scene as a UsdPhysics stage (Y up, metres, kilograms), the inverse of Scene.from_usd.

Bodies are Xforms with RigidBodyAPI, velocities and MassAPI (mass, centre of mass, diagonal inertia, principal
axes), each with a child collision shape (Cube, Sphere, Capsule, Cylinder or Mesh, with CollisionAPI) bound to a
physics material; colliders the same without RigidBodyAPI; planes UsdGeom.Plane colliders; joints their UsdPhysics
joint prims under /World/Joints (a D6 a UsdPhysics.Joint with LimitAPI and DriveAPI per axis; angles in degrees,
an angular drive's gains per degree), localPos/localRot in the written prims' frames; cloth, particles and emitters
carry warp_sim's ``warpSim:`` attributes (usd_attributes). What UsdPhysics cannot hold (point-mass shapes, soft
bodies, springs outside a cloth, force fields, ramps, a D6's cone) is left out with one warning naming it.
"""
from __future__ import annotations

import math
import os
import warnings

import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

from ..util import checks
from ..util.rotations import matrix_to_quat, quat_to_matrix
from . import usd_attributes, usd_joints
from .joints import AXES, FREE, LIMITED, LOCKED

#: the schema each joint kind is written as
SCHEMAS = {"revolute": UsdPhysics.RevoluteJoint, "prismatic": UsdPhysics.PrismaticJoint,
           "ball": UsdPhysics.SphericalJoint, "fixed": UsdPhysics.FixedJoint, "distance": UsdPhysics.DistanceJoint,
           "d6": UsdPhysics.Joint}


def _quat(q) -> Gf.Quatf:
    return Gf.Quatf(float(q[3]), float(q[0]), float(q[1]), float(q[2]))


def _points(a) -> Vt.Vec3fArray:
    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1, 3))


def _place(prim, position, orientation) -> None:
    xform = UsdGeom.Xformable(prim)
    xform.AddTranslateOp().Set(Gf.Vec3d(*np.asarray(position, dtype=np.float64).tolist()))
    xform.AddOrientOp().Set(_quat(orientation))


class _Writer:
    def __init__(self, scene, stage):
        self.scene, self.stage = scene, stage
        self.materials: dict[tuple, UsdShade.Material] = {}
        self.left_out: dict[str, list[str]] = {}
        self.body_paths: dict[int, Sdf.Path] = {}       # body index -> its prim (the shape's frame)
        self.collider_paths: dict[int, Sdf.Path] = {}   # collider index -> its collision shape prim

    def material(self, restitution: float, friction: float) -> UsdShade.Material:
        key = (float(restitution), float(friction))
        if key not in self.materials:
            material = UsdShade.Material.Define(self.stage, f"/World/Materials/material{len(self.materials)}")
            api = UsdPhysics.MaterialAPI.Apply(material.GetPrim())
            api.CreateRestitutionAttr(key[0])
            api.CreateDynamicFrictionAttr(key[1])
            api.CreateStaticFrictionAttr(key[1])
            self.materials[key] = material
        return self.materials[key]

    def shape(self, parent: Sdf.Path, shape, restitution: float, friction: float, owner: str) -> bool:
        """A collision shape prim under ``parent`` in its frame; False when UsdPhysics has no such shape."""
        path, kind = parent.AppendChild("collision"), shape.kind
        if kind == "none":   # a body without a shape: its MassAPI alone, as UsdPhysics allows
            return True
        if kind == "box":
            cube = UsdGeom.Cube.Define(self.stage, path)
            cube.CreateSizeAttr(2.0)
            cube.AddScaleOp().Set(Gf.Vec3f(*np.asarray(shape.size, dtype=np.float64).tolist()))
        elif kind == "sphere":
            UsdGeom.Sphere.Define(self.stage, path).CreateRadiusAttr(float(shape.radius))
        elif kind in ("capsule", "cylinder"):
            prim = (UsdGeom.Capsule if kind == "capsule" else UsdGeom.Cylinder).Define(self.stage, path)
            prim.CreateAxisAttr("Y")
            prim.CreateRadiusAttr(float(shape.radius))
            prim.CreateHeightAttr(2.0 * float(shape.half_height))
        elif kind == "mesh":
            mesh = UsdGeom.Mesh.Define(self.stage, path)
            mesh.CreatePointsAttr(_points(shape.vertices))
            mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(shape.faces), 3, dtype=np.int32)))
            mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.asarray(shape.faces, dtype=np.int32).ravel()))
            UsdPhysics.MeshCollisionAPI.Apply(mesh.GetPrim()).CreateApproximationAttr("none")
        else:
            self.left_out.setdefault(f"{kind} shapes (UsdPhysics has none)", []).append(owner)
            return False
        prim = self.stage.GetPrimAtPath(path)
        UsdPhysics.CollisionAPI.Apply(prim)
        UsdShade.MaterialBindingAPI.Apply(prim).Bind(self.material(restitution, friction),
                                                     UsdShade.Tokens.weakerThanDescendants, "physics")
        return True

    def bodies(self) -> None:
        for index, body in enumerate(self.scene.bodies):
            R = quat_to_matrix(body.orientation)
            origin = body.position - R @ body.mass.com          # the shape's origin: the prim's frame
            path = Sdf.Path(f"/World/Bodies/{_identifier(body.name)}")
            prim = UsdGeom.Xform.Define(self.stage, path).GetPrim()
            _place(prim, origin, body.orientation)
            if not self.shape(path, body.shape, body.restitution, body.friction, body.name):
                self.stage.RemovePrim(path)
                continue
            self.body_paths[index] = path
            rigid = UsdPhysics.RigidBodyAPI.Apply(prim)
            mass = body.mass.mass
            rigid.CreateVelocityAttr(Gf.Vec3f(*(body.momentum / mass).tolist()))
            inertia_world = R @ body.mass.inertia @ R.T
            omega = np.linalg.solve(inertia_world, body.angular_momentum)
            rigid.CreateAngularVelocityAttr(Gf.Vec3f(*np.degrees(omega).tolist()))
            moments, axes = np.linalg.eigh(body.mass.inertia)
            if np.linalg.det(axes) < 0.0:
                axes[:, 0] = -axes[:, 0]
            api = UsdPhysics.MassAPI.Apply(prim)
            api.CreateMassAttr(mass)
            api.CreateCenterOfMassAttr(Gf.Vec3f(*body.mass.com.tolist()))
            api.CreateDiagonalInertiaAttr(Gf.Vec3f(*moments.tolist()))
            api.CreatePrincipalAxesAttr(_quat(matrix_to_quat(axes)))

    def colliders(self) -> None:
        for index, collider in enumerate(self.scene.colliders):
            path = Sdf.Path(f"/World/Colliders/{_identifier(collider.name)}")
            prim = UsdGeom.Xform.Define(self.stage, path).GetPrim()
            _place(prim, collider.position, collider.orientation)
            if self.shape(path, collider.shape, collider.restitution, collider.friction, collider.name):
                self.collider_paths[index] = path.AppendChild("collision")
            else:
                self.stage.RemovePrim(path)
        for plane in self.scene.planes:
            path = Sdf.Path(f"/World/Planes/{_identifier(plane.name)}")
            geom = UsdGeom.Plane.Define(self.stage, path)
            geom.CreateAxisAttr("Y")
            turn = _turn_y_to(plane.normal)
            _place(geom.GetPrim(), plane.normal * plane.offset, matrix_to_quat(turn))
            UsdPhysics.CollisionAPI.Apply(geom.GetPrim())
            UsdShade.MaterialBindingAPI.Apply(geom.GetPrim()).Bind(
                self.material(plane.restitution, plane.friction), UsdShade.Tokens.weakerThanDescendants, "physics")

    def joints(self) -> None:
        """Every joint as its UsdPhysics joint prim under /World/Joints (a D6 as UsdPhysics.Joint)."""
        for joint in self.scene.joints:
            sides = (self.collider_paths.get(joint.parent_collider) if joint.parent < 0 else
                     self.body_paths.get(joint.parent), self.body_paths.get(joint.child))
            if sides[1] is None or (joint.parent >= 0 and sides[0] is None):
                self.left_out.setdefault("joints to bodies left out", []).append(joint.name)
                continue
            path = Sdf.Path(f"/World/Joints/{_identifier(joint.name)}")
            while self.stage.GetPrimAtPath(path):
                path = Sdf.Path(f"{path}_")
            usd = SCHEMAS[joint.kind].Define(self.stage, path)
            for k, (index, anchor, frame, target) in enumerate((
                    (joint.parent, joint.parent_anchor, joint.parent_frame, sides[0]),
                    (joint.child, joint.child_anchor, joint.child_frame, sides[1]))):
                if target is not None:
                    (usd.CreateBody0Rel() if k == 0 else usd.CreateBody1Rel()).SetTargets([target])
                position, rotation = self.local_pose(index, anchor, frame, target)
                (usd.CreateLocalPos0Attr if k == 0 else usd.CreateLocalPos1Attr)(Gf.Vec3f(*position.tolist()))
                (usd.CreateLocalRot0Attr if k == 0 else usd.CreateLocalRot1Attr)(_quat(rotation))
            usd.CreateCollisionEnabledAttr(bool(joint.collide))
            usd.CreateJointEnabledAttr(bool(joint.enabled))
            if np.isfinite(joint.break_force):
                usd.CreateBreakForceAttr(float(joint.break_force))
            if np.isfinite(joint.break_torque):
                usd.CreateBreakTorqueAttr(float(joint.break_torque))
            self.motion(usd, joint)

    def local_pose(self, index: int, anchor, frame, target) -> tuple[np.ndarray, np.ndarray]:
        """A joint side's anchor and frame (in body ``index``'s frame, the world's for -1) in the frame of the
        written prim ``target`` (None: the world), its scale included."""
        point, rotation = np.asarray(anchor, float), quat_to_matrix(frame)
        if index >= 0:
            body = self.scene.bodies[index]
            R = quat_to_matrix(body.orientation)
            point, rotation = body.position + R @ point, R @ rotation
        if target is not None:
            prim = UsdGeom.Xformable(self.stage.GetPrimAtPath(target))
            world = prim.ComputeLocalToWorldTransform(Usd.TimeCode.Default())
            point = np.array(world.GetInverse().Transform(Gf.Vec3d(*point.tolist())))
            rotation = np.array(world.RemoveScaleShear().ExtractRotationMatrix()) @ rotation
        return point, matrix_to_quat(rotation)

    def motion(self, usd, joint) -> None:
        """A joint's limits (in degrees for angles) and drives, as its schema holds them."""
        prim = usd.GetPrim()
        if joint.kind in usd_joints.DRIVEN:
            instance, axis = usd_joints.DRIVEN[joint.kind]
            k = AXES.index(axis)
            if joint.modes[k] == LIMITED:
                for attribute, value in ((usd.CreateLowerLimitAttr, joint.lower[k]),
                                         (usd.CreateUpperLimitAttr, joint.upper[k])):
                    if np.isfinite(value):
                        attribute(float(value / _unit(axis)))
            _drive(prim, instance, axis, joint.drives[k])
        elif joint.kind == "ball" and np.isfinite(joint.cone):
            usd.CreateConeAngle0LimitAttr(float(np.degrees(joint.cone)))
            usd.CreateConeAngle1LimitAttr(float(np.degrees(joint.cone)))
        elif joint.kind == "distance":
            low, high = joint.distance
            if np.isfinite(high):
                usd.CreateMaxDistanceAttr(float(high))
                if low > 0.0:
                    usd.CreateMinDistanceAttr(float(low))
        elif joint.kind == "d6":
            for k, axis in enumerate(AXES):
                if joint.modes[k] != FREE:
                    limit = UsdPhysics.LimitAPI.Apply(prim, axis)
                    locked = joint.modes[k] == LOCKED
                    limit.CreateLowAttr(1.0 if locked else float(joint.lower[k] / _unit(axis)))
                    limit.CreateHighAttr(-1.0 if locked else float(joint.upper[k] / _unit(axis)))
                _drive(prim, axis, axis, joint.drives[k])
            if np.isfinite(joint.cone):
                self.left_out.setdefault("the cones of D6 joints (UsdPhysics.Joint has none)", []).append(joint.name)

    def particles(self) -> None:
        scene = self.scene
        x, v = scene.particle_array("position"), scene.particle_array("velocity")
        mass, radius = scene.particle_array("mass"), scene.particle_array("radius")
        pinned = scene.particle_array("pinned")
        in_mesh = {(mesh.start, mesh.count) for mesh in scene.meshes}
        for mesh in scene.meshes:
            self.cloth(mesh, x, mass, pinned)
        for group in scene.particle_groups:
            if group.pooled or (group.start, group.count) in in_mesh:
                continue
            span = slice(group.start, group.start + group.count)
            points = UsdGeom.Points.Define(self.stage, f"/World/Particles/{_identifier(group.name)}")
            points.CreatePointsAttr(_points(x[span]))
            points.CreateVelocitiesAttr(_points(v[span]))
            points.CreateWidthsAttr(Vt.FloatArray.FromNumpy(np.ascontiguousarray(2.0 * radius[span], dtype=np.float32)))
            values = {"mass": mass[span].tolist(), "pinned": np.flatnonzero(pinned[span]).tolist() or None}
            restitution, friction = scene.particle_array("restitution")[span], scene.particle_array("friction")[span]
            if restitution[0] >= 0.0:
                values["restitution"] = float(restitution[0])
            if friction[0] >= 0.0:
                values["friction"] = float(friction[0])
            prim = points.GetPrim()
            prim.CreateAttribute(usd_attributes.PARTICLES, Sdf.ValueTypeNames.Bool, custom=True).Set(True)
            usd_attributes.write(prim, usd_attributes.PARTICLE_ATTRIBUTES, values)
        if scene.spring_count > sum(sum(len(s) for s in mesh.springs.values()) for mesh in scene.meshes):
            self.left_out.setdefault("springs outside a cloth", []).append("the scene's springs")
        if scene.fields:
            self.left_out.setdefault("force fields", []).extend(type(f).__name__ for f in scene.fields)

    def cloth(self, mesh, x, mass, pinned) -> None:
        span = slice(mesh.start, mesh.start + mesh.count)
        if set(mesh.springs) != {"structural", "shear", "bend"}:
            self.left_out.setdefault("soft bodies", []).append(mesh.name)
            return
        geom = UsdGeom.Mesh.Define(self.stage, f"/World/Meshes/{_identifier(mesh.name)}")
        geom.CreatePointsAttr(_points(x[span]))
        geom.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.asarray(mesh.face_counts, dtype=np.int32)))
        geom.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.asarray(mesh.face_indices, dtype=np.int32)))
        springs = self.scene
        families = ("structural", "shear", "bend")

        def family(key):
            return tuple(float(springs.spring_array(key)[mesh.springs[name][0]]) if len(mesh.springs[name]) else 0.0
                         for name in families)
        values = {"mass": float(mass[span].sum()), "stiffness": family("stiffness"), "damping": family("damping"),
                  "pinned": np.flatnonzero(pinned[span]).tolist() or None, "drag": mesh.drag or None,
                  "lift": mesh.lift or None, "max_stretch": mesh.max_stretch,
                  "radius": float(self.scene.particle_array("radius")[mesh.start])}
        prim = geom.GetPrim()
        prim.CreateAttribute(usd_attributes.CLOTH, Sdf.ValueTypeNames.Bool, custom=True).Set(True)
        usd_attributes.write(prim, usd_attributes.CLOTH_ATTRIBUTES, values)

    def emitters(self) -> None:
        for e in self.scene.emitters:
            xform = UsdGeom.Xform.Define(self.stage, f"/World/Emitters/{_identifier(e.name)}")
            _place(xform.GetPrim(), e.position, matrix_to_quat(_turn_y_to(e.direction)))
            values = {"rate": e.rate, "lifetime": tuple(e.lifetime), "speed": tuple(e.speed), "spread": e.spread,
                      "size": tuple(e.size), "mass": tuple(e.mass), "shape": e.shape, "seed": e.seed}
            if e.shape in ("disc", "sphere", "ball"):
                values["radius"] = float(e.extent[0])
            prim = xform.GetPrim()
            prim.CreateAttribute(usd_attributes.EMITTER, Sdf.ValueTypeNames.Bool, custom=True).Set(True)
            usd_attributes.write(prim, usd_attributes.EMITTER_ATTRIBUTES, values)
            if e.bursts or e.size_ramp is not None or e.color[2] is not None or e.opacity[2] is not None:
                self.left_out.setdefault("emitter bursts and ramps", []).append(e.name)


def _turn_y_to(direction) -> np.ndarray:
    """A rotation taking +Y onto the unit vector ``direction``."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    y = np.array([0.0, 1.0, 0.0])
    axis = np.cross(y, d)
    s, c = np.linalg.norm(axis), float(y @ d)
    if s < 1e-12:
        return np.eye(3) if c > 0.0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def _unit(axis: str) -> float:
    """SI per written unit of a coordinate along ``axis``: radians per degree for a rotation, else 1 (metres)."""
    return math.radians(1.0) if axis.startswith("rot") else 1.0


def _drive(prim, instance: str, axis: str, drive) -> None:
    """``PhysicsDriveAPI:<instance>`` of a Drive on ``axis`` (nothing for None): an angle's target in degrees, its
    stiffness per degree and damping per degree/s."""
    if drive is None:
        return
    unit = _unit(axis)
    api = UsdPhysics.DriveAPI.Apply(prim, instance)
    api.CreateTypeAttr("acceleration" if drive.acceleration else "force")
    api.CreateTargetPositionAttr(float(drive.target / unit))
    api.CreateTargetVelocityAttr(float(drive.velocity / unit))
    api.CreateStiffnessAttr(float(drive.stiffness * unit))
    api.CreateDampingAttr(float(drive.damping * unit))
    if np.isfinite(drive.max_force):
        api.CreateMaxForceAttr(float(drive.max_force))


def _identifier(name: str) -> str:
    return Tf.MakeValidIdentifier(str(name))   # the rule the stage writer names its prims by


def write(scene, path) -> str:
    """Scene.to_usd (see there)."""
    if not isinstance(path, (str, os.PathLike)) or not str(path).endswith((".usd", ".usda", ".usdc")):
        raise checks.fail("path", path, "expected a file path ending in .usd, .usda or .usdc")
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    physics = UsdPhysics.Scene.Define(stage, "/World/PhysicsScene")
    magnitude = float(np.linalg.norm(scene.gravity))
    physics.CreateGravityMagnitudeAttr(magnitude)
    physics.CreateGravityDirectionAttr(Gf.Vec3f(*(scene.gravity / magnitude if magnitude else np.zeros(3)).tolist()))
    writer = _Writer(scene, stage)
    writer.bodies()
    writer.colliders()
    writer.joints()
    writer.particles()
    writer.emitters()
    for what, names in writer.left_out.items():
        warnings.warn(f"Scene.to_usd: {what} left out: {', '.join(names)}", UserWarning, stacklevel=3)
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    if not stage.GetRootLayer().Export(os.fspath(path)):
        raise OSError(f"cannot write {os.fspath(path)!r}")
    return os.fspath(path)

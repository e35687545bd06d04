"""Scene.from_usd: a stage's UsdPhysics description (and warp_sim's own ``warpSim:`` attributes) as a Scene.

The schema's rules are usd-core's: its parser (``UsdPhysics.LoadUsdPhysicsFromRange``) resolves bodies, shapes with
their scaled sizes and poses relative to their body, materials and the physics scene with its defaults, and its
``RigidBodyAPI.ComputeMassProperties`` applies the precedence of mass, density and materials, with warp_sim's shapes
supplying each shape's volume, inertia and centre of mass; joints are read by ``usd_joints``. Everything is converted
to SI and Y up (``usd_units.StageUnits``); ``scene.usd_source`` keeps what the way back needs (``stages.overlay``).
"""
from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, field

import numpy as np
import trimesh
from pxr import Gf, Usd, UsdGeom, UsdPhysics

from ..util import checks
from ..util.rotations import matrix_to_quat
from . import usd_attributes, usd_bodies, usd_geometry, usd_joints, usd_values
from .shapes import Box, Capsule, Cylinder, MeshShape, Sphere
from .usd_units import StageUnits

EARTH_GRAVITY = 9.80665   # [m/s^2], the schema's default magnitude
DEFAULT_DENSITY = 1000.0   # [kg/m^3], the schema's default
# the rotation taking warp_sim's capsule and cylinder axis (Y) onto the schema's axis
AXIS_ROTATIONS = {"X": np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), "Y": np.eye(3),
                  "Z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])}
SHAPE_TYPES = {"CubeShape", "SphereShape", "CapsuleShape", "CylinderShape", "MeshShape", "PlaneShape"}
UNSUPPORTED = {"ConeShape": "cone shapes", "CustomShape": "custom shapes", "SpherePointsShape": "sphere points",
               "Capsule1Shape": "capsules with two radii", "Cylinder1Shape": "cylinders with two radii",
               "CollisionGroup": "collision groups"}


@dataclass
class PrimLink:
    """How a simulated prim maps to the scene, and back.

    path: the prim's path; kind: "body", "collider", "cloth" or "particles"; index: the body or collider index,
    or the particle ids; offset: the shape's frame in the prim's frame (rotation (3, 3), position (3,) [m]) for
    bodies; world: the prim's local-to-world matrix at the read time (4, 4), stage units, column vectors;
    parent: its parent's (4, 4); scale: its authored local scale (3,); pooled: an emitter's pool; kinematic: a
    kinematic body (its own animation drives it, so the overlay leaves it alone)
    """
    path: str
    kind: str
    index: object
    world: np.ndarray
    parent: np.ndarray
    scale: np.ndarray
    offset: tuple = (np.eye(3), np.zeros(3))
    pooled: bool = False
    kinematic: bool = False


@dataclass
class UsdSource:
    """The stage a Scene was read from: its file (None for an in-memory stage), units, time base and the links."""
    path: str | None
    units: StageUnits
    time_codes_per_second: float
    start_time_code: float
    links: list[PrimLink] = field(default_factory=list)


def _matrix(gf) -> np.ndarray:
    """A Gf.Matrix4d (row vectors) as a numpy (4, 4) for column vectors."""
    return np.array(gf, dtype=np.float64).T


def _rotation(quat) -> np.ndarray:
    q = Gf.Rotation(Gf.Quatd(quat.GetReal(), Gf.Vec3d(quat.GetImaginary())))
    return np.array(Gf.Matrix3d(q), dtype=np.float64).T


def _rigid(world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, translation) of a local-to-world matrix (column vectors), its scale taken out (polar part)."""
    U, _, Vh = np.linalg.svd(world[:3, :3])
    return U @ Vh, world[:3, 3].copy()


def _vec(v) -> np.ndarray:
    return np.array(list(v), dtype=np.float64)


class _Reader:
    def __init__(self, scene_class, source, time, precision):
        self.stage, self.file = _open(source)
        self.time = Usd.TimeCode.Default() if time is None else Usd.TimeCode(time)
        stage = self.stage
        self.precision = checks.choice("precision", precision, tuple(checks.LARGEST))
        self.units = usd_values.stage_units(stage, self._name())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)   # the new name takes other arguments
            parsed = UsdPhysics.LoadUsdPhysicsFromRange(stage, ["/"])
        self.descs = {}
        for kind, (paths, descs) in parsed.items():
            for path, desc in zip(paths, descs):
                self.descs.setdefault(kind.name, {})[str(path)] = desc
        self.scene = scene_class(gravity=self._gravity(), precision=precision)
        self.source = UsdSource(self.file, self.units, stage.GetTimeCodesPerSecond(), stage.GetStartTimeCode())
        self.skipped: dict[str, list[str]] = {}
        self.friction_warned = False

    def _gravity(self) -> np.ndarray:
        scenes = self.descs.get("Scene", {})
        if not scenes:
            warnings.warn(f"{self._name()}: no UsdPhysics.Scene, so Earth's gravity ({EARTH_GRAVITY} m/s^2) acts "
                          "against the up axis", UserWarning, stacklevel=4)
            return np.array([0.0, -EARTH_GRAVITY, 0.0])
        path, desc = next(iter(scenes.items()))
        usd_values.gravity(self.stage.GetPrimAtPath(path), self.units, self.precision)
        return self.units.direction(_vec(desc.gravityDirection)) * self.units.length(desc.gravityMagnitude)

    def _name(self) -> str:
        return repr(self.file) if self.file else "the stage"

    # ---- shapes ------------------------------------------------------------------------------------------------
    def _shape(self, kind: str, desc, prim_path: str, static: bool = False):
        """(warp_sim shape, its frame in the body's or world's frame (R, p [m])) of a shape desc (``static``: a
        static collider's), or None."""
        u = self.units
        R, p = _rotation(desc.localRot), u.length(_vec(desc.localPos))
        # sizes are the magnitudes: the values were checked (usd_values); usd-core puts a mirror in the signs of all
        # three scales with a turn by 180 degrees in the rotation, and a box, sphere, capsule or cylinder is its own
        # mirror image (a mesh takes the signs: usd_geometry)
        with usd_values.named(prim_path):
            if kind == "CubeShape":
                return Box(u.length(np.abs(_vec(desc.halfExtents)))), R, p
            if kind == "SphereShape":
                return Sphere(float(u.length(abs(desc.radius)))), R, p
            if kind in ("CapsuleShape", "CylinderShape"):
                make = Capsule if kind == "CapsuleShape" else Cylinder
                return (make(float(u.length(abs(desc.radius))), float(u.length(abs(desc.halfHeight)))),
                        R @ AXIS_ROTATIONS[str(desc.axis).rsplit(".", 1)[-1]], p)
            if kind == "MeshShape":
                return usd_geometry.mesh_shape(self.stage.GetPrimAtPath(prim_path), self.time, _vec(desc.meshScale),
                                               u, (R, p), static, self.skipped)
        return None

    def _check_shape(self, path: str) -> None:
        """A body's or collider's shape prim: its transform (not mirrored), its own attributes and its MassAPI."""
        prim = self.stage.GetPrimAtPath(path)
        usd_values.transform(prim, self.time, rigid=True)
        usd_values.shape(prim, self.time)
        usd_values.mass(prim, self.time)

    def _material(self, desc) -> tuple[float, float, float | None]:
        """(restitution, friction, density [kg/m^3] or None) of a shape's bound physics material: usd-core's binding,
        or a material:binding:physics without MaterialBindingAPI, read as PhysX reads it (warned once)."""
        materials = self.descs.get("RigidBodyMaterial", {})
        paths = [str(path) for path in desc.materials if str(path) in materials]
        if not paths:
            bound, binder = usd_bodies.bound_material(self.stage.GetPrimAtPath(str(desc.primPath)))
            paths = [str(bound.GetPath())] if bound is not None else []
            if binder is not None:
                self.skipped.setdefault(usd_bodies.UNBOUND_NOTE, []).append(str(binder.GetPath()))
        for path in paths:
            material = materials.get(str(path))
            if material is not None:
                usd_values.material(self.stage.GetPrimAtPath(path))
                if material.staticFriction != material.dynamicFriction and not self.friction_warned:
                    self.friction_warned = True
                    warnings.warn(f"{self._name()}: material {path} has staticFriction {material.staticFriction:g} "
                                  f"and dynamicFriction {material.dynamicFriction:g}; warp_sim has one Coulomb "
                                  "coefficient and uses the dynamic one (said once)", UserWarning, stacklevel=5)
                density = material.density * self.units.kilograms_per_unit / self.units.meters_per_unit ** 3
                return float(material.restitution), float(material.dynamicFriction), density or None
        return 0.0, 0.5, None

    def _all_shapes(self) -> dict[str, tuple[str, object]]:
        return {path: (kind, desc) for kind in SHAPE_TYPES for path, desc in self.descs.get(kind, {}).items()}

    # ---- bodies -------------------------------------------------------------------------------------------------
    def bodies(self) -> None:
        shapes = self._all_shapes()
        for path, desc in self.descs.get("RigidBody", {}).items():
            parts = [(str(p), *shapes[str(p)]) for p in desc.collisions if str(p) in shapes]
            enabled = [(p, kind, d) for p, kind, d in parts if d.collisionEnabled]
            if not desc.rigidBodyEnabled:
                for shape_path, kind, shape_desc in enabled:
                    self._collider(shape_path, kind, shape_desc, body=desc)
                continue
            if not enabled and len(parts) < len(list(desc.collisions)):   # cones, custom shapes: warned as such
                self.skipped.setdefault("rigid bodies whose only collision shapes are not simulated (left out)",
                                        []).append(path)
                continue
            self._body(path, desc, parts, enabled)

    def _body(self, path: str, desc, parts, enabled) -> None:
        """One dynamic body: collision shapes from ``enabled``, mass from usd-core over every shape of ``parts``
        (it leaves out a shape whose collisions are disabled, so warp_sim does too); without an enabled shape, a
        body that collides with nothing, its mass from its MassAPI (usd_bodies)."""
        u = self.units
        prim = self.stage.GetPrimAtPath(path)
        usd_values.transform(prim, self.time, rigid=True)
        usd_values.body(prim, self.time)
        usd_values.mass(prim, self.time)
        for shape_path, _, _ in parts:
            self._check_shape(shape_path)
        built = {}
        for shape_path, kind, shape_desc in parts:
            made = self._shape(kind, shape_desc, shape_path)
            if made is None or (isinstance(made[0], MeshShape) and not made[0].solid):
                self.skipped.setdefault("dynamic bodies with open meshes or planes (need a closed shape: author "
                                        "physics:approximation = 'convexHull' on the mesh)", []).append(path)
                return
            built[shape_path] = made
        if enabled:
            restitution, friction, _ = self._material(enabled[0][2])
            values = usd_bodies.computed(prim, self.time, built, u,
                                         unbound=[p for p, _, d in parts if not list(d.materials)])
            colliding = [built[shape_path] for shape_path, _, _ in enabled]
            if len(colliding) == 1:
                shape, Rs, ps = colliding[0]
            else:   # a compound: its parts' surfaces in the body's frame, one closed mesh
                shape, Rs, ps = _compound(colliding), np.eye(3), np.zeros(3)
            source = "usd-core's mass computation from its MassAPI and its collision shapes"
        else:   # no collider: a body that collides with nothing (a joint's anchor), its mass its MassAPI's
            restitution, friction = 0.0, 0.5
            values = usd_bodies.without_collider(prim, self.time, u, self.skipped)
            shape, Rs, ps = None, np.eye(3), np.zeros(3)
            source = "its PhysicsMassAPI, as it has no enabled collider"
        properties = usd_bodies.properties(path, values, u, Rs, ps, source)
        rotation, position = _rigid(_matrix(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(self.time)))
        R_world = u.rotation(rotation)             # from the prim's xform in double (the desc's pose is float)
        origin = u.point(position) + R_world @ ps
        parent = _matrix(UsdGeom.Xformable(prim).ComputeParentToWorldTransform(self.time))
        to_world = u.C @ parent[:3, :3] / np.cbrt(max(abs(np.linalg.det(parent[:3, :3])), 1e-300))
        velocity = to_world @ _vec(desc.linearVelocity) * u.meters_per_unit
        spin = to_world @ np.radians(_vec(desc.angularVelocity))
        track = self._track(prim, Rs, ps) if desc.kinematicBody else None
        with usd_values.named(path, {"position": "xformOp:translate", "linear_velocity": "physics:velocity",
                                     "angular_velocity": "physics:angularVelocity", "mass": "physics:mass",
                                     "inertia": "physics:diagonalInertia"}):
            index = self.scene.add_rigid_body(shape, mass_properties=properties, position=origin,
                                              orientation=matrix_to_quat(R_world @ Rs), linear_velocity=velocity,
                                              angular_velocity=spin, restitution=restitution, friction=friction,
                                              name=usd_attributes.unique(prim.GetName(), self.scene.bodies),
                                              kinematic=track)
        self._link(path, "body", index, offset=(Rs, ps), kinematic=desc.kinematicBody)

    def _track(self, prim, Rs, ps) -> tuple:
        """A kinematic body's keys: its prim's world pose at every time sample of its and its ancestors' xforms
        (seconds from the stage's start), as the shape's origin and orientation in warp_sim's frame."""
        times = set()
        for ancestor in prim.GetPath().GetAncestorsRange():
            xformable = UsdGeom.Xformable(self.stage.GetPrimAtPath(ancestor))
            if xformable:
                times.update(xformable.GetTimeSamples())
        codes = sorted(times) or [self.time.GetValue() if not self.time.IsDefault() else 0.0]
        keys, positions, orientations = [], [], []
        xformable = UsdGeom.Xformable(prim)
        for code in codes:
            usd_values.transform(prim, Usd.TimeCode(code), rigid=True, when=f" at time code {code:g}")
            rotation, position = _rigid(_matrix(xformable.ComputeLocalToWorldTransform(Usd.TimeCode(code))))
            R = self.units.rotation(rotation)
            keys.append((code - self.source.start_time_code) / self.source.time_codes_per_second)
            positions.append(self.units.point(position) + R @ ps)
            orientations.append(matrix_to_quat(R @ Rs))
        return keys, positions, orientations

    # ---- static colliders ----------------------------------------------------------------------------------------
    def colliders(self) -> None:
        for path, (kind, desc) in self._all_shapes().items():
            if desc.rigidBody.isEmpty and desc.collisionEnabled:
                self._collider(path, kind, desc)

    def _collider(self, path: str, kind: str, desc, body=None) -> None:
        u = self.units
        self._check_shape(path)
        restitution, friction, _ = self._material(desc)
        R_body = np.eye(3) if body is None else _rotation(body.rotation)
        p_body = np.zeros(3) if body is None else _vec(body.position)
        if kind == "PlaneShape":
            axis = str(desc.axis).rsplit(".", 1)[-1]
            normal_stage = R_body @ _rotation(desc.localRot)[:, "XYZ".index(axis)]
            point = u.point(p_body + R_body @ _vec(desc.localPos))
            normal = u.direction(normal_stage)
            with usd_values.named(path, {"offset": "xformOp:translate"}):
                index = self.scene.add_plane(normal, float(normal @ point), restitution, friction,
                                             name=usd_attributes.unique(self.stage.GetPrimAtPath(path).GetName(),
                                                                        self.scene.planes))
            self._link(path, "plane", index)
            return
        made = self._shape(kind, desc, path, static=True)
        if made is None:
            return
        shape, Rs, ps = made
        if body is not None:
            Rs, ps = u.rotation(R_body) @ Rs, u.point(p_body) + u.rotation(R_body) @ ps
        else:   # the shape's frame is in the stage's world: turn it to warp_sim's axes (its length already scaled)
            Rs, ps = u.rotation(Rs), u.C @ ps
        with usd_values.named(path, {"position": "xformOp:translate"}):
            index = self.scene.add_collider(shape, position=ps, orientation=matrix_to_quat(Rs),
                                            restitution=restitution, friction=friction,
                                            name=usd_attributes.unique(self.stage.GetPrimAtPath(path).GetName(),
                                                                       self.scene.colliders))
        self._link(path, "collider", index)

    # ---- everything else ----------------------------------------------------------------------------------------
    def others(self) -> None:
        for kind, descs in self.descs.items():
            if kind in UNSUPPORTED:
                self.skipped.setdefault(UNSUPPORTED[kind] + " (not simulated)", []).extend(descs)
        filtered = sorted({str(d.primPath) for descs in self.descs.values() for d in descs.values()
                           if list(getattr(d, "filteredCollisions", []) or [])})
        if filtered:
            self.skipped.setdefault("filtered collision pairs (they collide here)", []).extend(filtered)
        noted = self.skipped.pop(usd_attributes.FOREIGN_NOTE, [])   # the joints' (found again below)
        foreign = {str(path): [] for path in noted}
        for prim in self.stage.Traverse(Usd.TraverseInstanceProxies()):   # the raw apiSchemas: unregistered ones too
            names = [name for name in usd_attributes.applied_schemas(prim) if name.startswith(usd_attributes.FOREIGN)]
            if names:
                foreign[str(prim.GetPath())] = names
        if foreign:
            self.skipped[usd_attributes.FOREIGN_NOTE] = [f"{path} ({', '.join(names)})" if names else path
                                                         for path, names in foreign.items()]

    def warn_skipped(self) -> None:
        for what, paths in self.skipped.items():
            shown = sorted(set(paths))
            more = f" and {len(shown) - 5} more" if len(shown) > 5 else ""
            warnings.warn(f"{self._name()}: {what}: {', '.join(shown[:5])}{more}", UserWarning, stacklevel=4)

    def _link(self, path: str, kind: str, index, offset=None, pooled: bool = False, kinematic: bool = False) -> None:
        prim = self.stage.GetPrimAtPath(path)
        xformable = UsdGeom.Xformable(prim)
        world = _matrix(xformable.ComputeLocalToWorldTransform(self.time))
        parent = _matrix(xformable.ComputeParentToWorldTransform(self.time))
        local = np.linalg.inv(parent) @ world
        scale = np.linalg.norm(local[:3, :3], axis=0)
        link = PrimLink(path, kind, index, world, parent, scale, pooled=pooled, kinematic=kinematic)
        if offset is not None:
            link.offset = offset
        self.source.links.append(link)
        self.scene.usd_paths[path] = (kind, index)


def _open(source):
    if isinstance(source, Usd.Stage):
        layer = source.GetRootLayer()
        return source, (layer.realPath or None)
    if not isinstance(source, (str, os.PathLike)):
        raise checks.fail("path_or_stage", source, "expected a USD file path or a pxr.Usd.Stage")
    path = os.fspath(source)
    if not os.path.isfile(path):
        raise checks.fail("path_or_stage", path, "no such file")
    try:
        stage = Usd.Stage.Open(path)
    except Exception as error:   # pxr.Tf.ErrorException
        raise checks.fail("path_or_stage", path, f"cannot be read as USD ({str(error).strip().splitlines()[-1]})") \
            from None
    return stage, os.path.abspath(path)


def _compound(parts) -> MeshShape:
    """Several shapes of one body, each at its frame (R, p) in the body's frame, as one closed mesh (the union of
    their closed surfaces; its contacts follow every part's surface, its mass properties are set separately)."""
    meshes = []
    for shape, R, p in parts:
        surface = _surface(shape)
        surface.apply_transform(np.block([[R, p[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
        meshes.append(surface)
    return MeshShape(trimesh.util.concatenate(meshes), solid=True)


def _surface(shape) -> trimesh.Trimesh:
    if isinstance(shape, MeshShape):
        return trimesh.Trimesh(shape.vertices, shape.faces, process=False)
    if isinstance(shape, Box):
        return trimesh.creation.box(extents=2.0 * np.asarray(shape.size))
    if isinstance(shape, Sphere):
        return trimesh.creation.icosphere(3, radius=shape.radius)
    turn = trimesh.transformations.rotation_matrix(-math.pi / 2.0, (1.0, 0.0, 0.0))   # trimesh's Z to our Y
    if isinstance(shape, Capsule):
        return trimesh.creation.capsule(2.0 * shape.half_height, shape.radius, count=[16, 16]).apply_transform(turn)
    return trimesh.creation.cylinder(shape.radius, 2.0 * shape.half_height, sections=32).apply_transform(turn)


def read(scene_class, source, time=0, precision: str = "float32"):
    """Scene.from_usd (see there)."""
    reader = _Reader(scene_class, source, time, precision)
    reader.scene.usd_source = reader.source
    reader.bodies()
    reader.colliders()
    usd_attributes.read(reader.scene, reader.stage, reader.time, reader.units, reader._link)
    usd_joints.read(reader.scene, reader.stage, reader.time, reader.units, reader.descs, reader.skipped)
    reader.others()
    reader.warn_skipped()
    scene = reader.scene
    if scene.body_count == 0 and scene.particle_count == 0 and not scene.emitters:
        raise checks.fail("path_or_stage", reader.file or "<stage>",
                          "has nothing to simulate: no enabled rigid body (PhysicsRigidBodyAPI), no warpSim:cloth "
                          "mesh, warpSim:particles points or warpSim:emitter")
    return scene

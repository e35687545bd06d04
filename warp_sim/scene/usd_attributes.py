"""warp_sim's own attributes on USD prims (the ``warpSim:`` namespace): cloth on a Mesh, particles on Points, an
emitter on an Xform. Read by Scene.from_usd, written by Scene.to_usd; documented in docs/usd.md. Also which API
schemas a prim has applied, other solvers' included (``applied_schemas``).

Geometry (points, velocities, widths, the prim's transform) is in the stage's units and axes like any USD data;
the ``warpSim:`` values are SI (kg, kg/m^2, N/m, N s/m, m, s, degrees for a cone's spread).
"""
from __future__ import annotations

import numpy as np
import trimesh
from pxr import Sdf, UsdGeom

from . import usd_values

CLOTH, PARTICLES, EMITTER = "warpSim:cloth", "warpSim:particles", "warpSim:emitter"
FOREIGN = ("Physx", "Newton", "Mujoco")   # other solvers' schema prefixes: read by them, not here
FOREIGN_NOTE = "other solvers' schemas (ignored)"   # Scene.from_usd's one warning of them, naming the prims
# name -> (Sdf type, the add_* keyword it feeds)
CLOTH_ATTRIBUTES = {"warpSim:mass": (Sdf.ValueTypeNames.Float, "mass"),
                    "warpSim:density": (Sdf.ValueTypeNames.Float, "density"),
                    "warpSim:stiffness": (Sdf.ValueTypeNames.Float3, "stiffness"),
                    "warpSim:damping": (Sdf.ValueTypeNames.Float3, "damping"),
                    "warpSim:pinned": (Sdf.ValueTypeNames.IntArray, "pinned"),
                    "warpSim:drag": (Sdf.ValueTypeNames.Float, "drag"),
                    "warpSim:lift": (Sdf.ValueTypeNames.Float, "lift"),
                    "warpSim:maxStretch": (Sdf.ValueTypeNames.Float, "max_stretch"),
                    "warpSim:radius": (Sdf.ValueTypeNames.Float, "radius")}
PARTICLE_ATTRIBUTES = {"warpSim:mass": (Sdf.ValueTypeNames.FloatArray, "mass"),
                       "warpSim:pinned": (Sdf.ValueTypeNames.IntArray, "pinned"),
                       "warpSim:restitution": (Sdf.ValueTypeNames.Float, "restitution"),
                       "warpSim:friction": (Sdf.ValueTypeNames.Float, "friction")}
EMITTER_ATTRIBUTES = {"warpSim:rate": (Sdf.ValueTypeNames.Float, "rate"),
                      "warpSim:lifetime": (Sdf.ValueTypeNames.Float2, "lifetime"),
                      "warpSim:speed": (Sdf.ValueTypeNames.Float2, "speed"),
                      "warpSim:spread": (Sdf.ValueTypeNames.Float, "spread"),
                      "warpSim:size": (Sdf.ValueTypeNames.Float2, "size"),
                      "warpSim:mass": (Sdf.ValueTypeNames.Float2, "mass"),
                      "warpSim:shape": (Sdf.ValueTypeNames.Token, "shape"),
                      "warpSim:radius": (Sdf.ValueTypeNames.Float, "radius"),
                      "warpSim:seed": (Sdf.ValueTypeNames.Int, "seed")}


def applied_schemas(prim) -> list[str]:
    """The API schemas applied to ``prim``, as authored in its composed ``apiSchemas`` metadata, with those usd-core
    has no definition of (``PhysxRigidBodyAPI``, ``NewtonXxxAPI``, ``PhysicsJointStateAPI:angular``), which
    ``prim.GetAppliedSchemas()`` leaves out."""
    authored = prim.GetPrimTypeInfo().GetAppliedAPISchemas()
    return list(dict.fromkeys(str(name) for name in [*prim.GetAppliedSchemas(), *authored]))


def triangles(mesh, time) -> np.ndarray:
    """A UsdGeom.Mesh's faces as triangles (each polygon a fan from its first corner), (F, 3); its points and faces
    checked first (usd_values.mesh_faces: a ValueError naming the prim and the attribute)."""
    _, counts, indices = usd_values.mesh_faces(mesh.GetPrim(), time)
    faces, start = [], 0
    for count in counts:
        ring = indices[start:start + count]
        faces.extend((ring[0], ring[k], ring[k + 1]) for k in range(1, count - 1))
        start += count
    return np.array(faces, dtype=np.int64).reshape(-1, 3)


def _values(prim, names, time) -> dict:
    """The add_* keywords of the authored attributes among ``names``."""
    found = {}
    for name, (_, keyword) in names.items():
        attribute = prim.GetAttribute(name)
        if attribute and attribute.HasAuthoredValue():
            value = attribute.Get(time)
            if isinstance(value, str):
                found[keyword] = value
            elif np.ndim(value) == 0 and not hasattr(value, "__len__"):
                found[keyword] = value.item() if isinstance(value, np.generic) else value
            else:
                found[keyword] = np.array(value).tolist()
    return found


def _flag(prim, name: str) -> bool:
    attribute = prim.GetAttribute(name)
    return bool(attribute and attribute.Get())


def _world_points(prim, points, time, units) -> np.ndarray:
    world = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64)  # row vectors
    homogeneous = np.hstack([np.asarray(points, dtype=np.float64), np.ones((len(points), 1))])
    return units.point((homogeneous @ world)[:, :3])


def _names(attributes: dict) -> dict:
    """add_* keyword -> the warpSim attribute that feeds it, for errors in the stage's terms."""
    return {keyword: name for name, (_, keyword) in attributes.items()}


def read(scene, stage, time, units, link) -> None:
    """Add every warpSim cloth mesh, particle set and emitter of ``stage`` to ``scene``; ``link(path, kind, index)``
    records each. A bad value is a ValueError naming the prim and the attribute (usd_values)."""
    for prim in stage.Traverse():
        path = prim.GetPath()
        if prim.IsA(UsdGeom.Mesh) and _flag(prim, CLOTH):
            usd_values.transform(prim, time, rigid=False)
            mesh = UsdGeom.Mesh(prim)
            faces = triangles(mesh, time)
            vertices = _world_points(prim, mesh.GetPointsAttr().Get(time), time, units)
            options = _values(prim, CLOTH_ATTRIBUTES, time)
            with usd_values.named(path, {**_names(CLOTH_ATTRIBUTES), "mesh": "points"}):
                ids = scene.add_cloth_mesh(trimesh.Trimesh(vertices, faces, process=False),
                                           name=_name(scene, prim), **options)
            link(str(path), "cloth", ids)
        elif prim.IsA(UsdGeom.Points) and _flag(prim, PARTICLES):
            _particles(scene, prim, time, units, link)
        elif prim.IsA(UsdGeom.Xformable) and _flag(prim, EMITTER):
            usd_values.transform(prim, time, rigid=False)
            world = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64)
            direction = units.direction(world[1, :3] / np.linalg.norm(world[1, :3]))   # the prim's +Y
            with usd_values.named(path, {**_names(EMITTER_ATTRIBUTES), "position": "xformOp:translate"}):
                emitter = scene.add_emitter(position=units.point(world[3, :3]), direction=direction,
                                            name=_name(scene, prim), **_values(prim, EMITTER_ATTRIBUTES, time))
            link(str(path), "particles", np.arange(emitter.start_slot, emitter.start_slot + emitter.capacity),
                 pooled=True)


def _particles(scene, prim, time, units, link) -> None:
    """A warpSim:particles Points prim: at least one finite point; velocities one per point, widths [stage units]
    one or one per point (radius = width / 2, default 0.01 m), all finite and widths >= 0."""
    path = prim.GetPath()
    usd_values.transform(prim, time, rigid=False)
    points = UsdGeom.Points(prim)
    authored = points.GetPointsAttr().Get(time)
    if not authored:
        raise usd_values.error(path, "points", authored, "a warpSim:particles Points prim needs at least one point")
    count = len(authored)
    with usd_values.named(path, {"positions": "points"}):
        positions = _world_points(prim, usd_values.counts(path, "points", authored, count, "one"), time, units)
    velocities = points.GetVelocitiesAttr().Get(time)
    if velocities:
        velocities = usd_values.counts(path, "velocities", velocities, count, "one")
        velocities = units.direction(velocities) * units.meters_per_unit
    else:
        velocities = None
    widths = points.GetWidthsAttr().Get(time)
    radius = 0.01
    if widths:
        radius = units.length(usd_values.counts(path, "widths", widths, count, "one or each")) / 2.0
        if np.any(radius < 0.0):
            raise usd_values.error(path, "widths", widths, "every width must be >= 0 [stage units]")
        radius = float(radius[0]) if len(radius) == 1 else radius
    options = _values(prim, PARTICLE_ATTRIBUTES, time)
    if "mass" in options and np.ndim(options["mass"]) == 1 and len(options["mass"]) == 1:
        options["mass"] = options["mass"][0]
    with usd_values.named(path, {**_names(PARTICLE_ATTRIBUTES), "positions": "points", "velocities": "velocities",
                                 "radius": "widths"}):
        ids = scene.add_particles(positions, velocities, radius=radius, name=_name(scene, prim), **options)
    link(str(path), "particles", ids)


def unique(name: str, existing) -> str:
    """``name``, or ``name_1``, ``name_2``, ... : the first not taken by the ``name`` of any of ``existing``."""
    taken = {item.name for item in existing}
    label, k = name, 1
    while label in taken:
        label, k = f"{name}_{k}", k + 1
    return label


def _name(scene, prim) -> str:
    return unique(prim.GetName(), [*scene.particle_groups, *scene.emitters])


def write(prim, names: dict, values: dict) -> None:
    """Author ``values`` (add_* keywords) on ``prim`` under their ``warpSim:`` names (those of ``names``)."""
    for name, (type_name, keyword) in names.items():
        value = values.get(keyword)
        if value is not None:
            prim.CreateAttribute(name, type_name, custom=True).Set(value)

"""A Scene's StageLayout: which prims a stage of it holds (particle groups, springs, bodies, planes, meshes,
colliders), each drawn in the frame its samples are written in."""
from __future__ import annotations

import numpy as np

from ..scene import Scene
from .specs import BodySpec, ColliderSpec, MeshSpec, PlaneSpec, PointsGroup, StageLayout


def _shape_drawing(shape, origin) -> dict:
    """The USD drawing fields of a shape (kind, size, points, faces, radius), points relative to ``origin`` [m]."""
    points = faces = None
    radius = 0.02
    if shape.kind == "mesh":
        points, faces = shape.vertices - origin, shape.faces
    elif shape.kind == "points":
        points, radius = shape.positions - origin, shape.radius
    return {"kind": shape.kind, "size": tuple(shape.size), "points": points, "faces": faces, "radius": radius}


def body_spec(index: int, body) -> BodySpec:
    """The BodySpec of one scene body: its shape drawn in the body frame (centre of mass at the origin)."""
    return BodySpec(body.name, index, **_shape_drawing(body.shape, body.mass.com), color=body.color)


def collider_spec(collider) -> ColliderSpec:
    """The ColliderSpec of one scene collider: its shape drawn in the shape frame (no centre-of-mass offset)."""
    return ColliderSpec(collider.name, **_shape_drawing(collider.shape, np.zeros(3)), color=collider.color,
                        position=tuple(collider.position.tolist()), orientation=tuple(collider.orientation.tolist()))


def stage_layout(scene: Scene) -> StageLayout:
    """The StageLayout of a scene: its particle groups, springs, bodies, planes, cloths, soft bodies and
    static colliders.

    A cloth's or soft body's particles and springs are drawn as its UsdGeom.Mesh only, not also
    as Points and spring curves."""
    radius = scene.particle_array("radius")
    meshed = {(m.start, m.count) for m in scene.meshes}
    groups = tuple(PointsGroup(g.name, g.start, g.count, 2.0 * radius[g.start:g.start + g.count], g.color,
                               pooled=g.pooled) for g in scene.particle_groups if (g.start, g.count) not in meshed)
    planes = tuple(PlaneSpec(p.name, tuple(p.normal), p.offset) for p in scene.planes)
    springs = None
    if scene.spring_count:
        drawn = np.ones(scene.spring_count, dtype=bool)
        for mesh in scene.meshes:
            for family in mesh.springs.values():
                drawn[np.asarray(family, dtype=np.int64)] = False
        springs = scene.spring_array("pairs")[drawn] if drawn.any() else None
    bodies = tuple(body_spec(index, body) for index, body in enumerate(scene.bodies))
    meshes = tuple(MeshSpec(m.name, m.start, m.count, m.face_counts, m.face_indices, m.color) for m in scene.meshes)
    colliders = tuple(collider_spec(collider) for collider in scene.colliders)
    return StageLayout(points_groups=groups, springs=springs, planes=planes, bodies=bodies, meshes=meshes,
                       colliders=colliders)

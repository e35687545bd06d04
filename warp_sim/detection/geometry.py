"""The scene's collision shapes on the device: what the broad and narrow phases test against each other."""
from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..core.model import Model
from ..kernels import detection as detection_kernels
from ..kernels.geometry import KINDS
from ..util.rotations import quat_to_matrix

CYLINDER_RIM_SAMPLES = 16   # points on each rim of a cylinder tested against other shapes


def shape_samples(shape) -> tuple[np.ndarray, float]:
    """Contact sample points (shape frame) [m] and their radius [m]: spheres at these points stand for the shape
    where another shape's signed distance is tested."""
    kind = shape.kind
    if kind == "sphere":
        return np.zeros((1, 3)), shape.radius
    if kind == "box":
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
        return corners * np.asarray(shape.size), 0.0
    if kind == "capsule":
        return np.array([[0.0, -shape.half_height, 0.0], [0.0, 0.0, 0.0], [0.0, shape.half_height, 0.0]]), shape.radius
    if kind == "cylinder":
        angles = np.linspace(0.0, 2.0 * math.pi, CYLINDER_RIM_SAMPLES, endpoint=False)
        ring = np.stack([shape.radius * np.cos(angles), np.zeros_like(angles), shape.radius * np.sin(angles)], 1)
        return np.concatenate([ring - [0, shape.half_height, 0], ring + [0, shape.half_height, 0]]), 0.0
    if kind == "mesh":
        return np.asarray(shape.vertices, dtype=np.float64), 0.0
    if kind == "points":
        return np.asarray(shape.positions, dtype=np.float64), shape.radius
    if kind == "none":   # a body without a shape: nothing of it touches anything
        return np.zeros((0, 3)), 0.0
    raise ValueError(f"shape kind {kind!r} has no contact geometry")


def _size(shape) -> tuple:
    size = tuple(float(s) for s in shape.size)
    if shape.kind == "points":
        size = (float(shape.radius),)
    return (size + (0.0, 0.0, 0.0))[:3]


def _first_faces(faces: np.ndarray, vertex_count: int) -> np.ndarray:
    """Per vertex, the lowest index of a face using it (-1 if none)."""
    owner = np.full(vertex_count, np.iinfo(np.int32).max, dtype=np.int64)
    np.minimum.at(owner, faces.ravel(), np.repeat(np.arange(len(faces)), 3))
    owner[owner == np.iinfo(np.int32).max] = -1
    return owner.astype(np.int32)


class ContactGeometry:
    """The scene's collision shapes on the device, bodies then static colliders.

    geoms: a kernels.detection.Geoms (float32: kinds, sizes [m], centres of mass [m], meshes (static surfaces,
        ``MeshShape(solid=False)``, flagged two-sided), sample points [m], bounds [m], restitution, friction, poses)
    meshes: the wp.Mesh objects the geoms refer to (kept alive here)
    body_count, static_count: how many bodies and colliders
    max_reach: [the largest reach (bound + travel + margin), the largest travel over the step] [m], set by detection
    body_bound: the largest bounding radius of a body [m]
    """

    def __init__(self, model: Model, scene):
        device = model.device
        self.body_count = scene.body_count
        colliders = scene.colliders
        self.static_count = len(colliders)
        self.meshes: list[wp.Mesh] = []   # kept alive: the geoms hold their ids
        kinds, sizes, coms, mesh_ids, starts, counts, radii, bounds, e, mu, sides = ([] for _ in range(11))
        samples, owner_starts, owners, xs, qs = [], [], [], [], []
        sample_total = owner_total = 0

        def add(shape, com, mesh_points, bound, restitution, friction, x, q, static_mesh_faces=None):
            nonlocal sample_total, owner_total
            kinds.append(KINDS[shape.kind])
            sizes.append(_size(shape))
            coms.append(com)
            mesh_id = 0
            if shape.kind == "mesh":
                mesh = wp.Mesh(points=wp.array(mesh_points, dtype=wp.vec3f, device=device),
                               indices=wp.array(np.asarray(shape.faces, dtype=np.int32).ravel(), dtype=wp.int32,
                                                device=device))
                self.meshes.append(mesh)
                mesh_id = mesh.id
            mesh_ids.append(mesh_id)
            sides.append(int(static_mesh_faces is not None and not shape.solid))   # a surface: two-sided
            owner_starts.append(owner_total)
            if static_mesh_faces is not None:   # static meshes: vertices found by BVH query, not looped over
                owners.append(_first_faces(static_mesh_faces, len(mesh_points)))
                owner_total += len(mesh_points)
                points, radius = np.zeros((0, 3)), 0.0
            else:
                points, radius = shape_samples(shape)
            starts.append(sample_total)
            counts.append(len(points))
            samples.append(points)
            sample_total += len(points)
            radii.append(radius)
            bounds.append(bound)
            e.append(restitution)
            mu.append(friction)
            xs.append(x)
            qs.append(q)

        for body in scene.bodies:
            shape = body.shape
            mesh_points = shape.vertices if shape.kind == "mesh" else None
            add(shape, body.mass.com, mesh_points, shape.bounding_radius, body.restitution, body.friction,
                body.position, body.orientation)
        for collider in colliders:
            shape = collider.shape
            if shape.kind == "mesh":   # stored in world axes about the centre of its box: pose (centre, identity)
                world = np.asarray(shape.vertices) @ quat_to_matrix(collider.orientation).T + collider.position
                centre = (world.min(axis=0) + world.max(axis=0)) / 2.0
                local = world - centre
                add(shape, np.zeros(3), local, float(np.max(np.linalg.norm(local, axis=1))), collider.restitution,
                    collider.friction, centre, np.array([0.0, 0.0, 0.0, 1.0]), static_mesh_faces=shape.faces)
            else:
                add(shape, np.zeros(3), None, _origin_bound(shape), collider.restitution, collider.friction,
                    collider.position, collider.orientation)

        g = detection_kernels.Geoms()

        def array(values, dtype, shape=None):
            data = np.asarray(values, dtype=np.float64 if dtype not in (wp.int32, wp.uint64) else None)
            if shape is not None:
                data = data.reshape(shape)
            return wp.array(data, dtype=dtype, device=device)

        g.kind = array(kinds, wp.int32)
        g.size = array(sizes, wp.vec3f, (-1, 3))
        g.com = array(coms, wp.vec3f, (-1, 3))
        g.mesh = wp.array(np.asarray(mesh_ids, dtype=np.uint64), dtype=wp.uint64, device=device)
        g.two_sided = array(sides, wp.int32)
        g.sample_start = array(starts, wp.int32)
        g.sample_count = array(counts, wp.int32)
        g.samples = array(np.concatenate(samples) if samples else np.zeros((0, 3)), wp.vec3f, (-1, 3))
        g.sample_radius = array(radii, wp.float32)
        g.owner_start = array(owner_starts, wp.int32)
        g.owner = wp.array(np.concatenate(owners) if owners else np.zeros(0, np.int32), dtype=wp.int32, device=device)
        g.bound = array(bounds, wp.float32)
        g.restitution = array(e, wp.float32)
        g.friction = array(mu, wp.float32)
        g.x = array(xs, wp.vec3f, (-1, 3))
        g.q = array(qs, wp.quatf, (-1, 4))
        g.reach = array(bounds, wp.float32)
        planes = scene.planes
        g.plane_normal = wp.array(np.array([p.normal for p in planes]).reshape(-1, 3), dtype=wp.vec3f, device=device)
        g.plane_offset = array([p.offset for p in planes], wp.float32)
        g.plane_restitution = array([p.restitution for p in planes], wp.float32)
        g.plane_friction = array([p.friction for p in planes], wp.float32)
        g.skip_start, g.skip = (array(values, wp.int32) for values in skipped_pairs(scene))
        g.body_count = self.body_count
        self.geoms = g
        self.max_reach = wp.zeros(2, dtype=wp.float32, device=device)
        self.body_bound = max((b.shape.bounding_radius for b in scene.bodies), default=0.0)


def skipped_pairs(scene) -> tuple[np.ndarray, np.ndarray]:
    """(per body and one more, where its entries start; the geoms j > i each body does not collide with): the two
    bodies of every enabled joint that does not say ``collide``, a static collider it is anchored to included (a
    disabled joint is as if absent; a broken one keeps its pair apart, as at the start)."""
    B = scene.body_count
    others: list[set] = [set() for _ in range(B)]
    for joint in scene.joints:
        if joint.collide or not joint.enabled:
            continue
        parent = joint.parent if joint.parent >= 0 else (B + joint.parent_collider if joint.parent_collider >= 0
                                                         else -1)
        if parent >= 0:
            low, high = sorted((parent, joint.child))
            others[low].add(high)
    counts = np.array([len(s) for s in others], np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    flat = np.array([g for s in others for g in sorted(s)], np.int32)
    return starts, flat


def _origin_bound(shape) -> float:
    """Radius [m] about a primitive's (or point set's, or mesh's) own origin enclosing it."""
    if shape.kind == "mesh":
        return float(np.max(np.linalg.norm(shape.vertices, axis=1)))
    if shape.kind == "points":
        return float(np.max(np.linalg.norm(shape.positions, axis=1))) + shape.radius
    return shape.bounding_radius

"""What a stage contains: the specs of particle groups, springs, planes, bodies, meshes and colliders."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Sdf

#: USD file extensions accepted by the writer (the format follows the extension).
USD_EXTENSIONS = (".usd", ".usdc", ".usda")

WORLD_PATH = Sdf.Path("/World")


@dataclass(frozen=True)
class PointsGroup:
    """One ``UsdGeom.Points`` prim covering particles ``start .. start+count-1``.

    A fixed group draws all its particles with constant ``widths``, diameters in
    metres (2 * radius), shape ``(count,)``, and ``color``, the linear-RGB
    displayColor in 0..1. A ``pooled`` group is a fixed-capacity pool of which
    each frame draws only the alive slots, with ids, widths, colors and opacities
    from ``write_frame``'s ``particle_*`` arrays (its ``widths`` and ``color``
    are optional and unused); no other group or spring may use its slots.
    ``name`` is made a valid USD identifier with ``Tf.MakeValidIdentifier``.
    """

    name: str
    start: int
    count: int                                      # particles (fixed) or slots (pooled)
    widths: np.ndarray | None = None                # [m] (count,) diameters; required if fixed, unused if pooled
    color: tuple[float, float, float] | None = None  # linear RGB in 0..1; required if fixed, unused if pooled
    pooled: bool = False


@dataclass(frozen=True)
class PlaneSpec:
    """A static plane ``normal . x = offset`` (metres), drawn as a square quad of side ``size``."""

    name: str
    normal: tuple[float, float, float]
    offset: float
    size: float = 20.0


@dataclass(frozen=True)
class BodySpec:
    """One rigid body: an Xform at /World/Bodies/<name> driven by body_x[index], body_q[index].

    ``size`` in metres: sphere ``(radius,)``; box half extents ``(hx, hy, hz)``;
    capsule and cylinder ``(radius, half_height)`` along the body's Y axis;
    empty for mesh and points. ``points`` (metres, body frame with the centre of
    mass at the origin) and ``faces`` (triangle vertex indices) describe a mesh;
    ``points`` alone a body of point masses drawn with ``radius`` (metres).
    ``color`` is the linear-RGB displayColor in 0..1; ``name`` is made a valid
    USD identifier with ``Tf.MakeValidIdentifier``.
    """

    name: str
    index: int                          # row in the per-frame body_x (B, 3) and body_q (B, 4; x y z w) arrays
    kind: str                           # "sphere" | "box" | "capsule" | "cylinder" | "mesh" | "points" | "none"
    size: tuple = ()                    # [m] sphere (r,); box (hx, hy, hz); capsule/cylinder (r, half_height)
    points: np.ndarray | None = None    # [m] mesh: (V, 3) vertices, body frame; points: (N, 3) positions
    faces: np.ndarray | None = None     # mesh: (F, 3) triangle vertex indices
    radius: float = 0.02                # points: drawn radius [m]
    color: tuple = (0.6, 0.6, 0.6)


@dataclass(frozen=True)
class ColliderSpec:
    """A static collider: an Xform at /World/Colliders/<name>, written once with no time samples.

    ``position`` [m] (the shape frame's origin, world) and ``orientation`` (unit quaternion
    x, y, z, w) are its ``xformOp:translate`` and ``xformOp:orient`` default values; ``kind``,
    ``size``, ``points`` and ``faces`` (shape frame), ``radius`` and ``color`` draw its shape
    as the child ``Geom``, as for BodySpec.
    """

    name: str
    kind: str                           # as BodySpec.kind
    size: tuple = ()                    # [m] as BodySpec.size
    points: np.ndarray | None = None    # [m] mesh: (V, 3) vertices, shape frame; points: (N, 3) positions
    faces: np.ndarray | None = None     # mesh: (F, 3) triangle vertex indices
    radius: float = 0.02                # points: drawn radius [m]
    color: tuple = (0.45, 0.45, 0.5)
    position: tuple = (0.0, 0.0, 0.0)          # [m]
    orientation: tuple = (0.0, 0.0, 0.0, 1.0)  # x, y, z, w


@dataclass(frozen=True)
class MeshSpec:
    """A deforming ``UsdGeom.Mesh`` at /World/Meshes/<name> whose vertices are particles ``start .. start+count-1``.

    ``face_counts`` (F,): vertices per face (>= 3); ``face_indices`` (sum of face_counts,):
    vertex indices local to the mesh (0 .. count-1), each face counter-clockwise seen from
    its front (USD's rightHanded orientation). Drawn double-sided without subdivision in
    ``color``, the linear-RGB displayColor in 0..1. ``name`` is made a valid USD identifier
    with ``Tf.MakeValidIdentifier``. Its particles may also be in a PointsGroup (then drawn
    twice); ``warp_sim.simulator.stage_layout`` leaves them out of the Points.
    """

    name: str
    start: int
    count: int
    face_counts: np.ndarray
    face_indices: np.ndarray
    color: tuple = (0.8, 0.8, 0.8)


@dataclass(frozen=True)
class StageLayout:
    """What the stage contains: particle groups, spring segments, static planes, rigid bodies, meshes, colliders.

    ``springs`` is ``(K, 2)`` global particle indices (or None); ``spring_width``
    is the drawn curve width in metres; ``meshes``: cloths and soft bodies;
    ``colliders``: static shapes, written once.
    """

    points_groups: tuple[PointsGroup, ...] = ()
    springs: np.ndarray | None = None
    spring_width: float = 0.005
    planes: tuple[PlaneSpec, ...] = ()
    bodies: tuple[BodySpec, ...] = ()
    meshes: tuple[MeshSpec, ...] = ()
    colliders: tuple[ColliderSpec, ...] = ()

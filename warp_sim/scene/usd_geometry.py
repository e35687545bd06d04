"""A UsdGeom.Mesh collision shape as UsdPhysics defines it: its ``physics:approximation``, its ``doubleSided``, and
its winding with mirrors and ``orientation`` folded in (docs/usd.md, "Collision geometry").

The points are taken through the shape's world scale as usd-core's parser gives it (``meshScale``, signed: a mirror
is three negative components there, with a turn by 180 degrees in the shape's rotation), so a mirrored mesh keeps
its handedness. An odd number of negative components and ``orientation = "leftHanded"`` each reverse the winding,
before anything is checked. Then, by ``physics:approximation`` (authored on the prim, with or without
``PhysicsMeshCollisionAPI``):

- ``none`` (the default) and ``meshSimplification``: the triangles. For a static collider, a ``doubleSided`` or
  open mesh is a surface that collides from both sides (``MeshShape(solid=False)``); a closed single-sided one, and
  any body's, is a solid (a closed mesh wound inward is re-wound, with one warning naming the prims);
- ``convexHull``, and ``convexDecomposition`` (one warning naming the prims): the convex hull of the points
  (``hulls.convex_hull``); a flat one (a quad's) is a slab (``flat_hull``);
- ``boundingCube``: a Box, axis-aligned in the mesh's own frame, about the points' bounds;
- ``boundingSphere``: a Sphere about the centre of those bounds, through the farthest point;
- anything else: read as ``none``, with one warning naming the prims and their values.

A slab (or a flat bounding box) keeps its top face where the points are and is ``SLAB_FRACTION`` of its widest
extent thick, ``SLAB_MIN`` at least, behind the points' front: the side their authored ``normals`` point to,
else the side the stage's up axis points to, else the side of their winding. So a body resting on a ground quad
rests exactly at the quad's height, and the slab's depth below it catches a body that sinks in during a step.
"""
from __future__ import annotations

import numpy as np
import trimesh
from pxr import UsdGeom

from . import usd_attributes, usd_values
from .hulls import convex_hull, flat_hull
from .shapes import DEGENERATE_RATIO, Box, MeshShape, Sphere

FLAT_RATIO = 1e-6        # thinnest / widest extent of the points at or below which they lie in a plane (or a line)
HULL_TOLERANCE = 1e-7    # of the widest extent [m]: points this close to a hull count as on it (float32 points)
SLAB_FRACTION = 0.01     # a flat hull's thickness, as a fraction of its widest extent
SLAB_MIN = 0.005         # [m] a flat hull's thickness at least
SURFACE = ("none", "meshSimplification")
HULL = ("convexHull", "convexDecomposition")
UP = {"Y": np.array([0.0, 1.0, 0.0]), "Z": np.array([0.0, 0.0, 1.0])}
HULL_ADVICE = 'or author physics:approximation = "convexHull" on it'


def mesh_shape(prim, time, mesh_scale, units, frame, static: bool, notes: dict):
    """(shape, R, p): the collision shape of Mesh ``prim`` at ``time`` and its frame (R, p [m]), from the frame
    usd-core gives it (``frame``: its rotation and position [m]), its signed world ``mesh_scale`` (stage units per
    point unit) and ``units`` (a StageUnits); ``static``: a static collider's (a body's mesh is always a solid);
    ``notes``: the reader's warnings (what -> prim paths), added to."""
    path = str(prim.GetPath())
    mesh = UsdGeom.Mesh(prim)
    scale = units.length(np.asarray(mesh_scale, dtype=np.float64))
    points = np.array(mesh.GetPointsAttr().Get(time), dtype=np.float64).reshape(-1, 3) * scale
    faces = usd_attributes.triangles(mesh, time)
    if (str(mesh.GetOrientationAttr().Get(time)) == "leftHanded") != (np.prod(np.sign(scale)) < 0.0):
        faces = faces[:, ::-1]
    approximation = _approximation(prim)
    side = _Side(prim, time, scale, units.up_axis, points, faces)
    R, p = frame
    if approximation in HULL:
        if approximation == "convexDecomposition":
            notes.setdefault('physics:approximation = "convexDecomposition" read as one convex hull',
                             []).append(path)
        return _hull(prim, points, side), R, p
    if approximation == "boundingCube":
        box, centre = _bounding_box(prim, points, side)
        return box, R, p + R @ centre
    if approximation == "boundingSphere":
        centre = (points.min(axis=0) + points.max(axis=0)) / 2.0
        radius = float(np.max(np.linalg.norm(points - centre, axis=1)))
        if not radius > 0.0:
            raise _flat_error(prim, "its points coincide", 'physics:approximation = "boundingSphere"')
        return Sphere(radius), R, p + R @ centre
    if approximation not in SURFACE:
        notes.setdefault('unknown physics:approximation values, read as "none" (the triangles)',
                         []).append(f"{path} ({approximation!r})")
    return _triangles(prim, time, points, faces, static, notes), R, p


def _approximation(prim) -> str:
    attribute = prim.GetAttribute("physics:approximation")
    value = attribute.Get() if attribute else None
    return "none" if value is None else str(value)


class _Side:
    """The front of a flat set of points: for a plane normal (the shape frame's), the sign that points to the side
    the authored normals face, else to the stage's up axis, else to the faces' winding."""

    def __init__(self, prim, time, scale, up_axis, points, faces):
        self.scale = scale
        self.normals = _authored_normals(prim, time)
        world = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64).T[:3, :3]
        self.up = scale * np.linalg.solve(world, UP[up_axis])   # the up direction in the shape frame (affine map)
        a, b, c = (points[faces[:, k]] for k in range(3))
        self.winding = np.cross(b - a, c - a).sum(axis=0)

    def front(self, normal: np.ndarray) -> np.ndarray:
        """``normal`` (unit) or its opposite, whichever faces the front."""
        covector = None if self.normals is None else self.normals / self.scale   # a normal's map is the inverse
        for direction in (covector, self.up, self.winding):
            if direction is not None and abs(normal @ direction) > 1e-3 * np.linalg.norm(direction):
                return normal if normal @ direction > 0.0 else -normal
        return normal


def _authored_normals(prim, time):
    """The mean of the mesh's authored normals (``primvars:normals`` or ``normals``), in its points' frame, or None."""
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar("normals")
    values = primvar.ComputeFlattened(time) if primvar and primvar.HasAuthoredValue() else None
    if values is None:
        attribute = UsdGeom.Mesh(prim).GetNormalsAttr()
        values = attribute.Get(time) if attribute.HasAuthoredValue() else None
    if not values:
        return None
    mean = np.mean(np.array(values, dtype=np.float64).reshape(-1, 3), axis=0)
    return mean if np.all(np.isfinite(mean)) and np.any(mean) else None


def _extents(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the points' extents along their principal axes (3,) [m], those axes (rows))."""
    centred = points - points.mean(axis=0)
    axes = np.linalg.svd(centred, full_matrices=False)[2]
    return np.ptp(centred @ axes.T, axis=0), axes


def slab_thickness(points: np.ndarray) -> float:
    """The thickness [m] of a flat hull of ``points`` [m]: SLAB_FRACTION of their widest extent along the shape
    frame's axes, SLAB_MIN at least."""
    return max(SLAB_FRACTION * float(np.max(np.ptp(points, axis=0))), SLAB_MIN)


def _hull(prim, points: np.ndarray, side: _Side) -> MeshShape:
    """The convex hull of the points as a solid; a flat one as a slab behind its front."""
    extents, axes = _extents(points)
    widest = float(np.max(extents))
    if not np.sort(extents)[1] > FLAT_RATIO * widest:
        raise _flat_error(prim, "its points lie on a line or coincide", 'physics:approximation = "convexHull"')
    if extents[2] <= FLAT_RATIO * widest:
        vertices, faces = flat_hull(points, side.front(axes[2]), slab_thickness(points))
    else:
        vertices, faces = convex_hull(points, HULL_TOLERANCE * widest)
    return MeshShape(trimesh.Trimesh(vertices, faces, process=False), solid=True)


def _bounding_box(prim, points: np.ndarray, side: _Side) -> tuple[Box, np.ndarray]:
    """(the Box about the points' bounds in the shape frame, its centre [m]); flat along an axis: a slab."""
    low, high = points.min(axis=0), points.max(axis=0)
    size = high - low
    thin = size <= FLAT_RATIO * np.max(size)
    if np.count_nonzero(thin) > 1:
        raise _flat_error(prim, "its points lie on a line along an axis, or coincide",
                          'physics:approximation = "boundingCube"')
    centre = (low + high) / 2.0
    for k in np.flatnonzero(thin):
        thickness = slab_thickness(points)
        sign = side.front(np.eye(3)[k])[k]
        size[k] = thickness
        centre[k] -= sign * thickness / 2.0
    return Box(size / 2.0), centre


def _flat_error(prim, why: str, what: str) -> ValueError:
    """The error for a mesh whose points or faces span too little for ``what`` (the approximation, or its faces)."""
    return usd_values.error(prim.GetPath(), "points", UsdGeom.Mesh(prim).GetPointsAttr().Get(),
                            f"{why}, so {what} has nothing to collide with; give the mesh extent in two directions "
                            "at least, or use another shape")


def _triangles(prim, time, points: np.ndarray, faces: np.ndarray, static: bool, notes: dict) -> MeshShape:
    """The triangles: a surface for a static doubleSided or open mesh (and for a body's open one, which the reader
    leaves out), else a solid, re-wound where it winds inward."""
    path = prim.GetPath()
    surface = trimesh.Trimesh(points, faces, process=False)
    double = bool(UsdGeom.Mesh(prim).GetDoubleSidedAttr().Get(time))
    if not surface.is_watertight or (static and double):
        return MeshShape(_with_area(prim, surface), solid=False)
    indices = UsdGeom.Mesh(prim).GetFaceVertexIndicesAttr().Get(time)
    both = "" if not static else ', author doubleSided = true (its triangles then collide from both sides)'
    if not surface.is_winding_consistent:
        raise usd_values.error(path, "faceVertexIndices", indices,
                               "neighbouring faces wind opposite ways, so the closed mesh bounds no solid; re-export "
                               f"it with its normals unified (all outward){both}, {HULL_ADVICE}")
    volume = float(trimesh.triangles.mass_properties(surface.triangles, density=1.0).volume)
    if volume < 0.0:
        notes.setdefault('closed meshes wound inward, read re-wound (author orientation = "leftHanded", or reverse '
                         'their faceVertexIndices, to match)', []).append(str(path))
        surface = trimesh.Trimesh(points, faces[:, ::-1], process=False)
    try:
        return MeshShape(surface, solid=True)
    except ValueError as failure:   # its message names a trimesh object and Python repairs: say it in USD terms
        reason = str(failure).split(" is invalid: ", 1)[-1].split("; ", 1)[0]
        raise usd_values.error(path, "points", UsdGeom.Mesh(prim).GetPointsAttr().Get(time),
                               f"{reason}; repair the mesh in the modeller{both}, {HULL_ADVICE}") from None


def _with_area(prim, surface: trimesh.Trimesh) -> trimesh.Trimesh:
    """The surface without its zero-area faces (a fan over collinear corners), which touch nothing."""
    a, b, c = np.moveaxis(surface.triangles, 1, 0)
    twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.max([np.sum((b - a) ** 2, axis=1), np.sum((c - b) ** 2, axis=1), np.sum((a - c) ** 2, axis=1)],
                     axis=0)
    kept = twice_area > DEGENERATE_RATIO * longest
    if not np.any(kept):
        raise _flat_error(prim, "every face has zero area (its corners coincide or lie on a line)", "the mesh")
    return trimesh.Trimesh(surface.vertices, surface.faces[kept], process=False)

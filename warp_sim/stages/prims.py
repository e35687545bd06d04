"""The prim writers: one small class per prim kind, defined once and sampled every frame (see writer.py)."""

from __future__ import annotations

import functools
import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, Vt

from .specs import WORLD_PATH, BodySpec, ColliderSpec, MeshSpec, PlaneSpec, PointsGroup, StageLayout


@dataclass(frozen=True)
class Frame:
    """One checked frame: time code, particle x [m] and v [m/s] (N, 3), body x [m] and unit q as Vt arrays,
    pool arrays (N rows): alive (bool), id (int64), radius [m], color (N, 3) and opacity in 0..1; or None."""

    time: float
    particle_x: np.ndarray | None
    particle_v: np.ndarray | None
    body_x: Vt.Vec3dArray | None
    body_q: Vt.QuatfArray | None
    particle_alive: np.ndarray | None = None
    particle_id: np.ndarray | None = None
    particle_radius: np.ndarray | None = None
    particle_color: np.ndarray | None = None
    particle_opacity: np.ndarray | None = None


#: ``write_frame``'s per-particle arrays required by pooled groups.
POOL_ARRAYS = ("particle_alive", "particle_id", "particle_radius", "particle_color", "particle_opacity")
#: the largest finite float32: a stage's points, velocities and widths are float32, so a larger value is refused
FLOAT32_MAX = float(np.finfo(np.float32).max)


# --------------------------------------------------------------------------- helpers


def _vec3f(a: np.ndarray) -> Vt.Vec3fArray:
    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1, 3))


def _floats(a) -> Vt.FloatArray:
    return Vt.FloatArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1))


def _extent(lo: np.ndarray, hi: np.ndarray, pad=0.0) -> Vt.Vec3fArray:
    """Extent array [min(lo - pad), max(hi + pad)] from per-point bounds (n, 3) and a pad, (n,) or scalar, metres."""
    # Column by column: numpy's axis-0 reduction of an (n, 3) array is ~15x slower.
    return _vec3f([[(lo[:, i] - pad).min() for i in range(3)], [(hi[:, i] + pad).max() for i in range(3)]])


def _gather(a: np.ndarray, rows: slice | np.ndarray) -> np.ndarray:
    """Rows ``rows`` of ``a``: a view for a slice, else a copy (``np.take``, ~3x faster than fancy indexing)."""
    return a[rows] if isinstance(rows, slice) else np.take(a, rows, axis=0)


def _identifier(name: str) -> str:
    return Tf.MakeValidIdentifier(str(name))


def require(ok: bool, message: str) -> None:
    if not ok:
        raise ValueError(message)


def _color(label: str, color) -> np.ndarray:
    """``color`` as 3 finite floats, else ValueError."""
    c = np.asarray(color, dtype=np.float64)
    require(c.shape == (3,) and bool(np.all(np.isfinite(c))), f"{label}: color must be 3 finite floats, got {color!r}")
    return c


def _first_bad(bad: np.ndarray, checked: np.ndarray | None) -> int | None:
    """First row flagged in ``bad`` (per element) among the rows flagged in ``checked`` (None: all rows)."""
    if not bad.any():  # flat: fast
        return None
    if bad.ndim == 2:  # column by column: numpy's row reduction of an (n, 3) array is ~10x slower
        bad = functools.reduce(np.logical_or, bad.T)
    if checked is not None:
        bad &= checked
    rows = np.flatnonzero(bad)
    return int(rows[0]) if rows.size else None


def check_rows(frame: int, name: str, a, width: int | None, min_rows: int, what: str,
          checked: np.ndarray | None = None) -> np.ndarray:
    """``a`` as an (n, width) array, or (n,) for width None, with n >= min_rows (n == len(checked) if given),
    finite in the rows flagged in ``checked`` (None: all rows); else ValueError naming the first bad row."""
    a = np.asarray(a)
    shape = "(N,)" if width is None else f"(N, {width})"
    require(a.ndim == (1 if width is None else 2) and a.shape[1:] == (() if width is None else (width,))
             and a.shape[0] >= min_rows, f"frame {frame}: {name} must have shape {shape} with N >= {min_rows}, "
             f"got {a.shape}")
    if checked is not None and len(a) != len(checked):
        raise ValueError(f"frame {frame}: {name} has {len(a)} rows but particle_alive has {len(checked)}")
    if a.dtype.kind not in "biu":   # float32's finite range: a float64 value beyond it is an infinity in USD
        bad = _first_bad(~(np.abs(a) <= FLOAT32_MAX), checked)
        if bad is not None:
            kind = "non-finite value" if not np.isfinite(a[bad]).all() else "value beyond float32's range (+-3.4e38)"
            raise ValueError(f"frame {frame}: {name} has a {kind} at {what} index {bad}")
    return a


def check_in_range(frame: int, name: str, a: np.ndarray, lo: float, hi: float, checked: np.ndarray) -> None:
    """ValueError naming the first row flagged in ``checked`` with a value of ``a`` outside [lo, hi]."""
    if not a.size or (a.min() >= lo and a.max() <= hi):  # flat: fast (False with NaN, in dead rows too)
        return
    bad = _first_bad((a < lo) | (a > hi), checked)
    if bad is not None:
        raise ValueError(f"frame {frame}: {name} has a value outside [{lo:g}, {hi:g}] at particle index {bad} "
                         f"(got {a[bad]})")


# --------------------------------------------------------------------------- prim writers


class _PrimWriter:
    """One prim (or prim family) on the stage.

    ``define`` authors everything that never changes; ``write`` authors the
    time samples of one ``Frame``. ``min_particles`` / ``min_bodies`` are the
    smallest particle / body array lengths it needs (0: it reads none).
    ``sdf_only`` writers author with Sdf API only, so a frame batches them in
    one ``Sdf.ChangeBlock`` (where Usd API is unsafe). ``pool`` is the particle
    slice of a pooled group, whose dead rows are neither read nor checked.
    """

    path: Sdf.Path
    min_particles: int = 0
    min_bodies: int = 0
    sdf_only: bool = False
    pool: slice | None = None   # pooled particle slots: only their alive rows are read (and checked)

    def define(self, stage: Usd.Stage) -> None:
        raise NotImplementedError

    def write(self, frame: Frame) -> None:
        """Author one frame's samples; static prims keep this no-op."""

    def uses(self, lo: int, hi: int) -> bool:
        """Whether it reads any particle row in ``lo .. hi - 1``."""
        return False


class _PointsWriter(_PrimWriter):
    """A ``UsdGeom.Points`` group: points, ids, widths, velocities, displayColor, extent per frame.

    A fixed group writes all its particles with constant ids (global indices),
    widths and color; a pooled group writes its alive slots in slot order, with
    their ids, widths (2 radius), colors and ``primvars:displayOpacity`` (vertex),
    and blocks the extent of a frame without live particles.
    """

    def __init__(self, group: PointsGroup):
        start, count = int(group.start), int(group.count)
        label = f"PointsGroup {group.name!r}"
        require(start >= 0 and count >= 1,
                 f"{label}: start must be >= 0 and count >= 1, got start={start}, count={count}")
        self.path = WORLD_PATH.AppendPath(Sdf.Path(f"Particles/{_identifier(group.name)}"))
        self.slice = slice(start, start + count)
        self.min_particles = start + count
        if group.pooled:  # widths and colors come per frame from particle_radius and particle_color
            self.pool = self.slice
            return
        require(group.widths is not None and group.color is not None,
                 f"{label}: widths and color are required for a fixed (not pooled) group")
        widths = np.asarray(group.widths, dtype=np.float64)
        require(widths.shape == (count,), f"{label}: widths must have shape ({count},), got {widths.shape}")
        require(bool(np.all(np.isfinite(widths)) and np.all(widths >= 0)),
                 f"{label}: widths must be finite and >= 0")
        color = _color(label, group.color)
        self.radii = widths / 2.0
        self.ids = Vt.Int64Array.FromNumpy(np.arange(start, start + count, dtype=np.int64))
        self.widths = _floats(widths)
        self.colors = _vec3f(np.broadcast_to(color, (count, 3)))

    def define(self, stage: Usd.Stage) -> None:
        self.prim = UsdGeom.Points.Define(stage, self.path)
        self.color_primvar = self.prim.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)
        if self.pool is not None:
            self.opacity_primvar = self.prim.CreateDisplayOpacityPrimvar(UsdGeom.Tokens.vertex)

    def write(self, frame: Frame) -> None:
        time = frame.time
        if self.pool is None:
            rows, radii, ids, widths, colors = self.slice, self.radii, self.ids, self.widths, self.colors
        else:  # the alive slots, in slot order: one mask, then a gather per array
            rows = self.pool.start + np.flatnonzero(frame.particle_alive[self.pool])
            radii = _gather(frame.particle_radius, rows)
            ids = Vt.Int64Array.FromNumpy(_gather(frame.particle_id, rows))
            widths, colors = _floats(2.0 * radii), _vec3f(_gather(frame.particle_color, rows))
            self.opacity_primvar.Set(_floats(_gather(frame.particle_opacity, rows)), time)
        p = _gather(frame.particle_x, rows)
        self.prim.CreatePointsAttr().Set(_vec3f(p), time)
        self.prim.CreateIdsAttr().Set(ids, time)
        self.prim.CreateWidthsAttr().Set(widths, time)
        self.prim.CreateVelocitiesAttr().Set(_vec3f(_gather(frame.particle_v, rows)), time)
        self.color_primvar.Set(colors, time)
        # No extent of no points: block it, so bounds are computed (empty), not held from another frame.
        self.prim.CreateExtentAttr().Set(_extent(p, p, radii) if len(p) else Sdf.ValueBlock(), time)

    def uses(self, lo: int, hi: int) -> bool:
        return self.slice.start < hi and lo < self.slice.stop


class _SpringsWriter(_PrimWriter):
    """Spring segments as one linear ``UsdGeom.BasisCurves``: topology once, endpoints per frame."""

    def __init__(self, springs: np.ndarray, width: float):
        springs = np.asarray(springs)
        require(springs.ndim == 2 and springs.shape[1] == 2 and np.issubdtype(springs.dtype, np.integer),
                 f"springs must be an integer array of shape (K, 2), got {springs.dtype} {springs.shape}")
        require(springs.size == 0 or int(springs.min()) >= 0, "springs must hold particle indices >= 0")
        require(math.isfinite(width) and width > 0, f"spring_width must be finite and > 0, got {width!r}")
        self.path = WORLD_PATH.AppendChild("Springs")
        self.springs = springs.astype(np.int64)
        self.min_particles = int(springs.max()) + 1 if springs.size else 0
        self.half_width = float(width) / 2.0
        self.width = float(width)

    def define(self, stage: Usd.Stage) -> None:
        self.prim = UsdGeom.BasisCurves.Define(stage, self.path)
        self.prim.CreateTypeAttr(UsdGeom.Tokens.linear)
        self.prim.CreateCurveVertexCountsAttr(
            Vt.IntArray.FromNumpy(np.full(len(self.springs), 2, dtype=np.int32)))
        self.prim.CreateWidthsAttr(_floats([self.width]))
        self.prim.SetWidthsInterpolation(UsdGeom.Tokens.constant)

    def write(self, frame: Frame) -> None:
        time, p = frame.time, frame.particle_x[self.springs.reshape(-1)]
        self.prim.CreatePointsAttr().Set(_vec3f(p), time)
        self.prim.CreateExtentAttr().Set(_extent(p, p, self.half_width), time)

    def uses(self, lo: int, hi: int) -> bool:
        return bool(np.any((self.springs >= lo) & (self.springs < hi)))


class _PlaneWriter(_PrimWriter):
    """A static double-sided quad ``UsdGeom.Mesh`` for a plane; no time samples."""

    def __init__(self, plane: PlaneSpec):
        normal = np.asarray(plane.normal, dtype=np.float64)
        length = float(np.linalg.norm(normal)) if normal.shape == (3,) else 0.0
        label = f"PlaneSpec {plane.name!r}"
        require(math.isfinite(length) and length > 0,
                 f"{label}: normal must be a finite non-zero 3-vector, got {plane.normal!r}")
        require(math.isfinite(plane.offset), f"{label}: offset must be finite, got {plane.offset!r}")
        require(math.isfinite(plane.size) and plane.size > 0,
                 f"{label}: size must be finite and > 0, got {plane.size!r}")
        self.path = WORLD_PATH.AppendPath(Sdf.Path(f"Planes/{_identifier(plane.name)}"))
        n = normal / length
        # Tangents u, v with u x v = n, so the quad winds counter-clockwise seen from +n.
        helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        u = np.cross(helper, n)
        u /= np.linalg.norm(u)
        w = np.cross(n, u)
        h = plane.size / 2.0
        centre = n * float(plane.offset)
        self.points = centre + h * np.array([-u - w, u - w, u + w, -u + w])

    def define(self, stage: Usd.Stage) -> None:
        mesh = UsdGeom.Mesh.Define(stage, self.path)
        mesh.CreatePointsAttr(_vec3f(self.points))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.array([4], dtype=np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.arange(4, dtype=np.int32)))
        mesh.CreateExtentAttr(_extent(self.points, self.points))
        mesh.CreateDoubleSidedAttr(True)
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)


class _MeshWriter(_PrimWriter):
    """A cloth or soft body: a ``UsdGeom.Mesh`` with its topology, no subdivision, double-sided and a
    constant displayColor authored once; points, velocities and extent of its particles sampled per frame."""

    def __init__(self, mesh: MeshSpec):
        label = f"MeshSpec {mesh.name!r}"
        whole = all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) for n in (mesh.start, mesh.count))
        require(whole and mesh.start >= 0 and mesh.count >= 3,
                 f"{label}: start must be an integer >= 0 and count an integer >= 3, got start={mesh.start!r}, "
                 f"count={mesh.count!r}")
        start, count = int(mesh.start), int(mesh.count)
        counts, indices = np.asarray(mesh.face_counts), np.asarray(mesh.face_indices)
        require(counts.ndim == 1 and counts.size >= 1 and np.issubdtype(counts.dtype, np.integer)
                 and int(counts.min()) >= 3,
                 f"{label}: face_counts must be a 1-d integer array of faces' vertex counts (each >= 3), got "
                 f"{counts.dtype} {counts.shape}")
        require(indices.ndim == 1 and np.issubdtype(indices.dtype, np.integer) and indices.size == int(counts.sum()),
                 f"{label}: face_indices must be a 1-d integer array of sum(face_counts) = {int(counts.sum())} "
                 f"indices, got {indices.dtype} {indices.shape}")
        require(int(indices.min()) >= 0 and int(indices.max()) < count,
                 f"{label}: face_indices must index its {count} vertices (0 .. {count - 1}), got "
                 f"{int(indices.min())} .. {int(indices.max())}")
        self.color = _color(label, mesh.color)
        self.counts = Vt.IntArray.FromNumpy(counts.astype(np.int32))
        self.indices = Vt.IntArray.FromNumpy(indices.astype(np.int32))
        self.path = WORLD_PATH.AppendPath(Sdf.Path(f"Meshes/{_identifier(mesh.name)}"))
        self.slice = slice(start, start + count)
        self.min_particles = start + count

    def define(self, stage: Usd.Stage) -> None:
        mesh = UsdGeom.Mesh.Define(stage, self.path)
        mesh.CreateFaceVertexCountsAttr(self.counts)
        mesh.CreateFaceVertexIndicesAttr(self.indices)
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateDoubleSidedAttr(True)
        mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(_vec3f(self.color))
        self.points, self.velocities = mesh.CreatePointsAttr(), mesh.CreateVelocitiesAttr()
        self.extent = mesh.CreateExtentAttr()

    def write(self, frame: Frame) -> None:
        time, p = frame.time, frame.particle_x[self.slice]
        self.points.Set(_vec3f(p), time)
        self.velocities.Set(_vec3f(frame.particle_v[self.slice]), time)
        self.extent.Set(_extent(p, p), time)

    def uses(self, lo: int, hi: int) -> bool:
        return self.slice.start < hi and lo < self.slice.stop


#: Number of ``BodySpec.size`` values per body kind, and what they are.
BODY_SIZES = {"sphere": (1, "(radius,)"), "box": (3, "half extents (hx, hy, hz)"),
              "capsule": (2, "(radius, half_height)"), "cylinder": (2, "(radius, half_height)"),
              "mesh": (0, "() (the shape is in points/faces)"), "points": (0, "() (the shape is in points)"),
              "none": (0, "() (a body without a shape: no Geom child)")}

#: Largest accepted deviation of a body_q row's norm from 1.
QUAT_NORM_TOLERANCE = 1e-3


class _ShapeXformWriter(_PrimWriter):
    """An Xform with ``xformOp:translate`` (double, metres) and ``xformOp:orient`` (float quaternion), and the
    shape of a BodySpec or ColliderSpec (kind, size, points, faces, radius, color) as its static child gprim
    ``Geom``; ``noun`` ("body", "collider") names the owner in error messages."""

    def __init__(self, spec, label: str, noun: str, path: Sdf.Path):
        kind = spec.kind
        require(kind in BODY_SIZES, f"{label}: kind must be one of {', '.join(BODY_SIZES)}, got {kind!r}")
        count, meaning = BODY_SIZES[kind]
        size = np.asarray(spec.size, dtype=np.float64)
        require(size.shape == (count,) and bool(np.all(np.isfinite(size)) and np.all(size > 0)),
                 f"{label}: size of a {kind} must be {meaning}: {count} finite values > 0 [m], got {spec.size!r}")
        shaped = kind in ("mesh", "points")
        require((spec.points is not None) == shaped,
                 f"{label}: points are {'required' if shaped else 'not used'} for a {kind} {noun}")
        require((spec.faces is not None) == (kind == "mesh"),
                 f"{label}: faces are {'required' if kind == 'mesh' else 'not used'} for a {kind} {noun}")
        self.kind, self.size, self.color = kind, size, _color(label, spec.color)
        self.path = path
        if shaped:
            points = np.asarray(spec.points, dtype=np.float64)
            require(points.ndim == 2 and points.shape[1] == 3 and len(points) >= 1 and bool(np.isfinite(points).all()),
                     f"{label}: points must be a finite (N, 3) array with N >= 1 [m], got shape {points.shape}")
            self.points = points
        if kind == "mesh":
            faces = np.asarray(spec.faces)
            require(faces.ndim == 2 and faces.shape[1] == 3 and len(faces) >= 1
                     and np.issubdtype(faces.dtype, np.integer),
                     f"{label}: faces must be an integer (F, 3) array with F >= 1, got {faces.dtype} {faces.shape}")
            require(int(faces.min()) >= 0 and int(faces.max()) < len(points),
                     f"{label}: faces must index the {len(points)} points (0 .. {len(points) - 1}), "
                     f"got indices {int(faces.min())} .. {int(faces.max())}")
            self.faces = faces.astype(np.int32)
        if kind == "points":
            require(math.isfinite(spec.radius) and spec.radius > 0,
                     f"{label}: radius must be finite and > 0 [m], got {spec.radius!r}")
            self.radius = float(spec.radius)
        # The child's extent [m] in its own space (before the box's scale op).
        if shaped:
            pad = self.radius if kind == "points" else 0.0
            self.lo, self.hi = points.min(axis=0) - pad, points.max(axis=0) + pad
        elif kind == "none":
            self.lo = self.hi = np.zeros(3)
        else:
            r, h = size[0], size[-1]
            half = {"sphere": (r, r, r), "box": (1.0, 1.0, 1.0), "capsule": (r, h + r, r), "cylinder": (r, h, r)}[kind]
            self.hi = np.array(half)
            self.lo = -self.hi

    def define(self, stage: Usd.Stage) -> None:
        xform = UsdGeom.Xform.Define(stage, self.path)
        self.translate_op = xform.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble)
        self.orient_op = xform.AddOrientOp(UsdGeom.XformOp.PrecisionFloat)
        if self.kind == "none":   # a body without a shape: its Xform alone
            return
        path, size = self.path.AppendChild("Geom"), self.size
        if self.kind == "sphere":
            geom = UsdGeom.Sphere.Define(stage, path)
            geom.CreateRadiusAttr(float(size[0]))
        elif self.kind == "box":
            geom = UsdGeom.Cube.Define(stage, path)
            geom.CreateSizeAttr(2.0)
            geom.AddScaleOp().Set(Gf.Vec3f(*size.tolist()))
        elif self.kind in ("capsule", "cylinder"):
            geom = (UsdGeom.Capsule if self.kind == "capsule" else UsdGeom.Cylinder).Define(stage, path)
            geom.CreateRadiusAttr(float(size[0]))
            geom.CreateHeightAttr(2.0 * float(size[1]))
            geom.CreateAxisAttr(UsdGeom.Tokens.y)
        elif self.kind == "mesh":
            geom = UsdGeom.Mesh.Define(stage, path)
            geom.CreatePointsAttr(_vec3f(self.points))
            geom.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(self.faces), 3, dtype=np.int32)))
            geom.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(self.faces.reshape(-1)))
            geom.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        else:
            geom = UsdGeom.Points.Define(stage, path)
            geom.CreatePointsAttr(_vec3f(self.points))
            geom.CreateWidthsAttr(_floats(np.full(len(self.points), 2.0 * self.radius)))
        geom.CreateExtentAttr(_extent(self.lo[None], self.hi[None]))
        geom.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(_vec3f(self.color))


class _BodyWriter(_ShapeXformWriter):
    """A rigid body at /World/Bodies/<name>: translate (centre of mass) and orient sampled per frame."""

    sdf_only = True

    def __init__(self, body: BodySpec):
        label = f"BodySpec {body.name!r}"
        require(isinstance(body.index, (int, np.integer)) and not isinstance(body.index, bool) and body.index >= 0,
                 f"{label}: index must be an integer >= 0, got {body.index!r}")
        super().__init__(body, label, "body", WORLD_PATH.AppendPath(Sdf.Path(f"Bodies/{_identifier(body.name)}")))
        self.index = int(body.index)
        self.min_bodies = self.index + 1

    def define(self, stage: Usd.Stage) -> None:
        super().define(stage)
        self.translate = self.translate_op.GetAttr().GetPath()
        self.orient = self.orient_op.GetAttr().GetPath()
        self.layer = stage.GetEditTarget().GetLayer()

    def write(self, frame: Frame) -> None:
        self.layer.SetTimeSample(self.translate, frame.time, frame.body_x[self.index])
        self.layer.SetTimeSample(self.orient, frame.time, frame.body_q[self.index])


class _ColliderWriter(_ShapeXformWriter):
    """A static collider at /World/Colliders/<name>: translate and orient authored once, no time samples."""

    def __init__(self, collider: ColliderSpec):
        label = f"ColliderSpec {collider.name!r}"
        super().__init__(collider, label, "collider",
                         WORLD_PATH.AppendPath(Sdf.Path(f"Colliders/{_identifier(collider.name)}")))
        position = np.asarray(collider.position, dtype=np.float64)
        require(position.shape == (3,) and bool(np.isfinite(position).all()),
                 f"{label}: position must be 3 finite floats [m], got {collider.position!r}")
        q = np.asarray(collider.orientation, dtype=np.float64)
        norm = float(np.linalg.norm(q)) if q.shape == (4,) else math.nan
        require(abs(norm - 1.0) <= QUAT_NORM_TOLERANCE,
                 f"{label}: orientation must be a unit quaternion (x, y, z, w) (norm within {QUAT_NORM_TOLERANCE} "
                 f"of 1), got {collider.orientation!r}")
        self.position, self.orientation = position, q / norm

    def define(self, stage: Usd.Stage) -> None:
        super().define(stage)
        x, y, z, w = self.orientation.tolist()
        self.translate_op.Set(Gf.Vec3d(*self.position.tolist()))
        self.orient_op.Set(Gf.Quatf(w, x, y, z))


def prim_writers(layout: StageLayout) -> list[_PrimWriter]:
    """All prim writers for ``layout``; add new prim kinds here."""
    writers: list[_PrimWriter] = [_PointsWriter(g) for g in layout.points_groups]
    if layout.springs is not None and np.asarray(layout.springs).size:
        writers.append(_SpringsWriter(layout.springs, layout.spring_width))
    writers += [_PlaneWriter(p) for p in layout.planes]
    writers += [_BodyWriter(b) for b in layout.bodies]
    writers += [_ColliderWriter(c) for c in layout.colliders]
    writers += [_MeshWriter(m) for m in layout.meshes]
    dupes = sorted(str(p) for p, n in Counter(w.path for w in writers).items() if n > 1)  # linear: thousands of bodies
    require(not dupes, f"layout names must be unique after Tf.MakeValidIdentifier; duplicated prim paths: {dupes}")
    for pool in (w for w in writers if w.pool is not None):  # dead slots hold no valid particle
        lo, hi = pool.pool.start, pool.pool.stop
        shared = [str(w.path) for w in writers if w is not pool and w.uses(lo, hi)]
        require(not shared, f"pooled group {str(pool.path)!r}: its slots {lo} .. {hi - 1} must not be read "
                 f"by other prims, got {', '.join(shared)}")
    return writers


# --------------------------------------------------------------------------- stage writer

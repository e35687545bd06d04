"""What a preview frame shows: world-space geometry per frame, recorded from a Simulator or read from a USD stage.

Positions and sizes in metres, times in seconds, colours linear RGB in 0..1.
"""
from __future__ import annotations

import math
import os
import pathlib
from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom

from ..simulator import Simulator
from ..stages import stage_layout
from ..util import checks
from ..util.rotations import quat_to_matrix

#: Default colour of geometry without a displayColor (linear RGB, 0..1).
DEFAULT_COLOR = (0.6, 0.6, 0.6)


def _empty(width: int) -> np.ndarray:
    return np.zeros((0,) + ((width,) if width else ()), dtype=np.float64)


# ---------------------------------------------------------------------------------------------------------------
# what a frame shows


@dataclass
class Snapshot:
    """What one frame shows, in world coordinates [m]: spheres (``centres`` (N, 3), ``radii`` (N,),
    ``sphere_colors`` (N, 3)), ``triangles`` (T, 3, 3) with ``triangle_colors`` (T, 3) and line
    ``segments`` (S, 2, 3) with ``segment_colors`` (S, 3); colours linear RGB in 0..1; ``time`` [s]."""

    time: float = 0.0
    centres: np.ndarray = field(default_factory=lambda: _empty(3))
    radii: np.ndarray = field(default_factory=lambda: _empty(0))
    sphere_colors: np.ndarray = field(default_factory=lambda: _empty(3))
    triangles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    triangle_colors: np.ndarray = field(default_factory=lambda: _empty(3))
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    segment_colors: np.ndarray = field(default_factory=lambda: _empty(3))

    def __add__(self, other: "Snapshot") -> "Snapshot":
        return Snapshot(self.time, *(np.concatenate([getattr(self, k), getattr(other, k)]) for k in (
            "centres", "radii", "sphere_colors", "triangles", "triangle_colors", "segments", "segment_colors")))

    def bounds(self):
        """(lo, hi) [m] of everything drawn, or None when it draws nothing."""
        parts = [self.centres - self.radii[:, None], self.centres + self.radii[:, None],
                 self.triangles.reshape(-1, 3), self.segments.reshape(-1, 3)]
        points = np.concatenate(parts)
        points = points[np.isfinite(points).all(axis=1)]
        return (points.min(axis=0), points.max(axis=0)) if len(points) else None


class _Parts:
    """Collects geometry for one Snapshot."""

    def __init__(self):
        self.spheres, self.tris, self.segs = [], [], []

    def add_spheres(self, centres, radii, colors):
        centres = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
        n = len(centres)
        if n:
            self.spheres.append((centres, np.broadcast_to(np.asarray(radii, dtype=np.float64), (n,)),
                                 np.broadcast_to(np.asarray(colors, dtype=np.float64), (n, 3))))

    def add_triangles(self, triangles, colors):
        triangles = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        if len(triangles):
            self.tris.append((triangles, np.broadcast_to(np.asarray(colors, dtype=np.float64), (len(triangles), 3))))

    def add_segments(self, segments, colors):
        segments = np.asarray(segments, dtype=np.float64).reshape(-1, 2, 3)
        if len(segments):
            self.segs.append((segments, np.broadcast_to(np.asarray(colors, dtype=np.float64), (len(segments), 3))))

    def snapshot(self, time: float = 0.0) -> Snapshot:
        snap = Snapshot(float(time))
        if self.spheres:
            snap.centres, snap.radii, snap.sphere_colors = (np.concatenate(a) for a in zip(*self.spheres))
        if self.tris:
            snap.triangles, snap.triangle_colors = (np.concatenate(a) for a in zip(*self.tris))
        if self.segs:
            snap.segments, snap.segment_colors = (np.concatenate(a) for a in zip(*self.segs))
        return snap


@dataclass(frozen=True)
class _Plane:
    normal: np.ndarray          # unit
    offset: float               # normal . x = offset [m]
    centre: np.ndarray          # a point of it [m]
    half_size: float            # drawn out to this distance from centre along its tangents [m]; inf: unbounded


def _plane(normal, offset, size=math.inf) -> _Plane:
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    # ground-like planes are drawn unbounded; walls as squares of side ``size``, as in the USD stage
    half = math.inf if n[1] > math.cos(math.radians(30.0)) else 0.5 * float(size)
    return _Plane(n, float(offset), n * float(offset), half)


@dataclass
class Recording:
    """Frames to render: ``frames`` (one Snapshot each, times in seconds), ``static`` geometry drawn in every
    frame (colliders), ``planes`` and the frame rate ``fps`` [1/s]."""

    frames: list
    static: Snapshot = field(default_factory=Snapshot)
    planes: list = field(default_factory=list)
    fps: float = 30.0

    def __len__(self) -> int:
        return len(self.frames)

    def points(self, limit: int = 200_000):
        """(points (N, 3) [m], radii (N,) [m]): sphere centres with their radii, triangle corners and segment
        ends of every frame (at most about ``limit``, evenly thinned), for framing a camera."""
        parts = [(s.centres, s.radii) for s in [self.static, *self.frames]]
        parts += [(s.triangles.reshape(-1, 3), np.zeros(3 * len(s.triangles))) for s in [self.static, *self.frames]]
        parts += [(s.segments.reshape(-1, 3), np.zeros(2 * len(s.segments))) for s in [self.static, *self.frames]]
        points = np.concatenate([p for p, _ in parts])
        radii = np.concatenate([r for _, r in parts])
        finite = np.isfinite(points).all(axis=1)
        points, radii = points[finite], radii[finite]
        step = max(1, len(points) // limit)
        return points[::step], radii[::step]

    def bounds(self):
        """(lo, hi) [m]: the box around everything drawn in any frame (planes aside); a 2 m box when empty."""
        boxes = [b for b in (s.bounds() for s in [self.static, *self.frames]) if b is not None]
        if not boxes:
            return np.array([-1.0, 0.0, -1.0]), np.array([1.0, 2.0, 1.0])
        return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)


# ---------------------------------------------------------------------------------------------------------------
# shapes as spheres and triangles in their own frame

_BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
_BOX_CORNERS = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def _box(half) -> np.ndarray:
    return (_BOX_CORNERS * np.asarray(half, dtype=np.float64))[_BOX_FACES]


def _lathe(rho, y, segments: int) -> np.ndarray:
    """Triangles of the surface of revolution about +Y through rings of radius rho [m] at heights y [m]."""
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    rho, y = np.asarray(rho, dtype=np.float64)[:, None], np.asarray(y, dtype=np.float64)[:, None]
    v = np.stack([rho * np.cos(phi), np.broadcast_to(y, (len(y), segments)), rho * np.sin(phi)], axis=-1)
    a, b = v[:-1], np.roll(v[:-1], -1, axis=1)
    c, d = np.roll(v[1:], -1, axis=1), v[1:]
    tris = np.concatenate([np.stack([a, b, c], axis=-2), np.stack([a, c, d], axis=-2)]).reshape(-1, 3, 3)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    return tris[np.linalg.norm(np.cross(e1, e2), axis=1) > 1e-12]    # no pole slivers


def _cylinder(radius: float, half_height: float, segments: int) -> np.ndarray:
    return _lathe([0.0, radius, radius, 0.0], [half_height, half_height, -half_height, -half_height], segments)


def _capsule(radius: float, half_height: float, segments: int) -> np.ndarray:
    theta = np.linspace(0.0, np.pi / 2.0, 5)
    rho = np.concatenate([radius * np.sin(theta), radius * np.sin(theta[::-1])])
    y = np.concatenate([half_height + radius * np.cos(theta), -half_height - radius * np.cos(theta[::-1])])
    return _lathe(rho, y, segments)


def _fan(face_counts, face_indices) -> np.ndarray:
    """(T, 3) triangles of polygons given as USD face counts and vertex indices (fan triangulation)."""
    counts = np.asarray(face_counts, dtype=np.int64)
    indices = np.asarray(face_indices, dtype=np.int64)
    if counts.size == 0:
        return np.zeros((0, 3), dtype=np.int64)
    starts = np.cumsum(counts) - counts
    per = np.maximum(counts - 2, 0)
    face = np.repeat(np.arange(len(counts)), per)
    k = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per) + 1
    base = starts[face]
    return np.stack([indices[base], indices[base + k], indices[base + k + 1]], axis=1)


@dataclass(frozen=True)
class _Local:
    """A shape in its own frame [m]: spheres (centres, radii) and triangles (T, 3, 3)."""
    centres: np.ndarray
    radii: np.ndarray
    triangles: np.ndarray


def _local_shape(kind: str, size=(), points=None, faces=None, radius=0.02, segments: int = 16) -> _Local:
    """Tessellate a warp_sim shape kind (sphere, box, capsule, cylinder along Y, mesh, points)."""
    none, no_tris = _empty(3), np.zeros((0, 3, 3))
    size = tuple(float(s) for s in size)
    if kind == "sphere":
        return _Local(np.zeros((1, 3)), np.array([size[0]]), no_tris)
    if kind == "box":
        return _Local(none, _empty(0), _box(size))
    if kind == "cylinder":
        return _Local(none, _empty(0), _cylinder(size[0], size[1], segments))
    if kind == "capsule":
        return _Local(none, _empty(0), _capsule(size[0], size[1], segments))
    if kind == "mesh":
        points = np.asarray(points, dtype=np.float64)
        return _Local(none, _empty(0), points[np.asarray(faces, dtype=np.int64)])
    if kind == "points":
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return _Local(points, np.full(len(points), float(radius)), no_tris)
    if kind == "none":   # a body without a shape: nothing to draw
        return _Local(none, _empty(0), no_tris)
    raise checks.fail("kind", kind, "expected sphere, box, capsule, cylinder, mesh or points")


def _place(local: _Local, rotations: np.ndarray, translations: np.ndarray, colors: np.ndarray, parts: _Parts):
    """Add ``local`` placed at every (R, t) of (G, 3, 3) rotations and (G, 3) translations [m]."""
    if len(local.centres):
        centres = np.einsum("gij,nj->gni", rotations, local.centres) + translations[:, None]
        parts.add_spheres(centres.reshape(-1, 3), np.tile(local.radii, len(rotations)),
                          np.repeat(colors, len(local.centres), axis=0))
    if len(local.triangles):
        tris = np.einsum("gij,tkj->gtki", rotations, local.triangles) + translations[:, None, None]
        parts.add_triangles(tris.reshape(-1, 3, 3), np.repeat(colors, len(local.triangles), axis=0))


# ---------------------------------------------------------------------------------------------------------------
# from a simulator


class _SimulatorLayout:
    """What a Simulator's scene draws, prepared once: the same layout as its USD stage."""

    def __init__(self, sim, segments: int = 16):
        layout = stage_layout(sim.scene)
        self.groups = layout.points_groups
        self.springs = layout.springs
        self.meshes = [(m.start, m.start + _fan(m.face_counts, m.face_indices), np.asarray(m.color, dtype=np.float64))
                       for m in layout.meshes]
        groups: dict = {}
        for body in layout.bodies:
            key = (body.kind, tuple(body.size), id(body.points), float(body.radius))
            groups.setdefault(key, []).append(body)
        self.body_groups = []
        for bodies in groups.values():
            b = bodies[0]
            local = _local_shape(b.kind, b.size, b.points, b.faces, b.radius, segments)
            self.body_groups.append((local, np.array([x.index for x in bodies]),
                                     np.array([x.color for x in bodies], dtype=np.float64)))
        parts = _Parts()
        for c in layout.colliders:
            local = _local_shape(c.kind, c.size, c.points, c.faces, c.radius, segments)
            _place(local, quat_to_matrix(c.orientation)[None], np.asarray(c.position, dtype=np.float64)[None],
                   np.asarray([c.color], dtype=np.float64), parts)
        self.static = parts.snapshot()
        self.planes = [_plane(p.normal, p.offset, p.size) for p in layout.planes]

    def snapshot(self, arrays: dict, time: float) -> Snapshot:
        parts = _Parts()
        x = arrays.get("particle_x")
        for group in self.groups:
            rows = slice(group.start, group.start + group.count)
            if group.pooled:
                alive = np.flatnonzero(arrays["particle_alive"][rows]) + group.start
                alive = alive[arrays["particle_opacity"][alive] >= 0.05]
                parts.add_spheres(x[alive], arrays["particle_radius"][alive], arrays["particle_color"][alive])
            else:
                parts.add_spheres(x[rows], np.asarray(group.widths) / 2.0, group.color)
        if self.springs is not None:
            parts.add_segments(x[self.springs], (0.25, 0.25, 0.3))
        for start, tris, color in self.meshes:
            parts.add_triangles(x[tris], color)
        for local, index, colors in self.body_groups:
            _place(local, quat_to_matrix(arrays["body_q"][index]), arrays["body_x"][index].astype(np.float64),
                   colors, parts)
        return parts.snapshot(time)


def _check_simulator(sim):
    if not isinstance(sim, Simulator):
        raise checks.fail("sim", sim, "expected a warp_sim.Simulator")


def snapshot(sim) -> Recording:
    """A one-frame Recording of a Simulator's current state (nothing is stepped)."""
    _check_simulator(sim)
    layout = _SimulatorLayout(sim)
    return Recording([layout.snapshot(sim.frame_arrays(), sim.time)], layout.static, layout.planes)


def record(sim, seconds: float, fps: float = 30.0, substeps="auto", callback=None) -> Recording:
    """Run ``sim`` for round(seconds * fps) frames (``substeps`` as ``Simulator.run`` takes it: frame 0
    is the state before the first step) and keep what each frame shows.

    seconds [s], fps [frames per second]; callback(sim, frame) is called after each frame is taken (e.g.
    to measure something). Returns a Recording."""
    _check_simulator(sim)
    start = sim.time
    steps = sim.frames(seconds, fps, substeps)
    layout = _SimulatorLayout(sim)
    frames = []
    for frame, time, arrays in steps:
        frames.append(layout.snapshot(arrays, time - start))
        if callback is not None:
            callback(sim, frame)
    return Recording(frames, layout.static, layout.planes, fps)


# ---------------------------------------------------------------------------------------------------------------
# from a USD stage


def _gf_matrix(m) -> np.ndarray:
    return np.array([[m[i][j] for j in range(4)] for i in range(4)], dtype=np.float64)


def _primvar(prim, name: str, time, default):
    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    value = primvar.Get(time) if primvar and primvar.HasValue() else None
    return default if value is None or len(value) == 0 else np.asarray(value, dtype=np.float64)


class _UsdItem:
    """One gprim of a stage: draws itself into _Parts at a time code."""

    def __init__(self, prim, segments: int):
        self.prim, self.segments = prim, segments
        self.type = prim.GetTypeName()
        self.gprim = UsdGeom.Gprim(prim)
        self.topology = None

    def time_varying(self) -> bool:
        if any(attr.GetNumTimeSamples() > 0 for attr in self.prim.GetAttributes()):
            return True
        prim = self.prim
        while prim and not prim.IsPseudoRoot():
            xformable = UsdGeom.Xformable(prim)
            if xformable and xformable.TransformMightBeTimeVarying():
                return True
            prim = prim.GetParent()
        return False

    def draw(self, parts: _Parts, time, cache) -> None:
        prim = self.prim
        m = _gf_matrix(cache.GetLocalToWorldTransform(prim))
        linear, shift = m[:3, :3], m[3, :3]

        def world(p):
            return np.asarray(p, dtype=np.float64).reshape(-1, 3) @ linear + shift

        color = _primvar(prim, "displayColor", time, np.array([DEFAULT_COLOR]))
        kind = self.type
        if kind == "Points":
            points = world(UsdGeom.Points(prim).GetPointsAttr().Get(time) or [])
            if not len(points):
                return
            widths = np.asarray(UsdGeom.Points(prim).GetWidthsAttr().Get(time) or [0.02], dtype=np.float64)
            scale = abs(np.linalg.det(linear)) ** (1.0 / 3.0)
            radii = 0.5 * scale * (widths if len(widths) == len(points) else np.full(len(points), widths[0]))
            colors = color if len(color) == len(points) else np.broadcast_to(color[0], (len(points), 3))
            opacity = _primvar(prim, "displayOpacity", time, None)
            if opacity is not None and len(opacity) == len(points):
                keep = opacity >= 0.05
                points, radii, colors = points[keep], radii[keep], colors[keep]
            parts.add_spheres(points, radii, colors)
        elif kind == "Mesh":
            mesh = UsdGeom.Mesh(prim)
            if self.topology is None or mesh.GetFaceVertexIndicesAttr().GetNumTimeSamples():
                counts = mesh.GetFaceVertexCountsAttr().Get(time)
                self.face_counts = np.asarray(counts if counts is not None else [], dtype=np.int64)
                self.topology = _fan(self.face_counts, mesh.GetFaceVertexIndicesAttr().Get(time) or [])
            points = world(mesh.GetPointsAttr().Get(time) or [])
            if not len(points) or not len(self.topology):
                return
            faces = len(self.face_counts)
            if len(color) == faces:
                colors = np.repeat(color, np.maximum(self.face_counts - 2, 0), axis=0)
            elif len(color) == len(points):
                colors = color[self.topology].mean(axis=1)
            else:
                colors = color[0]
            parts.add_triangles(points[self.topology], colors)
        elif kind == "BasisCurves":
            curves = UsdGeom.BasisCurves(prim)
            points = world(curves.GetPointsAttr().Get(time) or [])
            counts = np.asarray(curves.GetCurveVertexCountsAttr().Get(time) or [len(points)], dtype=np.int64)
            if not len(points) or counts.sum() != len(points):
                return
            ends = np.cumsum(counts)
            a = np.arange(len(points) - 1)
            a = a[~np.isin(a + 1, ends)]          # no segment across two curves
            parts.add_segments(np.stack([points[a], points[a + 1]], axis=1), (0.25, 0.25, 0.3))
        elif kind in ("Sphere", "Cube", "Capsule", "Cylinder"):
            schema = getattr(UsdGeom, kind)(prim)
            if kind == "Sphere":
                local = _local_shape("sphere", (schema.GetRadiusAttr().Get(time),))
            elif kind == "Cube":
                half = 0.5 * schema.GetSizeAttr().Get(time)
                local = _local_shape("box", (half, half, half))
            else:
                r, height = schema.GetRadiusAttr().Get(time), schema.GetHeightAttr().Get(time)
                local = _local_shape(kind.lower(), (r, 0.5 * height), segments=self.segments)
                axis = schema.GetAxisAttr().Get(time)
                if axis in ("X", "Z"):        # tessellated along Y: swap Y with the axis
                    order = [1, 0, 2] if axis == "X" else [0, 2, 1]
                    local = _Local(local.centres, local.radii, local.triangles[..., order])
            if len(local.centres):
                scale = abs(np.linalg.det(linear)) ** (1.0 / 3.0)
                parts.add_spheres(world(local.centres), scale * local.radii, color[0])
            if len(local.triangles):
                parts.add_triangles(world(local.triangles).reshape(-1, 3, 3), color[0])


def read_usd(path, frames=None, segments: int = 16) -> Recording:
    """A Recording of a USD stage: every time code from the start to the end time code (or the given
    ``frames``, time codes), at the stage's timeCodesPerSecond. Meshes under a prim named ``Planes`` are
    drawn as planes (checkered floors); everything without time samples is drawn once as static geometry.
    Invisible prims are skipped."""
    if not isinstance(path, (str, os.PathLike)):
        raise checks.fail("path", path, "expected the path of a USD stage (str or pathlib.Path)")
    path = pathlib.Path(path)
    if not path.is_file():
        raise checks.fail("path", str(path), "no such file")
    stage = Usd.Stage.Open(str(path))
    if stage is None:
        raise checks.fail("path", str(path), "could not be opened as a USD stage")
    fps = stage.GetTimeCodesPerSecond() or 24.0
    start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    if frames is None:
        times = [float(t) for t in np.arange(start, end + 0.5)] if end >= start else [0.0]
    else:
        times = [float(t) for t in np.atleast_1d(checks.finite_array("frames", frames, (-1,)))]
        if not times:
            raise checks.fail("frames", frames, "expected at least one time code")
    static_parts, dynamic, planes = _Parts(), [], []
    first = Usd.TimeCode(times[0])
    cache = UsdGeom.XformCache(first)
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Gprim):
            continue
        if UsdGeom.Imageable(prim).ComputeVisibility(first) == UsdGeom.Tokens.invisible:
            continue
        if prim.GetTypeName() == "Mesh" and "Planes" in prim.GetPath().pathString.split("/")[:-1]:
            points = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(first), dtype=np.float64)
            if len(points) >= 3:
                m = _gf_matrix(cache.GetLocalToWorldTransform(prim))
                points = points @ m[:3, :3] + m[3, :3]
                normal = np.cross(points[1] - points[0], points[2] - points[0])
                if np.linalg.norm(normal) > 0:
                    normal /= np.linalg.norm(normal)
                    size = 2.0 * float(np.abs(points - points.mean(axis=0)).max())
                    planes.append(_plane(normal, float(normal @ points[0]), size))
                    continue
        item = _UsdItem(prim, segments)
        if item.time_varying():
            dynamic.append(item)
        else:
            item.draw(static_parts, first, cache)
    snapshots = []
    for t in times:
        code, parts = Usd.TimeCode(t), _Parts()
        cache = UsdGeom.XformCache(code)
        for item in dynamic:
            item.draw(parts, code, cache)
        snapshots.append(parts.snapshot((t - times[0]) / fps))
    return Recording(snapshots, static_parts.snapshot(), planes, float(fps))



"""Previews without a GPU or a display: a small numpy rasteriser, PNG frames and an HTML flipbook.

Two sources: a :class:`~warp_sim.Simulator` run frame by frame (:func:`record`), or a USD stage
written by ``Simulator.run(usd=...)`` (:func:`read_usd`; any stage of Points, Meshes, BasisCurves,
Spheres, Cubes, Capsules and Cylinders under Xforms will do). Either becomes a :class:`Recording`
(world-space geometry per frame), which :func:`render` draws with a fixed perspective camera:

* particles and spheres as shaded discs, at least ``min_point_px`` pixels in radius;
* cloth, soft bodies, boxes, capsules, cylinders and meshes as flat-shaded triangles (z-buffer);
* springs and curves as one-pixel lines;
* planes as checkered floors fading into the sky, with straight-down blob shadows on floors.

:func:`flipbook` wraps the frames in a self-contained HTML page (base64 PNGs, a slider and a play
button) whose :class:`Flipbook` shows itself inline in Jupyter; :func:`animate` does all three::

    import warp_sim as ws
    from warp_sim import preview

    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    preview.animate(sim, seconds=2.0, fps=30, substeps=8)        # runs the simulator, then shows it
    preview.animate("out/scene.usdc", camera=dict(azimuth=60))   # or a written stage

The camera: ``camera=None`` looks at the centre of the box around everything in every frame (planes
aside) from azimuth 35 and elevation 20 degrees, as near as it can with all of it in view; a dict
of :meth:`Camera.framing` options (``azimuth``, ``elevation``, ``fov``, ``zoom``) changes those; a
:class:`Camera` (eye, target, up, fov) fixes it.
The sky and the floors do not change with the frame and are drawn once per render.

Units: positions and sizes in metres, angles in degrees, times in seconds, image sizes in pixels.
PNG files are written with zlib and struct only. Speed: 64 frames of 320 x 240 of a few dozen
bodies and particles and a 20 x 20 cloth take about a second to draw and encode on two CPU cores.
"""
from __future__ import annotations

import base64
import hashlib
import html
import itertools
import json
import math
import os
import pathlib
import struct
import zlib
from dataclasses import dataclass, field

import numpy as np

from . import checks
from .rotations import quat_to_matrix

__all__ = ["Camera", "Snapshot", "Recording", "snapshot", "record", "read_usd", "render", "png_bytes", "PNGImage",
           "Flipbook", "flipbook", "animate"]

#: Default colour of geometry without a displayColor (linear RGB, 0..1).
DEFAULT_COLOR = (0.6, 0.6, 0.6)
#: Triangles and discs whose pixel bounding boxes add up to more than this are drawn in chunks.
_CHUNK_PIXELS = 1 << 21
#: Largest image side accepted [px].
_MAX_SIDE = 4096

_SKY_TOP = np.array([0.66, 0.77, 0.91])
_SKY_HORIZON = np.array([0.92, 0.93, 0.95])
_FLOOR = (np.array([0.82, 0.81, 0.78]), np.array([0.70, 0.69, 0.66]))
_WALL = (np.array([0.84, 0.83, 0.88]), np.array([0.75, 0.74, 0.80]))
_SHADOW = 0.62          # floor brightness under a shadow
_FLOOR_SAMPLES = 2      # the sky and floors are drawn at this many samples per pixel side, then averaged
_CHECKER = 1.0 / 4.0    # checker square [m] per metre from the camera to its target (rounded to 1, 2, 5)
_AMBIENT, _DIFFUSE = 0.38, 0.62


def _empty(width: int) -> np.ndarray:
    return np.zeros((0,) + ((width,) if width else ()), dtype=np.float64)


def _nice(x: float) -> float:
    """The number 1, 2 or 5 times a power of ten nearest (in ratio) to x > 0."""
    exponent = math.floor(math.log10(x))
    base = 10.0 ** exponent
    return min((m * base for m in (1.0, 2.0, 5.0, 10.0)), key=lambda v: abs(math.log(v / x)))


# ---------------------------------------------------------------------------------------------------------------
# the camera


@dataclass(frozen=True)
class Camera:
    """A perspective pinhole camera: ``eye`` and ``target`` [m], ``up`` (a direction), ``fov`` the vertical
    field of view [degrees]. :meth:`framing` builds one that looks at a bounding box."""

    eye: tuple = (3.0, 2.0, 4.0)
    target: tuple = (0.0, 0.5, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 40.0

    def __post_init__(self):
        eye, target = checks.vec3("eye", self.eye), checks.vec3("target", self.target)
        up = checks.unit_vec3("up", self.up)
        fov = checks.scalar("fov", self.fov, low=1.0, high=170.0)
        forward = target - eye
        if np.linalg.norm(forward) < 1e-9:
            raise checks.fail("target", self.target, "must differ from eye")
        if np.linalg.norm(np.cross(forward / np.linalg.norm(forward), up)) < 1e-6:
            raise checks.fail("up", self.up, "must not be parallel to the viewing direction target - eye")
        object.__setattr__(self, "eye", tuple(eye.tolist()))
        object.__setattr__(self, "target", tuple(target.tolist()))
        object.__setattr__(self, "up", tuple(up.tolist()))
        object.__setattr__(self, "fov", fov)

    @classmethod
    def framing(cls, lo, hi, azimuth: float = 35.0, elevation: float = 20.0, fov: float = 40.0, zoom: float = 1.0,
                aspect: float = 4.0 / 3.0, points=None, radii=None) -> "Camera":
        """A camera looking at the centre of the box ``lo``..``hi`` [m] from ``azimuth`` (degrees about +Y,
        0 = from +Z, 90 = from +X) and ``elevation`` (degrees above the horizontal), as near as it can be
        with the box's 8 corners in the view of an image ``aspect`` = width / height wide (8 % to spare),
        or, when given, the ``points`` (N, 3) [m] with their ``radii`` (N,) [m] (spheres; default 0);
        ``zoom`` > 1 moves closer."""
        lo, hi = checks.vec3("lo", lo), checks.vec3("hi", hi)
        if np.any(hi < lo):
            raise checks.fail("hi", hi, f"must be >= lo = {lo} in every coordinate")
        zoom = checks.scalar("zoom", zoom, low=0.0, low_open=True)
        aspect = checks.scalar("aspect", aspect, low=0.0, low_open=True)
        fov = checks.scalar("fov", fov, low=1.0, high=170.0)
        elevation = checks.scalar("elevation", elevation, low=-89.0, high=89.0)
        azimuth = checks.scalar("azimuth", azimuth)
        centre = 0.5 * (lo + hi)
        a, e = math.radians(azimuth), math.radians(elevation)
        direction = np.array([math.sin(a) * math.cos(e), math.sin(e), math.cos(a) * math.cos(e)])
        forward = -direction
        right = np.cross(forward, (0.0, 1.0, 0.0))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        tan_y = math.tan(math.radians(fov) / 2.0)
        tan_x = tan_y * aspect
        if points is None:
            offsets = _BOX_CORNERS * np.maximum(0.5 * (hi - lo), 0.02)
            pad = np.zeros(len(offsets))
        else:
            offsets = checks.finite_array("points", points, (-1, 3)) - centre
            pad = np.zeros(len(offsets)) if radii is None else checks.finite_array("radii", radii, (len(offsets),))
            if not len(offsets):
                raise checks.fail("points", points, "expected at least one point")
        x, y, z = np.abs(offsets @ right) + pad, np.abs(offsets @ up) + pad, offsets @ forward
        # point k is in view from distance d when |x_k| <= tan_x (d + z_k) and |y_k| <= tan_y (d + z_k)
        distance = float(np.max(np.maximum(x / tan_x, y / tan_y) - z)) * 1.08
        distance = max(distance, float(np.max(pad - z)) * 1.05, 0.05) / zoom   # in front of everything
        return cls(eye=tuple(centre + distance * direction), target=tuple(centre), fov=fov)

    def basis(self):
        """(eye, forward, right, up) as float64 arrays: the camera frame, unit vectors."""
        eye = np.asarray(self.eye, dtype=np.float64)
        forward = np.asarray(self.target) - eye
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(self.up))
        right /= np.linalg.norm(right)
        return eye, forward, right, np.cross(right, forward)


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
        from .simulator import stage_layout

        layout = stage_layout(sim.model.scene)
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
    from .simulator import Simulator

    if not isinstance(sim, Simulator):
        raise checks.fail("sim", sim, "expected a warp_sim.Simulator")


def snapshot(sim) -> Recording:
    """A one-frame Recording of a Simulator's current state (nothing is stepped)."""
    _check_simulator(sim)
    layout = _SimulatorLayout(sim)
    return Recording([layout.snapshot(sim._frame_arrays(), sim.time)], layout.static, layout.planes)


def record(sim, seconds: float, fps: float = 30.0, substeps: int = 8, callback=None) -> Recording:
    """Run ``sim`` for round(seconds * fps) frames of ``substeps`` steps each (as ``Simulator.run`` does: frame 0
    is the state before the first step, steps of 1 / (fps substeps) seconds) and keep what each frame shows.

    seconds [s], fps [frames per second]; callback(sim, frame) is called after each frame is taken (e.g.
    to measure something). Returns a Recording."""
    _check_simulator(sim)
    seconds = checks.scalar("seconds", seconds, low=0.0, low_open=True)
    fps = checks.scalar("fps", fps, low=0.0, low_open=True)
    if isinstance(substeps, bool) or not isinstance(substeps, (int, np.integer)) or substeps < 1:
        raise checks.fail("substeps", substeps, "expected an integer >= 1")
    count = int(round(seconds * fps))
    if count < 1:
        raise checks.fail("seconds", seconds, f"covers no frame at fps={fps}; need seconds >= {0.5 / fps:g}")
    layout = _SimulatorLayout(sim)
    start, h = sim.time, 1.0 / (fps * substeps)
    frames = []
    for frame in range(count):
        if frame > 0:
            sim.step(h, steps=int(substeps))
            sim.time = start + frame / fps
        frames.append(layout.snapshot(sim._frame_arrays(), sim.time - start))
        if callback is not None:
            callback(sim, frame)
    return Recording(frames, layout.static, layout.planes, fps)


# ---------------------------------------------------------------------------------------------------------------
# from a USD stage


def _gf_matrix(m) -> np.ndarray:
    return np.array([[m[i][j] for j in range(4)] for i in range(4)], dtype=np.float64)


def _primvar(prim, name: str, time, default):
    from pxr import UsdGeom

    primvar = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    value = primvar.Get(time) if primvar and primvar.HasValue() else None
    return default if value is None or len(value) == 0 else np.asarray(value, dtype=np.float64)


class _UsdItem:
    """One gprim of a stage: draws itself into _Parts at a time code."""

    def __init__(self, prim, segments: int):
        from pxr import UsdGeom

        self.prim, self.segments = prim, segments
        self.type = prim.GetTypeName()
        self.gprim = UsdGeom.Gprim(prim)
        self.topology = None

    def time_varying(self) -> bool:
        from pxr import UsdGeom

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
        from pxr import UsdGeom

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
    from pxr import Usd, UsdGeom

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


# ---------------------------------------------------------------------------------------------------------------
# the rasteriser


def _spans(lo_x, hi_x, lo_y, hi_y):
    """Pixel fragments of inclusive integer boxes, in chunks of about _CHUNK_PIXELS: yields (primitive index,
    px, py) arrays."""
    counts = (hi_x - lo_x + 1) * (hi_y - lo_y + 1)
    cumulative = np.cumsum(counts)
    start = 0
    while start < len(counts):
        base = cumulative[start - 1] if start else 0
        stop = max(int(np.searchsorted(cumulative, base + _CHUNK_PIXELS, side="right")), start + 1)
        chunk = np.arange(start, stop)
        c = counts[chunk]
        idx = np.repeat(chunk, c)
        local = np.arange(int(c.sum())) - np.repeat(np.cumsum(c) - c, c)
        width = (hi_x - lo_x + 1)[idx]
        yield idx, lo_x[idx] + local % width, lo_y[idx] + local // width
        start = stop


class _Renderer:
    """Draws Snapshots with one camera into (H, W, 3) uint8 images; the planes (sky, floors) are drawn once."""

    def __init__(self, camera: Camera, width: int, height: int, planes, min_point_px: float, static: Snapshot):
        self.width, self.height = width, height
        self.eye, self.forward, self.right, self.up = camera.basis()
        self.target = np.asarray(camera.target, dtype=np.float64)
        self.focal = 0.5 * height / math.tan(math.radians(camera.fov) / 2.0)
        self.near = 1e-3 * float(np.linalg.norm(self.target - self.eye))      # nearer than this is not drawn [m]
        self.min_px = min_point_px
        # light from above, behind the camera's left shoulder (a unit vector towards the light)
        light = 0.8 * np.array([0.0, 1.0, 0.0]) - 0.5 * self.forward - 0.35 * self.right
        self.light = light / np.linalg.norm(light)
        self.planes = planes
        self._background()
        self.static = static

    # -- camera space
    def project(self, p):
        d = p - self.eye
        z = d @ self.forward
        with np.errstate(divide="ignore", invalid="ignore"):
            sx = 0.5 * self.width + self.focal * (d @ self.right) / z
            sy = 0.5 * self.height - self.focal * (d @ self.up) / z
        return sx, sy, z

    def _rays(self, ss: int):
        """Per sample (H ss, W ss) unnormalised ray directions with unit forward component."""
        xs = (np.arange(self.width * ss) + 0.5) / ss - 0.5 * self.width
        ys = (np.arange(self.height * ss) + 0.5) / ss - 0.5 * self.height
        return (self.forward + (xs[None, :, None] * self.right - ys[:, None, None] * self.up) / self.focal)

    def _background(self):
        """Sky and planes at 2 x 2 samples per pixel (averaged: less checker aliasing); depth at the pixel centres."""
        with np.errstate(all="ignore"):
            self._draw_background()

    def _plane_hits(self, rays, plane: _Plane):
        """Where rays (..., 3) (unit forward component) meet ``plane``: (t [m] = depth, in-plane coordinates
        a, b [m], whether it is drawn there); a plane seen from behind is not drawn (bodies stay on the side
        its normal points to, which faces the camera)."""
        height = float(plane.normal @ self.eye) - plane.offset
        denom = rays @ plane.normal
        t = -height / denom
        hit = self.eye + t[..., None] * rays
        helper = np.array([1.0, 0.0, 0.0]) if abs(plane.normal[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        tu = np.cross(plane.normal, helper)
        tu /= np.linalg.norm(tu)
        tv = np.cross(plane.normal, tu)
        a, b = (hit - plane.centre) @ tu, (hit - plane.centre) @ tv
        ok = (height > 0.0) & (denom < 0.0) & (t > 0.0)
        if math.isfinite(plane.half_size):
            ok &= (np.abs(a) <= plane.half_size) & (np.abs(b) <= plane.half_size)
        return t, a, b, ok

    def _draw_background(self):
        ss, (W, H) = _FLOOR_SAMPLES, (self.width, self.height)
        rays = self._rays(ss)
        middle = rays[:, rays.shape[1] // 2]        # the sky's shade by the elevation of each row's middle ray
        elevation = middle[:, 1] / np.linalg.norm(middle, axis=-1)
        s = np.clip(elevation, 0.0, 1.0)[:, None, None] ** 0.6
        color = np.broadcast_to(_SKY_HORIZON * (1.0 - s) + _SKY_TOP * s, rays.shape)
        depth = np.full(rays.shape[:2], np.inf)
        centres = self._rays(1)
        self.depth = np.full((H, W), np.inf)        # at the pixel centres
        distance = float(np.linalg.norm(self.target - self.eye))
        cell = _nice(distance * _CHECKER)           # checker squares [m]
        self.floor_planes = []
        for plane in self.planes:
            t, a, b, ok = self._plane_hits(rays, plane)
            ok &= t < depth
            ground = plane.normal[1] > 0.5
            light, dark = _FLOOR if ground else _WALL
            checker = ((np.floor(a / cell) + np.floor(b / cell)) % 2 == 0)[..., None]
            # fog: the floor fades into the horizon from 1.2 to 3 times the camera's distance to its target
            x = np.clip((np.nan_to_num(t, posinf=1e9) - 1.2 * distance) / (1.8 * distance), 0.0, 1.0)
            fog = (x * x * (3.0 - 2.0 * x))[..., None]
            tint = np.where(checker, light, dark) * (1.0 - fog) + _SKY_HORIZON * fog
            color = np.where(ok[..., None], tint, color)
            depth = np.where(ok, t, depth)
            t, _, _, ok = self._plane_hits(centres, plane)
            self.depth = np.where(ok & (t < self.depth), t, self.depth)
            if ground and ok.any():
                self.floor_planes.append(plane)
        self.background = color.reshape(H, ss, W, ss, 3).mean(axis=(1, 3)).reshape(-1, 3)
        self.depth = self.depth.reshape(-1)

    # -- fragments: (pixel index, depth [m], colour or None)
    def _boxes(self, lo_x, hi_x, lo_y, hi_y):
        W, H = self.width, self.height
        x0 = np.clip(np.ceil(lo_x - 0.5), 0, W).astype(np.int64)
        x1 = np.clip(np.floor(hi_x - 0.5), -1, W - 1).astype(np.int64)
        y0 = np.clip(np.ceil(lo_y - 0.5), 0, H).astype(np.int64)
        y1 = np.clip(np.floor(hi_y - 0.5), -1, H - 1).astype(np.int64)
        return x0, x1, y0, y1, (x0 <= x1) & (y0 <= y1)

    def triangle_fragments(self, triangles: np.ndarray):
        """Yields (triangle index, pixel index, depth [m]) of triangles (T, 3, 3) [m]."""
        if not len(triangles):
            return
        sx, sy, z = self.project(triangles)
        x0, x1, y0, y1, ok = self._boxes(sx.min(axis=1), sx.max(axis=1), sy.min(axis=1), sy.max(axis=1))
        area = (sx[:, 1] - sx[:, 0]) * (sy[:, 2] - sy[:, 0]) - (sx[:, 2] - sx[:, 0]) * (sy[:, 1] - sy[:, 0])
        ok &= (z > self.near).all(axis=1) & np.isfinite(area) & (np.abs(area) > 1e-9)
        keep = np.flatnonzero(ok)
        if not len(keep):
            return
        sx, sy, z, area = sx[keep], sy[keep], z[keep], area[keep]

        def edge(i, j):   # the barycentric weight of the vertex opposite edge i -> j, as a x + b y + c
            a = -(sy[:, j] - sy[:, i]) / area
            b = (sx[:, j] - sx[:, i]) / area
            return a, b, -(a * sx[:, i] + b * sy[:, i])

        w0, w1 = edge(1, 2), edge(2, 0)
        w2 = tuple(-p - q for p, q in zip(w0[:2], w1[:2])) + (1.0 - w0[2] - w1[2],)
        inv = 1.0 / z
        iz = tuple(w0[k] * inv[:, 0] + w1[k] * inv[:, 1] + w2[k] * inv[:, 2] for k in range(3))
        for idx, px, py in _spans(x0[keep], x1[keep], y0[keep], y1[keep]):
            cx, cy = px + 0.5, py + 0.5
            a = w0[0][idx] * cx + w0[1][idx] * cy + w0[2][idx]
            b = w1[0][idx] * cx + w1[1][idx] * cy + w1[2][idx]
            inside = (a >= -1e-7) & (b >= -1e-7) & (a + b <= 1.0 + 1e-7)
            idx, px, py, cx, cy = idx[inside], px[inside], py[inside], cx[inside], cy[inside]
            invz = iz[0][idx] * cx + iz[1][idx] * cy + iz[2][idx]
            yield keep[idx], py * self.width + px, 1.0 / invz

    def disc_fragments(self, centres, radii):
        """Yields (sphere index, pixel index, depth [m], camera-space normal (F, 3)) of spheres [m]."""
        if not len(centres):
            return
        sx, sy, z = self.project(centres)
        with np.errstate(divide="ignore", invalid="ignore"):
            rpx = np.maximum(self.focal * radii / z, self.min_px)
        x0, x1, y0, y1, ok = self._boxes(sx - rpx, sx + rpx, sy - rpx, sy + rpx)
        ok &= (z - radii > self.near) & np.isfinite(sx) & np.isfinite(sy)
        keep = np.flatnonzero(ok)
        for idx, px, py in _spans(x0[keep], x1[keep], y0[keep], y1[keep]):
            k = keep[idx]
            dx, dy = (px + 0.5 - sx[k]) / rpx[k], (py + 0.5 - sy[k]) / rpx[k]
            d2 = dx * dx + dy * dy
            inside = d2 <= 1.0
            k, px, py, dx, dy, d2 = k[inside], px[inside], py[inside], dx[inside], dy[inside], d2[inside]
            nz = np.sqrt(1.0 - d2)
            yield k, py * self.width + px, z[k] - radii[k] * nz, np.stack([dx, -dy, -nz], axis=1)

    def segment_fragments(self, segments):
        """Yields (segment index, pixel index, depth [m]) of one-pixel lines (S, 2, 3) [m]."""
        if not len(segments):
            return
        sx, sy, z = self.project(segments)
        ok = (z > self.near).all(axis=1) & np.isfinite(sx).all(axis=1) & np.isfinite(sy).all(axis=1)
        keep = np.flatnonzero(ok)
        if not len(keep):
            return
        sx, sy, z = sx[keep], sy[keep], z[keep]
        n = np.minimum(np.ceil(np.maximum(np.abs(sx[:, 1] - sx[:, 0]), np.abs(sy[:, 1] - sy[:, 0]))), 4096)
        n = n.astype(np.int64) + 1
        idx = np.repeat(np.arange(len(n)), n)
        s = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / np.maximum(n[idx] - 1, 1)
        px = np.floor(sx[idx, 0] + s * (sx[idx, 1] - sx[idx, 0])).astype(np.int64)
        py = np.floor(sy[idx, 0] + s * (sy[idx, 1] - sy[idx, 0])).astype(np.int64)
        depth = 1.0 / ((1.0 - s) / z[idx, 0] + s / z[idx, 1])
        on = (px >= 0) & (px < self.width) & (py >= 0) & (py < self.height)
        yield keep[idx[on]], py[on] * self.width + px[on], depth[on]

    # -- shading
    def _shade_triangles(self, triangles, colors):
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-30)
        return colors * (_AMBIENT + _DIFFUSE * np.abs(normal @ self.light))[:, None]

    def _shadows(self, snap: Snapshot, shadow: np.ndarray):
        """Mark the floor pixels under everything (projected straight down onto each visible floor)."""
        for plane in self.floor_planes:
            n, o = plane.normal, plane.offset
            tris = [snap.triangles]
            centres, radii = snap.centres, snap.radii
            above = centres @ n - o > -radii
            if above.any():
                helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
                tu = np.cross(n, helper)
                tu /= np.linalg.norm(tu)
                tv = np.cross(n, tu)
                phi = np.linspace(0.0, 2.0 * np.pi, 9)
                ring = np.cos(phi)[:, None] * tu + np.sin(phi)[:, None] * tv            # (9, 3)
                c, r = centres[above], radii[above][:, None, None]
                rim = c[:, None] + r * ring[None]
                tris.append(np.stack([np.broadcast_to(c[:, None], rim[:, :-1].shape), rim[:, :-1], rim[:, 1:]],
                                     axis=2).reshape(-1, 3, 3))
            tris = np.concatenate(tris)
            if not len(tris):
                continue
            height = tris @ n - o                                          # (T, 3) above the plane [m]
            flat = tris - (height / n[1])[..., None] * np.array([0.0, 1.0, 0.0])
            flat += 1e-4 * n                                                # a hair above: no fight with the floor
            for _, pix, depth in self.triangle_fragments(flat):
                near_floor = depth <= self.depth[pix] * (1.0 + 1e-3) + 1e-6
                shadow[pix[near_floor]] = True

    def __call__(self, snap: Snapshot) -> np.ndarray:
        snap = self.static + snap
        image = self.background.copy()
        depth = self.depth.copy()
        if self.floor_planes:
            shadow = np.zeros(len(depth), dtype=bool)
            self._shadows(snap, shadow)
            image[shadow] *= _SHADOW
        pixels, depths, colors = [], [], []
        if len(snap.triangles):
            shaded = self._shade_triangles(snap.triangles, snap.triangle_colors)
            for k, pix, d in self.triangle_fragments(snap.triangles):
                pixels.append(pix), depths.append(d), colors.append(shaded[k])
        light_cam = np.array([self.light @ self.right, self.light @ self.up, self.light @ self.forward])
        half = light_cam - np.array([0.0, 0.0, 1.0])                        # Blinn's half vector, viewer at -z
        half /= np.linalg.norm(half)
        for k, pix, d, normal in self.disc_fragments(snap.centres, snap.radii):
            lambert = np.clip(normal @ light_cam, 0.0, 1.0)
            highlight = 0.25 * np.clip(normal @ half, 0.0, 1.0) ** 24
            pixels.append(pix), depths.append(d)
            colors.append(snap.sphere_colors[k] * (_AMBIENT + _DIFFUSE * lambert)[:, None] + highlight[:, None])
        for k, pix, d in self.segment_fragments(snap.segments):
            pixels.append(pix), depths.append(d), colors.append(snap.segment_colors[k])
        if pixels:
            pix, d, rgb = np.concatenate(pixels), np.concatenate(depths), np.concatenate(colors)
            np.minimum.at(depth, pix, d)
            front = d <= depth[pix]
            image[pix[front]] = rgb[front]
        return (np.clip(image, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8).reshape(self.height, self.width, 3)


def _recording(source, seconds, fps, substeps, frames) -> Recording:
    from .simulator import Simulator

    if isinstance(source, Recording):
        return source
    if isinstance(source, Snapshot):
        return Recording([source])
    if isinstance(source, Simulator):
        return snapshot(source) if seconds is None else record(source, seconds, fps, substeps)
    if isinstance(source, (str, os.PathLike)):
        return read_usd(source, frames)
    raise checks.fail("source", source, "expected a warp_sim.Simulator, a USD stage path, a preview.Recording "
                      "or a preview.Snapshot")


_FRAMING_OPTIONS = {"azimuth", "elevation", "fov", "zoom"}


def _camera(camera, recording: Recording, aspect: float) -> Camera:
    if isinstance(camera, Camera):
        return camera
    if camera is None or isinstance(camera, dict):
        unknown = set(camera or {}) - _FRAMING_OPTIONS
        if unknown:
            raise checks.fail("camera", camera, f"unknown framing options {sorted(unknown)}; expected some of "
                                                f"{sorted(_FRAMING_OPTIONS)}")
        lo, hi = recording.bounds()
        points, radii = recording.points()
        if not len(points):
            points, radii = None, None
        return Camera.framing(lo, hi, aspect=aspect, points=points, radii=radii, **(camera or {}))
    raise checks.fail("camera", camera, "expected a preview.Camera, a dict of Camera.framing options "
                      "(azimuth, elevation, fov, zoom) or None")


def render(source, camera=None, width: int = 320, height: int = 240, seconds: float | None = None,
           fps: float = 30.0, substeps: int = 8, frames=None, min_point_px: float = 1.0) -> list:
    """Render ``source`` to a list of (height, width, 3) uint8 RGB images, one per frame.

    source: a Recording, a Snapshot, a USD stage path (``frames``: its time codes, default all) or a
    Simulator: with ``seconds`` it is run for round(seconds * fps) frames of ``substeps`` steps
    (:func:`record`), without it its current state is drawn. camera: a Camera; a dict of
    :meth:`Camera.framing` options (azimuth, elevation [degrees], fov [degrees], zoom) for automatic
    framing of every frame's bounds; or None (automatic, azimuth 35, elevation 20). width, height [px];
    min_point_px: the smallest drawn sphere radius [px]."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value <= _MAX_SIDE:
            raise checks.fail(name, value, f"expected an integer number of pixels in 1 .. {_MAX_SIDE}")
    min_point_px = checks.scalar("min_point_px", min_point_px, low=0.0)
    recording = _recording(source, seconds, fps, substeps, frames)
    if not len(recording):
        raise checks.fail("source", source, "has no frames")
    camera = _camera(camera, recording, width / height)
    renderer = _Renderer(camera, int(width), int(height), recording.planes, min_point_px, recording.static)
    return [renderer(snap) for snap in recording.frames]


# ---------------------------------------------------------------------------------------------------------------
# PNG


def _image(image, name: str = "image") -> np.ndarray:
    """``image`` as a C-contiguous uint8 (H, W, 3 or 4) array; floats are read as 0..1 and clipped."""
    array = np.asarray(image)
    if array.ndim == 2:
        array = np.repeat(array[..., None], 3, axis=2)
    if array.ndim != 3 or array.shape[2] not in (3, 4) or array.shape[0] < 1 or array.shape[1] < 1:
        raise checks.fail(name, array.shape, "expected an image array of shape (H, W), (H, W, 3) or (H, W, 4)")
    if array.dtype == np.uint8:
        return np.ascontiguousarray(array)
    if array.dtype.kind == "f":
        if not np.isfinite(array).all():
            raise checks.fail(name, "non-finite values", "a float image must hold finite values in 0..1")
        return (np.clip(array, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    raise checks.fail(name, array.dtype, "expected uint8 (0..255) or float (0..1) pixel values")


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png_bytes(image, level: int = 9) -> bytes:
    """The PNG file (bytes) of an (H, W, 3) RGB or (H, W, 4) RGBA image (uint8, or floats in 0..1; (H, W) grey
    is drawn as RGB): 8 bits per channel, no filter (type 0 on every row), zlib ``level`` 0..9."""
    array = _image(image)
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or not 0 <= level <= 9:
        raise checks.fail("level", level, "expected a zlib compression level 0..9")
    h, w, c = array.shape
    rows = np.concatenate([np.zeros((h, 1), dtype=np.uint8), array.reshape(h, w * c)], axis=1)
    header = struct.pack(">IIBBBBB", w, h, 8, 6 if c == 4 else 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", header) + _chunk(b"IDAT", zlib.compress(rows.tobytes(), level))
            + _chunk(b"IEND", b""))


class PNGImage:
    """One image that Jupyter shows inline (``_repr_png_``); ``png`` holds the file's bytes."""

    def __init__(self, image):
        self.png = image if isinstance(image, bytes) else png_bytes(image)
        if not self.png.startswith(b"\x89PNG\r\n\x1a\n"):
            raise checks.fail("image", self.png[:16], "bytes must be a PNG file")

    def _repr_png_(self) -> bytes:
        return self.png

    def save(self, path) -> pathlib.Path:
        path = pathlib.Path(path)
        path.write_bytes(self.png)
        return path


# ---------------------------------------------------------------------------------------------------------------
# the flipbook

_FLIPBOOK_IDS = itertools.count()


def _png_size(data: bytes):
    if not isinstance(data, bytes) or not data.startswith(b"\x89PNG\r\n\x1a\n") or data[12:16] != b"IHDR":
        raise checks.fail("frames", data[:16] if isinstance(data, bytes) else type(data).__name__,
                          "each frame must be an image array or the bytes of a PNG file")
    return struct.unpack(">II", data[16:24])


class Flipbook:
    """An animation as a self-contained HTML snippet: base64 PNG frames, a slider and a play button.

    ``pngs``: the frames as PNG file bytes; ``times`` [s] per frame; ``fps``: playback frames per second.
    Jupyter shows it inline (``_repr_html_``); ``html`` is the snippet, ``save(path)`` writes a page."""

    def __init__(self, pngs, fps: float = 30.0, times=None, title: str = "warp_sim preview"):
        self.pngs = list(pngs)
        if not self.pngs:
            raise checks.fail("frames", self.pngs, "expected at least one frame")
        sizes = {_png_size(p) for p in self.pngs}
        if len(sizes) != 1:
            raise checks.fail("frames", sorted(sizes), "every frame must have the same size")
        self.width, self.height = sizes.pop()
        self.fps = checks.scalar("fps", fps, low=0.0, low_open=True)
        if times is None:
            times = np.arange(len(self.pngs)) / self.fps
        self.times = [float(t) for t in checks.finite_array("times", times, (len(self.pngs),))]
        self.title = str(title)
        digest = hashlib.sha1(b"".join(self.pngs)).hexdigest()[:10]
        self.element_id = f"warp-sim-flipbook-{digest}-{next(_FLIPBOOK_IDS)}"

    def __len__(self) -> int:
        return len(self.pngs)

    @property
    def html(self) -> str:
        frames = [base64.b64encode(p).decode("ascii") for p in self.pngs]
        n, uid, title = len(frames), self.element_id, html.escape(self.title)
        slider = max(self.width - 170, 60)
        return f"""<div id="{uid}" class="warp-sim-flipbook" style="display:inline-block;font:12px sans-serif">
<img src="data:image/png;base64,{frames[0]}" width="{self.width}" height="{self.height}" alt="{title}, frame 1 of {n}"
 title="{title}" style="display:block;border:1px solid #ccc">
<div style="margin-top:4px;white-space:nowrap">
<button type="button" style="width:70px">&#9654; play</button>
<input type="range" min="0" max="{n - 1}" value="0" step="1" style="width:{slider}px;vertical-align:middle">
<span style="font-family:monospace">1/{n}</span>
</div>
<script type="text/javascript">
(function () {{
  var root = document.getElementById("{uid}");
  if (!root) return;
  var frames = {json.dumps(frames)};
  var times = {json.dumps([round(t, 6) for t in self.times])};
  var img = root.querySelector("img"), button = root.querySelector("button");
  var slider = root.querySelector("input"), label = root.querySelector("span");
  var k = 0, timer = null;
  function show(i) {{
    k = (i + frames.length) % frames.length;
    img.src = "data:image/png;base64," + frames[k];
    slider.value = k;
    label.textContent = (k + 1) + "/" + frames.length + "  t = " + times[k].toFixed(3) + " s";
  }}
  function stop() {{
    if (timer !== null) {{ clearInterval(timer); timer = null; }}
    button.innerHTML = "&#9654; play";
  }}
  button.addEventListener("click", function () {{
    if (timer !== null) {{ stop(); return; }}
    button.innerHTML = "&#10074;&#10074; pause";
    timer = setInterval(function () {{ show(k + 1); }}, {1000.0 / self.fps:.3f});
  }});
  slider.addEventListener("input", function () {{ stop(); show(parseInt(slider.value, 10)); }});
  show(0);
}})();
</script>
</div>"""

    def _repr_html_(self) -> str:
        return self.html

    def save(self, path) -> pathlib.Path:
        """Write a standalone HTML page holding the flipbook; returns the path."""
        path = pathlib.Path(path)
        path.write_text(f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{html.escape(self.title)}"
                        f"</title></head>\n<body>\n{self.html}\n</body></html>\n", encoding="utf-8")
        return path

    def __repr__(self) -> str:
        return f"Flipbook({len(self)} frames of {self.width}x{self.height} px at {self.fps:g} fps)"


def flipbook(frames, fps: float = 30.0, times=None, title: str = "warp_sim preview") -> Flipbook:
    """A Flipbook of ``frames``: image arrays ((H, W, 3) uint8 or floats in 0..1) or PNG file bytes, all the
    same size; ``fps`` [frames per second] for playback; ``times`` [s] shown per frame (default k / fps)."""
    if isinstance(frames, (np.ndarray, bytes)) or not hasattr(frames, "__iter__"):
        raise checks.fail("frames", type(frames).__name__, "expected a list of images or PNG bytes")
    pngs = [f if isinstance(f, bytes) else png_bytes(_image(f, "frames")) for f in frames]
    return Flipbook(pngs, fps=fps, times=times, title=title)


def animate(source, camera=None, width: int = 320, height: int = 240, seconds: float | None = None,
            fps: float | None = None, substeps: int = 8, frames=None, min_point_px: float = 1.0,
            title: str = "warp_sim preview") -> Flipbook:
    """Render ``source`` (see :func:`render`) and return its Flipbook, played at ``fps`` (default: the
    recording's frame rate; for a Simulator, also the rate it is recorded at, 30 when not given)."""
    recording = _recording(source, seconds, 30.0 if fps is None else fps, substeps, frames)
    images = render(recording, camera=camera, width=width, height=height, min_point_px=min_point_px)
    rate = recording.fps if fps is None else fps
    return flipbook(images, fps=rate, times=[s.time for s in recording.frames], title=title)

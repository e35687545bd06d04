"""The camera and the rasteriser: a Recording drawn to RGB images (numpy), with a perspective camera.

Positions in metres, angles in degrees, image sizes in pixels.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..simulator import Simulator
from ..util import checks
from .frames import _BOX_CORNERS, Recording, Snapshot, _Plane, read_usd, record, snapshot

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
           fps: float = 30.0, substeps="auto", frames=None, min_point_px: float = 1.0) -> list:
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



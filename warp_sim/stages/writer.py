"""Frame-by-frame USD animation writer fed with numpy particle arrays.

Units are SI: metres, seconds, kilograms (metersPerUnit = kilogramsPerUnit = 1),
Y up. Frame ``k`` is written at time code ``k``; ``timeCodesPerSecond`` and
``framesPerSecond`` both equal the writer's ``fps``.

Each prim kind is a small ``_PrimWriter`` subclass with a define-once step
(``define``) and a per-frame step (``write``); new kinds (rigid-body Xforms,
cloth Meshes, ...) are further subclasses added in ``_prim_writers``.

The stage is built in a hidden temporary file next to the final path, saved
every ``chunk_frames`` frames, and moved onto the final path by ``close()``
with ``os.replace``, so the final path never holds a half-written stage.
"""

from __future__ import annotations

import math
import os
import pathlib
from dataclasses import dataclass

import numpy as np
from pxr import Sdf, Tf, Usd, UsdGeom, UsdPhysics, Vt

__all__ = ["PointsGroup", "PlaneSpec", "StageLayout", "StageWriter"]

#: USD file extensions accepted by the writer (the format follows the extension).
USD_EXTENSIONS = (".usd", ".usdc", ".usda")

WORLD_PATH = Sdf.Path("/World")


@dataclass(frozen=True)
class PointsGroup:
    """One ``UsdGeom.Points`` prim covering particles ``start .. start+count-1``.

    ``widths`` are diameters in metres (2 * radius), shape ``(count,)``;
    ``color`` is the linear-RGB displayColor in 0..1. ``name`` is made a valid
    USD identifier with ``Tf.MakeValidIdentifier``.
    """

    name: str
    start: int
    count: int
    widths: np.ndarray
    color: tuple[float, float, float]


@dataclass(frozen=True)
class PlaneSpec:
    """A static plane ``normal . x = offset`` (metres), drawn as a square quad of side ``size``."""

    name: str
    normal: tuple[float, float, float]
    offset: float
    size: float = 20.0


@dataclass(frozen=True)
class StageLayout:
    """What the stage contains: particle groups, spring segments, static planes.

    ``springs`` is ``(K, 2)`` global particle indices (or None); ``spring_width``
    is the drawn curve width in metres.
    """

    points_groups: tuple[PointsGroup, ...] = ()
    springs: np.ndarray | None = None
    spring_width: float = 0.005
    planes: tuple[PlaneSpec, ...] = ()


# --------------------------------------------------------------------------- helpers


def _vec3f(a: np.ndarray) -> Vt.Vec3fArray:
    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1, 3))


def _floats(a) -> Vt.FloatArray:
    return Vt.FloatArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1))


def _extent(lo: np.ndarray, hi: np.ndarray) -> Vt.Vec3fArray:
    """Extent array [min, max] from per-point lower/upper bounds, shape (n, 3), metres."""
    return _vec3f(np.stack([lo.min(axis=0), hi.max(axis=0)]))


def _identifier(name: str) -> str:
    return Tf.MakeValidIdentifier(str(name))


def _require(ok: bool, message: str) -> None:
    if not ok:
        raise ValueError(message)


# --------------------------------------------------------------------------- prim writers


class _PrimWriter:
    """One prim (or prim family) on the stage.

    ``define`` authors everything that never changes; ``write`` authors the
    time samples of one frame from all-particle arrays ``x``/``v`` ((N, 3),
    metres and metres/second). ``min_particles`` is the smallest N it accepts.
    """

    path: Sdf.Path
    min_particles: int = 0

    def define(self, stage: Usd.Stage) -> None:
        raise NotImplementedError

    def write(self, time: Usd.TimeCode, x: np.ndarray, v: np.ndarray) -> None:
        """Author one frame's samples; static prims keep this no-op."""


class _PointsWriter(_PrimWriter):
    """A ``UsdGeom.Points`` group: points, ids, widths, velocities, displayColor, extent per frame."""

    def __init__(self, group: PointsGroup):
        start, count = int(group.start), int(group.count)
        widths = np.asarray(group.widths, dtype=np.float64)
        color = np.asarray(group.color, dtype=np.float64)
        label = f"PointsGroup {group.name!r}"
        _require(start >= 0 and count >= 1,
                 f"{label}: start must be >= 0 and count >= 1, got start={start}, count={count}")
        _require(widths.shape == (count,), f"{label}: widths must have shape ({count},), got {widths.shape}")
        _require(bool(np.all(np.isfinite(widths)) and np.all(widths >= 0)),
                 f"{label}: widths must be finite and >= 0")
        _require(color.shape == (3,) and bool(np.all(np.isfinite(color))),
                 f"{label}: color must be 3 finite floats, got {group.color!r}")
        self.path = WORLD_PATH.AppendPath(Sdf.Path(f"Particles/{_identifier(group.name)}"))
        self.slice = slice(start, start + count)
        self.min_particles = start + count
        self.radii = (widths / 2.0)[:, None]
        self.ids = Vt.Int64Array.FromNumpy(np.arange(start, start + count, dtype=np.int64))
        self.widths = _floats(widths)
        self.colors = _vec3f(np.broadcast_to(color, (count, 3)))

    def define(self, stage: Usd.Stage) -> None:
        self.prim = UsdGeom.Points.Define(stage, self.path)
        self.color_primvar = self.prim.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)

    def write(self, time: Usd.TimeCode, x: np.ndarray, v: np.ndarray) -> None:
        p = x[self.slice]
        self.prim.CreatePointsAttr().Set(_vec3f(p), time)
        self.prim.CreateIdsAttr().Set(self.ids, time)
        self.prim.CreateWidthsAttr().Set(self.widths, time)
        self.prim.CreateVelocitiesAttr().Set(_vec3f(v[self.slice]), time)
        self.color_primvar.Set(self.colors, time)
        self.prim.CreateExtentAttr().Set(_extent(p - self.radii, p + self.radii), time)


class _SpringsWriter(_PrimWriter):
    """Spring segments as one linear ``UsdGeom.BasisCurves``: topology once, endpoints per frame."""

    def __init__(self, springs: np.ndarray, width: float):
        springs = np.asarray(springs)
        _require(springs.ndim == 2 and springs.shape[1] == 2 and np.issubdtype(springs.dtype, np.integer),
                 f"springs must be an integer array of shape (K, 2), got {springs.dtype} {springs.shape}")
        _require(springs.size == 0 or int(springs.min()) >= 0, "springs must hold particle indices >= 0")
        _require(math.isfinite(width) and width > 0, f"spring_width must be finite and > 0, got {width!r}")
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

    def write(self, time: Usd.TimeCode, x: np.ndarray, v: np.ndarray) -> None:
        p = x[self.springs.reshape(-1)]
        self.prim.CreatePointsAttr().Set(_vec3f(p), time)
        self.prim.CreateExtentAttr().Set(_extent(p - self.half_width, p + self.half_width), time)


class _PlaneWriter(_PrimWriter):
    """A static double-sided quad ``UsdGeom.Mesh`` for a plane; no time samples."""

    def __init__(self, plane: PlaneSpec):
        normal = np.asarray(plane.normal, dtype=np.float64)
        length = float(np.linalg.norm(normal)) if normal.shape == (3,) else 0.0
        label = f"PlaneSpec {plane.name!r}"
        _require(math.isfinite(length) and length > 0,
                 f"{label}: normal must be a finite non-zero 3-vector, got {plane.normal!r}")
        _require(math.isfinite(plane.offset), f"{label}: offset must be finite, got {plane.offset!r}")
        _require(math.isfinite(plane.size) and plane.size > 0,
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


def _prim_writers(layout: StageLayout) -> list[_PrimWriter]:
    """All prim writers for ``layout``; add new prim kinds here."""
    writers: list[_PrimWriter] = [_PointsWriter(g) for g in layout.points_groups]
    if layout.springs is not None and np.asarray(layout.springs).size:
        writers.append(_SpringsWriter(layout.springs, layout.spring_width))
    writers += [_PlaneWriter(p) for p in layout.planes]
    paths = [w.path for w in writers]
    dupes = sorted({str(p) for p in paths if paths.count(p) > 1})
    _require(not dupes, f"layout names must be unique after Tf.MakeValidIdentifier; duplicated prim paths: {dupes}")
    return writers


# --------------------------------------------------------------------------- stage writer


class StageWriter:
    """Write an animated USD stage one frame at a time; atomic on ``close()``.

    Use as a context manager: leaving the block normally calls ``close()``, an
    exception calls ``abort()`` (the final path is then left untouched).
    """

    def __init__(self, path, fps: float, layout: StageLayout, chunk_frames: int = 240):
        self._path = pathlib.Path(path)
        if not self._path.suffix:
            self._path = self._path.with_suffix(".usdc")   # binary crate by default
        ext = self._path.suffix.lower()
        _require(ext in USD_EXTENSIONS,
                 f"path must end in one of {', '.join(USD_EXTENSIONS)}; got {str(path)!r} (extension {ext!r})")
        _require(isinstance(fps, (int, float, np.number)) and math.isfinite(fps) and fps > 0,
                 f"fps must be a finite number > 0, got {fps!r}")
        _require(isinstance(chunk_frames, (int, np.integer)) and chunk_frames >= 1,
                 f"chunk_frames must be an integer >= 1, got {chunk_frames!r}")
        self._fps = float(fps)
        self._chunk_frames = int(chunk_frames)
        self._writers = _prim_writers(layout)
        self._min_particles = max((w.min_particles for w in self._writers), default=0)
        self._frames = 0

        self._path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self._path.with_name(f".{self._path.stem}.partial-{os.getpid()}{ext}")
        self._tmp.unlink(missing_ok=True)
        self._stage = Usd.Stage.CreateNew(str(self._tmp))
        self._define()

    def _define(self) -> None:
        stage = self._stage
        UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
        UsdGeom.SetStageMetersPerUnit(stage, 1.0)
        UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
        stage.SetTimeCodesPerSecond(self._fps)
        stage.SetFramesPerSecond(self._fps)
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(0)
        stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, WORLD_PATH).GetPrim())
        for writer in self._writers:
            for parent in writer.path.GetAncestorsRange():
                if parent != writer.path and not stage.GetPrimAtPath(parent):
                    UsdGeom.Xform.Define(stage, parent)
            writer.define(stage)

    @property
    def frames_written(self) -> int:
        """Number of frames written so far (the next frame index to write)."""
        return self._frames

    @property
    def path(self) -> pathlib.Path:
        """The final output path."""
        return self._path

    def _check_open(self) -> None:
        if self._stage is None:
            raise RuntimeError(f"StageWriter for {str(self._path)!r} is already closed or aborted")

    def _check_arrays(self, frame: int, x, v) -> tuple[np.ndarray, np.ndarray]:
        x, v = np.asarray(x), np.asarray(v)
        for name, a in (("particle_x", x), ("particle_v", v)):
            _require(a.ndim == 2 and a.shape[1] == 3 and a.shape[0] >= self._min_particles,
                     f"frame {frame}: {name} must have shape (N, 3) with N >= {self._min_particles}, got {a.shape}")
            bad = np.flatnonzero(~np.isfinite(a).all(axis=1))
            if bad.size:
                raise ValueError(f"frame {frame}: {name} has a non-finite value at particle index {bad[0]}")
        _require(x.shape == v.shape, f"frame {frame}: particle_x {x.shape} and particle_v {v.shape} shapes differ")
        return x, v

    def write_frame(self, frame: int, particle_x: np.ndarray, particle_v: np.ndarray) -> None:
        """Write frame ``frame`` (must be ``frames_written``) at time code ``frame``.

        ``particle_x`` (metres) and ``particle_v`` (metres/second) are (N, 3)
        arrays of all particles. Nothing is authored unless all checks pass.
        """
        self._check_open()
        _require(frame == self._frames,
                 f"frame must be written in order 0, 1, 2, ...: expected frame {self._frames}, got {frame!r}")
        x, v = self._check_arrays(frame, particle_x, particle_v)
        time = Usd.TimeCode(self._frames)
        for writer in self._writers:
            writer.write(time, x, v)
        self._frames += 1
        if self._frames % self._chunk_frames == 0:
            self._save()

    def _save(self) -> None:
        self._stage.SetEndTimeCode(max(self._frames - 1, 0))
        self._stage.Save()

    def close(self) -> pathlib.Path:
        """Save the stage and move it onto the final path; returns that path."""
        self._check_open()
        _require(self._frames > 0, f"close(): no frames written to {str(self._path)!r}; an empty animation is not a stage")
        self._save()
        self._stage = None  # release the layer before moving its file
        with open(self._tmp, "rb+") as f:  # data on disk before the rename makes it visible
            os.fsync(f.fileno())
        self._path.parent.mkdir(parents=True, exist_ok=True)
        os.replace(self._tmp, self._path)
        return self._path

    def abort(self) -> None:
        """Drop the temporary file; the final path is untouched. No-op once closed."""
        self._stage = None
        self._tmp.unlink(missing_ok=True)

    def __enter__(self) -> "StageWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            self.abort()
            return
        try:
            self.close()
        except BaseException:
            self.abort()
            raise

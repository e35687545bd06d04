"""Frame-by-frame USD animation writer fed with numpy particle and rigid-body arrays.

Units are SI: metres, seconds, kilograms (metersPerUnit = kilogramsPerUnit = 1),
Y up. Frame ``k`` is written at time code ``k``; ``timeCodesPerSecond`` and
``framesPerSecond`` both equal the writer's ``fps``.

Each prim kind is a small ``_PrimWriter`` subclass with a define-once step
(``define``) and a per-frame step (``write``); new kinds (cloth Meshes, ...)
are further subclasses added in ``prim_writers``.

A pooled particle group (an emitter's fixed-capacity pool) is a
``UsdGeom.Points`` whose point count follows its live particles: each frame it
samples points, ids, widths, velocities, displayColor and displayOpacity of
exactly the alive slots, selected with one boolean mask per group; a frame with
no live particle samples empty arrays and blocks the extent (``Sdf.ValueBlock``),
so bounds are computed (empty) rather than held from a neighbouring frame.

A cloth or soft body (``MeshSpec``) is a ``UsdGeom.Mesh`` at ``/World/Meshes/<name>`` whose
vertices are a range of particles: its topology (faceVertexCounts, faceVertexIndices), no
subdivision, double-sided and a constant displayColor are authored once; points,
velocities and extent are sampled every frame.

A rigid body is a ``UsdGeom.Xform`` whose ``xformOp:translate`` (centre of
mass, metres, double) and ``xformOp:orient`` (unit quaternion, float) are
sampled every frame, with its shape as a static child ``Geom``. Body samples
are authored at the Sdf level (``Sdf.Layer.SetTimeSample``) inside one
``Sdf.ChangeBlock`` per frame, from ``Vt`` arrays built once per frame: with
1000 bodies that measured about 10-13 ms/frame against 20-25 ms for
``Usd.Attribute.Set`` (and 30-45 ms when building ``Gf`` values per body).

A static collider (``ColliderSpec``) is a ``UsdGeom.Xform`` at ``/World/Colliders/<name>``
drawn like a body, but its translate and orient are default values, written once, with no
time samples.

The stage is built in memory and written in chunks of ``chunk_frames`` frames: each chunk's
time samples move from memory into a chunk file of the run's hidden folder beside the final path
(``stages.runs``: ``.<name>.run-<pid>/``), written once and atomically, so memory stays flat and
a kill at any moment leaves only whole chunks. ``close()`` stitches the static stage and every
chunk into one layer (``UsdUtils.StitchLayers``), exports it afresh (only live data: the size of
a stage saved once, linear in the frames) to a temporary file, flushes it and renames it onto the
final path, so the final path never holds a half-written stage.

A run that is given a ``checkpoint`` after a chunk (``StageWriter.checkpoint``) can be taken up
again by a later writer with ``resume=True`` and the same ``key``: it adopts the dead run's
folder, starts at the frame after the checkpoint and returns the checkpoint in ``resumed``.

The path is checked when the writer is made, before anything is simulated: its extension,
that it is not an existing folder, that it is no file the run reads (the overlay's input stage and
every layer and asset of it, and the stages in ``reads``: ``stages.inputs``; a ValueError before
anything is made), that its folder can be made and written (the run folder is made there at
once). Run folders of processes that are no longer alive are removed then (unless one is
resumed). Any failure of ``close()`` (a full disk, a chunk damaged since it was written) removes
the temporary export and raises OSError naming the user's path. A resume that finds a checkpoint
or chunk it cannot read says so in one warning naming the file, and goes on from the checkpoint
before it or from frame 0.
"""

from __future__ import annotations

import math
import os
import pathlib
import warnings
from typing import TYPE_CHECKING

import numpy as np
from pxr import Sdf, Tf, Usd, UsdGeom, UsdPhysics, UsdUtils, Vt

if TYPE_CHECKING:
    from typing_extensions import Self  # typing.Self needs Python 3.11

from .inputs import refuse_overwrite
from .overlay import Overlay
from .prims import POOL_ARRAYS, QUAT_NORM_TOLERANCE, Frame, check_in_range, check_rows, prim_writers, require
from .runs import (
    FORMAT,
    RunFolder,
    error_reason,
    export_layer,
    read_chunk,
    remove_strays,
    run_folder,
    strays,
    write_atomically,
)
from .specs import USD_EXTENSIONS, WORLD_PATH, StageLayout

__all__ = ["StageWriter"]


class StageWriter:
    """Write an animated USD stage one frame at a time; atomic on ``close()``.

    Use as a context manager: leaving the block normally calls ``close()``, an
    exception calls ``abort()`` (the final path is then left untouched).
    """

    def __init__(self, path, fps: float, layout: StageLayout | None, chunk_frames: int = 240, key: str | None = None,
                 resume: bool = False, overlay: Overlay | None = None, reads=()):
        require(isinstance(path, (str, os.PathLike)) and str(path).strip() != "",
                f"usd={path!r} is invalid: expected a file path ending in {', '.join(USD_EXTENSIONS)}")
        self._given = path
        self._path = pathlib.Path(path)
        if not self._path.suffix:
            self._path = self._path.with_suffix(".usdc")   # binary crate by default
        ext = self._path.suffix.lower()
        require(ext in USD_EXTENSIONS,
                 f"path must end in one of {', '.join(USD_EXTENSIONS)}; got {str(path)!r} (extension {ext!r})")
        require(isinstance(fps, (int, float, np.number)) and math.isfinite(fps) and fps > 0,
                 f"fps must be a finite number > 0, got {fps!r}")
        require(isinstance(chunk_frames, (int, np.integer)) and chunk_frames >= 1,
                 f"chunk_frames must be an integer >= 1, got {chunk_frames!r}")
        self._fps = float(fps)
        self._chunk_frames = int(chunk_frames)
        self._overlay = overlay
        self._writers = overlay.writers if overlay is not None else prim_writers(layout)
        self._time_start, self._time_step = overlay.time_code(self._fps) if overlay is not None else (0.0, 1.0)
        self._usd_writers = [w for w in self._writers if not w.sdf_only]
        self._sdf_writers = [w for w in self._writers if w.sdf_only]
        self._min_particles = max((w.min_particles for w in self._writers), default=0)
        self._min_bodies = max((w.min_bodies for w in self._writers), default=0)
        self._pools = [w.pool for w in self._writers if w.pool is not None]
        self._frames = 0

        folder = next((p for p in (pathlib.Path(path), self._path) if p.is_dir()), None)   # as given, and with .usdc
        require(folder is None, f"usd={str(path)!r} is invalid: it is an existing folder; give a file path such as "
                                f"{str((folder or self._path) / ('out' + ext))!r}")
        sources = ([(f"the input stage over={overlay.input!r}", overlay.stage)] if overlay else []) + list(reads)
        refuse_overwrite(self._path, path, sources)   # before anything is made: the output never replaces an input
        try:
            self._path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise OSError(f"cannot write {str(path)!r}: its folder cannot be made ({error.strerror})") from None
        if not os.access(self._path.parent, os.W_OK):
            raise OSError(f"cannot write {str(path)!r}: its folder {str(self._path.parent)!r} is not writable")
        self._key = key
        self._run = RunFolder(run_folder(self._path, os.getpid()))
        self._animated: set = set()   # attribute paths with time samples
        self.resumed = self._resume() if resume else None
        remove_strays(self._path, keep=self._run.folder if self.resumed is not None else None)
        if self.resumed is None:
            try:
                self._run.create()
            except OSError as error:
                raise OSError(f"cannot write {str(path)!r}: {error.strerror or error}") from None
        self._checkpointed = self._frames
        self._saving = False
        self.complete = False   # True once close() has put the whole stage on the final path
        self._stage = Usd.Stage.CreateInMemory(f"anon{self._path.suffix}")
        self._define()

    def _resume(self) -> tuple[dict, dict] | None:
        """Adopt the newest dead run's folder whose checkpoint has this writer's key: (arrays, meta) of its
        checkpoint, or None when there is none. ValueError when checkpoints exist but none has the key. A
        checkpoint or chunk that cannot be read is said in one warning naming it, with where the run goes on from:
        the checkpoint before it, or frame 0 (``RunFolder.checkpoints``)."""
        found = [(folder, *RunFolder(folder).checkpoints()) for folder in strays(self._path)]
        damaged = [item for _, _, bad in found for item in bad]
        found = [(folder, checkpoint) for folder, checkpoint, _ in found if checkpoint is not None]
        matching = [(folder, checkpoint) for folder, checkpoint in found
                    if checkpoint[1].get("key") == self._key and checkpoint[1].get("format") == FORMAT]
        if not matching:
            if found:
                folder, (_, meta, _) = found[-1]
                raise ValueError(
                    f"resume: the checkpoint of {str(self._given)!r} in {folder.name} was written for another "
                    f"scene, simulator or run arguments (fingerprint {meta.get('key')}, format "
                    f"{meta.get('format')}; this run's: {self._key}, format {FORMAT}); it was not used: run without "
                    "resume to start over (which removes it)")
            _say_damaged(damaged, "starting over from frame 0")
            return None
        folder, (arrays, meta, name) = max(matching, key=lambda item: item[1][1]["frames"])
        _say_damaged(damaged, f"going on from frame {meta['frames']}, the checkpoint before it")
        self._run.adopt(folder, meta["chunks"], name)
        self._frames = int(meta["frames"])
        return arrays, meta

    def _define(self) -> None:
        stage = self._stage
        if self._overlay is not None:
            self._overlay.define(stage, self._path)
            for writer in self._writers:
                writer.define(stage)
            return
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

    def _check_frame(self, frame: int, arrays: dict) -> Frame:
        """The checked arrays of ``frame`` (``write_frame``'s keywords); ValueError naming the array and first bad
        row otherwise.

        Each array is checked when given, and required when the layout needs it.
        Dead slots of pooled groups are not checked; the pool arrays are checked
        in the live slots only.
        """
        for what, names in (("particle", ("particle_x", "particle_v") if self._min_particles else ()),
                            ("body", ("body_x", "body_q") if self._min_bodies else ()),
                            ("pooled PointsGroup", POOL_ARRAYS if self._pools else ())):
            for name in names:
                require(arrays[name] is not None, f"frame {frame}: {name} is required: the layout has {what} prims")

        def rows(name, width, min_rows, what="particle", checked=None, kinds=""):
            a = arrays[name]
            if a is None:
                return None
            a = check_rows(frame, name, a, width, min_rows, what, checked)
            if kinds and a.dtype.kind not in kinds:
                raise ValueError(f"frame {frame}: {name} must hold {'bools or ' * ('b' in kinds)}integers, "
                                 f"got dtype {a.dtype}")
            return a

        n = self._min_particles
        alive = rows("particle_alive", None, n, kinds="biu")
        checked = live = None  # rows to check: all but dead pool slots; the live pool slots
        if alive is not None:
            alive = alive.astype(bool, copy=False)  # nonzero = alive
            checked, live = np.ones(len(alive), dtype=bool), np.zeros(len(alive), dtype=bool)
            for pool in self._pools:
                checked[pool] = live[pool] = alive[pool]
        x = rows("particle_x", 3, n, checked=checked)
        v = rows("particle_v", 3, n, checked=checked)
        if x is not None and v is not None:
            require(x.shape == v.shape, f"frame {frame}: particle_x {x.shape} and particle_v {v.shape} shapes differ")
        ids = rows("particle_id", None, n, checked=live, kinds="iu")
        radius = rows("particle_radius", None, n, checked=live)
        color = rows("particle_color", 3, n, checked=live)
        opacity = rows("particle_opacity", None, n, checked=live)
        for name, a, hi in (("particle_radius", radius, math.inf), ("particle_color", color, 1.0),
                            ("particle_opacity", opacity, 1.0)):
            if a is not None:
                check_in_range(frame, name, a, 0.0, hi, live)
        if ids is not None:
            ids = ids.astype(np.int64, copy=False)
            if live is not None:  # unique among the live slots (a sort: ~ 10 ms for 5e5 ids)
                ordered = np.sort(ids[live])
                dupes = ordered[1:][ordered[1:] == ordered[:-1]]
                if dupes.size:
                    first = np.flatnonzero(live & (ids == dupes[0]))[:2].tolist()
                    raise ValueError(f"frame {frame}: particle_id {dupes[0]} is used by more than one live particle, "
                                     f"at particle indices {first[0]} and {first[1]}")

        bx = rows("body_x", 3, self._min_bodies, "body")
        bq = rows("body_q", 4, self._min_bodies, "body")
        if bx is not None and bq is not None:
            require(len(bx) == len(bq),
                     f"frame {frame}: body_x {bx.shape} and body_q {bq.shape} hold different numbers of bodies")
        if bq is not None:
            norm = np.linalg.norm(bq.astype(np.float64), axis=1)
            bad = np.flatnonzero(np.abs(norm - 1.0) > QUAT_NORM_TOLERANCE)
            if bad.size:
                raise ValueError(f"frame {frame}: body_q has a non-unit quaternion at body index {bad[0]} "
                                 f"(norm {norm[bad[0]]:.6g}; must be within {QUAT_NORM_TOLERANCE} of 1)")
            # Vt.QuatfArray.FromNumpy reads rows in GfQuatf memory order (x, y, z, w), Warp's order.
            bq = Vt.QuatfArray.FromNumpy(np.ascontiguousarray(bq / norm[:, None], dtype=np.float32))
        if bx is not None:
            bx = Vt.Vec3dArray.FromNumpy(np.ascontiguousarray(bx, dtype=np.float64))
        return Frame(self._time_start + frame * self._time_step, x, v, bx, bq, alive, ids, radius, color, opacity)

    def write_frame(self, frame: int, particle_x: np.ndarray | None = None, particle_v: np.ndarray | None = None,
                    body_x: np.ndarray | None = None, body_q: np.ndarray | None = None,
                    particle_alive: np.ndarray | None = None, particle_id: np.ndarray | None = None,
                    particle_radius: np.ndarray | None = None, particle_color: np.ndarray | None = None,
                    particle_opacity: np.ndarray | None = None) -> None:
        """Write frame ``frame`` (must be ``frames_written``) at time code ``frame``.

        ``particle_x`` (metres) and ``particle_v`` (metres/second) are (N, 3)
        arrays of all particles, required when the layout has particle prims;
        ``body_x`` (B, 3) centres of mass (metres) and ``body_q`` (B, 4) unit
        quaternions (x, y, z, w) of all bodies, required when it has bodies
        (rows are renormalised before writing).

        The pool arrays, required when the layout has pooled groups, have the N
        rows of ``particle_x``: ``particle_alive`` (N,) bool or int, nonzero =
        alive; ``particle_id`` (N,) integer ids, unique among live slots;
        ``particle_radius`` (N,) metres, >= 0 (widths = 2 radius);
        ``particle_color`` (N, 3) linear RGB and ``particle_opacity`` (N,), both
        in [0, 1] (out of range is a ValueError, never clipped). Dead slots of
        pooled groups may hold anything, in every array; live ones must be
        finite. Nothing is authored unless all checks pass.
        """
        self._check_open()
        require(frame == self._frames,
                 f"frame must be written in order 0, 1, 2, ...: expected frame {self._frames}, got {frame!r}")
        data = self._check_frame(frame, {
            "particle_x": particle_x, "particle_v": particle_v, "body_x": body_x, "body_q": body_q,
            "particle_alive": particle_alive, "particle_id": particle_id, "particle_radius": particle_radius,
            "particle_color": particle_color, "particle_opacity": particle_opacity})
        for writer in self._usd_writers:
            writer.write(data)
        with Sdf.ChangeBlock():  # Sdf-level edits only: Usd API is unsafe inside a change block
            for writer in self._sdf_writers:
                writer.write(data)
        self._frames += 1
        if self._frames % self._chunk_frames:
            return False
        self._flush()
        return True

    def _flush(self) -> None:
        """Move the time samples of the frames since the last chunk from memory into the next chunk file."""
        layer = self._stage.GetRootLayer()

        def collect(path):
            if path.IsPropertyPath():
                spec = layer.GetAttributeAtPath(path)
                if spec is not None and spec.HasInfo("timeSamples"):
                    self._animated.add(path)
        layer.Traverse(Sdf.Path.absoluteRootPath, collect)
        chunk = Sdf.Layer.CreateAnonymous(".usdc")
        for path in sorted(self._animated):
            spec = layer.GetAttributeAtPath(path)
            if spec is None or not spec.HasInfo("timeSamples"):
                continue
            Sdf.CreatePrimInLayer(chunk, path.GetPrimPath())
            Sdf.CopySpec(layer, path, chunk, path)
            spec.ClearInfo("timeSamples")
        try:
            self._run.add_chunk(chunk)
        except OSError as error:
            raise self._cannot_write(error) from None

    def _cannot_write(self, error: Exception) -> OSError:
        """OSError naming the user's path, with the reason of ``error`` (its last line)."""
        reason = error.strerror if isinstance(error, OSError) and error.strerror else str(error).strip()
        return OSError(f"cannot write {str(self._given)!r}: {reason.splitlines()[-1] if reason else repr(error)}")

    def checkpoint(self, arrays: dict, values: dict) -> None:
        """Keep what a run needs to go on after the frames written so far (call right after the ``write_frame``
        that returned True): ``arrays`` (numpy) and ``values`` (JSON), with this writer's key; a later writer with
        ``resume=True`` and the same key returns them in ``resumed``."""
        self._check_open()
        require(self._frames % self._chunk_frames == 0 and self._frames > 0,
                f"checkpoint(): {self._frames} frames are not a whole number of chunks of {self._chunk_frames}")
        self._saving = True   # a signal from here to the end may find either checkpoint in place (suspend)
        try:
            self._run.save_checkpoint(arrays, {"key": self._key, "frames": self._frames, "values": values})
        except OSError as error:
            raise self._cannot_write(error) from None
        self._checkpointed = self._frames
        self._saving = False

    @property
    def frames_checkpointed(self) -> int:
        """Frames a resumed run would not have to simulate again (0 without a checkpoint)."""
        return self._checkpointed

    def close(self, keep_checkpoint: bool = False) -> pathlib.Path:
        """Stitch the chunks into one stage, export it afresh and move it onto the final path; returns that path.
        The run's folder is removed, unless ``keep_checkpoint``. On any failure (a full disk) the temporary export
        is removed, the run's last checkpoint is kept (to resume from) and OSError names the user's path. A signal
        (Ctrl-C, SIGTERM) while it stitches stops it the same way, the final path untouched; one during the rename
        waits until the stage is in place and ``complete`` is True, then raises."""
        self._check_open()
        require(self._frames > 0,
                 f"close(): no frames written to {str(self._path)!r}; an empty animation is not a stage")
        try:
            layer = self._stage.GetRootLayer()
            for chunk in list(self._run.chunks):
                try:
                    UsdUtils.StitchLayers(layer, read_chunk(chunk))
                except (OSError, Tf.ErrorException) as error:   # damaged since written: no resume meets it again
                    self._run.drop(chunk)
                    loaded = self._run.load_checkpoint()
                    self._checkpointed = int(loaded[1]["frames"]) if loaded is not None else 0
                    raise OSError(f"{chunk} cannot be read ({error_reason(error)}); it was removed") from None
            self._stage.SetEndTimeCode(self._time_start + max(self._frames - 1, 0) * self._time_step)
            if self._overlay is not None:
                layer = self._overlay.finish(layer, self._path)

            def committed():   # with signals held from the rename to here: a signal after it finds the run complete
                self._stage, self.complete = None, True
                if not keep_checkpoint:
                    self._run.remove()
            write_atomically(self._path, lambda temporary: export_layer(layer, temporary), committed)
        except Exception as error:   # OSError, pxr.Tf.ErrorException: one message, the user's path
            self.suspend()
            raise self._cannot_write(error) from None
        return self._path

    def suspend(self) -> int:
        """Stop without a stage, keeping the run's folder if it holds a checkpoint (a later writer with
        ``resume=True`` goes on from it); returns the frames it holds (0: nothing was kept). No-op once closed."""
        self._stage = None
        if self._saving:   # stopped while a checkpoint was written: the one in place (the last or the new) is whole
            loaded = self._run.load_checkpoint()
            self._checkpointed = int(loaded[1]["frames"]) if loaded is not None else 0
            self._saving = False
        if self._checkpointed == 0:
            self._run.remove()
        return self._checkpointed

    def abort(self) -> None:
        """Drop every temporary file and the run's folder; the final path is untouched. No-op once closed."""
        self._stage = None
        self._run.remove()

    def __enter__(self) -> Self:
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


def _say_damaged(damaged: list[tuple[pathlib.Path, str]], then: str) -> None:
    """One warning for the files of run folders that cannot be read: the first named, with its reason."""
    if damaged:
        (path, reason), more = damaged[0], len(damaged) - 1
        others = f" (and {more} more file{'s' * (more > 1)})" if more else ""
        warnings.warn(f"resume: {path} cannot be read ({reason}){others}; {then}", stacklevel=4)

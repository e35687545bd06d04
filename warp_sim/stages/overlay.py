"""The way back to a DCC tool: the animation as a layer of overrides on the input stage's own prims.

The overlay layer sublayers the input and carries its stage metadata (up axis, units, time codes per second,
start), so opening it plays the artist's scene, materials and hierarchy included, moving. It holds only:

- per body, time samples of ``xformOp:translate`` and ``xformOp:orient`` local to the prim's parent, its authored
  scale as ``xformOp:scale``, and ``xformOpOrder`` overridden to those three ops;
- per cloth mesh or particle set, ``points`` (local to the prim) and ``extent``;
- per emitter, a new ``Points`` child ``warpSimParticles`` with its live particles (points, ids, widths, extent).

Frame k lands at time code ``start + k * timeCodesPerSecond / fps``. Everything is in the stage's units and axes
(``scene.usd_units.StageUnits``). ``flatten`` makes the output one standalone stage instead.
"""
from __future__ import annotations

import os
import pathlib

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from ..scene.usd_reader import UsdSource
from ..util.rotations import matrix_to_quat, quat_to_matrix
from .prims import Frame, _extent, _floats, _gather, _PrimWriter, _vec3f, require

XFORM_OPS = ("xformOp:translate", "xformOp:orient", "xformOp:scale")


def _to_local(world: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Stage-world points (N, 3) in the frame whose local-to-world matrix (column vectors) is ``world``."""
    inverse = np.linalg.inv(world)
    return points @ inverse[:3, :3].T + inverse[:3, 3]


class _OverBody(_PrimWriter):
    """A body's prim: translate and orient local to its parent, per frame; its scale and op order once."""

    sdf_only = True

    def __init__(self, link, units, com):
        self.path, self.link, self.units = Sdf.Path(link.path), link, units
        self.index = int(link.index)
        self.min_bodies = self.index + 1
        self.com = np.asarray(com, dtype=np.float64)          # in the shape's frame [m]
        self.parent_inverse = np.linalg.inv(link.parent)

    def define(self, stage: Usd.Stage) -> None:
        layer = self.layer = stage.GetRootLayer()
        spec = Sdf.CreatePrimInLayer(layer, self.path)
        spec.specifier = Sdf.SpecifierOver
        types = (Sdf.ValueTypeNames.Double3, Sdf.ValueTypeNames.Quatf, Sdf.ValueTypeNames.Float3)
        for name, type_name in zip(XFORM_OPS, types):
            Sdf.AttributeSpec(spec, name, type_name)
        spec.attributes["xformOp:scale"].default = Gf.Vec3f(*self.link.scale.tolist())
        order = Sdf.AttributeSpec(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform)
        order.default = Vt.TokenArray(list(XFORM_OPS))
        self.translate = self.path.AppendProperty("xformOp:translate")
        self.orient = self.path.AppendProperty("xformOp:orient")

    def write(self, frame: Frame) -> None:
        u, (Rs, ps) = self.units, self.link.offset
        q = _quat(frame.body_q[self.index])
        R = quat_to_matrix(q)
        x = np.array(frame.body_x[self.index], dtype=np.float64)
        R_prim = R @ Rs.T
        t_prim = (x - R @ self.com) - R_prim @ ps
        world = np.eye(4)
        world[:3, :3] = u.stage_rotation(R_prim)
        world[:3, 3] = u.stage_point(t_prim)
        local = self.parent_inverse @ world
        U, _, Vh = np.linalg.svd(local[:3, :3])                  # the rotation of a parent that scales
        rotation = U @ Vh
        w = matrix_to_quat(rotation)
        self.layer.SetTimeSample(self.translate, frame.time, Gf.Vec3d(*local[:3, 3].tolist()))
        self.layer.SetTimeSample(self.orient, frame.time, Gf.Quatf(float(w[3]), float(w[0]), float(w[1]),
                                                                   float(w[2])))


def _quat(q) -> np.ndarray:
    """A Gf.Quatf as (x, y, z, w)."""
    imaginary = q.GetImaginary()
    return np.array([imaginary[0], imaginary[1], imaginary[2], q.GetReal()], dtype=np.float64)


class _OverPoints(_PrimWriter):
    """A cloth mesh's or particle set's prim: points local to the prim, and extent, per frame."""

    def __init__(self, link, units):
        self.path, self.units = Sdf.Path(link.path), units
        self.rows = np.asarray(link.index, dtype=np.int64)
        self.min_particles = int(self.rows.max()) + 1
        self.world = link.world

    def define(self, stage: Usd.Stage) -> None:
        self.prim = stage.OverridePrim(self.path)

    def write(self, frame: Frame) -> None:
        p = _to_local(self.world, self.units.stage_point(_gather(frame.particle_x, self.rows)))
        self.prim.CreateAttribute("points", Sdf.ValueTypeNames.Point3fArray).Set(_vec3f(p), frame.time)
        self.prim.CreateAttribute("extent", Sdf.ValueTypeNames.Float3Array).Set(_extent(p, p), frame.time)


class _OverPool(_PrimWriter):
    """An emitter's live particles as a new Points child of its prim (points, ids, widths, extent per frame)."""

    def __init__(self, link, units):
        rows = np.asarray(link.index, dtype=np.int64)
        self.path = Sdf.Path(link.path).AppendChild("warpSimParticles")
        self.pool = slice(int(rows[0]), int(rows[-1]) + 1)
        self.min_particles = self.pool.stop
        self.units, self.world = units, link.world

    def define(self, stage: Usd.Stage) -> None:
        self.prim = UsdGeom.Points.Define(stage, self.path)

    def write(self, frame: Frame) -> None:
        rows = self.pool.start + np.flatnonzero(frame.particle_alive[self.pool])
        p = _to_local(self.world, self.units.stage_point(_gather(frame.particle_x, rows)))
        radii = _gather(frame.particle_radius, rows) / self.units.meters_per_unit
        self.prim.CreatePointsAttr().Set(_vec3f(p), frame.time)
        self.prim.CreateIdsAttr().Set(Vt.Int64Array.FromNumpy(_gather(frame.particle_id, rows)), frame.time)
        self.prim.CreateWidthsAttr().Set(_floats(2.0 * radii), frame.time)
        self.prim.CreateExtentAttr().Set(_extent(p, p, radii) if len(p) else Sdf.ValueBlock(), frame.time)

    def uses(self, lo: int, hi: int) -> bool:
        return self.pool.start < hi and lo < self.pool.stop


class Overlay:
    """What StageWriter needs to write an overlay of ``source`` (a UsdSource from Scene.from_usd).

    over: the input stage (a path, or a Usd.Stage with a file); bodies: the scene's bodies (for each centre of
    mass in its shape's frame); flatten: one standalone stage
    """

    def __init__(self, source: UsdSource, over, bodies, flatten: bool = False):
        self.source, self.flatten = source, flatten
        if isinstance(over, Usd.Stage):
            over = over.GetRootLayer().realPath or over.GetRootLayer().identifier
        require(isinstance(over, (str, os.PathLike)) and str(over) != "",
                f"over={over!r} is invalid: expected the input USD file (or its Usd.Stage)")
        self.input = str(over)
        stage = Usd.Stage.Open(self.input)
        missing = [link.path for link in source.links if not stage.GetPrimAtPath(link.path)]
        require(not missing, f"over={self.input!r} is not the stage the scene was read from: it has no prim at "
                             f"{', '.join(missing[:3])}")
        self.stage = stage
        units = source.units
        self.writers = []
        for link in source.links:
            if link.kind == "body" and not link.kinematic:
                self.writers.append(_OverBody(link, units, bodies[int(link.index)].mass.com))
            elif link.kind in ("cloth", "particles"):
                self.writers.append(_OverPool(link, units) if link.pooled else _OverPoints(link, units))

    def time_code(self, fps: float) -> tuple[float, float]:
        """(start, step): frame k lands at time code start + k step."""
        return self.source.start_time_code, self.source.time_codes_per_second / fps

    def define(self, stage: Usd.Stage, output: pathlib.Path) -> None:
        """The overlay's stage metadata: the input's (its sublayer is added by ``finish``, so the frames are
        authored without composing the input)."""
        source = self.stage
        for key in ("upAxis", "metersPerUnit", "kilogramsPerUnit", "timeCodesPerSecond", "framesPerSecond",
                    "startTimeCode", "defaultPrim"):
            if source.HasMetadata(key):
                stage.SetMetadata(key, source.GetMetadata(key))

    def finish(self, layer: Sdf.Layer, output: pathlib.Path) -> Sdf.Layer:
        """The layer to export: the overlay sublayering the input (by a path relative to the output), or with
        ``flatten`` the composed stage as one layer."""
        absolute = os.path.abspath(self.input)
        copy = Sdf.Layer.CreateAnonymous(output.suffix)   # not the writer's stage's layer: adding the input there
        copy.TransferContent(layer)                       # would compose it, while it is only to be written out
        if self.flatten:
            copy.subLayerPaths.append(absolute)
            flat = Sdf.Layer.CreateAnonymous(output.suffix)   # in the output's format
            flat.TransferContent(Usd.Stage.Open(copy).Flatten())
            return flat
        try:
            relative = os.path.relpath(absolute, os.path.dirname(os.path.abspath(output)))
        except ValueError:   # another drive
            relative = absolute
        copy.subLayerPaths.append(relative)
        return copy

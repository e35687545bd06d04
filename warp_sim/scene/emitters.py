"""Particle emitters: the lecture's particle systems, born by a stochastic process, aged, terminated.

This module holds the descriptions: ``Ramp`` and ``Emitter`` (validated, made by
``Scene.add_emitter``); the device bookkeeping a Simulator runs after each step is
``warp_sim.passes.emitters.EmitterPools``. Births follow the rate deterministically: particle k of
an emitter is born at start + (k + 1/2) / rate, so by time t exactly
floor(rate (t - start) + 1/2) have been born; a burst adds its count at its
time. A birth inside a step is placed where a ballistic flight from its birth
time puts it at the end of the step, so streams do not clump at step
boundaries. Random attributes come from Warp's counter-based generator keyed on
(seed, emitter, particle sequence number): a run is reproducible, and the same
particles are born on any device.
"""
from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass

import numpy as np
import trimesh

from ..util import checks

EMITTER_SHAPES = ("point", "disc", "sphere", "ball", "box", "mesh")
#: id of particle k of emitter e: e * ID_STRIDE + k (unique across the scene, increasing per emitter)
ID_STRIDE = 1 << 40


@dataclass(frozen=True)
class Ramp:
    """A value over a particle's normalised age s = age / lifetime in [0, 1], piecewise linear.

    keys: ascending ages in [0, 1] (at least two); values: one per key (a number,
    or an RGB triple for colours). Before the first key and after the last the
    end values hold.
    """
    keys: tuple
    values: tuple

    def __init__(self, keys, values):
        k = checks.finite_array("keys", keys, (-1,))
        if len(k) < 2 or np.any(np.diff(k) < 0) or k[0] < 0 or k[-1] > 1:
            raise checks.fail("keys", keys, "expected at least two ascending normalised ages in [0, 1]")
        try:
            v = np.asarray(values, dtype=np.float64)
        except (TypeError, ValueError):   # ragged, or not numbers
            raise checks.fail("values", values, f"expected {len(k)} values, one per key, each a number or an RGB "
                                                "triple, all of the same width") from None
        if v.ndim == 0 or v.shape[0] != len(k) or not np.all(np.isfinite(v)):
            raise checks.fail("values", values, f"expected {len(k)} finite values, one per key")
        object.__setattr__(self, "keys", tuple(k))
        object.__setattr__(self, "values", tuple(map(tuple, v.reshape(len(k), -1))))


def _range(name: str, value, low: float, low_open: bool = False) -> tuple[float, float]:
    """A constant or a (min, max) uniform range, each finite and >= low (> low with low_open)."""
    if np.ndim(value) == 0:
        number = checks.scalar(name, value, low=low, low_open=low_open)
        return number, number
    pair = checks.finite_array(name, value, (2,))
    for number in pair:
        checks.scalar(name, number, low=low, low_open=low_open)
    if pair[0] > pair[1]:
        raise checks.fail(name, value, f"a range must be (min, max) with min <= max; got min {pair[0]} > max {pair[1]}")
    return float(pair[0]), float(pair[1])


def _attribute(name: str, value, width: int, low: float, high: float | None):
    """(low end, high end, ramp or None): a constant, a (min, max) range, or a Ramp; entries in [low, high]."""
    def check(array):
        bad = np.flatnonzero((array < low) | ((array > high) if high is not None else False))
        if len(bad):
            raise checks.fail(name, value, f"every entry must lie in [{low}, {high if high is not None else 'inf'}]")

    if isinstance(value, Ramp):
        values = np.array(value.values)
        if values.shape[1] != width:
            raise checks.fail(name, value, f"a ramp of {name} needs {width} number(s) per key")
        check(values)
        first = values[0] if width > 1 else values[0, 0]
        return first, first, value
    array = checks.finite_array(name, value, np.shape(value))
    shape = (width,) if width > 1 else ()
    if array.shape == shape:
        check(array)
        return array, array, None
    if array.shape == (2,) + shape:
        check(array)
        if width == 1 and array[0] > array[1]:
            raise checks.fail(name, value, "a range must be (min, max) with min <= max")
        return array[0], array[1], None
    raise checks.fail(name, value, f"expected a constant, a (min, max) pair or a ws.Ramp; got shape {array.shape}")


@dataclass(frozen=True)
class Emitter:
    """One emitter as added to a scene (see Scene.add_emitter for the meaning of each field)."""
    name: str
    index: int
    start_slot: int          # first global particle index of its pool
    capacity: int
    rate: float              # [1/s]
    bursts: tuple            # ((time [s], count), ...)
    start: float             # [s]
    stop: float              # [s], inf for never
    shape: str
    position: np.ndarray
    direction: np.ndarray    # unit; the disc's normal
    radial: bool             # emit along the shape's outward normal
    extent: np.ndarray       # (radius, 0, 0) or box half extents [m]
    mesh_triangles: np.ndarray | None   # (F, 3, 3) world-space triangles of a mesh surface
    spread: float            # cone half-angle [degrees]
    speed: tuple
    lifetime: tuple
    size: tuple
    mass: tuple
    color: tuple             # (low RGB, high RGB, Ramp or None)
    opacity: tuple           # (low, high, Ramp or None)
    size_ramp: Ramp | None
    seed: int
    kill_planes: tuple       # ((unit normal, offset), ...): particles with n . x < offset die
    kill_on_contact: bool

    def emitted_by(self, t: float) -> int:
        """Particles of the continuous stream born by time t [s]: floor(rate (t - start) + 1/2)."""
        if self.rate == 0.0 or t < self.start:
            return 0
        return int(math.floor(self.rate * (min(t, self.stop) - self.start) + 0.5))


#: bytes a pool slot costs on the device and in a frame's arrays (float64 state x2, materials, pool arrays, output)
SLOT_BYTES = 256
#: the largest pool accepted [bytes]
MAX_POOL_BYTES = 16 * 2**30


def make_emitter(index: int, start_slot: int, name: str, rate, lifetime, position, direction, spread, speed,
                 shape, radius, half_extents, mesh, size, mass, color, opacity, bursts, start, stop, capacity,
                 seed, kill_planes, kill_on_contact) -> Emitter:
    """Validate Scene.add_emitter's arguments into an Emitter."""
    rate = checks.scalar("rate", rate, low=0.0)
    lifetime = _range("lifetime", lifetime, low=0.0, low_open=True)
    spread = checks.scalar("spread", spread, low=0.0, high=180.0)
    speed = _range("speed", speed, low=0.0)
    mass = _range("mass", mass, low=0.0, low_open=True)
    size_low, size_high, size_ramp = _attribute("size", size, 1, 0.0, None)
    color = _attribute("color", color, 3, 0.0, 1.0)
    opacity = _attribute("opacity", opacity, 1, 0.0, 1.0)
    start = checks.scalar("start", start, low=0.0)
    stop = math.inf if stop is None else checks.scalar("stop", stop, low=start)
    shape = checks.choice("shape", shape, EMITTER_SHAPES)
    position = checks.vec3("position", position)
    radial = isinstance(direction, str)
    if radial:
        checks.choice("direction", direction, ("normal",))
        if shape not in ("sphere", "ball", "mesh"):
            raise checks.fail("direction", direction, "'normal' needs a sphere, ball or mesh shape")
        axis = np.array([0.0, 1.0, 0.0])
    else:
        axis = checks.unit_vec3("direction", direction)
    extent = np.zeros(3)
    if shape in ("disc", "sphere", "ball"):
        extent[0] = checks.scalar("radius", radius, low=0.0, low_open=True)
    elif shape == "box":
        extent = checks.finite_array("half_extents", half_extents if half_extents is not None else np.nan, (3,))
        if np.any(extent <= 0):
            raise checks.fail("half_extents", half_extents, "each half extent must be > 0 [m]")
    triangles = _mesh_triangles(mesh, position) if shape == "mesh" else None
    if shape != "mesh" and mesh is not None:
        raise checks.fail("mesh", mesh, "a mesh is only used with shape='mesh'")
    burst_list = []
    for burst in bursts:
        pair = checks.finite_array("bursts", burst, (2,))
        if pair[0] < 0 or pair[1] < 1 or pair[1] != int(pair[1]):
            raise checks.fail("bursts", bursts, "each burst is (time >= 0 [s], count >= 1 integer)")
        burst_list.append((float(pair[0]), int(pair[1])))
    if rate == 0.0 and not burst_list:
        raise checks.fail("rate", rate, "an emitter needs a rate > 0 or at least one burst")
    given = capacity
    if capacity is None:
        capacity = math.ceil(rate * lifetime[1]) + 1 + sum(count for _, count in burst_list)
    elif isinstance(capacity, bool) or not isinstance(capacity, (int, np.integer)) or capacity < 1:
        raise checks.fail("capacity", capacity, "expected an integer >= 1 (or None: rate x max lifetime + bursts)")
    if capacity * SLOT_BYTES > MAX_POOL_BYTES:
        name, value = ("capacity", given) if given is not None else ("rate", rate)
        raise checks.fail(name, value, f"the pool would hold {capacity:,} particles, about "
                                       f"{capacity * SLOT_BYTES / 2**30:,.1f} GiB of state (float64) and output, above "
                                       f"the {MAX_POOL_BYTES // 2**30} GiB bound; lower rate or lifetime, or give a "
                                       "smaller capacity (births that find it full are skipped and counted)")
    seed_value = seed if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) else None
    if seed_value is None or not 0 <= seed_value < 2**31:
        raise checks.fail("seed", seed, "expected an integer in [0, 2^31)")
    planes = []
    if not isinstance(kill_planes, (list, tuple)):
        raise checks.fail("kill_planes", kill_planes, "expected a list of (normal, offset) planes")
    for plane in kill_planes:
        if not isinstance(plane, (list, tuple)) or len(plane) != 2:
            raise checks.fail("kill_planes", kill_planes, "each kill plane is (normal, offset), e.g. ((0, 1, 0), -1)")
        planes.append((checks.unit_vec3("kill_planes", plane[0]), checks.scalar("kill_planes", plane[1])))
    return Emitter(name=name, index=index, start_slot=start_slot, capacity=int(capacity), rate=rate,
                   bursts=tuple(burst_list), start=start, stop=stop, shape=shape, position=position, direction=axis,
                   radial=radial, extent=extent, mesh_triangles=triangles, spread=spread, speed=speed,
                   lifetime=lifetime, size=(float(size_low), float(size_high)), mass=mass, color=color,
                   opacity=opacity, size_ramp=size_ramp, seed=int(seed_value), kill_planes=tuple(planes),
                   kill_on_contact=bool(kill_on_contact))


def _mesh_triangles(mesh, position) -> np.ndarray:
    """The world-space triangles (F, 3, 3) of a trimesh mesh or mesh file, offset by position."""
    if isinstance(mesh, (str, pathlib.Path)):
        try:
            mesh = trimesh.load(mesh, force="mesh")
        except Exception as error:  # noqa: BLE001 - trimesh raises many kinds
            raise checks.fail("mesh", mesh, f"could not be loaded by trimesh: {error}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise checks.fail("mesh", mesh, "expected a trimesh.Trimesh with triangles, or a path trimesh loads")
    triangles = np.asarray(mesh.triangles, dtype=np.float64) + position
    if not np.all(np.isfinite(triangles)):
        raise checks.fail("mesh", mesh, "vertices must be finite")
    areas = np.asarray(mesh.area_faces)
    if areas.sum() <= 0:
        raise checks.fail("mesh", mesh, "the surface has zero area")
    return triangles

"""Particle emitters: the lecture's particle systems, born by a stochastic process, aged, terminated.

Host side: ``Ramp`` and ``Emitter`` (a validated description, made by
``Scene.add_emitter``) and ``EmitterPools`` (the device bookkeeping a Simulator
runs after each step). Births follow the rate deterministically: particle k of
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
import warnings
from dataclasses import dataclass

import numpy as np
import warp as wp

from . import checks

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
        v = np.asarray(values, dtype=np.float64)
        if v.shape[0] != len(k) or not np.all(np.isfinite(v)):
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
    if capacity is None:
        capacity = math.ceil(rate * lifetime[1]) + 1 + sum(count for _, count in burst_list)
    elif isinstance(capacity, bool) or not isinstance(capacity, (int, np.integer)) or capacity < 1:
        raise checks.fail("capacity", capacity, "expected an integer >= 1 (or None: rate x max lifetime + bursts)")
    seed_value = seed if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) else None
    if seed_value is None or not 0 <= seed_value < 2**31:
        raise checks.fail("seed", seed, "expected an integer in [0, 2^31)")
    planes = []
    for plane in kill_planes:
        if len(plane) != 2:
            raise checks.fail("kill_planes", kill_planes, "each kill plane is (normal, offset)")
        planes.append((checks.unit_vec3("kill_planes", plane[0]), checks.scalar("kill_planes", plane[1])))
    return Emitter(name=name, index=index, start_slot=start_slot, capacity=int(capacity), rate=rate,
                   bursts=tuple(burst_list), start=start, stop=stop, shape=shape, position=position, direction=axis,
                   radial=radial, extent=extent, mesh_triangles=triangles, spread=spread, speed=speed,
                   lifetime=lifetime, size=(float(size_low), float(size_high)), mass=mass, color=color,
                   opacity=opacity, size_ramp=size_ramp, seed=int(seed_value), kill_planes=tuple(planes),
                   kill_on_contact=bool(kill_on_contact))


def _mesh_triangles(mesh, position) -> np.ndarray:
    """The world-space triangles (F, 3, 3) of a trimesh mesh or mesh file, offset by position."""
    import trimesh

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


class EmitterPools:
    """Device bookkeeping of every emitter of a scene: pools, births, ages, deaths, statistics.

    Built only for scenes with emitters. ``after_step(state, t, h)`` runs after each
    solver step on the new state; ``arrays`` are global-length per-particle arrays:
    alive (int32), ids (int64), color (RGB), opacity.
    """

    def __init__(self, model, scene):
        from .kernels import emitters as kernels

        self.kernels = kernels
        self.model = model
        self.emitters: list[Emitter] = list(scene.emitters)
        device, count = model.device, model.particle_count
        alive = np.ones(count, dtype=np.int32)
        ids = np.arange(count, dtype=np.int64)
        color = np.zeros((count, 3), dtype=np.float32)
        for group in scene.particle_groups:
            color[group.start:group.start + group.count] = group.color
        for e in self.emitters:
            alive[e.start_slot:e.start_slot + e.capacity] = 0
        self.alive = wp.array(alive, dtype=wp.int32, device=device)
        self.ids = wp.array(ids, dtype=wp.int64, device=device)
        self.color = wp.array(color, dtype=wp.vec3f, device=device)
        self.opacity = wp.ones(count, dtype=wp.float32, device=device)
        self.pools = [_Pool(e, self, model, scene) for e in self.emitters]
        #: contact flags the impulse pass sets, for kill-on-contact emitters (else None)
        self.touched = None
        if any(e.kill_on_contact for e in self.emitters) and model.plane_count:
            self.touched = wp.zeros(count, dtype=wp.int32, device=device)
            for pool in self.pools:
                if pool.e.kill_on_contact:
                    pool.touched = self.touched
        self.shortest_lifetime = min(e.lifetime[0] for e in self.emitters)

    def initial_births(self, state, t: float) -> None:
        """Births at the start time t (bursts at t and continuous births up to t)."""
        for pool in self.pools:
            pool.births(state, t, t, include_start=True)

    def check_step(self, h: float) -> None:
        """A step may not be longer than the shortest lifetime, or a particle could outlive it."""
        if h > self.shortest_lifetime:
            raise checks.fail("dt", h, f"a step may not exceed the shortest particle lifetime "
                                       f"({self.shortest_lifetime:g} s), or particles would outlive it")

    def after_step(self, state, t: float, h: float) -> None:
        """Age and kill over the step (t, t + h], then the births of that step, on ``state`` at t + h."""
        for pool in self.pools:
            pool.age_and_kill(state, t + h)
            pool.births(state, t, t + h, include_start=False)

    def stats(self) -> list[dict]:
        """Per emitter: name, capacity, live, born and skipped (births that found the pool full)."""
        return [pool.stats() for pool in self.pools]

    def warn_if_skipped(self) -> None:
        for entry in self.stats():
            if entry["skipped"]:
                warnings.warn(f"emitter {entry['name']!r}: {entry['skipped']} births skipped because its pool of "
                              f"{entry['capacity']} was full; raise capacity=", stacklevel=3)


class _Pool:
    """One emitter's slots, free stack, counters and launch parameters."""

    def __init__(self, e: Emitter, owner: EmitterPools, model, scene):
        self.e, self.model, self.k = e, model, owner.kernels
        device, n = model.device, e.capacity
        s = slice(e.start_slot, e.start_slot + n)
        self.alive, self.ids = owner.alive[s], owner.ids[s]
        self.color, self.opacity = owner.color[s], owner.opacity[s]
        self.birth = wp.zeros(n, dtype=wp.float64, device=device)     # [s]
        self.age = wp.zeros(n, dtype=wp.float64, device=device)       # [s]
        self.lifetime = wp.zeros(n, dtype=wp.float64, device=device)  # [s]
        self.free_slots = wp.array(np.arange(n - 1, -1, -1, dtype=np.int32), dtype=wp.int32, device=device)
        self.free_count = wp.array([n], dtype=wp.int32, device=device)
        self.born = wp.zeros(1, dtype=wp.int64, device=device)
        self.skipped = wp.zeros(1, dtype=wp.int64, device=device)
        self.emitted = 0            # sequence numbers handed out so far (host)
        self.stream = 0             # continuous-stream births so far (host)
        self.params = self._params(scene)
        self._mesh_arrays(device)
        self._ramp_arrays(device)
        self._kill_arrays(model, device)

    def _params(self, scene):
        e, p = self.e, self.k.EmitterParams()
        p.shape = EMITTER_SHAPES.index(e.shape)
        p.position = wp.vec3f(*(e.position if e.shape != "mesh" else np.zeros(3)))
        p.axis = wp.vec3f(*e.direction)
        p.extent = wp.vec3f(*e.extent)
        p.radial = int(e.radial)
        p.cos_spread = math.cos(math.radians(e.spread))
        p.speed, p.size, p.mass = (wp.vec2f(*pair) for pair in (e.speed, e.size, e.mass))
        p.lifetime = wp.vec2d(*e.lifetime)
        p.color_low, p.color_high = wp.vec3f(*e.color[0]), wp.vec3f(*e.color[1])
        p.opacity = wp.vec2f(float(e.opacity[0]), float(e.opacity[1]))
        ramps = (e.color[2], e.opacity[2], e.size_ramp)
        p.color_ramp, p.opacity_ramp, p.size_ramp = (int(ramp is not None) for ramp in ramps)
        p.gravity = wp.vec3f(*scene.gravity)
        p.seed = (e.seed * 2654435761 + e.index * 40503) & 0x7FFFFFFF   # (seed, emitter) mixed into one int32
        return p

    def _mesh_arrays(self, device):
        triangles = self.e.mesh_triangles
        if triangles is None:
            triangles = np.zeros((1, 3, 3))
        areas = 0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]),
                                     axis=1)
        cdf = np.cumsum(areas) / max(areas.sum(), 1e-300)
        self.mesh = [wp.array(cdf, dtype=wp.float32, device=device)] + [
            wp.array(triangles[:, corner], dtype=wp.vec3f, device=device) for corner in range(3)]

    def _ramp_arrays(self, device):
        self.ramps = []
        for ramp in (self.e.color[2], self.e.opacity[2], self.e.size_ramp):
            keys, values = (ramp.keys, np.array(ramp.values)) if ramp is not None else ((0.0, 1.0), np.zeros((2, 1)))
            padded = np.zeros((len(keys), 4))
            padded[:, :values.shape[1]] = values
            self.ramps += [wp.array(keys, dtype=wp.float32, device=device),
                           wp.array(padded, dtype=wp.vec4f, device=device)]

    def _kill_arrays(self, model, device):
        planes = self.e.kill_planes
        self.kill_normal = wp.array([n for n, _ in planes], dtype=wp.vec3f, device=device) if planes else \
            wp.empty(0, dtype=wp.vec3f, device=device)
        self.kill_offset = wp.array([o for _, o in planes], dtype=wp.float32, device=device)
        contact = self.e.kill_on_contact and model.plane_count > 0
        self.contact_normal = model.plane_normal if contact else model.empty(model.vec3)
        self.contact_offset = model.plane_offset if contact else model.empty()
        self.touched = model.empty(wp.int32)

    def age_and_kill(self, state, now: float) -> None:
        m = self.model
        m.launch(self.k.age_and_kill, self.e.capacity,
                 [self.params, self.e.start_slot, self.kill_normal, self.kill_offset, wp.float64(now),
                  self.contact_normal, self.contact_offset, self.touched, *self.ramps, state.particle_x,
                  state.particle_v, m.particle_inv_mass, m.particle_radius, self.alive, self.birth, self.age,
                  self.lifetime, self.color, self.opacity, self.free_slots,
                  self.free_count])

    def births(self, state, t0: float, t1: float, include_start: bool) -> None:
        """Emit the births in (t0, t1] (or [t0, t1] with include_start), aged to t1."""
        e = self.e
        stream = e.emitted_by(t1 + 1e-9 * max(1.0, abs(t1)))
        if stream > self.stream:
            # the stream's particle k is born at start + (k + 1/2) / rate
            first_age = t1 - (e.start + (self.stream + 0.5) / e.rate)
            self._emit(state, t1, stream - self.stream, first_age, 1.0 / e.rate)
            self.stream = stream
        eps = 1e-9 * max(1.0, abs(t1))      # simulated time is a sum of steps: 30 x 1/60 is 0.49999999999999994
        for time, count in e.bursts:
            if (t0 + eps < time <= t1 + eps) or (include_start and abs(time - t0) <= eps):
                self._emit(state, t1, count, max(t1 - time, 0.0), 0.0)

    def _emit(self, state, now: float, count: int, first_age: float, age_step: float) -> None:
        m = self.model
        m.launch(self.k.emit, count,
                 [self.params, self.e.start_slot, self.emitted, wp.int64(self.e.index * ID_STRIDE),
                  wp.float64(first_age), wp.float64(age_step), self.free_slots, self.free_count, *self.mesh,
                  *self.ramps, state.particle_x, state.particle_v, m.particle_inv_mass, m.particle_radius, self.alive,
                  self.ids,
                  wp.float64(now), self.birth, self.age, self.lifetime, self.color,
                  self.opacity])
        m.launch(self.k.commit_births, 1, [count, self.free_count, self.born, self.skipped])
        self.emitted += count

    def stats(self) -> dict:
        free = int(self.free_count.numpy()[0])
        return {"name": self.e.name, "capacity": self.e.capacity, "live": self.e.capacity - free,
                "born": int(self.born.numpy()[0]), "skipped": int(self.skipped.numpy()[0])}

"""Emitter pools on the device: births, ages and deaths of every emitter's particles, after each step.

The descriptions (``Emitter``, ``Ramp``) are in ``warp_sim.scene.emitters``; see there for the
birth schedule and the randomness. Built only for scenes with emitters.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import warp as wp

from ..core.persistence import Persistent
from ..core.protocols import Pass
from ..kernels import blocks
from ..kernels import emitters as kernels
from ..scene.emitters import EMITTER_SHAPES, ID_STRIDE, Emitter
from ..util import checks


class EmitterPools(Pass):
    """Device bookkeeping of every emitter of a scene: pools, births, ages, deaths, statistics.

    Built only for scenes with emitters. ``apply(start, end, t, h)`` runs after each
    solver step on the new state; ``arrays`` are global-length per-particle arrays:
    alive (int32), ids (int64), color (RGB), opacity.
    """

    kernels = ("emitters",)

    persistent = ("alive", "ids", "color", "opacity", "model.particle_inv_mass", "model.particle_radius")

    def __init__(self, model, scene):
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

    def persistent_parts(self) -> dict:
        return {f"pool{k}": pool for k, pool in enumerate(self.pools)}

    def initial_births(self, state, t: float) -> None:
        """Births at the start time t (bursts at t and continuous births up to t)."""
        for pool in self.pools:
            pool.births(state, t, t, include_start=True)

    def check_step(self, h: float) -> None:
        """A step may not be longer than the shortest lifetime, or a particle could outlive it."""
        if h > self.shortest_lifetime:
            raise checks.fail("dt", h, f"a step may not exceed the shortest particle lifetime "
                                       f"({self.shortest_lifetime:g} s), or particles would outlive it")

    def apply(self, start, end, t: float, h: float) -> None:
        """Age and kill over the step (t, t + h], then the births of that step, on ``end`` (at t + h)."""
        for pool in self.pools:
            pool.age_and_kill(end, t + h)
            pool.births(end, t, t + h, include_start=False)

    def stats(self) -> list[dict]:
        """Per emitter: name, capacity, live, born and skipped (births that found the pool full)."""
        return [pool.stats() for pool in self.pools]

    def warn_if_skipped(self) -> None:
        for entry in self.stats():
            if entry["skipped"]:
                warnings.warn(f"emitter {entry['name']!r}: {entry['skipped']} births skipped because its pool of "
                              f"{entry['capacity']} was full; raise capacity=", stacklevel=3)


class _Pool(Persistent):
    """One emitter's slots, free stack, counters and launch parameters."""

    persistent = ("birth", "age", "lifetime", "free_slots", "free_count", "born", "skipped", "emitted", "stream")

    def __init__(self, e: Emitter, owner: EmitterPools, model, scene):
        self.e, self.model, self.k = e, model, kernels
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
        self.slots = blocks.fill(kernels.Pool, alive=self.alive, ids=self.ids, birth=self.birth, age=self.age,
                                 lifetime=self.lifetime, color=self.color, opacity=self.opacity,
                                 free_slots=self.free_slots, free_count=self.free_count)
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
        a, b, c = (wp.array(triangles[:, corner], dtype=wp.vec3f, device=device) for corner in range(3))
        self.mesh = blocks.fill(kernels.MeshSurface, cdf=wp.array(cdf, dtype=wp.float32, device=device), a=a, b=b, c=c)

    def _ramp_arrays(self, device):
        arrays = {}
        for name, ramp in (("color", self.e.color[2]), ("opacity", self.e.opacity[2]), ("size", self.e.size_ramp)):
            keys, values = (ramp.keys, np.array(ramp.values)) if ramp is not None else ((0.0, 1.0), np.zeros((2, 1)))
            padded = np.zeros((len(keys), 4))
            padded[:, :values.shape[1]] = values
            arrays[f"{name}_keys"] = wp.array(keys, dtype=wp.float32, device=device)
            arrays[f"{name}_values"] = wp.array(padded, dtype=wp.vec4f, device=device)
        self.ramps = blocks.fill(kernels.Ramps, **arrays)

    def _kill_arrays(self, model, device):
        planes = self.e.kill_planes
        normal = wp.array([n for n, _ in planes], dtype=wp.vec3f, device=device) if planes else \
            wp.empty(0, dtype=wp.vec3f, device=device)
        self.kill = blocks.fill(kernels.KillPlanes, normal=normal,
                                offset=wp.array([o for _, o in planes], dtype=wp.float32, device=device))
        contact = self.e.kill_on_contact and model.plane_count > 0
        self.contact_planes = model.planes if contact else model.no_planes()
        self.touched = model.empty(wp.int32)

    def age_and_kill(self, state, now: float) -> None:
        m = self.model
        m.launch(self.k.age_and_kill, self.e.capacity,
                 [self.params, self.e.start_slot, wp.float64(now), self.kill, self.contact_planes, self.touched,
                  self.slots, self.ramps, state.particle_x, state.particle_v, m.particle_material])

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
                  wp.float64(first_age), wp.float64(age_step), wp.float64(now), self.slots, self.mesh, self.ramps,
                  state.particle_x, state.particle_v, m.particle_material])
        m.launch(self.k.commit_births, 1, [count, self.free_count, self.born, self.skipped])
        self.emitted += count

    def stats(self) -> dict:
        free = int(self.free_count.numpy()[0])
        return {"name": self.e.name, "capacity": self.e.capacity, "live": self.e.capacity - free,
                "born": int(self.born.numpy()[0]), "skipped": int(self.skipped.numpy()[0])}

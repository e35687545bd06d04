"""Cloth throughput: a mass-spring cloth stepped by warp_sim, side by side with numpy, Taichi and Newton.

    python benchmarks/cloth.py [--device cpu|cuda] [--sizes 32 64 128] [--steps N] [--repeats R]
                               [--implicit-sizes 32 64 128] [--implicit-steps 30]
                               [--out benchmarks/results/cloth.json]

The scene: one square cloth, 1 m x 1 m, n x n vertices (default 32, 64, 128; 256 too on a
CUDA device), density 0.2 kg/m^2, hanging upright from its two top corners (pinned), with
structural, shear and bend springs and their dampers (stiffness 1e4, 1e4, 1e3 N/m; damping
0.01, 0.01, 0.001 N s/m), gravity, no air, no contact; float32.

Explicit part: warp_sim's symplectic_euler at DT = 5e-6 s, the same dt in every
implementation and at every size (about half the stability limit of the 256 x 256 cloth,
whose vertices are the lightest; see README), against
  (a) numpy: the same step written here over the scene's own arrays (vectorised; the
      scatter of spring forces onto particles by np.bincount), float32;
  (b) Taichi on its CPU backend (optional: reported "not installed" when absent);
  (c) Newton's SolverSemiImplicit with triangle contact off, the same particles and springs,
      particle-particle contact off (optional, on warp_sim's device).
Every implementation is first CHECKED against a float64 numpy run of the same step, from the
same state (the cloth as built plus random velocities, fixed seed, rounded to float32): the
velocity change of one step (as an acceleration) and the positions and velocities after
CHECK_STEPS steps. warp_sim (and Taichi, when present) run the check in float64 too, with
tolerances near float64 rounding: that pins the step itself. The float32 runs are held to
float32-rounding tolerances (TOLERANCES), which only catch gross errors: on these light
vertices, rounding a spring's length to float32 is an acceleration of order 1 m/s^2, and
rounding a position to its float32 spacing (1.2e-7 m near 1 m) one of order 100 m/s^2, while
a step at this dt moves a vertex by only a few spacings. A warp_sim or numpy failure
raises; an optional implementation's failure is reported as an error in its column.
Then the float32 implementations are timed: --repeats rounds of --steps steps, interleaved,
median reported. warp_sim is timed with its guard off (the same work as the others) and on
(the default); the ratios use guard off. A per-kernel profile of the warp_sim step follows.

Implicit part: the same cloth from rest under warp_sim's implicit_euler at h = 1/60 s for
--implicit-steps steps: steps/s, the conjugate gradient iterations of each step (min,
mean, max), the solves that stopped at the cap and the median relative residual, with the
solver's defaults (relative tolerance 1e-3, cap max(200, 4 sqrt(particles))) and, in the same
run, with the defaults before them (``ImplicitEuler(tolerance=1e-6, max_iterations=200)``).
Results in --out (JSON). See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import importlib
import inspect
import json
import os
import statistics
import time
import warnings
from functools import partial
from pathlib import Path

import numpy as np
import warp as wp
from common import KernelProfile, device_name, markdown, pick_device

import warp_sim as ws

GRAVITY = (0.0, -9.81, 0.0)  # [m/s^2]
CLOTH = {"size": (1.0, 1.0), "position": (0.0, 1.0, 0.0), "density": 0.2, "pinned": ["top_corners"],
         "stiffness": (1.0e4, 1.0e4, 1.0e3), "damping": (0.01, 0.01, 0.001)}  # [m], [kg/m^2], [N/m], [N s/m]
DT = 5.0e-6  # [s], explicit step of every implementation at every size
IMPLICIT_DT = 1.0 / 60.0  # [s]
CHECK_STEPS = 20
CHECK_SPEED = 0.1  # [m/s], standard deviation of each initial velocity component in the check and the timed runs
#: the check's tolerances by precision: max |dv| / DT after one step (an acceleration error, m/s^2), max |dx| [m]
#: and max |dv| [m/s] after CHECK_STEPS steps, each against numpy float64 from the same (float32-representable) state
TOLERANCES = {"float64": {"max_da": 1.0e-4, "max_dx": 1.0e-12, "max_dv": 1.0e-8},
              "float32": {"max_da": 5.0, "max_dx": 5.0e-6, "max_dv": 0.2}}
WARMUP_STEPS = 3
SEED = 0
DEFAULT_SIZES = [32, 64, 128]
CUDA_SIZES = [256]  # added on a CUDA device
KERNEL_LABELS = {"spring_forces": "springs", "particle_acceleration": "acceleration", "axpy": "axpy",
                 "copy": "copy", "check_finite_and_bounded": "guard"}


def optional_import(name: str):
    """(module or None, status): "available", "not installed", or why the import failed."""
    try:
        return importlib.import_module(name), "available"
    except ModuleNotFoundError as error:
        if error.name == name:
            return None, "not installed"
        return None, f"import failed: {error}"
    except Exception as error:  # a broken install (missing library, incompatible warp) is reported, not fatal
        return None, f"import failed: {type(error).__name__}: {error}"


def make_scene(n: int, precision: str = "float32") -> ws.Scene:
    scene = ws.Scene(gravity=GRAVITY, precision=precision)
    scene.add_cloth_grid(resolution=(n, n), **CLOTH)
    return scene


def initial_state(scene: ws.Scene) -> tuple[np.ndarray, np.ndarray]:
    """(x, v): the cloth as built, velocities N(0, CHECK_SPEED) per component (pinned: 0), fixed seed; rounded to
    float32 (kept as float64), so that every implementation, float32 or float64, starts from exactly this state."""
    x = scene.particle_array("position")
    v = np.random.default_rng(SEED).normal(0.0, CHECK_SPEED, size=x.shape)
    v[scene.particle_array("pinned")] = 0.0
    return x.astype(np.float32).astype(np.float64), v.astype(np.float32).astype(np.float64)


class NumpyCloth:
    """The step written in numpy over the scene's arrays, as warp_sim defines it (kernels/springs.py,
    kernels/particles.py, symplectic Euler): per spring d = (x2 - x1) / L, f2 = (-ks (L - L0) - kd (v2 - v1).d) d
    on p2 and -f2 on p1 (no force where L = 0); a = g + f / m, 0 for pinned particles; v += h a; x += h v.
    The scatter of spring forces onto particles is np.bincount (accumulating in float64), the fastest of
    np.add.at, np.bincount and np.add.reduceat over sorted ends here. gravity, damping: False leaves them out
    (to show what the check would catch)."""

    def __init__(self, scene: ws.Scene, dtype=np.float32, gravity: bool = True, damping: bool = True):
        self.dtype = np.dtype(dtype)
        self.name, self.precision = f"numpy {self.dtype.name}", self.dtype.name
        pairs = scene.spring_array("pairs")
        self.p1, self.p2 = pairs[:, 0].astype(np.intp), pairs[:, 1].astype(np.intp)
        self.ks = scene.spring_array("stiffness").astype(dtype)
        self.kd = scene.spring_array("damping").astype(dtype) * damping
        self.rest = scene.spring_array("rest_length").astype(dtype)
        mass, pinned = scene.particle_array("mass"), scene.particle_array("pinned")
        self.count = len(mass)
        self.inv_mass = np.where(pinned, 0.0, 1.0 / mass).astype(dtype)[:, None]
        self.gravity = np.where(pinned[:, None], 0.0, np.asarray(GRAVITY) * gravity).astype(dtype)
        self.h = self.dtype.type(DT)

    def reset(self, x: np.ndarray, v: np.ndarray) -> None:
        self.x, self.v = x.astype(self.dtype), v.astype(self.dtype)

    def advance(self, steps: int) -> None:
        x, v, p1, p2, n = self.x, self.v, self.p1, self.p2, self.count
        for _ in range(steps):
            delta = x[p2] - x[p1]
            length = np.sqrt(np.einsum("ij,ij->i", delta, delta))
            d = delta / np.where(length > 0, length, 1)[:, None]  # L = 0: delta = 0, so d = 0 and no force
            magnitude = -self.ks * (length - self.rest) - self.kd * np.einsum("ij,ij->i", v[p2] - v[p1], d)
            f2 = magnitude[:, None] * d
            force = np.stack([np.bincount(p2, f2[:, c], n) - np.bincount(p1, f2[:, c], n) for c in range(3)], axis=1)
            v += self.h * (self.gravity + force.astype(self.dtype, copy=False) * self.inv_mass)
            x += self.h * v

    def sync(self) -> None:
        pass

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x.astype(np.float64), self.v.astype(np.float64)


class WarpSimCloth:
    """warp_sim's Simulator on the scene (symplectic_euler, no contact), its state overwritten by reset()."""

    def __init__(self, scene: ws.Scene, device, guard: bool, profile: KernelProfile | None = None):
        self.precision = scene.precision
        self.name = "warp_sim" + (" (guard)" if guard else "") + ("" if self.precision == "float32" else " float64")
        make = partial(ws.Simulator, scene, "symplectic_euler", device.alias, guard=guard)
        self.sim = profile.instrumented(make) if profile is not None else make()

    def reset(self, x: np.ndarray, v: np.ndarray) -> None:
        model, state = self.sim.model, self.sim.state
        for array, values in ((state.particle_x, x), (state.particle_v, v)):
            array.assign(wp.array(values.astype(model.numpy_scalar), dtype=model.vec3, device=model.device))

    def advance(self, steps: int) -> None:
        self.sim.step(DT, steps=steps)

    def sync(self) -> None:
        wp.synchronize_device(self.sim.device)

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        state = self.sim.state
        return state.particle_x.numpy().astype(np.float64), state.particle_v.numpy().astype(np.float64)


def taichi_init(ti, arch: str = "cpu", threads: int | None = None, **options) -> None:
    """ti.init on ti.cpu (all cores, Taichi's default, or ``threads``) or ti.cuda; an earlier Taichi field or
    kernel is dead afterwards."""
    if threads is not None:
        options["cpu_max_num_threads"] = threads
    ti.init(arch=getattr(ti, arch), log_level=ti.WARN, **options)


class TaichiCloth:
    """The same step in Taichi, one kernel of three parallel loops: clear the forces, the springs (atomic adds
    onto both ends), integrate. On Taichi's CPU backend (all cores, Taichi's default, unless ``threads``) or
    arch="cuda". ti.init is called here: an instance made earlier (another size or precision) is dead afterwards."""

    style = ""

    def __init__(self, ti, scene: ws.Scene, precision: str = "float32", arch: str = "cpu", threads: int | None = None):
        self.ti, self.precision = ti, precision
        self.name = (f"Taichi {arch}{self.style}" + (f" ({threads} thread{'s' * (threads != 1)})" if threads else "")
                     + ("" if precision == "float32" else " float64"))
        real, self.dtype = (ti.f32, np.float32) if precision == "float32" else (ti.f64, np.float64)
        taichi_init(ti, arch, threads, default_fp=real)
        pairs = scene.spring_array("pairs").astype(np.int32)
        mass, pinned = scene.particle_array("mass"), scene.particle_array("pinned")
        n, s = len(mass), len(pairs)
        self.x, self.v, g = (ti.Vector.field(3, real, shape=n) for _ in range(3))
        w = ti.field(real, shape=n)
        ks, kd, rest = (ti.field(real, shape=s) for _ in range(3))
        h = ti.field(real, shape=())  # the step as a field, not a kernel argument: no annotation to resolve
        for field, values in ((ks, scene.spring_array("stiffness")), (kd, scene.spring_array("damping")),
                              (rest, scene.spring_array("rest_length")), (w, np.where(pinned, 0.0, 1.0 / mass)),
                              (g, np.where(pinned[:, None], 0.0, np.asarray(GRAVITY)))):
            field.from_numpy(values.astype(self.dtype))
        h[None] = DT
        self.step = self._kernel(ti, real, pairs, self.x, self.v, g, w, ks, kd, rest, h)

    @staticmethod
    def _kernel(ti, real, pairs, x, v, g, w, ks, kd, rest, h):
        f = ti.Vector.field(3, real, shape=x.shape)
        ends = ti.Vector.field(2, ti.i32, shape=len(pairs))
        ends.from_numpy(pairs)

        @ti.kernel
        def step():
            for i in f:
                f[i] = ti.Vector([0.0, 0.0, 0.0])
            for k in ends:
                a, b = ends[k][0], ends[k][1]
                delta = x[b] - x[a]
                length = delta.norm()
                if length > 0.0:
                    d = delta / length
                    magnitude = -ks[k] * (length - rest[k]) - kd[k] * (v[b] - v[a]).dot(d)
                    f[b] += magnitude * d  # atomic in a parallel loop
                    f[a] -= magnitude * d
            for i in v:
                v[i] += h[None] * (g[i] + f[i] * w[i])
                x[i] += h[None] * v[i]

        return step

    def reset(self, x: np.ndarray, v: np.ndarray) -> None:
        self.x.from_numpy(x.astype(self.dtype))
        self.v.from_numpy(v.astype(self.dtype))

    def advance(self, steps: int) -> None:
        for _ in range(steps):
            self.step()

    def sync(self) -> None:
        self.ti.sync()

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x.to_numpy().astype(np.float64), self.v.to_numpy().astype(np.float64)


class TaichiGatherCloth(TaichiCloth):
    """The same step gather-style: per particle, the forces of its springs summed through an adjacency list
    (CSR: the other end and the spring of each), no atomics, the new velocity written to a second field; then a
    second loop integrates. With d = (x_i - x_j) / L, the force on i is (-ks (L - L0) - kd (v_i - v_j).d) d from
    either end, the same as the scatter step's."""

    style = " gather"

    @staticmethod
    def _kernel(ti, real, pairs, x, v, g, w, ks, kd, rest, h):
        n = x.shape[0]
        ends = np.concatenate([pairs[:, 0], pairs[:, 1]])
        order = np.argsort(ends, kind="stable")
        start_np = np.zeros(n + 1, dtype=np.int32)
        np.cumsum(np.bincount(ends, minlength=n), out=start_np[1:])
        start = ti.field(ti.i32, shape=n + 1)
        other, spring = (ti.field(ti.i32, shape=len(ends)) for _ in range(2))
        start.from_numpy(start_np)
        other.from_numpy(np.concatenate([pairs[:, 1], pairs[:, 0]])[order].astype(np.int32))
        spring.from_numpy(np.concatenate([np.arange(len(pairs))] * 2)[order].astype(np.int32))
        v_new = ti.Vector.field(3, real, shape=n)

        @ti.kernel
        def step():
            for i in x:
                xi, vi = x[i], v[i]
                f = ti.Vector([0.0, 0.0, 0.0])
                for e in range(start[i], start[i + 1]):
                    j, k = other[e], spring[e]
                    delta = xi - x[j]
                    length = delta.norm()
                    if length > 0.0:
                        d = delta / length
                        f += (-ks[k] * (length - rest[k]) - kd[k] * (vi - v[j]).dot(d)) * d
                v_new[i] = vi + h[None] * (g[i] + f * w[i])
            for i in x:
                v[i] = v_new[i]
                x[i] += h[None] * v_new[i]

        return step


def newton_builder(newton, scene: ws.Scene, gravity=GRAVITY):
    """A Newton ModelBuilder (y up, ``gravity``) with the scene's particles (pinned: mass 0) and springs (rest
    length: the initial distance, measured again in float32 by Newton; newton_model sets the scene's)."""
    builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=tuple(float(g) for g in gravity))  # a 3-vector
    mass, pinned = scene.particle_array("mass"), scene.particle_array("pinned")
    for position, m, pin in zip(scene.particle_array("position").tolist(), mass.tolist(), pinned.tolist(),
                                strict=True):
        builder.add_particle(tuple(position), (0.0, 0.0, 0.0), 0.0 if pin else m)
    extra = {"control": 0.0} if "control" in inspect.signature(builder.add_spring).parameters else {}
    for (a, b), ke, kd in zip(scene.spring_array("pairs").tolist(), scene.spring_array("stiffness").tolist(),
                              scene.spring_array("damping").tolist(), strict=True):
        builder.add_spring(a, b, ke, kd, **extra)
    return builder


def newton_model(builder, scene: ws.Scene, device, requires_grad: bool = False):
    """builder.finalize on ``device`` with the scene's rest lengths, particle-particle contact off
    (model.particle_grid = None)."""
    model = builder.finalize(device=device.alias, requires_grad=requires_grad)
    # Newton's builder measures rest lengths in float32; the scene's (float64) make the two agree to the digit
    model.spring_rest_length.assign(scene.spring_array("rest_length").astype(np.float32))
    model.particle_grid = None
    return model


def newton_solver(newton, model):
    """SolverSemiImplicit (symplectic Euler) with triangle contact off."""
    solver = getattr(newton.solvers, "SolverSemiImplicit", None) or newton.solvers.SemiImplicitSolver
    return solver(model, enable_tri_contact=False)


class NewtonCloth:
    """Newton's SolverSemiImplicit (symplectic Euler) on the same particles (pinned: mass 0) and springs, y up;
    no triangles, triangle contact off, particle-particle contact off (model.particle_grid = None), no shapes."""

    name, precision = "Newton", "float32"

    def __init__(self, newton, scene: ws.Scene, device):
        self.model = newton_model(newton_builder(newton, scene), scene, device)
        self.solver = newton_solver(newton, self.model)
        self.states = [self.model.state(), self.model.state()]
        self.control = self.model.control()

    def reset(self, x: np.ndarray, v: np.ndarray) -> None:
        device = self.model.device
        self.states[0].particle_q.assign(wp.array(x.astype(np.float32), dtype=wp.vec3, device=device))
        self.states[0].particle_qd.assign(wp.array(v.astype(np.float32), dtype=wp.vec3, device=device))

    def advance(self, steps: int) -> None:
        for _ in range(steps):
            state_in, state_out = self.states
            state_in.clear_forces()
            self.solver.step(state_in, state_out, self.control, None, DT)
            self.states.reverse()

    def sync(self) -> None:
        wp.synchronize_device(self.model.device)

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        state = self.states[0]
        return state.particle_q.numpy().astype(np.float64), state.particle_qd.numpy().astype(np.float64)


def trajectory(implementation, x0: np.ndarray, v0: np.ndarray) -> tuple:
    """((x, v) after one step, (x, v) after CHECK_STEPS steps) from (x0, v0); the implementation is reset after."""
    implementation.reset(x0, v0)
    implementation.advance(1)
    implementation.sync()
    one = implementation.read()
    implementation.advance(CHECK_STEPS - 1)
    implementation.sync()
    last = implementation.read()
    implementation.reset(x0, v0)
    return one, last


def deviation(run: tuple, reference: tuple, precision: str | None) -> dict:
    """max |dv| / DT after one step, max |dx| and |dv| after CHECK_STEPS steps; ok: within TOLERANCES[precision]."""
    (_, v1), (x, v) = run
    (_, rv1), (rx, rv) = reference
    result = {"max_da": float(np.abs(v1 - rv1).max()) / DT, "max_dx": float(np.abs(x - rx).max()),
              "max_dv": float(np.abs(v - rv).max())}
    if precision is not None:
        result["precision"] = precision
        result["ok"] = all(result[key] <= limit for key, limit in TOLERANCES[precision].items())
    return result


def check(key: str, implementation, x0, v0, reference, optional: dict, checks: dict, status: dict) -> bool:
    """Run the check on one implementation, print it, record it in checks[key]. A warp_sim or numpy failure
    raises; an optional implementation's failure or disagreement is recorded in status[key] (False returned)."""
    try:
        result = deviation(trajectory(implementation, x0, v0), reference, implementation.precision)
    except Exception as error:
        if key.split()[0] not in optional:
            raise
        status[key.split()[0]] = f"error: {type(error).__name__}: {error}"
        print(f"  {implementation.name}: {status[key.split()[0]]}", flush=True)
        return False
    checks[key] = {"name": implementation.name, **result}
    limits = TOLERANCES[implementation.precision]
    print(f"  check {implementation.name}: one step max |da| = {result['max_da']:.2e} m/s^2, after {CHECK_STEPS} steps "
          f"max |dx| = {result['max_dx']:.2e} m, max |dv| = {result['max_dv']:.2e} m/s, against numpy float64: "
          f"{'ok' if result['ok'] else 'DISAGREES'} (tolerances {limits['max_da']:g}, {limits['max_dx']:g}, "
          f"{limits['max_dv']:g})", flush=True)
    if result["ok"]:
        return True
    message = (f"{implementation.name} disagrees with the numpy float64 step: one step max |da| = "
               f"{result['max_da']:.3e} m/s^2, after {CHECK_STEPS} steps max |dx| = {result['max_dx']:.3e} m, "
               f"max |dv| = {result['max_dv']:.3e} m/s; tolerances ({implementation.precision}) {limits}")
    if key.split()[0] not in optional:
        raise AssertionError(message)
    status[key.split()[0]] = "error: disagrees with the reference step"
    print(f"  {message}", flush=True)
    return False


def timed(implementation, steps: int) -> float:
    implementation.sync()
    start = time.perf_counter()
    implementation.advance(steps)
    implementation.sync()
    return time.perf_counter() - start


def bench_explicit(n: int, device, args, optional: dict) -> dict:
    """Check every implementation against numpy float64, then time the float32 ones (interleaved, median)."""
    scene = make_scene(n)
    x0, v0 = initial_state(scene)
    reference = trajectory(NumpyCloth(scene, np.float64), x0, v0)
    sensitivity = {label: deviation(trajectory(NumpyCloth(scene, np.float64, **change), x0, v0), reference, None)
                   for label, change in (("gravity dropped", {"gravity": False}),
                                         ("dampers dropped", {"damping": False}))}
    status, checks = {"warp_sim": "ok", "warp_sim_guard": "ok", "numpy": "ok"}, {}

    # float64: the step itself (no float32 rounding to hide a difference); checked, not timed
    check("warp_sim float64", WarpSimCloth(make_scene(n, "float64"), device, guard=False), x0, v0, reference,
          optional, checks, status)
    if optional["taichi"][0] is not None:
        try:
            taichi64 = TaichiCloth(optional["taichi"][0], scene, "float64")
        except Exception as error:  # an optional backend that cannot run this scene is reported, not fatal
            status["taichi"] = f"error: {type(error).__name__}: {error}"
            print(f"  taichi: {status['taichi']}", flush=True)
        else:
            check("taichi float64", taichi64, x0, v0, reference, optional, checks, status)
            del taichi64

    # float32: the timed implementations
    profile = KernelProfile()
    profile.enabled = False
    implementations = {"warp_sim": WarpSimCloth(scene, device, guard=False, profile=profile),
                       "warp_sim_guard": WarpSimCloth(scene, device, guard=True),
                       "numpy": NumpyCloth(scene, np.float32)}
    for key, (module, available) in optional.items():
        if key in status:  # failed in float64 already
            continue
        if module is None:
            status[key] = available
            continue
        try:
            implementations[key] = TaichiCloth(module, scene) if key == "taichi" else NewtonCloth(module, scene, device)
            status[key] = "ok"
        except Exception as error:
            status[key] = f"error: {type(error).__name__}: {error}"
            print(f"  {key}: {status[key]}", flush=True)
    for key, implementation in list(implementations.items()):
        if not check(key, implementation, x0, v0, reference, optional, checks, status):
            del implementations[key]

    for implementation in implementations.values():  # load kernels, touch every buffer
        timed(implementation, WARMUP_STEPS)
    seconds = {key: [] for key in implementations}
    for _ in range(args.repeats):  # interleaved, so every implementation sees the same machine noise
        for key, implementation in implementations.items():
            seconds[key].append(timed(implementation, args.steps))

    profile_steps = max(1, args.steps // 2)
    profile.enabled = True
    implementations["warp_sim"].advance(profile_steps)
    profile.enabled = False
    kernels = profile.per_step(profile_steps)

    rates = {key: args.steps / statistics.median(times) for key, times in seconds.items()}
    ratios = {key: rates["warp_sim"] / rates[key] for key in rates if key not in ("warp_sim", "warp_sim_guard")}
    return {"n": n, "particles": scene.particle_count, "springs": scene.spring_count,
            "vertex_mass_interior_kg": float(scene.particle_array("mass").max()), "steps": args.steps,
            "repeats": args.repeats, "status": status, "check": checks, "check_sensitivity": sensitivity,
            "seconds": seconds, "steps_per_s": rates, "ms_per_step": {key: 1e3 / rate for key, rate in rates.items()},
            "warp_sim_over": ratios, "sim_seconds_per_s": rates["warp_sim"] * DT,
            "profile_steps": profile_steps, "warp_sim_kernels_per_step": kernels}


def relative_residual(integrator) -> float | None:
    """|b - A dv| / |b| of the last CG solve, where the integrator's attributes tell it (None otherwise)."""
    if hasattr(integrator, "last_tolerance") and getattr(integrator, "absolute_tolerance", 0.0) == 0.0:
        threshold = integrator.last_tolerance  # tolerance |b| when there is no absolute floor
        return integrator.last_residual * integrator.tolerance / threshold if threshold > 0 else None
    if getattr(integrator, "last_rhs_norm", 0.0) > 0:
        return integrator.last_residual / integrator.last_rhs_norm
    return None


#: the implicit settings compared: the defaults, and the defaults before they were chosen by measurement
IMPLICIT_SETTINGS = {"defaults": {}, "before (1e-6, cap 200)": {"tolerance": 1e-6, "max_iterations": 200}}


def bench_implicit(n: int, device, steps: int, label: str = "defaults") -> dict:
    """The cloth from rest, implicit_euler at IMPLICIT_DT with IMPLICIT_SETTINGS[label] (guard on): each step
    timed."""
    sim = ws.Simulator(make_scene(n), ws.ImplicitEuler(**IMPLICIT_SETTINGS[label]), device.alias)
    iterations, seconds, residuals = [], [], []
    for _ in range(steps):
        wp.synchronize_device(sim.device)
        start = time.perf_counter()
        with warnings.catch_warnings():   # unconverged solves are counted in the table instead
            warnings.simplefilter("ignore", RuntimeWarning)
            sim.step(IMPLICIT_DT)  # CG reads its residual back every iteration, so the step has finished here
        wp.synchronize_device(sim.device)
        seconds.append(time.perf_counter() - start)
        iterations.append(sim.integrator.last_iterations)
        residuals.append(relative_residual(sim.integrator))
    total = sum(seconds)
    rate = steps / total
    known = [r for r in residuals if r is not None]
    return {"n": n, "settings": label, "particles": sim.model.particle_count, "springs": sim.model.spring_count,
            "steps": steps,
            "h": IMPLICIT_DT, "seconds": seconds, "steps_per_s": rate, "ms_per_step": 1e3 / rate,
            "cg_iterations": iterations, "cg_min": min(iterations), "cg_mean": statistics.fmean(iterations),
            "cg_max": max(iterations), "cg_tolerance": sim.integrator.tolerance,
            "cg_max_iterations": sim.integrator.max_iterations,
            "unconverged_solves": sim.integrator.unconverged_solves, "cg_relative_residuals": residuals,
            "cg_relative_residual_median": statistics.median(known) if known else None,
            "ms_per_cg_iteration": 1e3 * total / max(1, sum(iterations)), "sim_seconds_per_s": rate * IMPLICIT_DT,
            "lowest_y": float(sim.state.particle_x.numpy()[:, 1].min())}


def load_kernels(device) -> float:
    """Seconds to compile or load warp_sim's kernels: a few steps of each integrator on an 8 x 8 cloth."""
    start = time.perf_counter()
    scene = make_scene(8)
    ws.Simulator(scene, "symplectic_euler", device.alias).step(DT, steps=2)
    ws.Simulator(scene, "implicit_euler", device.alias).step(IMPLICIT_DT, steps=2)
    wp.synchronize_device(device)
    return time.perf_counter() - start


def rate_cell(row: dict, key: str) -> str:
    """steps/s, or why there is none (an error shortened for the table; the JSON has it whole)."""
    if key in row["steps_per_s"]:
        return f"{row['steps_per_s'][key]:,.0f}"
    status = row["status"][key].replace("|", "/")
    return status if len(status) <= 48 else status[:45] + "..."


def ratio_cell(row: dict, key: str) -> str:
    return f"{row['warp_sim_over'][key]:.2f}x" if key in row["warp_sim_over"] else "-"


def tables(device_alias: str, explicit: list[dict], implicit: list[dict]) -> str:
    out = []
    if explicit:
        rows = [[device_alias, f"{r['n']}x{r['n']}", f"{r['particles']:,}", f"{r['springs']:,}",
                 rate_cell(r, "warp_sim"), rate_cell(r, "warp_sim_guard"), rate_cell(r, "numpy"),
                 rate_cell(r, "taichi"), rate_cell(r, "newton"), ratio_cell(r, "numpy"), ratio_cell(r, "taichi"),
                 ratio_cell(r, "newton")] for r in explicit]
        out.append(markdown(["device", "cloth", "particles", "springs", "warp_sim steps/s", "warp_sim (guard) steps/s",
                             "numpy steps/s", "Taichi cpu steps/s", "Newton steps/s", "warp_sim / numpy",
                             "warp_sim / Taichi", "warp_sim / Newton"], rows, left=("device", "cloth")))
        check_rows = []
        for r in explicit:
            cells = [(c["name"], c) for c in r["check"].values()]
            cells += [(f"(numpy float64, {label})", c) for label, c in r["check_sensitivity"].items()]
            for name, c in cells:
                check_rows.append([f"{r['n']}x{r['n']}", name, f"{c['max_da']:.1e}", f"{c['max_dx']:.1e}",
                                   f"{c['max_dv']:.1e}", ("ok" if c["ok"] else "DISAGREES") if "ok" in c else "-"])
        out.append(markdown(["cloth", "implementation", "1 step: max abs da [m/s^2]",
                             f"{CHECK_STEPS} steps: max abs dx [m]", f"{CHECK_STEPS} steps: max abs dv [m/s]", "check"],
                            check_rows, left=("cloth", "implementation", "check")))
        labels = [key for key in KERNEL_LABELS if any(key in r["warp_sim_kernels_per_step"] for r in explicit)]
        labels += sorted({key for r in explicit for key in r["warp_sim_kernels_per_step"]} - set(labels))
        kernel_rows = []
        for r in explicit:
            kernels = r["warp_sim_kernels_per_step"]
            total = sum(k["ms"] for k in kernels.values())
            kernel_rows.append([f"{r['n']}x{r['n']}"]
                               + [f"{kernels[key]['ms']:.3f} ({kernels[key]['launches']:.0f})" if key in kernels
                                  else "-" for key in labels]
                               + [f"{total:.3f}", f"{r['ms_per_step']['warp_sim']:.3f}"])
        out.append(markdown(["cloth"] + [f"{KERNEL_LABELS.get(key, key)} ms (launches)" for key in labels]
                            + ["sum ms", "timed ms/step"], kernel_rows, left=("cloth",)))
    if implicit:
        explicit_rate = {r["n"]: r["sim_seconds_per_s"] for r in explicit}
        rows = [[device_alias, f"{r['n']}x{r['n']}", r["settings"], f"{r['particles']:,}", f"{r['springs']:,}",
                 f"{r['steps_per_s']:.2f}", f"{r['ms_per_step']:.0f}",
                 f"{r['cg_min']} / {r['cg_mean']:.1f} / {r['cg_max']} (cap {r['cg_max_iterations']})",
                 f"{r['unconverged_solves']} of {r['steps']}",
                 "-" if r["cg_relative_residual_median"] is None else f"{r['cg_relative_residual_median']:.1e}",
                 f"{r['ms_per_cg_iteration']:.2f}", f"{r['sim_seconds_per_s']:.4f}",
                 f"{explicit_rate[r['n']]:.4f}" if r["n"] in explicit_rate else "-"] for r in implicit]
        out.append(markdown(["device", "cloth", "settings", "particles", "springs", "steps/s", "ms/step",
                             "CG its min / mean / max",
                             "unconverged (at the cap)", "median rel. residual", "ms per CG it", "sim s per s",
                             f"explicit sim s per s (dt {DT:g})"], rows, left=("device", "cloth", "settings")))
    return "\n\n".join(out)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", choices=("cpu", "cuda"), default=None, help="default: cuda if present, else cpu")
    parser.add_argument("--sizes", type=int, nargs="+", default=None,
                        help="explicit part: vertices per side (default 32 64 128, and 256 on cuda; 0: none)")
    parser.add_argument("--steps", type=int, default=200, help="explicit: timed steps per repeat")
    parser.add_argument("--repeats", type=int, default=5, help="explicit: timed repeats; the median is reported")
    parser.add_argument("--implicit-sizes", type=int, nargs="+", default=None,
                        help="implicit part: vertices per side (default: as --sizes; 0: none)")
    parser.add_argument("--implicit-steps", type=int, default=30, help="implicit: steps of 1/60 s, each timed")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/cloth.json"))
    args = parser.parse_args(argv)
    device = pick_device(parser, args.device)
    sizes = args.sizes if args.sizes is not None else DEFAULT_SIZES + (CUDA_SIZES if device.is_cuda else [])
    implicit_sizes = args.implicit_sizes if args.implicit_sizes is not None else sizes
    sizes, implicit_sizes = [n for n in sizes if n != 0], [n for n in implicit_sizes if n != 0]
    if min(sizes + implicit_sizes, default=3) < 3 or min(args.steps, args.repeats, args.implicit_steps) < 1:
        parser.error("sizes must be >= 3 (or 0 for none); --steps, --repeats and --implicit-steps >= 1")

    optional = {"taichi": optional_import("taichi"), "newton": optional_import("newton")}
    versions = {key: getattr(module, "__version__", "?") if module is not None else None
                for key, (module, _) in optional.items()}
    name = device_name(device)
    print(f"warp {wp.__version__}, warp_sim on {device.alias} ({name}), float32; numpy {np.__version__}; "
          + "; ".join(f"{key} {versions[key] or status}" for key, (_, status) in optional.items()))
    print(f"cloth 1 m x 1 m, {CLOTH['density']} kg/m^2, stiffness {CLOTH['stiffness']} N/m, damping "
          f"{CLOTH['damping']} N s/m, top corners pinned; explicit dt = {DT:g} s, implicit h = 1/60 s")
    kernels_s = load_kernels(device)
    print(f"warp_sim kernels compiled or loaded in {kernels_s:.2f} s", flush=True)

    explicit = []
    for n in sizes:
        print(f"explicit {n}x{n} ...", flush=True)
        explicit.append(bench_explicit(n, device, args, optional))
    implicit = []
    for n in implicit_sizes:
        for label in IMPLICIT_SETTINGS:
            print(f"implicit {n}x{n}, {label} ...", flush=True)
            implicit.append(bench_implicit(n, device, args.implicit_steps, label))
    print()
    print(tables(device.alias, explicit, implicit))

    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {"device": device.alias, "device_name": name, "cpu_count": os.cpu_count(), "warp_version": wp.__version__,
              "warp_sim_version": ws.__version__, "numpy_version": np.__version__,
              "optional": {key: {"status": status, "version": versions[key]}
                           for key, (_, status) in optional.items()},
              "precision": "float32", "gravity": GRAVITY, "cloth": CLOTH, "dt": DT, "implicit_h": IMPLICIT_DT,
              "check_steps": CHECK_STEPS, "check_speed": CHECK_SPEED, "check_tolerances": TOLERANCES,
              "seed": SEED, "kernel_load_s": kernels_s, "explicit": explicit, "implicit": implicit}
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""Side by side: warp_sim and every installed peer on the same four workloads, checked, then timed; one table.

    python benchmarks/compare.py [--device cpu|cuda] [--quick] [--workloads cloth particles pile bigpile]
                                 [--only warp_sim newton ...] [--baseline REV [REV ...]] [--pile-dt 1/500]
                                 [--budget S] [--timeout S] [--out benchmarks/results/compare.json]

Workloads (full sizes by default; --quick: smaller sizes and fewer steps, a couple of minutes in all):
  cloth      benchmarks/cloth.py's cloth (structural, shear and bend springs, gravity, two pinned corners,
             symplectic Euler at dt = 5e-6 s, float32), 32^2, 64^2, 128^2: warp_sim (guard off, the same work as
             the others; and guard on), Newton SolverSemiImplicit, a gather-style Taichi kernel on one CPU thread;
             MuJoCo: n/a (no mass-spring cloth).
  particles  benchmarks/particles.py's "box" scene (10^5 and 10^6 particles falling onto the ground, impulse
             contact, dt = 1/480 s), warp_sim with its guard on, against the copy-bandwidth floor measured in this
             run (x and v read and written once a step); on the CPU warp_sim on every core (its default,
             warp_sim.core.cpu_threads) and on one thread, each row followed by the floor of a copy on as many
             threads; Newton SolverSemiImplicit (penalty particle-ground contact; one CPU thread, as Warp runs a
             launch), a Taichi kernel (plane contact by impulse) on one CPU thread and on every core.
  pile       benchmarks/collision.py's pile of 100 bodies (boxes and spheres) on the ground at dt = 1/500 s: the
             step of Newton's own rigid-body examples and MuJoCo's default timestep, the same for every
             implementation: warp_sim (guard on), Newton SolverSemiImplicit and SolverXPBD (5 iterations, as in
             Newton's examples), MuJoCo (C, one thread) and MuJoCo-Warp on the same MJCF of the pile.
  bigpile    the same pile with 10^4 bodies, each run capped by --budget seconds (then "n/a (...)").

Each implementation-workload runs in a subprocess of its own (a crash, a Taichi init or a compile there cannot
touch another's numbers; a crash is reported as "failed: <its last line>"). The implementations of a workload
prepare each size one after another, then take their timed rounds in turn, A B C A B C ... (benchmarks/rounds.py),
so that a drift of a shared machine's speed reaches them alike; the ratios are the median of the per-round ratios
against warp_sim's round beside them. In its subprocess, every implementation is first CHECKED, before it is
timed, and the check is printed next to its speed:
  cloth      the one-step acceleration of a free particle (gravity) and of the two ends of a stretched, moving,
             damped spring against the closed form (tolerances CLOSED_FORM_TOLERANCES), and the cloth's one step
             and CHECK_STEPS steps against benchmarks/cloth.py's numpy float64 step (cloth.TOLERANCES["float32"]);
  particles  the first step's acceleration of every particle in free flight (above FREE_HEIGHT) against the
             closed form of that implementation's model, and the deepest penetration into the ground after each
             timed round;
  piles      the deepest point of any body below the ground over the settle (sampled every SAMPLE_STEPS steps) and
             the timed steps, the highest speed after the settle (has the pile come to rest?) and the energy bound
             (no body faster than a fall from the top of the pile allows).
A ground check passes at no more than MAX_DEPTH (1 mm) deep: a softer contact's sinking is reported as a failure,
not rewarded by its speed. Nothing about times is asserted. Results: one markdown table and --out (JSON). See
benchmarks/README.md.

--baseline REV ...: each revision is another implementation of every workload, "warp_sim @ REV", beside the
working tree's warp_sim in the same rounds: the revision checked out by ``git worktree add`` in a temporary
folder (``worktree``), its workers this script's own (the same benchmark code) with PYTHONPATH at that folder,
so that they import that revision's warp_sim (each result says which it imported; a worker that did not import
it fails). The worktrees are removed at the end. A second table gives the working tree's speed over each
revision's, and each later revision's over the first's (e.g. ``--baseline 8dcb2b4 HEAD``: the forward speed
before and after a change, committed, whatever the working tree holds).
"""
from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.metadata
import importlib.util
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

import cloth
import collision
import numpy as np
import particles
import rounds
import warp as wp
from common import device_name, environment, floor_bandwidth, git_state, markdown, pick_device

import warp_sim as ws
from warp_sim.core.cpu_threads import cpu_threads

#: peer key -> (module, distribution)
PEERS = {"newton": ("newton", "newton"), "taichi": ("taichi", "taichi"), "mujoco": ("mujoco", "mujoco"),
         "mujoco_warp": ("mujoco_warp", "mujoco-warp")}
WORKLOADS = ("cloth", "particles", "pile", "bigpile")
PILE_DT = 1.0 / 500.0  # [s] Newton's rigid examples (100 fps, 5 substeps) and MuJoCo's default timestep
MAX_DEPTH = 1.0e-3     # [m] deepest a body or particle may be in the ground for a check to pass
FREE_HEIGHT = 0.5      # [m] particles above this at the start are in free flight for the first step
FREE_TOLERANCE = 1.0e-2  # [m/s^2] the particles' one-step free-flight acceleration error (float32 rounding ~2e-4)
SAMPLE_STEPS = 10      # pile: steps between two looks at its deepest point during the settle
WARMUP_STEPS = 3
MJW_DENSE_LIMIT = 2**31  # [bytes] MuJoCo-Warp's dense Hessian (4 nv^2 B) above which it is not tried on the CPU
#                          (on CUDA: half the device's memory)
PARTICLE_GROUND = (0.5, 0.4)  # particles.make_scene's ground: restitution, friction
#: the closed-form check of a cloth step: the free particle's |da| [m/s^2], the spring ends' |da| / |a|
CLOSED_FORM_TOLERANCES = {"free": 1.0e-3, "spring": 1.0e-4}
#: the closed-form scene: a free particle, and a spring of SPRING["stiffness"] N/m, SPRING["damping"] N s/m and rest
#: length SPRING["rest"] m stretched to SPRING["length"] m, its far end moving away at SPRING["speed"] m/s
SPRING = {"mass": 0.01, "stiffness": 1.0e4, "damping": 100.0, "rest": 0.1, "length": 0.11, "speed": 0.2}

#: per workload and mode: sizes, and `repeats` timed rounds of `steps` (cloth: by size, so that a round takes a
#: tenth of a second or more; taken in turn by the implementations; the median reported), after `settle` untimed
#: seconds for the piles
SETTINGS = {
    "full": {"cloth": {"sizes": [32, 64, 128], "steps": {32: 2000, 64: 600, 128: 200}, "repeats": 9},
             "particles": {"sizes": [100_000, 1_000_000], "steps": 100, "repeats": 7},
             "pile": {"sizes": [100], "settle": 2.0, "steps": 100, "repeats": 5},
             "bigpile": {"sizes": [10_000], "settle": 2.0, "steps": 4, "repeats": 5}},
    "quick": {"cloth": {"sizes": [32, 64], "steps": {32: 200, 64: 50}, "repeats": 3},
              "particles": {"sizes": [10_000, 100_000], "steps": 20, "repeats": 3},
              "pile": {"sizes": [100], "settle": 0.4, "steps": 10, "repeats": 5},
              "bigpile": {"sizes": [500], "settle": 0.5, "steps": 2, "repeats": 5}},
}
BUDGET = {"full": 900.0, "quick": 60.0}     # [s] one pile run (settle + timed), else "n/a"
TIMEOUT = {"full": 3600.0, "quick": 300.0}  # [s] one answer of a worker (benchmarks/rounds.py)

NOT_MUJOCO_CLOTH = ("n/a (MuJoCo has no mass-spring cloth: its flex is a triangulated mesh with edge constraints "
                    "and plate/shell elasticity, not structural/shear/bend springs)")
NOT_MUJOCO_PARTICLES = "n/a (MuJoCo has no particle system: 10^5 free bodies are the pile workloads, not this one)"
NOT_TAICHI_PILE = "n/a (Taichi is a kernel language with no rigid-body contact solver; none is written here)"


def implementations(workload: str, device) -> list[dict]:
    """The rows of a workload, in table order: key, label, the peer it needs (None: warp_sim), why not (n/a)."""
    taichi = f"Taichi {'cuda' if device.is_cuda else 'cpu, 1 thread'}"
    cores = cpu_threads()
    threads = f", {cores} CPU threads" if device.is_cpu else ""
    # on the CPU, warp_sim's particles on one thread too, and Taichi on as many threads as warp_sim
    cpu_rows = [("warp_sim_1thread", "warp_sim (guard on, 1 CPU thread)", None)] if device.is_cpu else []
    if device.is_cpu and cores > 1:
        cpu_rows.append(("taichi_threads", f"Taichi cpu, {cores} threads, impulse ground", "taichi"))
    rows = {
        "cloth": [("warp_sim", "warp_sim (guard off)", None), ("warp_sim_guard", "warp_sim (guard on)", None),
                  ("newton", "Newton SemiImplicit", "newton"), ("taichi", f"{taichi}, gather", "taichi"),
                  ("mujoco", "MuJoCo", "mujoco", NOT_MUJOCO_CLOTH)],
        "particles": [("warp_sim", f"warp_sim (guard on{threads})", None)] + cpu_rows + [
                      ("newton", "Newton SemiImplicit (penalty ground, no drag)", "newton"),
                      ("taichi", f"{taichi}, impulse ground", "taichi"),
                      ("mujoco", "MuJoCo", "mujoco", NOT_MUJOCO_PARTICLES)],
        "pile": [("warp_sim", "warp_sim (guard on)", None),
                 ("warp_sim_capture", "warp_sim (guard on, capture=True)", None),
                 ("newton", "Newton SemiImplicit", "newton"),
                 ("newton_xpbd", "Newton XPBD (5 iterations)", "newton"),
                 ("mujoco", "MuJoCo C (cpu, 1 thread)", "mujoco"), ("mujoco_warp", "MuJoCo-Warp", "mujoco_warp"),
                 ("taichi", "Taichi", "taichi", NOT_TAICHI_PILE)],
    }[workload if workload != "bigpile" else "pile"]
    return [{"key": r[0], "label": r[1], "peer": r[2], "na": r[3] if len(r) > 3 else None} for r in rows]


def peer_status() -> dict:
    """Per peer: installed (found, not imported: a Taichi or MuJoCo import stays in the subprocesses), version."""
    status = {}
    for key, (module, distribution) in PEERS.items():
        found = importlib.util.find_spec(module) is not None
        try:
            version = importlib.metadata.version(distribution) if found else None
        except importlib.metadata.PackageNotFoundError:
            version = "?"
        status[key] = {"installed": found, "version": version}
    return status


class OverBudget(Exception):
    """A run that would take too long (or too much memory): its row says "n/a (...)", the message."""


# ---------------------------------------------------------------------------------------------------- adapters
# Every implementation below has advance(steps, dt), sync() and arrays(): numpy (x, v) for particles, (x, R, v) for
# bodies. The cloth implementations are benchmarks/cloth.py's (advance(steps) at cloth.DT, reset, read).

class WarpSimRun:
    """A warp_sim Simulator: sim.step(dt, steps) is one call (the guard read once at its end, as common.time_steps)."""

    def __init__(self, sim: ws.Simulator):
        self.sim = sim

    def advance(self, steps: int, dt: float) -> None:
        self.sim.step(dt, steps=steps)

    def sync(self) -> None:
        wp.synchronize_device(self.sim.device)

    def arrays(self):
        if self.sim.model.body_count:
            return collision.body_arrays(self.sim)
        return self.sim.state.particle_x.numpy(), self.sim.state.particle_v.numpy()


class NewtonParticles:
    """The particle scene in Newton: the same positions, velocities, masses and radii, y up, a ground plane
    (friction 0.4), SolverSemiImplicit: penalty contact of each particle with the ground from CollisionPipeline's
    soft contacts (one per particle), no particle-particle contact (model.particle_grid = None), no drag (Newton's
    particles have none)."""

    def __init__(self, newton, scene: ws.Scene, device):
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))
        builder.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=0.4))
        builder.add_particles(scene.particle_array("position").tolist(), scene.particle_array("velocity").tolist(),
                              scene.particle_array("mass").tolist(), scene.particle_array("radius").tolist())
        self.model = builder.finalize(device=device.alias)
        self.model.particle_grid = None
        self.solver = newton.solvers.SolverSemiImplicit(self.model)
        self.states = [self.model.state(), self.model.state()]
        self.control = self.model.control()
        self.pipeline = newton.CollisionPipeline(self.model, soft_contact_max=self.model.particle_count)
        self.contacts = self.pipeline.contacts()

    def advance(self, steps: int, dt: float) -> None:
        for _ in range(steps):
            state_in, state_out = self.states
            state_in.clear_forces()
            self.pipeline.collide(state_in, self.contacts)
            self.solver.step(state_in, state_out, self.control, self.contacts, dt)
            self.states.reverse()

    def sync(self) -> None:
        wp.synchronize_device(self.model.device)

    def arrays(self):
        return self.states[0].particle_q.numpy(), self.states[0].particle_qd.numpy()


class TaichiParticles:
    """The particle step in one Taichi kernel (float32): v += h (g - drag v / m); x += h v; then the ground: a
    particle below its radius is put back on it and, moving down, bounces with the ground's restitution, its
    tangential velocity reduced by friction x the normal impulse (Coulomb), not below zero."""

    def __init__(self, ti, scene: ws.Scene, dt: float, arch: str = "cpu", threads: int | None = 1):
        cloth.taichi_init(ti, arch, threads, default_fp=ti.f32)
        self.ti = ti
        n = scene.particle_count
        self.x, self.v = ti.Vector.field(3, ti.f32, shape=n), ti.Vector.field(3, ti.f32, shape=n)
        w, r = ti.field(ti.f32, shape=n), ti.field(ti.f32, shape=n)
        self.x.from_numpy(scene.particle_array("position").astype(np.float32))
        self.v.from_numpy(scene.particle_array("velocity").astype(np.float32))
        w.from_numpy((1.0 / scene.particle_array("mass")).astype(np.float32))
        r.from_numpy(scene.particle_array("radius").astype(np.float32))
        g, drag, h = ti.Vector(list(scene.gravity)), float(scene.drag), float(dt)
        restitution, friction = PARTICLE_GROUND
        x, v = self.x, self.v

        @ti.kernel
        def step():
            for i in x:
                vi = v[i] + h * (g - drag * v[i] * w[i])
                xi = x[i] + h * vi
                if xi[1] < r[i]:
                    xi[1] = r[i]
                    vn = vi[1]
                    if vn < 0.0:
                        impulse = -(1.0 + restitution) * vn
                        vi[1] = -restitution * vn
                        tangential = ti.sqrt(vi[0] * vi[0] + vi[2] * vi[2])
                        if tangential > 0.0:
                            scale = ti.max(0.0, tangential - friction * impulse) / tangential
                            vi[0] *= scale
                            vi[2] *= scale
                x[i] = xi
                v[i] = vi

        self.step = step

    def advance(self, steps: int, dt: float) -> None:
        for _ in range(steps):
            self.step()

    def sync(self) -> None:
        self.ti.sync()

    def arrays(self):
        return self.x.to_numpy(), self.v.to_numpy()



def pile_mjcf(parameters: dict, dt: float) -> str:
    """The pile as MJCF: y up (gravity -y, the plane's normal +y), one free body per pile body with its box or
    sphere geom, density, friction (MuJoCo's default torsional and rolling coefficients); MuJoCo's defaults else
    (soft contacts, solref 0.02 s: it has no restitution coefficient)."""
    geoms = []
    for i, (kind, size, position, q) in enumerate(zip(parameters["kind"].tolist(), parameters["size"].tolist(),
                                                      parameters["position"].tolist(),
                                                      parameters["orientation"].tolist(), strict=True)):
        shape = (f'type="box" size="{size[0]!r} {size[1]!r} {size[2]!r}"' if kind == "box"
                 else f'type="sphere" size="{size[0]!r}"')
        geoms.append(f'<body name="b{i}" pos="{position[0]!r} {position[1]!r} {position[2]!r}" '
                     f'quat="{q[3]!r} {q[0]!r} {q[1]!r} {q[2]!r}"><freejoint/><geom {shape}/></body>')
    n = len(geoms)
    return (f'<mujoco model="pile"><option timestep="{dt!r}" gravity="0 -9.81 0"/>'
            f'<size memory="{max(64, n // 4)}M"/>'
            f'<default><geom density="{collision.DENSITY!r}" friction="{collision.FRICTION!r} 0.005 0.0001"/>'
            f'</default><worldbody><geom name="ground" type="plane" size="0 0 1" zaxis="0 1 0"/>'
            + "".join(geoms) + "</worldbody></mujoco>")


class MujocoPile:
    """MuJoCo (C, one thread) on pile_mjcf: mj_step(nstep=steps)."""

    def __init__(self, mujoco, parameters: dict, dt: float):
        self.mujoco = mujoco
        self.model = mujoco.MjModel.from_xml_string(pile_mjcf(parameters, dt))
        self.data = mujoco.MjData(self.model)

    def advance(self, steps: int, dt: float) -> None:
        self.mujoco.mj_step(self.model, self.data, nstep=steps)

    def sync(self) -> None:
        pass

    def arrays(self):
        d = self.data
        self.mujoco.mj_kinematics(self.model, d)  # mj_step leaves xpos, xmat at the state before its integration
        return d.xpos[1:].copy(), d.xmat[1:].reshape(-1, 3, 3).copy(), d.qvel.reshape(-1, 6)[:, :3].copy()


class MujocoWarpPile:
    """MuJoCo-Warp on the same MJCF, on warp_sim's device: put_model / put_data (room for 16 contacts a body and 4
    constraint rows a contact), mjw.step per step."""

    def __init__(self, mujoco, mjw, parameters: dict, dt: float, device):
        self.mjw, self.device = mjw, device
        mjm = mujoco.MjModel.from_xml_string(pile_mjcf(parameters, dt))
        hessian = 4 * mjm.nv**2  # MuJoCo-Warp's Newton solver factors a dense nv x nv matrix (float32)
        if hessian > (device.total_memory // 2 if device.is_cuda else MJW_DENSE_LIMIT):
            raise OverBudget(f"n/a (MuJoCo-Warp's Newton solver factors a dense nv x nv matrix: nv = {mjm.nv:,}, "
                             f"{hessian / 2**30:.0f} GiB)")
        mjd = mujoco.MjData(mjm)
        mujoco.mj_forward(mjm, mjd)
        contacts = 16 * mjm.nbody
        with wp.ScopedDevice(device):
            self.m = mjw.put_model(mjm)
            self.d = mjw.put_data(mjm, mjd, nconmax=contacts, njmax=4 * contacts)

    def advance(self, steps: int, dt: float) -> None:
        with wp.ScopedDevice(self.device):
            for _ in range(steps):
                self.mjw.step(self.m, self.d)

    def sync(self) -> None:
        wp.synchronize_device(self.device)

    def arrays(self):
        d = self.d
        with wp.ScopedDevice(self.device):
            self.mjw.kinematics(self.m, d)  # as mj_step, mjw.step leaves the poses before its integration
        return d.xpos.numpy()[0, 1:], d.xmat.numpy()[0, 1:].reshape(-1, 3, 3), d.qvel.numpy()[0].reshape(-1, 6)[:, :3]


def timed(implementation, steps: int, dt: float) -> float:
    """Seconds for implementation.advance(steps, dt), synchronised on both sides."""
    implementation.sync()
    start = time.perf_counter()
    implementation.advance(steps, dt)
    implementation.sync()
    return time.perf_counter() - start


# ---------------------------------------------------------------------------------------------------- workers

def make_cloth(key: str, scene: ws.Scene, device, modules: dict):
    if key in ("warp_sim", "warp_sim_guard"):
        return cloth.WarpSimCloth(scene, device, guard=key == "warp_sim_guard")
    if key == "newton":
        return cloth.NewtonCloth(modules["newton"], scene, device)
    if device.is_cuda:
        return cloth.TaichiGatherCloth(modules["taichi"], scene, arch="cuda")
    return cloth.TaichiGatherCloth(modules["taichi"], scene, threads=1)


def closed_form_check(key: str, device, modules: dict) -> dict:
    """One step of a free particle and of a stretched, moving spring, against a = g and
    a = g +- (-k (L - L0) - c (v2 - v1).d) d / m at each end, from the float32-rounded state."""
    s = SPRING
    x0 = np.array([[0.0, 2.0, 0.0], [0.5, 1.0, 0.0], [0.5 + s["length"], 1.0, 0.0]])
    v0 = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [s["speed"], 0.0, 0.0]])
    x0, v0 = (a.astype(np.float32).astype(np.float64) for a in (x0, v0))
    scene = ws.Scene(gravity=cloth.GRAVITY)
    scene.add_particles(x0, v0, mass=s["mass"])
    scene.add_springs([[1, 2]], s["stiffness"], s["damping"], rest_length=[s["rest"]])
    implementation = make_cloth(key, scene, device, modules)
    implementation.reset(x0, v0)
    implementation.advance(1)
    implementation.sync()
    a = (implementation.read()[1] - v0) / cloth.DT
    delta = x0[2] - x0[1]
    length = np.linalg.norm(delta)
    d = delta / length
    f2 = (-s["stiffness"] * (length - s["rest"]) - s["damping"] * np.dot(v0[2] - v0[1], d)) * d
    g = np.asarray(cloth.GRAVITY)
    exact = np.stack([g, g - f2 / s["mass"], g + f2 / s["mass"]])
    free = float(np.abs(a[0] - exact[0]).max())
    spring = float(np.abs(a[1:] - exact[1:]).max() / np.abs(exact[1:]).max())
    return {"free_da": free, "spring_rel_da": spring,
            "ok": free <= CLOSED_FORM_TOLERANCES["free"] and spring <= CLOSED_FORM_TOLERANCES["spring"]}


def prepare_cloth(key: str, n: int, cfg: dict, device, modules: dict):
    """Build, check and warm up the cloth of n x n: (one timed round [s], the result from the rounds' seconds)."""
    steps = cfg["steps"][n]
    closed = closed_form_check(key, device, modules)
    scene = cloth.make_scene(n)
    x0, v0 = cloth.initial_state(scene)
    reference = cloth.trajectory(cloth.NumpyCloth(scene, np.float64), x0, v0)
    implementation = make_cloth(key, scene, device, modules)
    agreement = cloth.deviation(cloth.trajectory(implementation, x0, v0), reference, "float32")
    ok = closed["ok"] and agreement["ok"]
    summary = (f"{'pass' if ok else 'FAIL'}: spring a rel. err {closed['spring_rel_da']:.0e}, free "
               f"{closed['free_da']:.0e} m/s^2; cloth 1-step da {agreement['max_da']:.2f} m/s^2 vs numpy f64")
    cloth.timed(implementation, WARMUP_STEPS)

    def finish(seconds: list[float]) -> dict:
        return {"check": {"pass": ok, "summary": summary, "closed_form": closed, "against_numpy_float64": agreement,
                          "tolerances": {"closed_form": CLOSED_FORM_TOLERANCES, "cloth": cloth.TOLERANCES["float32"]}},
                "seconds": seconds, "steps_per_s": steps / statistics.median(seconds), "steps_per_round": steps,
                "particles": scene.particle_count, "springs": scene.spring_count, "dt": cloth.DT}
    return partial(cloth.timed, implementation, steps), finish


def particle_depth(x: np.ndarray, radius: np.ndarray) -> float:
    """The deepest any particle's surface is in the ground [m] (0 when none is)."""
    return float(max(0.0, (radius - x[:, 1]).max()))


def prepare_particles(key: str, n: int, cfg: dict, device, modules: dict):
    """Build, check and warm up n particles: (one timed round [s], then the deepest particle; the result)."""
    scene = particles.make_scene(n)
    radius = scene.particle_array("radius")
    if key in ("warp_sim", "warp_sim_1thread"):
        implementation = WarpSimRun(ws.Simulator(scene, "symplectic_euler", device.alias, contact="impulse",
                                                 guard=True, cpu_threads=1 if key == "warp_sim_1thread" else None))
    elif key == "newton":
        implementation = NewtonParticles(modules["newton"], scene, device)
    else:
        implementation = TaichiParticles(modules["taichi"], scene, particles.DT,
                                         *(("cuda", None) if device.is_cuda else ("cpu", 1 if key == "taichi" else
                                                                                  cpu_threads())))
    dt = particles.DT
    x0, v0 = (a.astype(np.float64) for a in implementation.arrays())
    implementation.advance(1, dt)
    implementation.sync()
    v1 = implementation.arrays()[1].astype(np.float64)
    free = x0[:, 1] > FREE_HEIGHT
    drag = 0.0 if key == "newton" else scene.drag  # Newton's particles have no drag
    exact = np.asarray(scene.gravity) - drag * v0[free] / scene.particle_array("mass")[free, None]
    free_da = float(np.abs((v1[free] - v0[free]) / dt - exact).max())
    timed(implementation, WARMUP_STEPS - 1, dt)
    depths, finite = [], [True]

    def round_() -> float:
        seconds = timed(implementation, cfg["steps"], dt)
        x, v = implementation.arrays()
        depths.append(particle_depth(x, radius))
        finite[0] = finite[0] and bool(np.isfinite(x).all() and np.isfinite(v).all())
        return seconds

    def finish(seconds: list[float]) -> dict:
        ok = finite[0] and free_da <= FREE_TOLERANCE and max(depths) <= MAX_DEPTH
        summary = (f"{'pass' if ok else 'FAIL'}: free-flight a err {free_da:.0e} m/s^2, deepest "
                   f"{1e3 * max(depths):.2f} mm" + ("" if finite[0] else ", NON-FINITE"))
        return {"check": {"pass": ok, "summary": summary, "free_flight_max_da": free_da, "free_particles":
                          int(free.sum()), "deepest_m_per_round": depths, "finite": finite[0],
                          "tolerances": {"free_flight_da": FREE_TOLERANCE, "depth_m": MAX_DEPTH}},
                "seconds": seconds, "steps_per_s": cfg["steps"] / statistics.median(seconds), "dt": dt,
                "simulated_s": dt * (WARMUP_STEPS + len(seconds) * cfg["steps"])}
    return round_, finish


def prepare_pile(key: str, n: int, cfg: dict, device, modules: dict, dt: float, budget: float):
    """Build a pile of n bodies and settle it (untimed, looked at every SAMPLE_STEPS steps; OverBudget if it and the
    timed rounds would take more than ``budget`` seconds): (one timed round [s], then a look; the result)."""
    parameters = collision.body_parameters(n)
    start = time.perf_counter()
    if key in ("warp_sim", "warp_sim_capture"):
        collision.load_kernels(device, dt)
        implementation = WarpSimRun(ws.Simulator(collision.build_scene(parameters), integrator="symplectic_euler",
                                                 device=device.alias, capture=key == "warp_sim_capture"))
    elif key in ("newton", "newton_xpbd"):
        implementation = collision.NewtonPile(modules["newton"], parameters, device,
                                              solver="xpbd" if key == "newton_xpbd" else "semi_implicit")
    elif key == "mujoco":
        implementation = MujocoPile(modules["mujoco"], parameters, dt)
    else:
        implementation = MujocoWarpPile(modules["mujoco"], modules["mujoco_warp"], parameters, dt, device)
    build_s = time.perf_counter() - start
    top = float(parameters["position"][:, 1].max())
    speed_bound = math.sqrt(2.0 * 9.81 * (top + collision.SIZE_RANGE[1]))  # a fall from the top of the pile
    settle_steps = max(3, round(cfg["settle"] / dt))
    deepest, done, clock = 0.0, 0, time.perf_counter()
    while done < settle_steps:  # untimed; the deepest point looked at after every chunk
        chunk = 1 if done < 2 else min(SAMPLE_STEPS, settle_steps - done)
        chunk_start = time.perf_counter()
        implementation.advance(chunk, dt)
        implementation.sync()
        done += chunk
        state = collision.pile_summary(*implementation.arrays(), parameters)
        deepest = min(deepest, state["lowest_point"])
        if not state["finite"]:
            break
        if done == 1:  # the first step compiles or loads kernels: the budget counts from the second
            clock = time.perf_counter()
            continue
        per_step = (time.perf_counter() - chunk_start) / chunk
        projected = time.perf_counter() - clock + per_step * (settle_steps - done + cfg["steps"] * cfg["repeats"])
        if projected > budget:
            raise OverBudget(f"n/a (over the {budget:.0f} s budget: {1e3 * per_step:,.0f} ms/step at step {done} of "
                             f"{settle_steps + cfg['steps'] * cfg['repeats']}, {projected:,.0f} s projected)")
    settled, looks = state, [state]

    def round_() -> float:
        seconds = timed(implementation, cfg["steps"], dt)
        looks.append(collision.pile_summary(*implementation.arrays(), parameters))
        return seconds

    def finish(seconds: list[float]) -> dict:
        final = looks[-1]
        lowest = min([deepest] + [look["lowest_point"] for look in looks[1:]])
        finite = all(look["finite"] for look in looks)
        fastest = max(look["max_speed"] for look in looks) if finite else float("nan")
        depth, end_depth = max(0.0, -lowest), max(0.0, -final["lowest_point"])  # [m] into the ground
        ok = finite and depth <= MAX_DEPTH and fastest <= speed_bound
        summary = (f"{'pass' if ok else 'FAIL'}: deepest {1e3 * depth:.2f} mm ({1e3 * end_depth:.2f} at "
                   f"the end), max speed {settled['max_speed']:.2f} m/s after {settle_steps * dt:.2g} s"
                   + ("" if finite else ", NON-FINITE")
                   + (f", faster than a fall allows ({speed_bound:.1f} m/s)" if finite and fastest > speed_bound
                      else ""))
        return {"check": {"pass": ok, "summary": summary, "deepest_m": depth, "deepest_at_end_m": end_depth,
                          "after_settle": settled, "after_timed": final, "speed_bound": speed_bound,
                          "tolerances": {"depth_m": MAX_DEPTH}},
                "seconds": seconds, "steps_per_s": cfg["steps"] / statistics.median(seconds), "dt": dt,
                "settle_steps": settle_steps, "build_s": build_s,
                "boxes": int(np.count_nonzero(parameters["kind"] == "box"))}
    return round_, finish


def worker(args, device) -> None:
    """One implementation on one workload, every size, answering the parent's PREPARE, ROUND and FINISH
    (benchmarks/rounds.py)."""
    workload, key = args.worker
    mode = "quick" if args.quick else "full"
    cfg = SETTINGS[mode][workload]
    peer = next(r["peer"] for r in implementations(workload, device) if r["key"] == key)
    modules = {}
    if peer is not None:
        modules[peer] = importlib.import_module(PEERS[peer][0])
        if peer == "mujoco_warp":
            modules["mujoco"] = importlib.import_module("mujoco")

    def prepare(n: int):
        if workload == "cloth":
            round_, finish = prepare_cloth(key, n, cfg, device, modules)
        elif workload == "particles":
            round_, finish = prepare_particles(key, n, cfg, device, modules)
        else:
            round_, finish = prepare_pile(key, n, cfg, device, modules, args.pile_dt, args.budget or BUDGET[mode])
        return round_, lambda seconds: {**finish(seconds), "status": "ok", "warp_sim_path": WARP_SIM_PATH}

    rounds.serve(cfg["sizes"], prepare, failure)


def failure(error: Exception) -> dict:
    """The status of a size that raised ``error``: "n/a (...)" over budget, else "failed: ..."."""
    if isinstance(error, OverBudget):
        return {"status": str(error)}
    if isinstance(error, ws.SimulationDiverged):
        return {"status": f"failed: SimulationDiverged at step {error.step}: {error.reason}"}
    return {"status": f"failed: {type(error).__name__}: {str(error).splitlines()[0] if str(error) else ''}"}


# ---------------------------------------------------------------------------------------------------- parent

ROOT = Path(__file__).resolve().parents[1]
WARP_SIM_PATH = str(Path(ws.__file__).resolve().parent)   # the warp_sim a worker imported
BASELINE = "warp_sim@"   # a baseline's key: BASELINE + the revision as given


@contextlib.contextmanager
def worktree(revision: str, repository: Path = ROOT):
    """A checkout of ``revision`` (``git worktree add --detach``) in a new temporary folder: yields (its root,
    the full commit); removed with the folder afterwards, whatever happened (``git worktree remove --force``,
    then ``git worktree prune``). A revision git cannot resolve is a ValueError, a failed checkout a
    RuntimeError."""
    found = subprocess.run(["git", "-C", str(repository), "rev-parse", "--verify", "--quiet", f"{revision}^{{commit}}"],
                           capture_output=True, text=True)
    if found.returncode != 0:
        raise ValueError(f"--baseline {revision}: not a commit of {repository}")
    commit = found.stdout.strip()
    folder = Path(tempfile.mkdtemp(prefix="warp_sim-baseline-"))
    root = folder / commit[:12]
    try:
        added = subprocess.run(["git", "-C", str(repository), "worktree", "add", "--detach", str(root), commit],
                               capture_output=True, text=True)
        if added.returncode != 0:
            raise RuntimeError(f"--baseline {revision}: git worktree add failed: {added.stderr.strip()}")
        yield root, commit
    finally:
        subprocess.run(["git", "-C", str(repository), "worktree", "remove", "--force", str(root)],
                       capture_output=True, text=True)
        shutil.rmtree(folder, ignore_errors=True)
        subprocess.run(["git", "-C", str(repository), "worktree", "prune"], capture_output=True, text=True)


def baseline_command(command: list[str], root: Path) -> list[str]:
    """A worker command that imports the warp_sim of the checkout at ``root`` (PYTHONPATH first)."""
    path = os.pathsep.join([str(root)] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else []))
    return ["env", f"PYTHONPATH={path}"] + command


def imported_from(result: dict, root: Path) -> dict:
    """A baseline worker's result, failed unless it imported the warp_sim at ``root``."""
    path = result.get("warp_sim_path")
    if path is None or Path(path) == root.resolve() / "warp_sim":
        return result
    return {"status": f"failed: imported warp_sim from {path}, not from the baseline's {root}"}


def worker_command(workload: str, key: str, args, device) -> list[str]:
    return [sys.executable, str(Path(__file__).resolve()), "--worker", workload, key, "--device", device.alias,
            "--pile-dt", repr(args.pile_dt)] + (["--quick"] if args.quick else []) \
        + (["--budget", repr(args.budget)] if args.budget else [])


def report(workload: str):
    """The line printed as each result of ``workload`` comes."""
    def line(key: str, n: int, result: dict) -> None:
        print(f"    {workload} {result_size(workload, n)} {key}: "
              f"{result['check']['summary'] if 'check' in result else result['status']}"
              + (f"; {result['steps_per_s']:,.1f} steps/s" if "steps_per_s" in result else ""), flush=True)
    return line


def result_size(workload: str, n: int) -> str:
    if workload == "cloth":
        return f"{n}x{n}"
    if workload == "particles":
        exponent = math.log10(n)
        return f"10^{exponent:.0f}" if exponent == round(exponent) else f"{n:,}"
    return f"{n:,} bodies"


def ratio_cell(reference: float | None, rate: float | None) -> str:
    return f"{reference / rate:.2f}x" if reference and rate else "-"


def table(rows: list[dict]) -> str:
    cells = []
    for row in rows:
        check = row["check"]["summary"] if "check" in row else row["status"]
        if "check" in row and row["status"] != "ok":
            check += f"; {row['status']}"
        rate = row.get("steps_per_s")
        ratio = f"{row['paired_ratio']:.2f}x" if row.get("paired_ratio") else ratio_cell(
            row.get("reference_steps_per_s"), rate)
        if row["key"] == row.get("reference_key") and rate:
            ratio = "1.00x (ref)"
        elif row["key"] == "floor" and rate and row.get("share_of"):
            ratio = ratio_cell(row["share_of"], rate) + f" ({row['share_of'] / rate:.1%} of the floor)"
        cells.append([row["workload_label"], row["size_label"], row["label"], check.replace("|", "/"),
                      f"{rate:,.1f}" if rate else "-", ratio])
    return markdown(["workload", "size", "implementation", "check", "steps/s", "warp_sim / this"], cells,
                    left=("workload", "size", "implementation", "check"))


def baseline_table(rows: list[dict], keys: list[str]) -> str:
    """The working tree's warp_sim against each baseline, per workload and size: steps/s, and the median of the
    per-round ratios (rounds.paired_ratio): the working tree's speed over the baseline's, and each later
    baseline's over the first's. Above 1: faster than the baseline."""
    header = ["workload", "size", "warp_sim (working tree) steps/s"]
    for key in keys:
        header += [f"{key.replace(BASELINE, 'warp_sim @ ')} steps/s", f"working tree / {key[len(BASELINE):]}"]
    header += [f"{key[len(BASELINE):]} / {keys[0][len(BASELINE):]}" for key in keys[1:]]
    cells = []
    by_size: dict = {}
    for row in rows:
        by_size.setdefault((row["workload_label"], row["size_label"]), {})[row["key"]] = row
    for (workload, size), found in by_size.items():
        here = found["warp_sim"]
        line = [workload, size, f"{here['steps_per_s']:,.1f}" if here.get("steps_per_s") else here["status"]]
        for key in keys:
            row = found[key]
            line += [f"{row['steps_per_s']:,.1f}" if row.get("steps_per_s") else row["status"].replace("|", "/"),
                     f"{row['paired_ratio']:.3f}x" if row.get("paired_ratio") else "-"]
        first = found[keys[0]]
        for key in keys[1:]:
            ratio = rounds.paired_ratio(first.get("seconds"), found[key].get("seconds"))
            found[key]["over_first_baseline"] = ratio
            line.append(f"{ratio:.3f}x" if ratio else "-")
        cells.append(line)
    return markdown(header, cells, left=("workload", "size"))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", choices=("cpu", "cuda"), default=None, help="default: cuda if present, else cpu")
    parser.add_argument("--quick", action="store_true", help="small sizes, few steps (a couple of minutes)")
    parser.add_argument("--workloads", nargs="+", choices=WORKLOADS, default=list(WORKLOADS))
    parser.add_argument("--only", nargs="+", default=None, metavar="IMPL",
                        help="only these implementations (warp_sim, warp_sim_guard, warp_sim_capture, "
                             "warp_sim_1thread, newton, newton_xpbd, taichi, taichi_threads, mujoco, mujoco_warp)")
    parser.add_argument("--pile-dt", type=collision.positive_time, default=PILE_DT,
                        help="the piles' step [s] (a number or a fraction; default 1/500)")
    parser.add_argument("--budget", type=float, default=None,
                        help="seconds one pile run may take, else n/a (default 900, --quick 60)")
    parser.add_argument("--timeout", type=float, default=None,
                        help="seconds a worker may take for one answer: a size's build, check and warm-up, or one "
                             "timed round (default 3600, --quick 300)")
    parser.add_argument("--baseline", nargs="+", default=[], metavar="REV",
                        help="git revisions whose warp_sim runs beside the working tree's, in the same rounds "
                             "(each from a temporary git worktree; e.g. 8dcb2b4 HEAD)")
    parser.add_argument("--copy-mb", type=int, default=256, help="size of the bandwidth-floor copy [MiB]")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/compare.json"))
    parser.add_argument("--worker", nargs=2, metavar=("WORKLOAD", "IMPL"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    device = pick_device(parser, args.device)
    if args.worker:
        worker(args, device)
        return
    mode = "quick" if args.quick else "full"
    timeout = args.timeout or TIMEOUT[mode]
    peers = peer_status()
    threads = cpu_threads()
    host_bw, floor_bw = floor_bandwidth(device, args.copy_mb, threads)
    name = device_name(device)
    print(f"warp {wp.__version__}, warp_sim {ws.__version__} on {device.alias} ({name}), {os.cpu_count()} cores; "
          + "; ".join(f"{key} {p['version'] if p['installed'] else 'not installed'}" for key, p in peers.items()))
    print(f"copy bandwidth (read + write): numpy {host_bw / 1e9:.2f} GB/s"
          + (f", device wp.copy {floor_bw / 1e9:.1f} GB/s" if device.is_cuda else "")
          + (f", numpy on {threads} threads {floor_bw / 1e9:.2f} GB/s" if device.is_cpu and threads > 1 else "")
          + f"; {mode} run", flush=True)

    started = time.perf_counter()
    rows = []
    with contextlib.ExitStack() as checkouts:
        baselines = {}   # key -> (the revision as given, its root, its commit)
        for revision in args.baseline:
            root, commit = checkouts.enter_context(worktree(revision))
            baselines[BASELINE + revision] = (revision, root, commit)
            print(f"baseline {revision}: {commit[:12]} checked out in {root}", flush=True)
        for workload in args.workloads:
            rows += run_workload(workload, args, device, mode, timeout, peers, baselines,
                                 (threads, host_bw, floor_bw))
    print()
    print(table(rows))
    if args.baseline:
        print()
        print(baseline_table(rows, list(baselines)))

    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {"device": device.alias, "device_name": name, "cpu_count": os.cpu_count(), "warp_version": wp.__version__,
              "warp_sim_version": ws.__version__, "numpy_version": np.__version__, "peers": peers, "mode": mode,
              "settings": {w: SETTINGS[mode][w] for w in args.workloads}, "pile_dt": args.pile_dt,
              "budget_s": args.budget or BUDGET[mode], "timeout_s": timeout,
              "cpu_threads": threads, "numpy_copy_bytes_per_s": host_bw, "floor_bytes_per_s": floor_bw,
              "floor_method": "wp.copy" if device.is_cuda else "np.copyto", "max_depth_m": MAX_DEPTH,
              "git": git_state(), "environment": environment(),
              "baselines": [{"key": key, "revision": revision, "commit": commit}
                            for key, (revision, _, commit) in baselines.items()],
              "wall_s": time.perf_counter() - started, "rows": rows}
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


def run_workload(workload: str, args, device, mode: str, timeout: float, peers: dict, baselines: dict,
                 floor: tuple) -> list[dict]:
    """One workload's implementations (the baselines right after warp_sim), their rounds in turn: its rows."""
    threads, host_bw, floor_bw = floor
    cfg = SETTINGS[mode][workload]
    by_key, commands = {}, {}
    labels = {impl["key"]: impl["label"] for impl in implementations(workload, device)}
    for impl in implementations(workload, device):
        if args.only and impl["key"] not in args.only and impl["key"] != "warp_sim":
            continue
        if impl["peer"] and not peers[impl["peer"]]["installed"]:
            by_key[impl["key"]] = {n: {"status": "not installed"} for n in cfg["sizes"]}
        elif impl["na"]:
            by_key[impl["key"]] = {n: {"status": impl["na"]} for n in cfg["sizes"]}
        else:
            by_key[impl["key"]] = None   # its place in the table
            commands[impl["key"]] = worker_command(workload, impl["key"], args, device)
        if impl["key"] == "warp_sim":
            for key, (revision, root, commit) in baselines.items():
                by_key[key] = None
                commands[key] = baseline_command(commands["warp_sim"], root)
                named = revision if commit.startswith(revision) else f"{revision} ({commit[:7]})"
                labels[key] = impl["label"].replace("warp_sim", f"warp_sim @ {named}", 1)
    print(f"  {workload}: {', '.join(commands)}, their timed rounds in turn ...", flush=True)
    by_key.update(rounds.interleave(commands, cfg["sizes"], cfg["repeats"], timeout, report(workload)))
    for key, (_, root, _) in baselines.items():
        by_key[key] = {n: imported_from(result, root) for n, result in by_key[key].items()}
    rows = []
    for n in cfg["sizes"]:
        reference = by_key["warp_sim"][n].get("steps_per_s")
        size_label = result_size(workload, n) + (f", dt 1/{1 / args.pile_dt:.0f} s"
                                                 if workload in ("pile", "bigpile") else "")
        base = {"workload": workload, "size": n, "size_label": size_label, "reference_key": "warp_sim",
                "reference_steps_per_s": reference,
                "workload_label": {"particles": "particles + ground"}.get(workload, workload)}
        for key, results in by_key.items():
            paired = rounds.paired_ratio(results[n].get("seconds"), by_key["warp_sim"][n].get("seconds"))
            rows.append({**base, "key": key, "label": labels[key], **results[n],
                         **({"paired_ratio": paired} if paired is not None and key != "warp_sim" else {})})
            if workload == "particles" and key in ("warp_sim", "warp_sim_1thread"):
                # each warp_sim row is followed by the copy floor on as many threads, its share of it
                one = key == "warp_sim_1thread" or device.is_cuda or threads == 1
                bandwidth = host_bw if key == "warp_sim_1thread" else floor_bw
                method = "wp.copy" if device.is_cuda else f"np.copyto, {1 if one else threads} thread" + (
                    "" if one else "s")
                rows.append({**base, "key": "floor", "status": "ok",
                             "steps_per_s": bandwidth / (particles.STATE_BYTES * n),
                             "share_of": results[n].get("steps_per_s"),
                             "label": f"copy floor ({method} {bandwidth / 1e9:.1f} GB/s, "
                                      f"{particles.STATE_BYTES} B/particle)",
                             "check": {"summary": "- (x and v read and written once a step)"}})
    return rows


if __name__ == "__main__":
    main()

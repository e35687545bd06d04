"""Collision throughput: a pile of boxes and spheres falling on the ground, impulse response, steps/s.

    python benchmarks/collision.py [--device cpu|cuda] [--sizes 100 1000 10000] [--dt 1/240] [--settle 1.0]
                                   [--steps 60] [--profile-steps 10] [--json benchmarks/results/collision.json]

The scene: N free rigid bodies, half ws.Box (half extents 0.05..0.1 m per axis, random) and
half ws.Sphere (radius 0.05..0.1 m, random), density 1000 kg/m^3, uniformly random
orientations, at rest on a jittered 3-D lattice above the ground (at most 10 layers, a
square footprint; the lattice spacing leaves a gap between any two bodies' bounding spheres
whatever the jitter, so nothing overlaps at the start), gravity (the Scene default),
scene.add_ground(restitution=0.3, friction=0.5) and the same restitution and friction on
every body (a contact uses the means of its two sides). Seeded RNG.
ws.Simulator(scene, integrator="symplectic_euler", device=...) with the defaults (contact
"impulse", guard on); dt = 1/240 s.

Procedure per N: build the scene (timed), the Simulator (timed), let the pile fall for
--settle seconds (one sim.step(dt, steps=...) call, timed on its own, not in the rates),
then time --steps steps (common.time_steps: the device synchronised around one
sim.step(dt, steps=...) call, the guard read once at its end). The kernels are warm: every
kernel was compiled or loaded beforehand on a small pile, and the settling steps have run at
this N. Reported: steps/s and ms/step, the pairs and contacts of the last step and the
buffers' capacities, growths and bytes (sim.body_contacts.stats()), the colours of the last
step, the kernel launches per step and those with one thread (the launcher's counters; a
colour of one manifold is one thread), and the pile's state at the end (highest speed,
deepest ground penetration, bodies whose centre is below the ground). The contact solve's
share is that of SOLVE_KERNELS in the profiled kernels' time.
Then --profile-steps more steps with every launch synchronised and timed on its own
(common.KernelProfile; the simulator is made inside it with profiling off until then), and the host's
share of a step, uncaptured and with ``capture=True`` (a second simulator, same settle and timed steps;
``host_shares``: 1 - the kernels' time over the step's time).

Optional peer: Newton's SolverSemiImplicit (penalty contacts) on the same pile, on the same
device, same dt, same settle and timed steps, when ``import newton`` works; otherwise its
column says "not installed" (an error while building or stepping it is reported there too).
The ratio is warp_sim steps/s over Newton steps/s: a cost-per-step comparison, not of the
contact models (impulses here, penalty springs there). Results in --json. See
benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time
from fractions import Fraction
from functools import partial
from pathlib import Path

import numpy as np
import warp as wp
from cloth import optional_import
from common import KernelProfile, device_name, markdown, pick_device, time_steps
from rigid import KERNEL_LABELS as SOLVER_KERNELS

import warp_sim as ws
from warp_sim.kernels import manifolds as manifold_kernels
from warp_sim.studies import contact_scenes
from warp_sim.util.rotations import quat_to_matrix

DT = 1.0 / 240.0  # [s]
SIZE_RANGE = contact_scenes.PILE_SIZES  # [m], box half extents (per axis) and sphere radii
DENSITY = contact_scenes.PILE_DENSITY  # [kg/m^3]
RESTITUTION, FRICTION = contact_scenes.PILE_RESTITUTION, contact_scenes.PILE_FRICTION  # the ground's and every body's
SEED = 0
#: BodyContacts' kernels in launch order (the profile table has a column each; the solver's and the guard's
#: launches, labelled as in rigid.py, are summed in one column)
CONTACT_KERNELS = {"gather_poses": "poses", "find_pairs": "broad", "narrow_phase": "narrow",
                   "count_pair_contacts": "count", "sort_by_pair": "sort", "load_velocities": "load v",
                   "prepare_contacts": "prepare", "recall_impulses": "recall", "colour_pairs": "colour",
                   "order_by_colour": "order", "collide_manifolds": "collision GS", "prepare_rows": "rows",
                   "warm_start_manifolds": "warm start", "solve_manifolds": "contact GS",
                   "remember_impulses": "remember", "finish_response": "finish", "project_manifolds": "project"}
#: the contact solve proper (its share of a step is reported): the coloured sweeps and what feeds them
SOLVE_KERNELS = ("colour_pairs", "order_by_colour", "collide_manifolds", "prepare_rows", "warm_start_manifolds",
                 "solve_manifolds", "finish_response", "project_manifolds")


def body_parameters(n: int, seed: int = SEED) -> dict:
    """contact_scenes.pile_bodies(n, seed), with the lattice's shape (x, y, z points) under "lattice"."""
    bodies = contact_scenes.pile_bodies(n, seed)
    layers = min(contact_scenes.PILE_LAYERS, math.ceil(round(n ** (1.0 / 3.0), 9)))
    side = math.ceil(math.sqrt(n / layers))
    bodies["lattice"] = (side, math.ceil(n / side**2), side)
    return bodies


def build_scene(parameters: dict) -> ws.Scene:
    """The ground and one add_rigid_body call per body, as a user would (contact_scenes.pile)."""
    return contact_scenes.pile(parameters)


def body_arrays(sim: ws.Simulator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centres, rotations, linear velocities) of warp_sim's bodies now, as numpy arrays."""
    return sim.state.body_x.numpy(), sim.body_rotations().numpy(), sim.body_velocities()[0].numpy()


def pile_state(sim: ws.Simulator, parameters: dict) -> dict:
    """The pile now (pile_summary) in warp_sim."""
    return pile_summary(*body_arrays(sim), parameters)


def pile_summary(x: np.ndarray, R: np.ndarray, v: np.ndarray, parameters: dict) -> dict:
    """The pile from its bodies' centres x, rotations R (body to world) and velocities v, in any simulator: highest
    speed [m/s], lowest body point (ground penetration when negative) [m], bodies whose centre is below the ground,
    the highest centre, and the bodies' spread from the axis (x, z) [m]."""
    x, R, v = (np.asarray(a, dtype=np.float64) for a in (x, R, v))
    lowest = contact_scenes.lowest_points(x, R, parameters)
    finite = bool(np.isfinite(x).all() and np.isfinite(v).all())
    return {"finite": finite, "max_speed": float(np.linalg.norm(v, axis=1).max()),
            "lowest_point": float(lowest.min()), "centres_below_ground": int(np.count_nonzero(x[:, 1] < 0.0)),
            "highest_centre": float(x[:, 1].max()), "max_horizontal": float(np.hypot(x[:, 0], x[:, 2]).max())}


class NewtonPile:
    """The same pile in Newton: one body per shape (y up, the same gravity), a ground plane, the same density,
    restitution and friction (Newton's default contact stiffness); SolverSemiImplicit (or solver="xpbd":
    SolverXPBD with ``iterations``), collision detection every step (CollisionPipeline where Newton has one, with
    the sweep-and-prune broad phase where it takes one; else model.collide)."""

    def __init__(self, newton, parameters: dict, device, solver: str = "semi_implicit", iterations: int = 5):
        builder = newton.ModelBuilder(up_axis=newton.Axis.Y, gravity=(0.0, -9.81, 0.0))   # Newton 1.8: a 3-vector
        config = newton.ModelBuilder.ShapeConfig(density=DENSITY, mu=FRICTION, restitution=RESTITUTION)
        builder.add_ground_plane(cfg=config)
        for kind, size, position, orientation in zip(parameters["kind"].tolist(), parameters["size"].tolist(),
                                                     parameters["position"].tolist(),
                                                     parameters["orientation"].tolist(), strict=True):
            body = builder.add_body(xform=wp.transform(wp.vec3(*position), wp.quat(*orientation)))
            if kind == "box":
                builder.add_shape_box(body, hx=size[0], hy=size[1], hz=size[2], cfg=config)
            else:
                builder.add_shape_sphere(body, radius=size[0], cfg=config)
        self.model = builder.finalize(device=device.alias)
        if solver == "xpbd":
            self.solver = newton.solvers.SolverXPBD(self.model, iterations=iterations)
        else:
            solver = getattr(newton.solvers, "SolverSemiImplicit", None) or newton.solvers.SemiImplicitSolver
            self.solver = solver(self.model)
        self.states = [self.model.state(), self.model.state()]
        self.control = self.model.control()
        pipeline = getattr(newton, "CollisionPipeline", None)
        if pipeline is not None:
            try:
                self.pipeline = pipeline(self.model, broad_phase="sap")  # not all pairs of 10^4 shapes
            except TypeError:  # a release without that argument
                self.pipeline = pipeline(self.model)
            self.contacts = self.pipeline.contacts()
        else:
            self.pipeline, self.contacts = None, None

    def advance(self, steps: int, dt: float) -> None:
        for _ in range(steps):
            state_in, state_out = self.states
            state_in.clear_forces()
            if self.pipeline is not None:
                self.pipeline.collide(state_in, self.contacts)
                contacts = self.contacts
            else:
                contacts = self.model.collide(state_in)
            self.solver.step(state_in, state_out, self.control, contacts, dt)
            self.states.reverse()

    def timed(self, steps: int, dt: float) -> float:
        self.sync()
        start = time.perf_counter()
        self.advance(steps, dt)
        self.sync()
        return time.perf_counter() - start

    def sync(self) -> None:
        wp.synchronize_device(self.model.device)

    def finite(self) -> bool:
        state = self.states[0]
        return bool(np.isfinite(state.body_q.numpy()).all() and np.isfinite(state.body_qd.numpy()).all())

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(centres, rotations, linear velocities) of the bodies now: body_q is (p, q xyzw), body_qd (v, omega)."""
        state = self.states[0]
        q, qd = state.body_q.numpy().astype(np.float64), state.body_qd.numpy().astype(np.float64)
        return q[:, :3], quat_to_matrix(q[:, 3:7]), qd[:, :3]


def bench_newton(newton, parameters: dict, device, args, settle_steps: int) -> dict:
    """Newton on the same pile: build, settle, timed steps; {"status": ...} and, when it ran, its timings."""
    try:
        start = time.perf_counter()
        pile = NewtonPile(newton, parameters, device)
        build_s = time.perf_counter() - start
        settle_s = pile.timed(settle_steps, args.dt)
        seconds = pile.timed(args.steps, args.dt)
        finite = pile.finite()
    except Exception as error:  # an optional peer that cannot run this scene is reported, not fatal
        return {"status": f"error: {type(error).__name__}: {error}"}
    rate = args.steps / seconds
    return {"status": "ok" if finite else "ran, state non-finite", "build_s": build_s, "settle_s": settle_s,
            "seconds": seconds, "steps_per_s": rate, "ms_per_step": 1e3 / rate, "finite": finite}


def load_kernels(device, dt: float) -> float:
    """Seconds to compile or load every kernel the timed runs use: a few steps of an 8-body pile in contact."""
    start = time.perf_counter()
    parameters = body_parameters(8, seed=1)
    parameters["position"][:, 1] = 0.05  # every body overlapping the ground: the whole contact path runs
    sim = ws.Simulator(build_scene(parameters), integrator="symplectic_euler", device=device.alias)
    sim.step(dt, steps=3)
    wp.synchronize_device(device)
    return time.perf_counter() - start


def bench_size(n: int, device, args, newton) -> dict:
    """Build times, the settle, the timed steps, contact statistics, the pile's state, a kernel profile, Newton."""
    parameters = body_parameters(n)
    print(f"N = {n}: lattice {parameters['lattice']}, building the scene ...", flush=True)
    start = time.perf_counter()
    scene = build_scene(parameters)
    scene_s = time.perf_counter() - start
    profile = KernelProfile()
    profile.enabled = False  # the settle and the timed steps run unmeasured; the same simulator is profiled last
    start = time.perf_counter()
    sim = profile.instrumented(partial(ws.Simulator, scene, integrator="symplectic_euler", device=device.alias))
    simulator_s = time.perf_counter() - start
    settle_steps = max(1, round(args.settle / args.dt))
    print(f"  scene {scene_s:.2f} s, Simulator {simulator_s:.2f} s; settling {settle_steps} steps ...", flush=True)
    result = {"bodies": n, "boxes": int(np.count_nonzero(parameters["kind"] == "box")),
              "lattice": parameters["lattice"], "scene_build_s": scene_s, "simulator_build_s": simulator_s,
              "settle_steps": settle_steps, "steps": args.steps}
    phase = "settle"
    try:
        result["settle_s"] = time_steps(sim, settle_steps, args.dt)
        result["stats_after_settle"] = sim.body_contacts.stats()
        result["pile_after_settle"] = pile_state(sim, parameters)
        print(f"  settled in {result['settle_s']:.2f} s; timing {args.steps} steps ...", flush=True)
        phase = "timed"
        launcher = sim.model.launcher
        launches, single = launcher.launches, sum(launcher.single_thread.values())
        seconds = time_steps(sim, args.steps, args.dt)
        launches_per_step = (launcher.launches - launches) / args.steps
        single_per_step = (sum(launcher.single_thread.values()) - single) / args.steps
        stats = sim.body_contacts.stats()
        pile = pile_state(sim, parameters)
        phase = "profile"
        profile_steps = args.profile_steps
        kernels = {}
        if profile_steps:
            kernels = profile.steps(sim, args.dt, profile_steps)
    except ws.SimulationDiverged as error:
        print(f"  {phase}: {error}", flush=True)
        result.update(error={"phase": phase, "type": "SimulationDiverged", "message": str(error),
                             "step": error.step, "time": error.time, "component": error.component,
                             "element": error.element, "reason": error.reason})
        return result
    rate = args.steps / seconds
    total_ms = sum(k["ms"] for k in kernels.values())
    solve_share = sum(kernels[k]["ms"] for k in SOLVE_KERNELS if k in kernels) / total_ms if total_ms else None
    print(f"  {rate:.1f} steps/s, {stats['pairs']} pairs, {stats['contacts']} contacts, {stats['colours']} colours, "
          f"{launches_per_step:.0f} launches/step ({single_per_step:.1f} with one thread), contact solve "
          f"{100 * (solve_share or 0):.0f} % of the kernels' time, max speed {pile['max_speed']:.3g} m/s, "
          f"lowest point {pile['lowest_point']:.4f} m", flush=True)
    result.update(seconds=seconds, steps_per_s=rate, ms_per_step=1e3 / rate, body_steps_per_s=rate * n,
                  contact_stats=stats, pile=pile, profile_steps=profile_steps, kernels_per_step=kernels,
                  launches_per_step=launches_per_step, single_thread_launches_per_step=single_per_step,
                  contact_solve_share=solve_share, simulated_s=sim.time)
    if kernels:
        result["host"] = host_shares(sim, profile, kernels, result, scene, args, settle_steps)
    del sim
    if newton is not None:
        print("  Newton ...", flush=True)
        result["newton"] = bench_newton(newton, parameters, device, args, settle_steps)
        if "steps_per_s" in result["newton"]:
            result["warp_sim_over_newton"] = rate / result["newton"]["steps_per_s"]
    return result


def launch_timing_cost(sim: ws.Simulator, profile: KernelProfile, launches: int = 2000) -> float:
    """Seconds the profile itself adds to each launch it times (the synchronisations and the clock): a one-thread
    kernel that does nothing useful, launched through the same launcher and profile."""
    profile.stats.clear()
    flags = wp.zeros(4, dtype=wp.int32, device=sim.device)
    profile.enabled = True
    for _ in range(launches):
        sim.model.launch(manifold_kernels.check_colours, 1, [flags, flags, flags])
    profile.enabled = False
    count, seconds, _ = profile.stats.pop("check_colours")
    return seconds / count


def host_shares(sim: ws.Simulator, profile: KernelProfile, kernels: dict, result: dict, scene: ws.Scene, args,
                settle_steps: int) -> dict:
    """The host's share of a step, uncaptured and captured: 1 - (the kernels' time) / (the step's time). The
    kernels' time is the profile's sum less what its own timing adds per launch (launch_timing_cost), and it
    still holds each launch's call into the kernel. The captured simulator (capture=True) runs the same settle
    and timed steps; its misses are the steps done again uncaptured (a buffer or colouring outgrew the graph)."""
    cost = launch_timing_cost(sim, profile)
    launches = sum(k["launches"] for k in kernels.values())
    kernel_s = sum(k["ms"] for k in kernels.values()) / 1e3 - launches * cost
    captured = ws.Simulator(scene, integrator="symplectic_euler", device=sim.device.alias, capture=True)
    settle_s = time_steps(captured, settle_steps, args.dt)
    graphs = captured._graphs
    settle_misses, settle_recorded = graphs.missed, graphs.recorded
    missed, recorded = graphs.missed, graphs.recorded
    seconds = time_steps(captured, args.steps, args.dt)
    step_s = seconds / args.steps
    out = dict(kernel_ms_per_step=kernel_s * 1e3, timing_cost_us_per_launch=cost * 1e6,
               uncaptured_share=1.0 - kernel_s / (result["ms_per_step"] / 1e3), captured_steps_per_s=1.0 / step_s,
               captured_ms_per_step=step_s * 1e3, captured_share=1.0 - kernel_s / step_s,
               captured_misses=graphs.missed - missed, captured_recorded=graphs.recorded - recorded,
               captured_settle_s=settle_s, captured_settle_misses=settle_misses,
               captured_settle_recorded=settle_recorded)
    print(f"  captured: {out['captured_steps_per_s']:.1f} steps/s ({out['captured_misses']} of {args.steps} steps "
          f"missed); host share {100 * out['uncaptured_share']:.0f} % uncaptured, "
          f"{100 * out['captured_share']:.0f} % captured", flush=True)
    return out


def newton_cells(result: dict, status: str) -> list[str]:
    peer = result.get("newton", {"status": status})
    if "steps_per_s" not in peer:
        text = peer["status"].replace("|", "/")
        return [text if len(text) <= 48 else text[:45] + "...", "-"]
    return [f"{peer['steps_per_s']:.1f}", f"{result['warp_sim_over_newton']:.2f}x"]


def tables(device_alias: str, results: list[dict], newton_status: str) -> str:
    rows, build_rows, pile_rows, kernel_rows, host_rows = [], [], [], [], []
    for r in results:
        n = f"{r['bodies']:,}"
        settle = (f"{r['settle_s']:.2f} ({1e3 * r['settle_s'] / r['settle_steps']:.1f})" if "settle_s" in r
                  else "-")
        build_rows.append([n, "x".join(map(str, r["lattice"])), f"{r['scene_build_s']:.2f}",
                           f"{r['simulator_build_s']:.2f}", f"{r['settle_steps']}", settle])
        if "error" in r:
            e = r["error"]
            rows.append([device_alias, n, f"{e['phase']}: {e['type']} at step {e['step']}"] + ["-"] * 14)
            continue
        s = r["contact_stats"]
        share = r.get("contact_solve_share")
        rows.append([device_alias, n, f"{r['boxes']:,} / {r['bodies'] - r['boxes']:,}", f"{r['steps_per_s']:.1f}",
                     f"{r['ms_per_step']:.2f}", "-" if share is None else f"{100 * share:.0f} %",
                     f"{s['colours']}", f"{r['launches_per_step']:.0f}", f"{r['single_thread_launches_per_step']:.1f}",
                     f"{s['pairs']:,}", f"{s['contacts']:,}", f"{s['pair_capacity']:,}",
                     f"{s['contact_capacity']:,}", f"{s['grows']}", f"{s['bytes'] / 2**20:.2f}"]
                    + newton_cells(r, newton_status))
        for label, p in (("after settle", r["pile_after_settle"]), ("after timed steps", r["pile"])):
            pile_rows.append([n, label, f"{p['max_speed']:.3f}", f"{p['lowest_point'] * 1e3:.2f}",
                              f"{p['centres_below_ground']}", f"{p['highest_centre']:.2f}",
                              f"{p['max_horizontal']:.2f}", "yes" if p["finite"] else "NO"])
        if "host" in r:
            h = r["host"]
            host_rows.append([n, f"{r['settle_s']:.2f}", f"{h['captured_settle_s']:.2f}",
                              f"{h['captured_settle_misses']} / {h['captured_settle_recorded']}",
                              f"{r['steps_per_s']:.1f}", f"{h['captured_steps_per_s']:.1f}",
                              f"{h['captured_steps_per_s'] / r['steps_per_s']:.2f}x", f"{h['captured_misses']}",
                              f"{h['kernel_ms_per_step']:.3f}", f"{100 * h['uncaptured_share']:.0f} %",
                              f"{100 * h['captured_share']:.0f} %"])
        kernels = r["kernels_per_step"]
        if kernels:
            solver = sum(k["ms"] for key, k in kernels.items() if key not in CONTACT_KERNELS)
            total = sum(k["ms"] for k in kernels.values())
            kernel_rows.append([n] + [f"{kernels[key]['ms']:.2f}" if key in kernels else "-" for key in CONTACT_KERNELS]
                               + [f"{solver:.2f}", f"{total:.2f}", f"{r['ms_per_step']:.2f}"])
    solver_labels = ", ".join(SOLVER_KERNELS.get(key, key) for key in sorted(
        {key for r in results for key in r.get("kernels_per_step", {}) if key not in CONTACT_KERNELS}))
    out = [markdown(["device", "N", "boxes / spheres", "steps/s", "ms/step", "contact solve share", "colours",
                     "launches/step", "one-thread launches/step", "pairs", "contacts", "pair capacity",
                     "contact capacity", "grows", "buffers MiB", "Newton steps/s", "warp_sim / Newton"], rows,
                    left=("device", "boxes / spheres")),
           markdown(["N", "lattice (x, y, z)", "scene s", "Simulator s", "settle steps", "settle s (ms/step)"],
                    build_rows, left=("lattice (x, y, z)",)),
           markdown(["N", "when", "max speed m/s", "lowest point mm", "centres below ground", "highest centre m",
                     "max distance from axis m", "finite"], pile_rows, left=("when", "finite")) if pile_rows else ""]
    if host_rows:
        out.append(markdown(["N", "settle s", "settle s, captured", "settle misses / recordings", "steps/s",
                             "captured steps/s", "captured / uncaptured", "captured misses",
                             "kernels ms/step", "host share", "host share, captured"], host_rows, left=()))
    if kernel_rows:
        out.append(markdown(["N"] + list(CONTACT_KERNELS.values()) + [f"solver + guard ({solver_labels})", "sum",
                                                                      "timed ms/step"], kernel_rows, left=()))
    return "\n\n".join(table for table in out if table)


def positive_time(text: str) -> float:
    """A duration [s], as a number or a fraction (1/240)."""
    value = float(Fraction(text))
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a time > 0, got {text}")
    return value


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu", help="cpu (default), or cuda where present")
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10_000], help="bodies per pile")
    parser.add_argument("--dt", type=positive_time, default=DT, help="step [s] (a number or a fraction, e.g. 1/240)")
    parser.add_argument("--settle", type=float, default=1.0, help="untimed fall before the timed steps [s]")
    parser.add_argument("--steps", type=int, default=60, help="timed steps")
    parser.add_argument("--profile-steps", type=int, default=10,
                        help="steps profiled per kernel after the timed ones (0: none)")
    parser.add_argument("--json", "--out", dest="out", metavar="PATH", type=Path,
                        default=Path("benchmarks/results/collision.json"), help="results (JSON)")
    args = parser.parse_args(argv)
    if min(args.sizes) < 2 or args.steps < 1 or args.settle < 0 or args.profile_steps < 0:
        parser.error("--sizes must be >= 2, --steps >= 1, --settle and --profile-steps >= 0")

    device = pick_device(parser, args.device)
    newton, newton_status = optional_import("newton")
    name = device_name(device)
    version = getattr(newton, "__version__", "?") if newton is not None else newton_status
    print(f"warp {wp.__version__}, warp_sim on {device.alias} ({name}); numpy {np.__version__}; newton {version}")
    print(f"dt = {args.dt:.6g} s, settle {args.settle:g} s, {args.steps} timed steps; boxes and spheres "
          f"{SIZE_RANGE[0]}..{SIZE_RANGE[1]} m, lattice pitch {contact_scenes.PILE_SPACING:.3f} m, "
          f"restitution {RESTITUTION}, friction {FRICTION}")
    kernels_s = load_kernels(device, args.dt)
    print(f"kernels compiled or loaded in {kernels_s:.2f} s", flush=True)

    started = time.perf_counter()
    results = []
    for n in args.sizes:
        size_start = time.perf_counter()
        results.append(bench_size(n, device, args, newton))
        results[-1]["wall_s"] = time.perf_counter() - size_start
        print(f"  N = {n}: {results[-1]['wall_s']:.1f} s in all", flush=True)
    print()
    print(tables(device.alias, results, newton_status))

    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {"device": device.alias, "device_name": name, "cpu_count": os.cpu_count(), "warp_version": wp.__version__,
              "warp_sim_version": ws.__version__, "numpy_version": np.__version__,
              "newton": {"status": newton_status, "version": version if newton is not None else None},
              "integrator": "symplectic_euler", "contact": "impulse", "precision": "float32", "dt": args.dt,
              "settle_s": args.settle, "steps": args.steps, "profile_steps": args.profile_steps,
              "size_range": SIZE_RANGE, "density": DENSITY, "restitution": RESTITUTION, "friction": FRICTION,
              "spacing": contact_scenes.PILE_SPACING, "jitter": contact_scenes.PILE_JITTER, "seed": SEED,
              "kernel_load_s": kernels_s,
              "wall_s": time.perf_counter() - started, "sizes_results": results}
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

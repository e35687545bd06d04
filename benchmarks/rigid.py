"""Rigid-body throughput: steps/s of every integrator on free bodies, against a memory-bandwidth floor.

    python benchmarks/rigid.py [--device cpu|cuda] [--sizes 10000 100000] [--integrators euler rk4 ...]
                               [--steps N] [--repeats R] [--precision float32|float64]
                               [--out benchmarks/results/rigid.json]

The scene: N free rigid bodies, half boxes and half spheres of random size, random
orientations, velocities and spins, under gravity, linear and angular drag; no planes,
so no contact (bodies do not collide with each other). Each integrator runs its own
Simulator (guard on) from the same scene; dt = 1/480 s.

The floor of one step is the least memory traffic any one-step method must have: each
body's state (x, q, P, L: 13 scalars) read once and written once, and the constants the
derivative reads per body read once (1/M, I_body^-1 (9), drag, angular_drag, held user
force and torque (6): 18 scalars): 44 scalars, 176 bytes per body at float32 (352 at
float64), at the bandwidth of a large copy measured in the same run (np.copyto on the
CPU, wp.copy of device arrays on CUDA). The floor is the same for every integrator.
A multi-stage integrator written as one pass over all elements per stage, as warp_sim's
are (any coupled system needs that: a stage reads every element's previous stage),
necessarily reads the state and the constants once per derivative evaluation and writes
and re-reads its stage derivatives: RK4 makes four evaluations, midpoint two, Euler one,
so it sits further from the floor than Euler by construction. These free bodies are
uncoupled, so a kernel fused per body could keep every stage in registers: the floor
stays attainable in principle. The "launched" traffic column counts what the launches
as issued actually pass (see bench_size). See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from functools import partial
from pathlib import Path

import numpy as np
import warp as wp
from common import KernelProfile, floor_setup, markdown, time_steps

import warp_sim as ws

DT = 1.0 / 480.0  # [s], 60 fps with 8 substeps
STATE_SCALARS = 13  # x (3), q (4), P (3), L (3)
CONSTANT_SCALARS = 18  # 1/M (1), I_body^-1 (9), drag and angular_drag (2), user force and torque (6)
FLOOR_SCALARS = 2 * STATE_SCALARS + CONSTANT_SCALARS  # state read and written once, constants read once
WARMUP_STEPS = 3
SCENE = {"gravity": (0.0, -9.81, 0.0), "drag": 0.05, "angular_drag": 0.01}
KERNEL_LABELS = {"body_momentum_rates": "dP,dL", "body_position_rates": "dx,dq", "axpy": "axpy",
                 "rk4_combine": "rk4 combine", "normalize_orientations": "normalize q", "check_bodies": "guard"}


def body_parameters(n: int, seed: int = 0) -> list[tuple]:
    """n bodies' add_rigid_body arguments as Python values: (shape kind, size, position, orientation,
    linear velocity, angular velocity). Half boxes (half extents 0.05..0.3 m), half spheres (radius
    0.05..0.3 m), spread over 200 x 100 x 200 m, uniformly random orientations, v ~ N(0, 2 m/s) and
    omega ~ N(0, 5 rad/s) per axis."""
    rng = np.random.default_rng(seed)
    is_box = rng.random(n) < 0.5
    sizes = rng.uniform(0.05, 0.3, size=(n, 3))
    positions = rng.uniform((-100.0, 0.0, -100.0), (100.0, 100.0, 100.0), size=(n, 3))
    quaternions = rng.normal(size=(n, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    velocities = rng.normal(0.0, 2.0, size=(n, 3))
    spins = rng.normal(0.0, 5.0, size=(n, 3))
    return list(zip(np.where(is_box, "box", "sphere").tolist(), sizes.tolist(), positions.tolist(),
                    quaternions.tolist(), velocities.tolist(), spins.tolist(), strict=True))


def add_bodies(scene: ws.Scene, parameters, start: int) -> None:
    """One add_rigid_body call per body, as a user would; bodies named body<start + k>."""
    for k, (kind, size, position, orientation, velocity, spin) in enumerate(parameters):
        shape = ws.Box(size) if kind == "box" else ws.Sphere(size[0])
        scene.add_rigid_body(shape, density=1000.0, position=position, orientation=orientation,
                             linear_velocity=velocity, angular_velocity=spin, name=f"body{start + k}")


def build_scene(parameters, precision: str) -> ws.Scene:
    """The scene: every body added to it in turn, as a user would."""
    scene = ws.Scene(precision=precision, **SCENE)
    add_bodies(scene, parameters, 0)
    return scene


def load_kernels(device, precision: str, integrators) -> float:
    """Seconds to compile or load every kernel the timed runs use: two steps of each integrator on 8 bodies."""
    start = time.perf_counter()
    scene = build_scene(body_parameters(8, seed=1), precision)
    for name in integrators:
        ws.Simulator(scene, name, device.alias, guard=True, collisions=False).step(DT, steps=2)
    wp.synchronize_device(device)
    return time.perf_counter() - start


def bench_size(n: int, device, args, bandwidth: float) -> dict:
    """Build times, timed rounds (integrators interleaved, median reported) and a per-kernel breakdown."""
    parameters = body_parameters(n)
    print(f"N = {n}: building the scene ...", flush=True)
    start = time.perf_counter()
    scene = build_scene(parameters, args.precision)
    scene_s = time.perf_counter() - start
    sims, simulator_s = {}, {}
    for name in args.integrators:
        start = time.perf_counter()
        sims[name] = ws.Simulator(scene, name, device.alias, guard=True, collisions=False)
        simulator_s[name] = time.perf_counter() - start
    print(f"  scene {scene_s:.2f} s, Simulator {min(simulator_s.values()):.2f}..{max(simulator_s.values()):.2f} s",
          flush=True)
    for sim in sims.values():  # load the kernels' recorded launches, touch every buffer
        time_steps(sim, WARMUP_STEPS, DT)
    seconds = {name: [] for name in sims}
    for _ in range(args.repeats):  # interleaved, so every integrator sees the same machine noise
        for name, sim in sims.items():
            seconds[name].append(time_steps(sim, args.steps, DT))
    del sims

    scalar_bytes = 4 if args.precision == "float32" else 8
    floor = bandwidth / (FLOOR_SCALARS * scalar_bytes * n)
    breakdown_steps = max(1, args.steps // 2)
    rows = []
    for name in args.integrators:
        profile = KernelProfile()
        sim = profile.instrumented(partial(ws.Simulator, scene, name, device.alias, guard=True, collisions=False))
        sim.step(DT, steps=WARMUP_STEPS)
        profile.stats.clear()
        sim.step(DT, steps=breakdown_steps)
        kernels = profile.per_step(breakdown_steps)
        rate = args.steps / statistics.median(seconds[name])
        launched = sum(k["bytes"] for k in kernels.values())
        rows.append({"bodies": n, "integrator": name, "order": ws.INTEGRATORS[name].order, "steps": args.steps,
                     "repeats": args.repeats, "seconds": seconds[name], "steps_per_s": rate, "ms_per_step": 1e3 / rate,
                     "body_steps_per_s": rate * n, "floor_steps_per_s": floor, "fraction_of_floor": rate / floor,
                     "launches_per_step": sum(k["launches"] for k in kernels.values()),
                     "launched_bytes_per_body_step": launched / n, "launched_bytes_per_s": launched * rate,
                     "breakdown_steps": breakdown_steps, "kernels_per_step": kernels,
                     "simulator_build_s": simulator_s[name]})
    return {"bodies": n, "scene_build_s": scene_s, "scene_build_us_per_body": 1e6 * scene_s / n,
            "simulator_build_s": simulator_s, "rows": rows}


def tables(device_alias: str, results: list[dict]) -> str:
    rows, kernel_rows, build_rows = [], [], []
    labels = list(KERNEL_LABELS)
    for result in results:
        simulator_s = result["simulator_build_s"].values()
        build_rows.append([f"{result['bodies']:,}", f"{result['scene_build_s']:.2f}",
                           f"{result['scene_build_us_per_body']:.0f}",
                           f"{min(simulator_s):.2f}..{max(simulator_s):.2f}"])
        for row in result["rows"]:
            rows.append([device_alias, f"{row['bodies']:,}", row["integrator"], f"{row['steps_per_s']:.1f}",
                         f"{row['ms_per_step']:.2f}", f"{row['body_steps_per_s'] / 1e6:.2f}",
                         f"{row['floor_steps_per_s']:.0f}", f"{row['fraction_of_floor']:.1%}",
                         f"{row['launches_per_step']:.0f}", f"{row['launched_bytes_per_body_step']:.0f}",
                         f"{row['launched_bytes_per_s'] / 1e9:.2f}"])
            kernels = row["kernels_per_step"]
            labels += [key for key in kernels if key not in labels]
            kernel_rows.append((row, kernels))
    labels = [key for key in labels if any(key in kernels for _, kernels in kernel_rows)]
    breakdown = [[f"{row['bodies']:,}", row["integrator"]]
                 + [f"{kernels[key]['ms']:.2f} ({kernels[key]['launches']:.0f})" if key in kernels else "-"
                    for key in labels] + [f"{sum(k['ms'] for k in kernels.values()):.2f}"]
                 for row, kernels in kernel_rows]
    return "\n\n".join([
        markdown(["device", "N", "integrator", "steps/s", "ms/step", "M body-steps/s", "floor steps/s", "of floor",
                  "launches/step", "launched B/body-step", "launched GB/s"], rows),
        markdown(["N", "integrator"] + [f"{KERNEL_LABELS.get(key, key)} ms (launches)" for key in labels]
                 + ["sum ms"], breakdown),
        markdown(["N", "scene s", "scene us/body", "Simulator s"], build_rows)])


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", choices=("cpu", "cuda"), default=None, help="default: cuda if present, else cpu")
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--integrators", nargs="+", choices=tuple(ws.INTEGRATORS), default=list(ws.INTEGRATORS))
    parser.add_argument("--steps", type=int, default=50, help="timed steps per repeat")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats; the median is reported")
    parser.add_argument("--precision", choices=("float32", "float64"), default="float32")
    parser.add_argument("--copy-mb", type=int, default=256, help="size of the bandwidth-floor copy [MiB]")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/rigid.json"))
    args = parser.parse_args(argv)
    if min(args.sizes) < 1 or args.steps < 1 or args.repeats < 1:
        parser.error("--sizes, --steps and --repeats must be >= 1")

    device, name, host_bw, floor_bw = floor_setup(parser, args.device, args.copy_mb,
                                                  f"{args.precision}, dt = {DT:.6g} s")
    kernels_s = load_kernels(device, args.precision, args.integrators)
    print(f"kernels compiled or loaded in {kernels_s:.2f} s", flush=True)

    results = [bench_size(n, device, args, floor_bw) for n in args.sizes]
    print()
    print(tables(device.alias, results))

    args.out.parent.mkdir(parents=True, exist_ok=True)
    scalar_bytes = 4 if args.precision == "float32" else 8
    result = {"device": device.alias, "device_name": name, "warp_version": wp.__version__,
              "warp_sim_version": ws.__version__, "numpy_version": np.__version__, "precision": args.precision,
              "dt": DT, "sizes": args.sizes, "integrators": args.integrators, "steps": args.steps,
              "repeats": args.repeats,
              "numpy_copy_bytes_per_s": host_bw, "floor_bytes_per_s": floor_bw,
              "floor_method": "wp.copy" if device.is_cuda else "np.copyto",
              "floor_bytes_per_body_step": FLOOR_SCALARS * scalar_bytes, "kernel_load_s": kernels_s,
              "sizes_results": results}
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

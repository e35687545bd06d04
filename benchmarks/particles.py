"""Particle throughput: steps/s of symplectic Euler + impulse ground contact, against a memory-bandwidth floor.

    python benchmarks/particles.py [--device cpu|cuda] [--sizes 100000 1000000] [--steps N]
                                   [--repeats R] [--out benchmarks/results/particles.json]

The floor of one step is the state read and written once (x and v, float32 vec3:
2 * N * 24 bytes) at the bandwidth of a large copy measured in the same run (numpy
np.copyto on the CPU, wp.copy of device arrays on CUDA). See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
import warp as wp
from common import device_name, floor_bandwidth, pick_device, time_steps

from warp_sim import Scene, Simulator

DT = 1.0 / 480.0  # [s], 60 fps with 8 substeps
STATE_BYTES = 2 * 24  # per particle and step: x and v (2 x 12 B) read once and written once
WARMUP_STEPS = 3


def make_scene(n: int, seed: int = 0) -> Scene:
    """n particles at random in a 20 x 2 x 20 m box above the ground, random velocities; gravity, drag, ground."""
    rng = np.random.default_rng(seed)
    scene = Scene(gravity=(0.0, -9.81, 0.0), precision="float32", drag=0.05)
    scene.add_ground(restitution=0.5, friction=0.4)
    positions = rng.uniform((-10.0, 0.02, -10.0), (10.0, 2.0, 10.0), size=(n, 3))
    scene.add_particles(positions, rng.normal(0.0, 1.0, size=(n, 3)), mass=1.0, radius=0.01)
    return scene


def phase_breakdown(sim: Simulator, steps: int) -> dict:
    """Mean ms per step of the solver, the impulse pass and the guard launch, each synchronised on its own."""
    totals: dict[str, float] = {}
    patched = [(name, obj, attr) for name, obj, attr in (("integrator", sim.integrator, "step"),
               ("impacts", sim.impacts, "apply"), ("guard", sim.guard, "record")) if obj is not None]

    def timed(name, fn):
        def wrapper(*args):
            wp.synchronize_device(sim.device)
            start = time.perf_counter()
            fn(*args)
            wp.synchronize_device(sim.device)
            totals[name] = totals.get(name, 0.0) + time.perf_counter() - start
        return wrapper

    for name, obj, attr in patched:
        setattr(obj, attr, timed(name, getattr(obj, attr)))
    try:
        for _ in range(steps):
            sim._advance(DT)
        sim.check()
    finally:
        for _, obj, attr in patched:
            delattr(obj, attr)  # back to the class's method
    return {name: 1e3 * total / steps for name, total in totals.items()}


def bench_size(n: int, device: str, steps: int, repeats: int, bandwidth: float) -> list[dict]:
    scene = make_scene(n)
    sims = {guard: Simulator(scene, "symplectic_euler", device, contact="impulse", guard=guard)
            for guard in (True, False)}
    for sim in sims.values():  # compile / load the kernels, touch every buffer
        time_steps(sim, WARMUP_STEPS, DT)
    seconds = {guard: [] for guard in sims}
    for _ in range(repeats):  # interleaved, so both variants see the same scene state and machine noise
        for guard, sim in sims.items():
            seconds[guard].append(time_steps(sim, steps, DT))
    phases = phase_breakdown(sims[True], max(1, steps // 2))
    floor = bandwidth / (STATE_BYTES * n)
    rows = []
    for guard in sims:
        rate = steps / statistics.median(seconds[guard])
        rows.append({"particles": n, "guard": guard, "steps": steps, "repeats": repeats,
                     "steps_per_s": rate, "ms_per_step": 1e3 / rate, "particle_steps_per_s": rate * n,
                     "floor_steps_per_s": floor, "fraction_of_floor": rate / floor,
                     "phase_ms_per_step": phases if guard else None})
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", choices=("cpu", "cuda"), default=None, help="default: cuda if present, else cpu")
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--steps", type=int, default=100, help="timed steps per repeat")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats; the median is reported")
    parser.add_argument("--copy-mb", type=int, default=256, help="size of the bandwidth-floor copy [MiB]")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/particles.json"))
    args = parser.parse_args(argv)

    device = pick_device(parser, args.device)
    host_bw, floor_bw = floor_bandwidth(device, args.copy_mb)
    name = device_name(device)
    print(f"warp {wp.__version__}, device {device.alias} ({name}), dt = {DT:.6g} s")
    print(f"copy bandwidth (read + write): numpy {host_bw / 1e9:.2f} GB/s"
          + (f", device wp.copy {floor_bw / 1e9:.1f} GB/s" if device.is_cuda else ""))

    rows = []
    header = (f"{'device':8s} {'N':>9s} {'guard':>5s} {'steps/s':>9s} {'ms/step':>8s} {'Mp-steps/s':>10s} "
              f"{'floor st/s':>10s} {'of floor':>8s}   phases ms/step")
    print(header + "\n" + "-" * len(header))
    for n in args.sizes:
        for row in bench_size(n, device.alias, args.steps, args.repeats, floor_bw):
            rows.append(row)
            phases = "  ".join(f"{k} {v:.2f}" for k, v in (row["phase_ms_per_step"] or {}).items())
            print(f"{device.alias:8s} {n:9d} {'on' if row['guard'] else 'off':>5s} {row['steps_per_s']:9.1f} "
                  f"{row['ms_per_step']:8.2f} {row['particle_steps_per_s'] / 1e6:10.1f} "
                  f"{row['floor_steps_per_s']:10.1f} {row['fraction_of_floor']:8.1%}   {phases}")

    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {"device": device.alias, "device_name": name, "warp_version": wp.__version__,
              "numpy_version": np.__version__, "integrator": "symplectic_euler", "contact": "impulse",
              "precision": "float32", "dt": DT, "numpy_copy_bytes_per_s": host_bw,
              "floor_bytes_per_s": floor_bw, "floor_method": "wp.copy" if device.is_cuda else "np.copyto",
              "state_bytes_per_particle_step": STATE_BYTES, "rows": rows}
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

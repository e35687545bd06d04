"""Particle throughput: steps/s of symplectic Euler + impulse ground contact, against a memory-bandwidth floor.

    python benchmarks/particles.py [--device cpu|cuda] [--cases box emitter] [--sizes 100000 1000000]
                                   [--steps N] [--repeats R] [--out benchmarks/results/particles.json]
                                   [--emitter-live 1e5 ...] [--emitter-lifetime 2] [--emitter-steps 20]
                                   [--emitter-repeats 3] [--usd-frames 5]
                                   [--emitter-out benchmarks/results/emitters.json]

Two cases. "box": N particles at random in a box above the ground (gravity, drag, ground),
guard on and off; rows in --out. The floor of one step is the state read and written
once (x and v, float32 vec3: 2 * N * 24 bytes) at the bandwidth of a large copy
measured in the same run (numpy np.copyto on the CPU, on as many threads as the simulator's CPU launches use
(warp_sim.core.cpu_threads: every core unless WARP_SIM_CPU_THREADS says otherwise), wp.copy of device arrays on
CUDA).

"emitter": one disc emitter in steady state (births = deaths) with gravity, drag, curl
noise (ws.Turbulence) and the ground; rate = live / lifetime, pool capacity
ceil(rate x lifetime) + 1.
The pool is filled by stepping one lifetime (plus 3 steps) first, then timed as the box
case (guard on). Its floor per step is, per pool slot (live or dead: every per-particle
kernel runs over the whole pool), x and v read and written once (48 B) plus the pool's
bookkeeping read once: age, birth time and lifetime (float64, 3 x 8 B), alive (int32,
4 B), colour (vec3f, 12 B) and opacity (float32, 4 B): 44 B; 92 B per slot in all, at the
same copy bandwidth. Not counted: what a real step must also touch (inv_mass, radius,
the ages written back, the births' writes), so the floor is a lower bound on traffic.
Also reported: the share of each kernel in a step (every launch synchronised and timed on
its own, common.KernelProfile), and the USD write cost per frame (the state fetched to
numpy with sim.frame_arrays(), StageWriter.write_frame, and the final save, per frame, in
a .usdc with the chunking Simulator.run uses) and the file's size per frame. Results in
--emitter-out. See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import tempfile
import time
from functools import partial
from pathlib import Path

import numpy as np
import warp as wp
from common import KernelProfile, floor_setup, markdown, time_steps

import warp_sim as ws
from warp_sim import Scene, Simulator
from warp_sim.core.cpu_threads import cpu_threads
from warp_sim.stages import StageWriter, stage_layout

DT = 1.0 / 480.0  # [s], 60 fps with 8 substeps
STATE_BYTES = 2 * 24  # per particle and step: x and v (2 x 12 B) read once and written once
WARMUP_STEPS = 3
FPS, SUBSTEPS = 60, 8  # frames of the USD measurement: 8 steps of DT each
#: per pool slot, read once: age, birth, lifetime (float64), alive (int32), colour (vec3f), opacity (float32)
POOL_BYTES = {"age": 8, "birth": 8, "lifetime": 8, "alive": 4, "color": 12, "opacity": 4}
EMITTER_FLOOR_BYTES = STATE_BYTES + sum(POOL_BYTES.values())  # 92 per slot and step
EMITTER_KERNELS = ("age_and_kill", "emit", "commit_births")
TURBULENCE_KERNEL = "turbulence_forces"


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
        sim.step(DT, steps=steps)
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


def make_emitter_scene(live: int, lifetime: float) -> Scene:
    """A disc spray of rate live / lifetime (so live particles in steady state), gravity, drag, curl noise, ground."""
    scene = Scene(gravity=(0.0, -9.81, 0.0), precision="float32", drag=0.01)
    scene.add_ground(restitution=0.4, friction=0.3)
    scene.add_emitter(rate=live / lifetime, lifetime=lifetime, position=(0.0, 0.05, 0.0), direction=(0.0, 1.0, 0.0),
                      spread=30.0, speed=(3.0, 6.0), shape="disc", radius=2.0, size=0.01, mass=0.001, seed=0,
                      name="spray")
    scene.add_field(ws.Turbulence(strength=2.0, scale=1.0))
    return scene


def usd_write(sim: Simulator, frames: int, directory: Path) -> dict:
    """Write `frames` frames of sim (SUBSTEPS steps apart, not timed) to a .usdc: seconds fetching the state
    (sim.frame_arrays()), in write_frame (checks, authoring, the periodic saves) and in close (the last save),
    and the file's size. Chunked as Simulator.run chunks (its default rule, restated here)."""
    particles = sim.model.particle_count
    chunk_frames = int(min(240, max(1, 256 * 2**20 // (40 * particles + 28 * sim.model.body_count + 1))))
    path = directory / "emitter.usdc"
    writer = StageWriter(path, FPS, stage_layout(sim.scene), chunk_frames)
    fetch = write = 0.0
    points = []
    try:
        for frame in range(frames):
            if frame:
                sim.step(1.0 / (FPS * SUBSTEPS), steps=SUBSTEPS)
            wp.synchronize_device(sim.device)
            start = time.perf_counter()
            arrays = sim.frame_arrays()
            middle = time.perf_counter()
            writer.write_frame(frame, **arrays)
            end = time.perf_counter()
            fetch, write = fetch + middle - start, write + end - middle
            points.append(int(np.count_nonzero(arrays["particle_alive"])))
        start = time.perf_counter()
        writer.close()
        close = time.perf_counter() - start
    except BaseException:
        writer.abort()
        raise
    size = path.stat().st_size
    path.unlink()
    return {"frames": frames, "chunk_frames": chunk_frames, "points_per_frame": points, "fetch_s": fetch,
            "write_frame_s": write, "close_s": close, "ms_per_frame": 1e3 * (fetch + write + close) / frames,
            "fetch_ms_per_frame": 1e3 * fetch / frames, "write_frame_ms_per_frame": 1e3 * write / frames,
            "close_ms_per_frame": 1e3 * close / frames, "file_bytes": size, "bytes_per_frame": size / frames}


def bench_emitter(live: int, lifetime: float, device: str, steps: int, repeats: int, bandwidth: float,
                  usd_frames: int) -> dict:
    """Fill the pool (one lifetime), time `repeats` rounds of `steps` steps (median), profile the kernels, write USD."""
    scene = make_emitter_scene(live, lifetime)
    profile = KernelProfile()
    profile.enabled = False  # the timed rounds run unmeasured; the same simulator is profiled afterwards
    sim = profile.instrumented(partial(Simulator, scene, "symplectic_euler", device, contact="impulse", guard=True))
    capacity = sim.emitter_stats()[0]["capacity"]
    fill_steps = math.ceil(lifetime / DT) + WARMUP_STEPS  # every slot's first occupant has died and been replaced
    print(f"emitter, {live} live: filling the pool of {capacity} slots ({fill_steps} steps) ...", flush=True)
    fill_s = time_steps(sim, fill_steps, DT)
    before = sim.emitter_stats()[0]
    seconds = [time_steps(sim, steps, DT) for _ in range(repeats)]
    after = sim.emitter_stats()[0]

    profile_steps = max(1, steps // 2)
    kernels = profile.steps(sim, DT, profile_steps)
    kernel_ms = sum(k["ms"] for k in kernels.values())
    for entry in kernels.values():
        entry["share"] = entry["ms"] / kernel_ms
    with tempfile.TemporaryDirectory(prefix="warp_sim_bench_") as directory:
        usd = usd_write(sim, usd_frames, Path(directory)) if usd_frames else None
    final = sim.emitter_stats()[0]

    rate = steps / statistics.median(seconds)
    floor = bandwidth / (EMITTER_FLOOR_BYTES * capacity)
    return {"live_target": live, "rate_per_s": live / lifetime, "lifetime_s": lifetime, "capacity": capacity,
            "fill_steps": fill_steps, "fill_s": fill_s, "stats_before": before, "stats_after": after,
            "stats_final": final, "steps": steps, "repeats": repeats, "seconds": seconds, "steps_per_s": rate,
            "ms_per_step": 1e3 / rate, "live_particle_steps_per_s": rate * after["live"],
            "floor_steps_per_s": floor, "fraction_of_floor": rate / floor, "profile_steps": profile_steps,
            "kernels_per_step": kernels, "profiled_ms_per_step": kernel_ms,
            "emitter_share": sum(kernels[k]["share"] for k in EMITTER_KERNELS if k in kernels),
            "turbulence_share": kernels.get(TURBULENCE_KERNEL, {}).get("share", 0.0), "usd": usd}


def emitter_tables(device_alias: str, rows: list[dict]) -> str:
    main_rows, kernel_rows = [], []
    for row in rows:
        usd = row["usd"] or {}
        kernels = row["kernels_per_step"]
        main_rows.append([device_alias, f"{row['stats_after']['live']:,}", f"{row['rate_per_s']:,.0f}",
                          f"{row['steps_per_s']:.1f}", f"{row['ms_per_step']:.2f}",
                          f"{row['live_particle_steps_per_s'] / 1e6:.1f}", f"{row['floor_steps_per_s']:.0f}",
                          f"{row['fraction_of_floor']:.1%}",
                          " / ".join(f"{kernels.get(k, {}).get('share', 0.0):.1%}" for k in EMITTER_KERNELS),
                          f"{row['turbulence_share']:.1%}",
                          f"{usd['ms_per_frame']:.0f}" if usd else "-",
                          f"{usd['bytes_per_frame'] / 1e6:.1f}" if usd else "-"])
        for key, entry in sorted(kernels.items(), key=lambda item: -item[1]["ms"]):
            kernel_rows.append([f"{row['stats_after']['live']:,}", key, f"{entry['launches']:.0f}",
                                f"{entry['ms']:.2f}", f"{entry['share']:.1%}"])
        kernel_rows.append([f"{row['stats_after']['live']:,}", "sum", "", f"{row['profiled_ms_per_step']:.2f}",
                            "100%"])
    usd_rows = [[f"{row['stats_after']['live']:,}", str(row["usd"]["frames"]), str(row["usd"]["chunk_frames"]),
                 f"{row['usd']['fetch_ms_per_frame']:.1f}", f"{row['usd']['write_frame_ms_per_frame']:.1f}",
                 f"{row['usd']['close_ms_per_frame']:.1f}", f"{row['usd']['ms_per_frame']:.1f}",
                 f"{row['usd']['bytes_per_frame'] / 1e6:.1f}"] for row in rows if row["usd"]]
    tables = [
        markdown(["device", "live", "births/s", "steps/s", "ms/step", "M live-steps/s", "floor steps/s", "of floor",
                  "age_and_kill / emit / commit", "turbulence", "USD ms/frame", "USD MB/frame"], main_rows),
        markdown(["live", "kernel", "launches/step", "ms/step", "share"], kernel_rows, left=("kernel",))]
    if usd_rows:
        tables.append(markdown(["live", "frames", "chunk", "fetch ms", "write_frame ms", "close ms", "ms/frame",
                                "MB/frame"], usd_rows))
    return "\n\n".join(tables)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", choices=("cpu", "cuda"), default=None, help="default: cuda if present, else cpu")
    parser.add_argument("--cases", nargs="+", choices=("box", "emitter"), default=["box", "emitter"])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000], help="box: particles")
    parser.add_argument("--steps", type=int, default=100, help="timed steps per repeat")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats; the median is reported")
    parser.add_argument("--copy-mb", type=int, default=256, help="size of the bandwidth-floor copy [MiB]")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/particles.json"), help="box results")
    parser.add_argument("--emitter-live", type=float, nargs="+", default=None,
                        help="emitter: live particles in steady state (rate x lifetime), e.g. 1e5 1e6; "
                             "default 1e6 on cuda, 1e5 on cpu")
    parser.add_argument("--emitter-lifetime", type=float, default=2.0, help="emitter: particle lifetime [s]")
    parser.add_argument("--emitter-steps", type=int, default=20, help="emitter: timed steps per repeat")
    parser.add_argument("--emitter-repeats", type=int, default=3, help="emitter: timed repeats (median reported)")
    parser.add_argument("--usd-frames", type=int, default=5, help="emitter: frames written to USD (0: none)")
    parser.add_argument("--emitter-out", type=Path, default=Path("benchmarks/results/emitters.json"),
                        help="emitter results")
    args = parser.parse_args(argv)
    if min(args.sizes + [args.steps, args.repeats, args.emitter_steps, args.emitter_repeats]) < 1:
        parser.error("--sizes, --steps, --repeats, --emitter-steps and --emitter-repeats must be >= 1")
    if args.usd_frames < 0:
        parser.error("--usd-frames must be >= 0")
    if args.emitter_lifetime < 2 * DT:
        parser.error(f"--emitter-lifetime must be at least {2 * DT:g} s (two steps)")

    threads = cpu_threads()
    device, name, host_bw, floor_bw = floor_setup(parser, args.device, args.copy_mb, f"dt = {DT:.6g} s", threads)
    common = {"device": device.alias, "device_name": name, "cpu_threads": threads, "warp_version": wp.__version__,
              "warp_sim_version": ws.__version__, "numpy_version": np.__version__, "integrator": "symplectic_euler",
              "contact": "impulse", "precision": "float32", "dt": DT, "numpy_copy_bytes_per_s": host_bw,
              "floor_bytes_per_s": floor_bw, "floor_method": "wp.copy" if device.is_cuda else "np.copyto"}

    if "box" in args.cases:
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
        args.out.write_text(json.dumps({**common, "state_bytes_per_particle_step": STATE_BYTES, "rows": rows},
                                       indent=2) + "\n")
        print(f"wrote {args.out}")

    if "emitter" in args.cases:
        lives = args.emitter_live or [1e6 if device.is_cuda else 1e5]
        if min(lives) < 1:
            parser.error("--emitter-live must be >= 1")
        rows = [bench_emitter(int(round(live)), args.emitter_lifetime, device.alias, args.emitter_steps,
                              args.emitter_repeats, floor_bw, args.usd_frames) for live in lives]
        print()
        print(emitter_tables(device.alias, rows))
        args.emitter_out.parent.mkdir(parents=True, exist_ok=True)
        result = {**common, "guard": True, "fps": FPS, "substeps": SUBSTEPS,
                  "floor_bytes_per_slot_step": EMITTER_FLOOR_BYTES,
                  "floor_bytes": {"x, v read and written": STATE_BYTES, **POOL_BYTES},
                  "emitter_kernels": list(EMITTER_KERNELS), "turbulence_kernel": TURBULENCE_KERNEL, "rows": rows}
        args.emitter_out.write_text(json.dumps(result, indent=2) + "\n")
        print(f"wrote {args.emitter_out}")


if __name__ == "__main__":
    main()

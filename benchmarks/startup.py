"""Start-up: how long a user's first `warp-sim demo` takes, cold and warm, and what each kernel module costs.

    python benchmarks/startup.py [--repeats 1] [--seconds 0.5] [--out benchmarks/results/startup.json]
    python benchmarks/startup.py --modules

Every run is the command itself, ``python -m warp_sim demo --device cpu --seconds S``, in a fresh process, timed
from its start to its exit (what the user waits), next to what it prints: its wall time and the part of it spent
compiling kernels, and the estimate it gives before compiling. In one run, side by side:

- "cold, 1 worker" (before): an empty kernel cache (a fresh ``WARP_CACHE_PATH``), the modules compiled one at a
  time (``WARP_SIM_CPU_THREADS=1``), as a first launch of each would;
- "cold, N workers" (after): an empty cache, the modules compiled at once on every core, the longest first;
- "warm": the cache the cold run filled;
- "after prepare": ``warp-sim prepare --precision float32`` into an empty cache (its own time in its row), then
  the demo.

And the cold compile time of every kernel module on one thread, its precompiled header built first (by a one-line
kernel), over the demo and scenes that launch the rest (penalty contacts, implicit Euler, turbulence, the fused
step, rk45): the figures of warp_sim.kernels.COMPILE_SECONDS, and from them the critical path of the demo's modules
on 1, 2, 4 and 8 workers (the longest queue of the longest-first split, each worker's header included): where a
module moved between files would shorten it. ``--modules`` prints only that. Nothing is asserted about times; the
targets (a first demo in 8 s cold and 2 s warm on 2 cores) are reported. The machine's load average is printed:
other processes on the cores lengthen every compile.
"""
from __future__ import annotations

import argparse
import heapq
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import cpu_model, markdown

from warp_sim.core.compiling import HEADER_SECONDS

MODULES_CHILD = """
import numpy as np, warp as wp
import warp_sim as ws
from warp_sim.demo import demo_scene
ws.set_verbose(True)   # Warp prints each module's load time

@wp.kernel
def header(a: wp.array(dtype=float)):   # builds this thread's precompiled header, timed apart
    a[wp.tid()] = 1.0

wp.launch(header, 1, [wp.zeros(1, dtype=float, device="cpu")], device="cpu")
sim = ws.Simulator(demo_scene(), integrator="rk4", device="cpu")
print("DEMO", " ".join(sim.kernel_modules()))
for integrator, contact, add in (("symplectic_euler", "impulse", "particles"), ("implicit_euler", "impulse", "cloth"),
                                 ("rk4", "penalty", "body"), ("rk45", "impulse", "field")):
    scene = ws.Scene()
    scene.add_ground()
    if add == "cloth":
        scene.add_cloth_grid(resolution=(4, 4), size=(1.0, 1.0))
    else:
        scene.add_particles(np.random.default_rng(0).uniform(0.1, 1.0, (10, 3)))
    if add == "body":
        scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), position=(0.0, 1.0, 0.0))
    if add in ("cloth", "field"):
        scene.add_field(ws.Turbulence(strength=1.0, scale=1.0))
    ws.Simulator(scene, integrator, "cpu", contact=contact)
"""
LOADED = re.compile(r"Module warp_sim\.kernels\.(\w+) \w+ load on device 'cpu' took ([0-9.]+) ms +\(compiled\)")
WROTE = re.compile(r"in ([0-9.]+) s wall time(?:, of which ([0-9.]+) s compiling)?")
ESTIMATE = re.compile(r"compiling kernels for \w+, once, about ([0-9]+) s")
TARGETS = {"cold": 8.0, "warm": 2.0}   # [s]: the first `warp-sim demo` on a 2-core machine


def module_seconds() -> tuple[dict[str, float], list[str]]:
    """Each kernel module's cold compile seconds on one thread (MODULES_CHILD in a fresh cache, one compile worker),
    longest first; and the demo's modules."""
    with tempfile.TemporaryDirectory(prefix="startup-modules-") as scratch:
        child = Path(scratch) / "modules_child.py"   # a file: Warp reads a kernel's source from it
        child.write_text(MODULES_CHILD)
        done = subprocess.run([sys.executable, str(child)], capture_output=True, text=True, check=True,
                              env=dict(os.environ, WARP_CACHE_PATH=str(Path(scratch) / "cache"),
                                       WARP_SIM_CPU_THREADS="1"))
    seconds = {name: float(ms) / 1e3 for name, ms in LOADED.findall(done.stdout + done.stderr)}
    demo = next(line.split()[1:] for line in done.stdout.splitlines() if line.startswith("DEMO "))
    return dict(sorted(seconds.items(), key=lambda item: -item[1])), demo


def command(args: list[str], cache: Path, threads: int | None = None) -> dict:
    """One `warp-sim` command in a fresh process: its wall time from start to exit, and what it printed."""
    env = dict(os.environ, WARP_CACHE_PATH=str(cache))
    env.pop("WARP_SIM_CPU_THREADS", None)
    if threads is not None:
        env["WARP_SIM_CPU_THREADS"] = str(threads)
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "warp_sim", *args], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise RuntimeError(f"warp-sim {' '.join(args)} failed:\n{done.stderr}")
    printed = WROTE.search(done.stdout.strip().splitlines()[-1])
    guess = ESTIMATE.search(done.stderr)
    return {"wall": wall, "printed": float(printed.group(1)) if printed else None,
            "compiling": float(printed.group(2) or 0.0) if printed else None,
            "estimate": float(guess.group(1)) if guess else None}


def demo(cache: Path, seconds: float, out: Path, threads: int | None = None) -> dict:
    return command(["demo", "--device", "cpu", "--seconds", str(seconds), "--out", str(out), "--no-progress"],
                   cache, threads)


def critical_paths(seconds: dict[str, float], names: list[str], workers=(1, 2, 4, 8)) -> dict[int, float]:
    """The compile of modules ``names`` on each count of workers from the measured seconds: the longest queue of
    the longest-first split, each worker's header included (the model of core.compiling.estimate)."""
    paths = {}
    for count in sorted(set(workers)):
        queues = [HEADER_SECONDS] * max(1, min(count, len(names)))
        for value in sorted((seconds.get(name, 0.0) for name in names), reverse=True):
            heapq.heappush(queues, heapq.heappop(queues) + value)
        paths[count] = max(queues)
    return paths


def print_modules(seconds: dict[str, float], demo_modules: list[str], cores: int) -> dict[int, float]:
    print(f"cold compile of each kernel module on one core of {cpu_model()} [s] (demo's: *):")
    print("COMPILE_SECONDS = {" + ", ".join(f'"{name}": {value:.2f}' for name, value in seconds.items()) + "}")
    paths = critical_paths(seconds, demo_modules, (1, 2, 4, 8, cores))
    longest = max(demo_modules, key=lambda name: seconds.get(name, 0.0))
    print(f"the demo's {len(demo_modules)} modules, {sum(seconds.get(n, 0.0) for n in demo_modules):.2f} s in all: "
          "critical path " + ", ".join(f"{w} worker{'s' if w > 1 else ''} {p:.2f} s" for w, p in paths.items())
          + f" (the longest module, {longest}, {seconds.get(longest, 0.0):.2f} s + {HEADER_SECONDS} s header)")
    return paths


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--seconds", type=float, default=0.5, help="simulated seconds of the demo")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/startup.json"))
    parser.add_argument("--modules", action="store_true", help="each kernel module's cold compile time only")
    args = parser.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    seconds, demo_modules = module_seconds()
    paths = print_modules(seconds, demo_modules, cores)
    args.out.with_name("compile_seconds.json").write_text(json.dumps(seconds, indent=2) + "\n")
    if args.modules:
        return
    runs = {"cold, 1 worker (before)": [], f"cold, {cores} workers (after)": [], "warm": [], "after prepare": []}
    prepares = []
    with tempfile.TemporaryDirectory(prefix="startup-") as scratch:
        for k in range(args.repeats):
            out = Path(scratch) / "demo.usdc"
            one, many, ready = (Path(scratch) / f"{name}{k}" for name in ("one", "many", "ready"))
            runs["cold, 1 worker (before)"].append(demo(one, args.seconds, out, threads=1))
            runs[f"cold, {cores} workers (after)"].append(demo(many, args.seconds, out))
            runs["warm"].append(demo(many, args.seconds, out))
            prepares.append(command(["prepare", "--precision", "float32"], ready))
            runs["after prepare"].append(demo(ready, args.seconds, out))
    rows = []
    for label, results in runs.items():
        median = {key: statistics.median(r[key] for r in results) if results[0][key] is not None else None
                  for key in results[0]}
        rows.append([label, f"{median['wall']:.2f}", f"{median['printed']:.2f}", f"{median['compiling']:.2f}",
                     "-" if median["estimate"] is None else f"{median['estimate']:.0f}"])
    print(f"\n`warp-sim demo --device cpu --seconds {args.seconds:g}` on {cpu_model()}, {cores} cores, median of "
          f"{args.repeats}; load average {load[0]:.2f} before, {os.getloadavg()[0]:.2f} after")
    print(markdown(["run", "process wall [s]", "printed wall [s]", "of which compiling [s]", "estimate printed [s]"],
                   rows, left=("run",)))
    prepared = statistics.median(p["wall"] for p in prepares)
    print(f"`warp-sim prepare --precision float32` (all {len(seconds)} modules, empty cache): {prepared:.2f} s")
    cold = statistics.median(r["wall"] for r in runs[f"cold, {cores} workers (after)"])
    warm = statistics.median(r["wall"] for r in runs["warm"])
    print(f"targets on 2 cores: cold <= {TARGETS['cold']:g} s (measured {cold:.2f} s), warm <= {TARGETS['warm']:g} s "
          f"(measured {warm:.2f} s); the critical path of the demo's compile alone on {cores} workers "
          f"{paths[cores]:.2f} s")
    args.out.write_text(json.dumps({"cpu": cpu_model(), "cores": cores, "seconds": args.seconds,
                                    "load_average": [load[0], os.getloadavg()[0]], "modules": seconds,
                                    "demo_modules": demo_modules, "critical_path": paths, "runs": runs,
                                    "prepare": prepares, "targets": TARGETS}, indent=2) + "\n")


if __name__ == "__main__":
    main()

"""Start-up: how long `warp-sim demo` makes a user wait before and while its first frames come, cold and warm.

    python benchmarks/startup.py [--repeats 3] [--seconds 0.5] [--out benchmarks/results/startup.json]
    python benchmarks/startup.py --modules

Each run is a fresh process that times, one after the other: ``import warp_sim``; building the demo scene;
``Simulator(...)`` (the Model, the parts, the initial state, and every kernel module the simulation launches
loaded from the cache or compiled, in parallel on all cores); the first ``sim.step`` of a frame; the rest of
``--seconds`` of frames to USD. "cold" runs with an empty kernel
cache (a fresh ``WARP_CACHE_PATH``, so every module it launches is compiled), "warm" with the cache the cold run
filled. The median of ``--repeats`` runs is shown. Nothing is asserted about times.

``--modules``: the cold compile time of every kernel module on one thread, its precompiled header built first
(by a one-line kernel), over the demo and scenes that launch the rest (penalty contacts, implicit Euler,
turbulence, the fused step, rk45), printed as warp_sim.kernels.COMPILE_SECONDS, the order Simulator compiles in.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from common import cpu_model, markdown

CHILD = """
import json, sys, time
clock = [time.perf_counter()]
import warp_sim as ws
from warp_sim.demo import demo_scene
clock.append(time.perf_counter())
scene = demo_scene()
clock.append(time.perf_counter())
sim = ws.Simulator(scene, device="cpu")
clock.append(time.perf_counter())
sim.step(1.0 / 480.0)
sim.check()
clock.append(time.perf_counter())
sim.run(float(sys.argv[1]), usd=sys.argv[2], progress=False)
clock.append(time.perf_counter())
print(json.dumps([b - a for a, b in zip(clock, clock[1:])]))
"""
PHASES = ("import", "scene", "Simulator", "first step", "frames to USD")

MODULES_CHILD = """
import os, numpy as np, warp as wp
import warp_sim as ws
from warp_sim.demo import demo_scene
ws.set_verbose(True)   # Warp prints each module's load time
os.cpu_count = lambda: 1   # the Simulator compiles one module at a time

@wp.kernel
def header(a: wp.array(dtype=float)):   # builds this thread's precompiled header, timed apart
    a[wp.tid()] = 1.0

wp.launch(header, 1, [wp.zeros(1, dtype=float, device="cpu")], device="cpu")
ws.Simulator(demo_scene(), integrator="rk4", device="cpu")
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


def module_seconds() -> dict[str, float]:
    """Each kernel module's cold compile seconds on one thread (MODULES_CHILD in a fresh cache), longest first."""
    with tempfile.TemporaryDirectory(prefix="startup-modules-") as scratch:
        child = Path(scratch) / "modules_child.py"   # a file: Warp reads a kernel's source from it
        child.write_text(MODULES_CHILD)
        done = subprocess.run([sys.executable, str(child)], capture_output=True, text=True, check=True,
                              env=dict(os.environ, WARP_CACHE_PATH=str(Path(scratch) / "cache")))
    seconds = {name: float(ms) / 1e3 for name, ms in LOADED.findall(done.stdout + done.stderr)}
    return dict(sorted(seconds.items(), key=lambda item: -item[1]))


def run(cache: Path, seconds: float, out: Path) -> list[float]:
    env = dict(os.environ, WARP_CACHE_PATH=str(cache))
    done = subprocess.run([sys.executable, "-c", CHILD, str(seconds), str(out)], capture_output=True, text=True,
                          env=env, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=0.5, help="simulated seconds of the demo after its start")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/startup.json"))
    parser.add_argument("--modules", action="store_true", help="each kernel module's cold compile time instead")
    args = parser.parse_args()
    if args.modules:
        seconds = module_seconds()
        print(f"cold compile of each kernel module on one core of {cpu_model()} [s]:")
        print("COMPILE_SECONDS = {" + ", ".join(f'"{name}": {value:.2f}' for name, value in seconds.items()) + "}")
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.with_name("compile_seconds.json").write_text(json.dumps(seconds, indent=2) + "\n")
        return
    cold, warm = [], []
    with tempfile.TemporaryDirectory(prefix="startup-") as scratch:
        for k in range(args.repeats):
            cache = Path(scratch) / f"cache{k}"
            cold.append(run(cache, args.seconds, Path(scratch) / "cold.usdc"))
            warm.append(run(cache, args.seconds, Path(scratch) / "warm.usdc"))
    rows = []
    for label, runs in (("cold", cold), ("warm", warm)):
        phases = [statistics.median(r[i] for r in runs) for i in range(len(PHASES))]
        rows.append([label, *(f"{p:.2f}" for p in phases), f"{sum(phases[:4]):.2f}", f"{sum(phases):.2f}"])
    print(f"start-up of the demo on {cpu_model()}, {os.cpu_count()} cores, median of {args.repeats}")
    print(markdown(["cache", *(f"{p} [s]" for p in PHASES), "to the first frame [s]", "in all [s]"], rows,
                   left=("cache",)))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"cpu": cpu_model(), "phases": PHASES, "seconds": args.seconds,
                                    "cold": cold, "warm": warm}, indent=2) + "\n")


if __name__ == "__main__":
    main()

"""Start-up: how long `warp-sim demo` makes a user wait before and while its first frames come, cold and warm.

    python benchmarks/startup.py [--repeats 3] [--seconds 0.5] [--out benchmarks/results/startup.json]

Each run is a fresh process that times, one after the other: ``import warp_sim``; building the demo scene;
``Simulator(...)`` (the Model, the parts, the initial state, and every kernel module the simulation launches
loaded from the cache or compiled, in parallel on all cores); the first ``sim.step`` of a frame; the rest of
``--seconds`` of frames to USD. "cold" runs with an empty kernel
cache (a fresh ``WARP_CACHE_PATH``, so every module it launches is compiled), "warm" with the cache the cold run
filled. The median of ``--repeats`` runs is shown. Nothing is asserted about times.
"""
from __future__ import annotations

import argparse
import json
import os
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
    args = parser.parse_args()
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

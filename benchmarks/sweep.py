"""Sweeps and studies on 1 and on 2 Dask workers, in the same run: wall times, speed-ups, and what a task costs.

    python benchmarks/sweep.py [--variants 16] [--seconds 1.0] [--out benchmarks/results/sweep.json]

Three measurements, each on an embedded LocalCluster of 1 worker and then of 2 (one thread each):

- a sweep of ``--variants`` variants of the demo's pile of boxes and spheres (the seed of the pile varies), each
  ``--seconds`` at 60 fps, written to USD; the cluster is started and warmed (its workers have imported warp_sim
  and loaded the kernels) before the clock starts, so the time is the sweep's own;
- the ``--quick`` accuracy study, its references and (problem, integrator) points spread over the workers;
- the overhead of one task: the round trip of an empty task (scheduling), and on a warm worker the import of
  warp_sim and the first Simulator of a scene whose kernels are in the cache (what the first variant on a
  worker pays and the others do not).

Nothing is asserted about times; the machine's cores are shared, so compare the ratios of one run.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import cpu_model, markdown
from distributed import Client, LocalCluster

import warp_sim as ws
from warp_sim import studies

PILE = """
import numpy as np
import warp_sim as ws
from warp_sim.demo import add_pile


def build(seed):
    scene = ws.Scene()
    scene.add_ground(restitution=0.3, friction=0.6)
    add_pile(scene, np.random.default_rng(seed), layers=3)
    return scene
"""

WARM_START = """
import time
started = time.perf_counter()
import warp_sim as ws
imported = time.perf_counter()
scene = ws.Scene()
scene.add_ground()
scene.add_particles([[0.0, 1.0, 0.0]])
sim = ws.Simulator(scene, device="cpu")
sim.step(1e-3)
print(imported - started, time.perf_counter() - imported)
"""


def cluster(workers: int):
    local = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                         dashboard_address=":0", silence_logs=40)
    return local, Client(local)


def timed_sweep(script: Path, variants: int, seconds: float, workers: int, scratch: Path) -> dict:
    local, client = cluster(workers)
    try:
        warm = scratch / f"warm-{workers}"   # every worker imports warp_sim and loads the pile's kernels
        ws.sweep(script, [{"seed": 1000 + k} for k in range(workers)], seconds=0.05, out=warm, client=client,
                 progress=False)
        out = scratch / f"sweep-{workers}"
        started = time.perf_counter()
        result = ws.sweep(script, {"seed": list(range(variants))}, seconds=seconds, out=out, client=client,
                          progress=False)
        wall = time.perf_counter() - started
        task_wall = [row["wall_s"] for row in result.rows]
        rounds = []
        for _ in range(20):   # scheduling: an empty task's round trip
            tick = time.perf_counter()
            client.submit(int, 0, pure=False).result()
            rounds.append(time.perf_counter() - tick)
    finally:
        client.close()
        local.close()
    return {"workers": workers, "wall_s": wall, "done": sum(r["status"] == "done" for r in result.rows),
            "task_mean_s": statistics.mean(task_wall), "schedule_ms": 1e3 * statistics.median(rounds)}


def timed_study(workers: int) -> dict:
    local, client = cluster(workers)
    try:
        started = time.perf_counter()
        result = studies.accuracy(quick=True, client=client)
        wall = time.perf_counter() - started
    finally:
        client.close()
        local.close()
    return {"workers": workers, "wall_s": wall, "rows": len(result.rows)}


def warm_start() -> dict:
    """The import of warp_sim and a first small Simulator with a warm kernel cache, in a fresh process."""
    runs = [subprocess.run([sys.executable, "-c", WARM_START], capture_output=True, text=True, check=True)
            for _ in range(3)]
    pairs = [tuple(float(x) for x in run.stdout.split()) for run in runs]
    return {"import_s": statistics.median(p[0] for p in pairs), "first_sim_s": statistics.median(p[1] for p in pairs)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", type=int, default=16)
    parser.add_argument("--seconds", type=float, default=1.0)
    parser.add_argument("--skip-study", action="store_true", help="leave the accuracy study out")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/sweep.json"))
    args = parser.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="sweep-"))
    try:
        script = scratch / "pile.py"
        script.write_text(PILE)
        sweeps = [timed_sweep(script, args.variants, args.seconds, w, scratch) for w in (1, 2)]
        study = [] if args.skip_study else [timed_study(w) for w in (1, 2)]
        warm = warm_start()
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"sweep benchmark on {cpu_model()}, {os.cpu_count()} cores")
    rows = [[f"pile sweep, {args.variants} variants x {args.seconds:g} s", str(s["workers"]), f"{s['wall_s']:.1f}",
             f"{sweeps[0]['wall_s'] / s['wall_s']:.2f}x", f"{s['task_mean_s']:.2f}", f"{s['schedule_ms']:.1f}"]
            for s in sweeps]
    rows += [["accuracy study --quick", str(s["workers"]), f"{s['wall_s']:.1f}",
              f"{study[0]['wall_s'] / s['wall_s']:.2f}x", "", ""] for s in study]
    print(markdown(["run", "workers", "wall [s]", "speed-up", "mean task [s]", "empty task [ms]"], rows,
                   left=("run",)))
    print(f"\na warm worker's first task also pays: import warp_sim {warm['import_s']:.2f} s, a first Simulator "
          f"with cached kernels {warm['first_sim_s']:.2f} s (each later task on that worker pays neither)")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"cpu": cpu_model(), "variants": args.variants, "seconds": args.seconds,
                                    "sweeps": sweeps, "study": study, "warm_start": warm}, indent=2) + "\n")


if __name__ == "__main__":
    main()

"""Soak: a long run of a small scene to USD, its memory and file size as it goes, and a resume after a kill.

    python benchmarks/soak.py [--frames 100000] [--every 10000] [--chunk-frames 1000] [--particles 100]
                              [--out benchmarks/results/soak.json]

A child process runs ``Simulator.run`` of ``--particles`` particles bouncing elastically on the ground
(symplectic Euler, one step per frame at 600 fps) for ``--frames`` frames into a scratch folder, checkpointing
every ``--chunk-frames``; the parent watches it from outside (its resident memory from /proc, its frames from the
checkpoint, the bytes of its chunks on disk) and prints a row every ``--every`` frames. Then the same run is
killed (SIGKILL) halfway and resumed with ``resume=True``: the resume's wall time, set against the share of the
uninterrupted run it has left to do, gives the cost of going on from a checkpoint. Nothing is asserted about
times.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from common import cpu_model, markdown
from pxr import Sdf

CHILD = """
import sys, numpy as np, warp_sim as ws
out, frames, chunk, count, resume = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
scene = ws.Scene()
scene.add_ground(restitution=1.0)   # elastic: they bounce for the whole run
rng = np.random.default_rng(0)
scene.add_particles(rng.uniform((-1.0, 0.5, -1.0), (1.0, 2.0, 1.0), (count, 3)), rng.normal(0.0, 1.0, (count, 3)),
                    radius=0.01)
sim = ws.Simulator(scene, integrator="symplectic_euler")
sim.run(frames / 600.0, fps=600.0, substeps=1, usd=out, progress=False, chunk_frames=chunk, resume=resume == "1")
"""


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def checkpointed(out: Path) -> tuple[int, int]:
    """(frames in the newest checkpoint beside ``out``, bytes of its run folder)."""
    for folder in out.parent.glob(f".{out.name}.run-*"):
        try:
            with np.load(folder / "checkpoint.npz", allow_pickle=False) as data:
                frames = json.loads(data["__meta__"].tobytes().decode())["frames"]
            return frames, sum(p.stat().st_size for p in folder.iterdir())
        except (OSError, ValueError, KeyError):
            continue
    return 0, 0


def start(out: Path, args, resume: bool) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", CHILD, str(out), str(args.frames), str(args.chunk_frames),
                             str(args.particles), "1" if resume else "0"], stderr=subprocess.DEVNULL)


def watch(out: Path, args) -> tuple[list[dict], float, float]:
    """Run to the end, sampling every --every frames: (rows, wall seconds, peak RSS [MB])."""
    rows, next_mark, peak = [], args.every, 0.0
    started = time.perf_counter()
    child = start(out, args, resume=False)
    while child.poll() is None:
        try:
            peak = max(peak, rss_mb(child.pid))
            frames, on_disk = checkpointed(out)
        except OSError:
            break
        if frames >= next_mark:
            rows.append({"frames": frames, "rss_mb": rss_mb(child.pid), "chunk_mb": on_disk / 1e6,
                         "wall_s": time.perf_counter() - started})
            next_mark += args.every
        time.sleep(0.05)
    wall = time.perf_counter() - started
    if child.returncode != 0:
        sys.exit(f"soak: the run failed (exit {child.returncode})")
    return rows, wall, peak


def kill_and_resume(out: Path, args, full_wall: float) -> dict:
    out.unlink()
    child = start(out, args, resume=False)
    while checkpointed(out)[0] < args.frames // 2:
        if child.poll() is not None:
            sys.exit("soak: the run ended before it could be killed")
        time.sleep(0.02)
    child.send_signal(signal.SIGKILL)
    child.wait()
    kept = checkpointed(out)[0]
    started = time.perf_counter()
    resumed = start(out, args, resume=True)
    resumed.wait()
    wall = time.perf_counter() - started
    left = (args.frames - kept) / args.frames
    return {"checkpointed_frames": kept, "resume_wall_s": wall, "left_share": left,
            "uninterrupted_share_s": left * full_wall, "overhead_s": wall - left * full_wall,
            "exit": resumed.returncode}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100_000)
    parser.add_argument("--every", type=int, default=10_000)
    parser.add_argument("--chunk-frames", type=int, default=1000)
    parser.add_argument("--particles", type=int, default=100)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/soak.json"))
    args = parser.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="soak-"))
    try:
        out = scratch / "soak.usdc"
        rows, wall, peak = watch(out, args)
        once = scratch / "once.usdc"
        Sdf.Layer.FindOrOpen(str(out)).Export(str(once))
        size, compact = out.stat().st_size, once.stat().st_size
        reference = out.read_bytes()
        resume = kill_and_resume(out, args, wall)
        resume["identical_file"] = out.read_bytes() == reference
        resume["strays"] = sorted(p.name for p in scratch.iterdir() if p.name.startswith("."))
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    print(f"soak: {args.frames} frames of {args.particles} particles, chunks of {args.chunk_frames}, "
          f"on {cpu_model()}, {os.cpu_count()} cores")
    print(markdown(["frames", "RSS [MB]", "chunks on disk [MB]", "wall [s]"],
                   [[f"{r['frames']:,}", f"{r['rss_mb']:.1f}", f"{r['chunk_mb']:.2f}", f"{r['wall_s']:.1f}"]
                    for r in rows], left=()))
    print(f"\nwhole run {wall:.1f} s, peak RSS {peak:.1f} MB; final stage {size / 1e6:.2f} MB, exported once "
          f"{compact / 1e6:.2f} MB ({size / compact:.3f}x)")
    print(f"killed at {resume['checkpointed_frames']:,} checkpointed frames; "
          f"resume took {resume['resume_wall_s']:.1f} s "
          f"for the {100 * resume['left_share']:.0f} % left (uninterrupted: {resume['uninterrupted_share_s']:.1f} s; "
          f"overhead {resume['overhead_s']:+.1f} s); same file as uninterrupted: {resume['identical_file']}; "
          f"strays: {resume['strays'] or 'none'}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"frames": args.frames, "particles": args.particles,
                                    "chunk_frames": args.chunk_frames, "cpu": cpu_model(), "samples": rows,
                                    "wall_s": wall, "peak_rss_mb": peak, "stage_bytes": size,
                                    "exported_once_bytes": compact, "resume": resume}, indent=2) + "\n")


if __name__ == "__main__":
    main()

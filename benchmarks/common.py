"""Shared by the benchmark scripts: device choice, the copy-bandwidth floor, step timing, per-kernel timing,
markdown tables, the host's name, the checkout's commit.

Imported as ``common`` by scripts run as ``python benchmarks/<name>.py`` (their folder is on sys.path).
"""
from __future__ import annotations

import argparse
import os
import platform
import subprocess
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import warp as wp

import warp_sim
from warp_sim import Simulator
from warp_sim.simulator import resolve_device

wp.config.log_level = wp.LOG_WARNING  # no per-module load messages (they are printed at launch, not import)


def pick_device(parser: argparse.ArgumentParser, requested: str | None):
    """The Warp device to run on (--device; default cuda when present, else cpu); a usage error, not a
    traceback, when cuda is asked for on a machine without a CUDA device."""
    wp.init()
    if requested == "cuda" and wp.get_cuda_device_count() == 0:
        parser.error("--device cuda: no CUDA device on this machine (use --device cpu, or leave --device out)")
    return wp.get_device(resolve_device(requested))


def best_rate(copy, nbytes: int, repeats: int = 7) -> float:
    """Bytes moved (read + written) per second by copy(), best of repeats after one warm-up."""
    copy()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        copy()
        times.append(time.perf_counter() - start)
    return 2 * nbytes / min(times)


def copy_bandwidth(megabytes: int, device=None, threads: int = 1) -> float:
    """A large float32 copy: np.copyto on the host (device None), in ``threads`` slices copied at once (numpy lets
    go of Python's lock for a copy), else wp.copy between device arrays."""
    count = megabytes * 2**20 // 4
    if device is None:
        src = np.ones(count, dtype=np.float32)
        dst = np.empty_like(src)
        if threads == 1:
            return best_rate(lambda: np.copyto(dst, src), 4 * count)
        cuts = [k * count // threads for k in range(threads + 1)]
        slices = [(dst[a:b], src[a:b]) for a, b in zip(cuts, cuts[1:])]
        with ThreadPoolExecutor(threads - 1) as workers:
            def copy():
                futures = [workers.submit(np.copyto, *pair) for pair in slices[1:]]
                np.copyto(*slices[0])
                for future in futures:
                    future.result()
            return best_rate(copy, 4 * count)
    src = wp.ones(count, dtype=wp.float32, device=device)
    dst = wp.empty_like(src)
    return best_rate(lambda: (wp.copy(dst, src), wp.synchronize_device(device)), 4 * count)


def floor_bandwidth(device, megabytes: int, threads: int = 1) -> tuple[float, float]:
    """(numpy host copy bandwidth on one thread, the floor's bandwidth): the device's own wp.copy on CUDA, else the
    host copy on ``threads`` threads (those the CPU launches use). Both in bytes read + written per second."""
    host = copy_bandwidth(megabytes)
    if device.is_cuda:
        return host, copy_bandwidth(megabytes, device)
    return host, (host if threads == 1 else copy_bandwidth(megabytes, threads=threads))


def floor_setup(parser: argparse.ArgumentParser, requested: str | None, megabytes: int, label: str,
                threads: int = 1):
    """Pick the device, measure the copy bandwidths and print them: (device, its name, host bandwidth on one
    thread, floor bandwidth) [bytes/s]. label: the run's settings for the first line (e.g. "float32, dt = ...");
    threads: the CPU threads the launches use, the floor's on the CPU (floor_bandwidth)."""
    device = pick_device(parser, requested)
    host_bw, floor_bw = floor_bandwidth(device, megabytes, threads)
    name = device_name(device)
    print(f"warp {wp.__version__}, device {device.alias} ({name}), {label}")
    print(f"copy bandwidth (read + write): numpy {host_bw / 1e9:.2f} GB/s"
          + (f", device wp.copy {floor_bw / 1e9:.1f} GB/s" if device.is_cuda else "")
          + (f", numpy on {threads} threads {floor_bw / 1e9:.2f} GB/s" if device.is_cpu and threads > 1 else ""))
    return device, name, host_bw, floor_bw


def time_steps(sim: Simulator, steps: int, dt: float) -> float:
    """Seconds for sim.step(dt, steps) (one guard read at the end), the device synchronised around it."""
    wp.synchronize_device(sim.device)
    start = time.perf_counter()
    sim.step(dt, steps=steps)
    wp.synchronize_device(sim.device)
    return time.perf_counter() - start


def cpu_model() -> str:
    cpuinfo = Path("/proc/cpuinfo")
    names = [line.split(":", 1)[1].strip() for line in (cpuinfo.read_text().splitlines() if cpuinfo.exists() else [])
             if line.startswith("model name")]
    return names[0] if names else platform.processor() or platform.machine()


def git_state(root: Path | None = None) -> dict:
    """The checkout whose warp_sim was imported (default: the folder above it; PYTHONPATH may point at another
    worktree): its HEAD commit and the files under warp_sim/ that differ from it (what was measured is the working
    tree); {} outside a git checkout."""
    root = root or Path(warp_sim.__file__).resolve().parents[1]
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                check=True).stdout.strip()
        status = subprocess.run(["git", "--no-optional-locks", "-C", str(root), "status", "--porcelain", "--",
                                 "warp_sim"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return {}
    return {"commit": commit, "warp_sim_modified": [line[3:] for line in status.splitlines()]}


def environment() -> dict:
    """The environment variables that change what a run measures: numpy's BLAS threads (a Scene's stable-step
    estimate runs on them), OpenMP's, and PYTHONPATH (which warp_sim is imported)."""
    return {key: os.environ.get(key) for key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "PYTHONPATH")}


def device_name(device) -> str:
    return device.name if device.is_cuda else cpu_model()


class KernelProfile:
    """Per kernel: launches, seconds (synchronised around each launch) and bytes of the arrays passed.

    Only the launches of the Simulators made by ``instrumented`` are measured (through their Model's
    launcher, ``Launcher.profile``), and only while ``enabled``, so one simulator can be timed whole and
    then profiled.
    """

    def __init__(self):
        self.stats: dict[str, list] = {}
        self._launchers = []
        self._enabled = True

    @property
    def enabled(self) -> bool:
        return self._enabled

    @enabled.setter
    def enabled(self, value: bool) -> None:
        self._enabled = value
        for launcher in self._launchers:
            launcher.profile = self.stats if value else None

    def instrumented(self, make):
        """make() (a Simulator), its launches measured while this profile is enabled."""
        sim = make()
        self._launchers.append(sim.model.launcher)
        self.enabled = self._enabled
        return sim

    def steps(self, sim, dt: float, steps: int) -> dict:
        """``sim.step(dt, steps=steps)`` measured (this profile enabled only for it): per_step(steps)."""
        self.stats.clear()
        self.enabled = True
        try:
            sim.step(dt, steps=steps)
        finally:
            self.enabled = False
        return self.per_step(steps)

    def per_step(self, steps: int) -> dict:
        return {key: {"launches": launches / steps, "ms": 1e3 * seconds / steps, "bytes": nbytes / steps}
                for key, (launches, seconds, nbytes) in self.stats.items()}


def markdown(header, rows, left=("device", "integrator")) -> str:
    """A markdown table; the columns named in ``left`` are left-aligned, the others right-aligned."""
    align = ["---" if h in left else "---:" for h in header]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows])

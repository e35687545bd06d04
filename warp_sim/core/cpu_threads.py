"""Threads for CPU launches: Warp runs a CPU launch's threads one after another on one core, so a launch whose
elements are independent is split into pieces that run at once, one per core (``Prepared.run_pieces`` for a
kernel that adds a ``base`` to wp.tid(), ``Launcher.launch_elementwise`` over views of the arrays).

Warp's compiled CPU entry point is called through ctypes, which releases Python's lock for the call, so pieces
called from several Python threads run in parallel. Only for kernels whose threads write disjoint elements:
Warp's CPU atomics are plain reads and writes.

``cpu_threads(value)`` is the count to use: ``value`` if given, else the environment variable WARP_SIM_CPU_THREADS,
else the cores this process may run on. ``CpuPool.shared(count)`` is the process's pool of that many threads.
"""
from __future__ import annotations

import ctypes
import os
from concurrent.futures import ThreadPoolExecutor, wait

from ..util import checks

VARIABLE = "WARP_SIM_CPU_THREADS"


def available_cores() -> int:
    """The cores this process may run on [1]."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


def cpu_threads(value: int | None = None) -> int:
    """The CPU threads a launch may use: ``value`` (an int >= 1) if given, else WARP_SIM_CPU_THREADS, else every
    available core. A bad value is a ValueError naming where it came from."""
    if value is not None:
        return checks.count("cpu_threads", value, low=1)
    text = os.environ.get(VARIABLE)
    if text is None or text.strip() == "":
        return available_cores()
    try:
        number = int(text)
    except ValueError:
        number = 0
    if number < 1:
        raise checks.fail(VARIABLE, text, "must be a whole number >= 1 (threads for CPU launches)")
    return number


#: elements a CPU thread of a chunked kernel takes (it first copies all its arguments, the structs' arrays too)
CPU_CHUNK = 256
#: elements a piece of a CPU launch holds at least: handing a piece to another thread costs about 10 us
MIN_PIECE = 16384


def chunked_launch(device, count: int) -> tuple[int, int, int]:
    """(elements a thread takes, threads, pieces at most) of a chunked kernel's launch over ``count`` elements:
    CPU_CHUNK a thread and a piece per MIN_PIECE elements on the CPU; one a thread, one piece on CUDA."""
    chunk = CPU_CHUNK if device.is_cpu else 1
    return chunk, -(-count // chunk), max(1, count // MIN_PIECE) if device.is_cpu else 1


class CpuPool:
    """``threads`` CPU threads: the caller's and threads - 1 workers, started at the first use (none for one)."""

    _shared: dict[int, CpuPool] = {}

    def __init__(self, threads: int):
        self.threads = threads
        self._workers: ThreadPoolExecutor | None = None
        self._pid = os.getpid()

    @classmethod
    def shared(cls, threads: int) -> CpuPool:
        """The process's pool of ``threads`` threads (one per count, so that Simulators share their workers)."""
        pool = cls._shared.get(threads)
        if pool is None:
            pool = cls._shared[threads] = cls(threads)
        return pool

    def call(self, calls: list[tuple]) -> None:
        """entry(byref(bounds), byref(arguments)) for every (entry, bounds, arguments) of ``calls`` (a CPU entry point,
        its launch bounds and arguments), the first on this thread and the rest on the workers at once; returns when
        all have."""
        if self._workers is None or self._pid != os.getpid():   # a forked child has none of its parent's threads
            self._workers = ThreadPoolExecutor(max(1, self.threads - 1), thread_name_prefix="warp_sim_cpu")
            self._pid = os.getpid()
        futures = [self._workers.submit(entry, ctypes.byref(bounds), ctypes.byref(arguments))
                   for entry, bounds, arguments in calls[1:]]
        entry, bounds, arguments = calls[0]
        try:
            entry(ctypes.byref(bounds), ctypes.byref(arguments))
            for future in futures:
                future.result()
        except BaseException:   # Ctrl-C or SIGTERM in the wait: no piece may still be writing once this returns
            wait(futures)
            raise

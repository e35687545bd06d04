"""Compiling the kernel modules: which are in Warp's kernel cache, how long the others take, one line before a
cold compile, the parallel load, and ahead-of-time compiles into the cache (``warp-sim prepare``).

Warp compiles a module once per precision and device and keeps the binary in its kernel cache
(``wp.config.kernel_cache_dir``: ``~/.cache/warp/<version>``, or ``WARP_CACHE_PATH``), in a folder named after
the module's hash. A module is cached for a device when that folder holds its binary for the device and its
meta file: the names ``Module.load`` looks for (``is_cached``). The hash covers the module's kernels and their
declared overloads (kernels.precisions), so a process that declared one precision finds only the binaries of a
process that declared that precision alone: ``prepare`` compiles one precision per process.

``load(names, device)`` is what a Simulator does at its start: the modules the simulation launches, the longest
first (kernels.COMPILE_SECONDS), with ``wp.force_load`` on ``workers`` threads (``cpu_threads()``: the available
cores, or WARP_SIM_CPU_THREADS; Warp's own default, ``wp.config.load_module_max_workers``, is 0, serial). When
some are not cached it first prints ``compiling kernels for cpu, once, about N s`` to stderr (``notice``; off
with ``set_notices(False)``), N the longest queue of an even split of their COMPILE_SECONDS over the workers plus
each worker's precompiled header (HEADER_SECONDS, built once per thread and process).

Every module sets ``enable_backward`` False at import, so nothing builds an adjoint unless a differentiable
Simulator asks: ``enable_adjoints(names)`` turns it on for its modules (the option is part of the hash, so that
build is cached apart, ADJOINT_FACTOR times as long to compile), for the rest of the process.
"""
from __future__ import annotations

import heapq
import pkgutil
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import warp as wp

from .. import kernels
from ..kernels import precisions
from .cpu_threads import cpu_threads

__all__ = ["is_cached", "pending", "estimate", "load", "module_names", "prepare", "notice", "set_notices",
           "seconds_compiling", "enable_adjoints", "adjoints_enabled", "HEADER_SECONDS", "CUDA_FACTOR",
           "ADJOINT_FACTOR"]

#: seconds a compile thread spends on its precompiled header before its first module (Warp builds one per thread
#: and process): 1.4 to 1.6 s on one core of a 2-core Xeon or EPYC (a thread's first module against the others)
HEADER_SECONDS = 1.5
#: NVRTC against the CPU compiler on one module, roughly: kernels.detection for sm_90 against the CPU, 8 s to 2.3 s
CUDA_FACTOR = 3.5
#: a module with its backward kernels against without (compiling.enable_adjoints): integrate, particles, springs
#: and rigid cold on one core, 3.2 s against 1.4 s after the header
ADJOINT_FACTOR = 2.3
#: the CUDA outputs of an ahead-of-time compile: Warp loads PTX where the driver is at least as new as its CUDA
#: toolkit, else CUBIN (``Device.get_cuda_output_format``), so a cache baked for another machine holds both
CUDA_OUTPUTS = ("ptx", "cubin")

_notices = [True]
_spent = [0.0]   # seconds this process spent in loads that compiled something
_lock = threading.Lock()


def set_notices(enabled: bool) -> None:
    """Print (True, the default) or not (False) the line before a cold compile."""
    if not isinstance(enabled, bool):
        raise ValueError(f"enabled={enabled!r} is invalid: expected True or False")
    _notices[0] = enabled


def notice(line: str) -> None:
    """One line on stderr, unless notices are off."""
    if _notices[0]:
        print(line, file=sys.stderr, flush=True)


def seconds_compiling() -> float:
    """Seconds this process has spent in ``load`` calls that compiled at least one module."""
    return _spent[0]


def _module(name: str):
    return wp.get_module(f"{kernels.__name__}.{name}")


def _block_dim(module, device) -> int:
    """The block_dim variant ``wp.force_load`` loads without one: 1 on the CPU, the module's (256) on CUDA."""
    if device.is_cpu:
        return 1
    return module.options["block_dim"] if module.options["block_dim"] > 0 else 256


def is_cached(name: str, device) -> bool:
    """Whether module ``name`` of warp_sim.kernels loads without compiling on ``device``: loaded in this process,
    or its binary and meta file for the device are in Warp's kernel cache (for the overloads declared now)."""
    wp.init()
    device = wp.get_device(device)
    module = _module(name)
    dim = _block_dim(module, device)
    loaded = module.execs.get((device.context, dim))
    if loaded is not None and loaded.module_hash == module.get_module_hash(dim):
        return True
    if not wp.config.cache_kernels:
        return False
    folder = Path(wp.config.kernel_cache_dir) / module.get_module_identifier(block_dim=dim)
    binary = module._get_compile_output_name(device, block_dim=dim)   # the names Module.load looks for (1.19)
    return (folder / binary).exists() and (folder / module._get_meta_name(block_dim=dim)).exists()


def adjoints_enabled(name: str) -> bool:
    """Whether module ``name`` of warp_sim.kernels builds its backward kernels (every module sets
    ``enable_backward`` False at import; ``enable_adjoints`` turns it on)."""
    return bool(_module(name).options.get("enable_backward"))


def enable_adjoints(names) -> list[str]:
    """Turn on the backward kernels of the modules ``names`` (a differentiable Simulator's, before it loads them):
    ``wp.set_module_options`` gives each module a new hash, so Warp builds it afresh with its adjoints, cached
    apart from its forward-only build, which every other process keeps loading. The modules keep their adjoints
    for the rest of this process (their forward kernels are the same code). Returns the names turned on now."""
    turned = [name for name in names if not adjoints_enabled(name)]
    for name in turned:
        wp.set_module_options({"enable_backward": True}, _module(name))
    return turned


def pending(names, device) -> list[str]:
    """The modules of ``names`` that would compile on ``device`` (not cached), in the order given."""
    return [name for name in names if not is_cached(name, device)]


def estimate(names, workers: int, cuda: bool = False, adjoints=()) -> float:
    """Seconds to compile ``names`` on ``workers`` threads: each thread's precompiled header, then the modules
    the longest first, each to the thread free first (kernels.COMPILE_SECONDS; CUDA_FACTOR times as long for
    CUDA, ADJOINT_FACTOR times for those of ``adjoints``, built with their backward kernels); the last thread's
    finish."""
    seconds = sorted((kernels.COMPILE_SECONDS.get(name, 0.5) * (ADJOINT_FACTOR if name in adjoints else 1.0)
                      for name in names), reverse=True)
    if not seconds:
        return 0.0
    queues = [HEADER_SECONDS] * max(1, min(workers, len(seconds)))
    for value in seconds:
        heapq.heappush(queues, heapq.heappop(queues) + value * (CUDA_FACTOR if cuda else 1.0))
    return max(queues)


def load(names, device, workers: int | None = None) -> float:
    """Compile (or load from Warp's cache) the modules ``names`` of warp_sim.kernels on ``device``, the longest
    first, on ``workers`` threads (default ``cpu_threads()``); before compiling any, one line says so and how
    long it takes (``notice``). Returns the seconds spent when something compiled, else 0."""
    wp.init()
    device = wp.get_device(device)
    workers = cpu_threads(workers)
    order = sorted(names, key=lambda name: -kernels.COMPILE_SECONDS.get(name, 0.0))
    todo = pending(order, device)
    started = time.perf_counter()
    if todo:
        seconds = estimate(todo, workers, cuda=device.is_cuda, adjoints=[n for n in todo if adjoints_enabled(n)])
        notice(f"compiling kernels for {device.alias}, once, about {max(1, round(seconds))} s")
    wp.force_load(device, modules=[_module(name) for name in order], max_workers=workers)
    if not todo:
        return 0.0
    spent = time.perf_counter() - started
    with _lock:
        _spent[0] += spent
    return spent


def module_names() -> list[str]:
    """Every module of warp_sim.kernels that holds kernels, the longest to compile first."""
    names = []
    for info in pkgutil.iter_modules(kernels.__path__):
        module = sys.modules.get(f"{kernels.__name__}.{info.name}")   # import warp_sim imports them all
        if module is not None and any(isinstance(value, wp.Kernel) and value.module.name == module.__name__
                                      for value in vars(module).values()):
            names.append(info.name)
    return sorted(names, key=lambda name: (-kernels.COMPILE_SECONDS.get(name, 0.0), name))


PRECISIONS = {"float32": wp.float32, "float64": wp.float64}


def _declare_alone(precision: str) -> None:
    """Declare the overloads of ``precision``, refusing a process that declared the other one (its modules' hashes
    then cover both, which no simulation of one precision looks up)."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision={precision!r} is invalid: expected 'float32' or 'float64'")
    others = [scalar for scalar in precisions._declared if scalar is not PRECISIONS[precision]]
    if others:
        raise ValueError(f"precision={precision!r} is invalid: this process already declared the kernels' other "
                         "precision; prepare each precision in a fresh process (warp-sim prepare does)")
    precisions.declare(PRECISIONS[precision])


def _cpu_job(name: str) -> tuple[str, str, str, float]:
    device = wp.get_device("cpu")
    if is_cached(name, device):
        return name, "cpu", "cached", 0.0
    started = time.perf_counter()
    wp.force_load(device, modules=[_module(name)], max_workers=0)
    return name, "cpu", "compiled", time.perf_counter() - started


def _cuda_job(name: str, arch: int, outputs: tuple[str, ...]) -> tuple[str, str, str, float]:
    module = _module(name)
    folder = Path(wp.config.kernel_cache_dir) / module.get_module_identifier(block_dim=_block_dim(module, _CUDA))
    suffix = {"ptx": ".ptx", "cubin": ".cubin"}
    missing = [kind for kind in outputs
               if not (folder / f"{folder.name}.sm{arch}{suffix[kind]}").exists()
               or not (folder / f"{folder.name}.meta").exists()]
    if not missing:
        return name, f"sm_{arch}", "cached", 0.0
    started = time.perf_counter()
    for kind in missing:
        wp.compile_aot_module(module, device=None, arch=arch, use_ptx=kind == "ptx")
    return name, f"sm_{arch}", f"compiled {', '.join(missing)}", time.perf_counter() - started


class _AnyCuda:
    """A stand-in device for _block_dim on a machine that may have no GPU."""
    is_cpu = False


_CUDA = _AnyCuda()


def prepare(precision: str, arches=(), names=None, workers: int | None = None, cpu: bool = True,
            outputs=CUDA_OUTPUTS, report=None) -> list[tuple[str, str, str, float]]:
    """Compile the kernel modules ``names`` (default: all, ``module_names()``) into Warp's kernel cache for
    ``precision`` ("float32" or "float64", declared alone: call it in a process that simulated nothing else) on
    the local CPU (unless ``cpu=False``) and for each CUDA architecture of ``arches`` (ints such as 80, 90; NVRTC
    compiles them with no GPU and no driver), both PTX and CUBIN (``outputs``), on ``workers`` threads.

    ``report(row)`` is called as each (module, target) finishes; returns the rows, (module, target, "cached" or
    "compiled ...", seconds)."""
    _declare_alone(precision)
    wp.init()
    names = module_names() if names is None else list(names)
    unknown = sorted(set(names) - set(module_names()))
    if unknown:
        raise ValueError(f"names={unknown!r} is invalid: expected modules of warp_sim.kernels with kernels, "
                         f"{', '.join(module_names())}")
    arches = [int(arch) for arch in arches]
    outputs = tuple(outputs)
    if not outputs or any(kind not in CUDA_OUTPUTS for kind in outputs):
        raise ValueError(f"outputs={outputs!r} is invalid: expected some of {', '.join(CUDA_OUTPUTS)}")
    rows = []
    with ThreadPoolExecutor(max_workers=cpu_threads(workers)) as pool:
        jobs = ([pool.submit(_cpu_job, name) for name in names] if cpu else []) + [
            pool.submit(_cuda_job, name, arch, outputs) for arch in arches for name in names]
        for job in as_completed(jobs):
            rows.append(job.result())
            if report is not None:
                report(rows[-1])
    return rows

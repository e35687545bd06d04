"""Recorded kernel launches: resolve a kernel's overload and pack its arguments once.

A simulator launches the same kernels on the same arrays every step (its two
states alternate), so each distinct (kernel, arrays and structs) launch is recorded once
with Warp's ``record_cmd`` and replayed, with only its scalar arguments (a step size,
a colour's first manifold) and its thread count set again. Arrays and struct arguments
(kernels.blocks) are keyed by identity: a struct must not have its fields reassigned after
its first launch (make a new one instead, as the growable contact buffers do).

On the CPU a replay calls the kernel's compiled entry point with an argument struct built
once (Warp's own ``Launch.launch`` rebuilds it on every call): about 1 us a launch instead
of 7 here, which is what small scenes and the colour-by-colour contact solve are bound by.
Where this Warp's internals differ from what the fast path expects, it falls back to
``Launch.launch``.
"""
from __future__ import annotations

import ctypes
import time
from collections import Counter

import warp as wp

_KINDS: dict[type, bool] = {}   # argument type -> passed by reference (filled as types are seen)


def _referenced(argument) -> bool:
    """Whether a launch argument is passed by reference (an array, or a struct of arrays), not by value."""
    kind = _KINDS.get(type(argument))
    if kind is None:
        kind = _KINDS[type(argument)] = isinstance(argument, wp.array) or hasattr(getattr(argument, "_cls", None),
                                                                                   "vars")
    return kind


def _identities(inputs: list) -> list:
    """Per input, its id() if it is passed by reference (the part of a recorded launch's key), else None. A launch
    key is built on every launch, so the type's kind is looked up inline (half the time of calling _referenced)."""
    kinds = _KINDS
    return [id(a) if (kinds.get(type(a)) or (type(a) not in kinds and _referenced(a))) else None for a in inputs]


def _direct_entry(command):
    """(forward entry point, argument struct, field names) to call a recorded CPU launch directly, or None."""
    if not command.device.is_cpu or getattr(command, "block_dim", 1) > 1 or command.adjoint:
        return None
    try:
        cached = command.kernel._invoke_cache.get((tuple(type(p) for p in command.params[1:]), False))
        struct_type, fields = cached
        arguments = struct_type()
        names = [name for name, _ in fields]
        for i, name in enumerate(names):
            setattr(arguments, name, command.params[1 + i])
        bounds = command.params[0]
        if type(bounds).__name__ != "launch_bounds_1d_t" or bounds.coord_mult != 1:
            return None
        return command.hooks.forward, arguments, names
    except (AttributeError, TypeError, ValueError):
        return None


class Prepared:
    """One recorded launch, to replay with new scalars and thread counts (``Launcher.prepare``): ``set(i, value)``
    sets input i (a scalar), ``run(dim)`` launches. A loop that launches one kernel many times (one launch
    per colour of the contact solve) holds one and pays only for what changes."""

    __slots__ = ("launcher", "command", "scalars", "inputs", "dim", "direct", "values", "simple", "bound")

    def __init__(self, launcher, command, inputs, dim):
        self.launcher, self.command, self.inputs, self.dim = launcher, command, inputs, dim
        self.scalars = [i for i, a in enumerate(inputs) if not _referenced(a)]
        self.values = {i: inputs[i] for i in self.scalars}   # the scalars last packed
        self.direct = None
        self.simple = set()   # scalar inputs whose packed field is a plain ctypes number, set without packing
        self.bound = False

    def _bind_direct(self) -> None:
        """After the first launch: find the direct CPU entry point, if this Warp and launch allow one."""
        self.bound = True
        self.direct = _direct_entry(self.command)
        if self.direct is not None:
            fields = type(self.direct[1])._fields_
            self.simple = {i for i in self.scalars if issubclass(fields[i][1], ctypes._SimpleCData)
                           and type(self.inputs[i]) in (int, float)}

    def set(self, i: int, value) -> None:
        """Input i (a scalar) is ``value`` from the next run on."""
        if value is self.values[i] or value == self.values[i]:
            return
        self.values[i] = value
        if self.direct is not None and i in self.simple and type(value) in (int, float):
            setattr(self.direct[1], self.direct[2][i], value)
            return
        self.command.set_param_at_index(i, value)
        if self.direct is not None:
            setattr(self.direct[1], self.direct[2][i], self.command.params[1 + i])

    def run(self, dim: int) -> None:
        """Launch over ``dim`` threads."""
        if dim == 0:
            return
        launcher = self.launcher
        launcher.launches += 1
        if dim == 1:
            launcher.single_thread[self.command.kernel.key] += 1
        if launcher.log is not None:
            launcher.log.append((self.command.kernel.key, dim))
        if launcher.profile is not None:
            self._timed(dim)
            return
        self._run(dim)

    def sweep(self, i: int, launches: list[tuple[int, int]], repeats: int = 1) -> None:
        """``repeats`` times: for each (value, dim) of ``launches``, set input i (an int) to value and run dim
        threads (a contact solve's colours: input i is the colour's first manifold). One call for a whole
        sweep, so on the CPU's direct path each launch costs little more than the call itself."""
        launcher = self.launcher
        if (self.direct is None or i not in self.simple or launcher.log is not None or launcher.profile is not None
                or launcher.capturing):
            for _ in range(repeats):
                for value, dim in launches:
                    self.set(i, value)
                    self.run(dim)
            return
        forward, arguments, names = self.direct
        name, bounds, shape = names[i], self.command.params[0], self.command.params[0].shape
        by_bounds, by_arguments = ctypes.byref(bounds), ctypes.byref(arguments)
        for _ in range(repeats):
            for value, dim in launches:
                setattr(arguments, name, value)
                shape[0] = dim
                bounds.size = dim
                forward(by_bounds, by_arguments)
        single = sum(1 for _, dim in launches if dim == 1) * repeats
        launcher.launches += len(launches) * repeats
        if single:
            launcher.single_thread[self.command.kernel.key] += single
        if launches:
            self.dim, self.values[i] = launches[-1][1], launches[-1][0]

    def run_pieces(self, dim: int, base: int, pieces: int) -> None:
        """Launch over ``dim`` threads as up to ``pieces`` pieces at once on the launcher's pool (core.cpu_threads),
        where input ``base`` (an int) is a piece's first thread, which the kernel adds to wp.tid(). Only for kernels
        whose threads write disjoint elements. One piece (base 0) off the direct CPU path, or while logged,
        profiled or captured."""
        launcher = self.launcher
        pool = launcher.pool
        pieces = min(pieces, pool.threads if pool is not None else 1, dim)
        if (pieces <= 1 or self.direct is None or launcher.log is not None or launcher.profile is not None
                or launcher.capturing or base not in self.simple):
            self.set(base, 0)
            self.run(dim)
            return
        forward, arguments, names = self.direct
        calls = []
        for piece in range(pieces):
            first, end = piece * dim // pieces, (piece + 1) * dim // pieces
            bounds = type(self.command.params[0]).from_buffer_copy(self.command.params[0])
            bounds.shape[0] = bounds.size = end - first
            piece_arguments = type(arguments).from_buffer_copy(arguments)
            setattr(piece_arguments, names[base], first)
            calls.append((forward, bounds, piece_arguments))
        launcher.launches += 1
        pool.call(calls)

    def _timed(self, dim: int) -> None:
        """run() with the device synchronised around the launch, its time and argument bytes added to the
        launcher's profile."""
        device = self.command.device
        wp.synchronize_device(device)
        start = time.perf_counter()
        self._run(dim)
        wp.synchronize_device(device)
        entry = self.launcher.profile.setdefault(self.command.kernel.key, [0, 0.0, 0])
        entry[0] += 1
        entry[1] += time.perf_counter() - start
        entry[2] += sum(a.size * wp.types.type_size_in_bytes(a.dtype) for a in self.inputs if isinstance(a, wp.array))

    def _run(self, dim: int) -> None:
        command = self.command
        if self.direct is None or self.launcher.capturing:   # through Warp, which records it in a capture
            for i in self.simple:   # scalars the direct path set in its own struct only
                command.set_param_at_index(i, self.values[i])
            if dim != self.dim:
                command.set_dim(dim)
                self.dim = dim
            command.launch()
            if not self.bound:
                self._bind_direct()
            return
        bounds = command.params[0]
        if dim != self.dim:   # a 1-D launch: its shape and size (coord_mult stays 1)
            bounds.shape[0] = dim
            bounds.size = dim
            self.dim = dim
        self.direct[0](ctypes.byref(bounds), ctypes.byref(self.direct[1]))


class Launcher:
    """Launch kernels on one device through a cache of recorded launches.

    The cache keeps the arrays it was recorded with alive, so a cached launch never
    points at freed memory; it lives as long as the owner (one per Model). A caller
    that passes new arrays on every call would fill it: past ``capacity`` entries it
    starts afresh, so memory stays bounded (and such calls cost a normal launch).

    launches: kernel launches so far; single_thread: a count per kernel name of launches with one thread;
    log: None, or a list each launch appends (kernel name, threads) to;
    profile: None, or a dict each launch adds to, per kernel name [launches, seconds, argument bytes], the device
        synchronised around each launch (benchmarks/common.KernelProfile)
    capturing: True while core.capture records a graph: every launch then goes through Warp
    pool: None, or the CPU threads a launch split into pieces runs on (Prepared.run_pieces, launch_elementwise;
        core.cpu_threads)
    """

    capacity = 512
    elementwise_piece = 32768   # elements a piece of launch_elementwise holds at least (a hand-off costs ~10 us)

    def __init__(self, device):
        self.device = device
        self._recorded: dict[tuple, Prepared] = {}
        self.launches = 0
        self.single_thread: Counter = Counter()
        self.log: list | None = None
        self.profile: dict | None = None
        self.capturing = False   # a graph is being recorded (core.capture): no direct CPU calls
        self.pool = None   # the CPU threads of run_pieces (core.cpu_threads.CpuPool; None: one)
        self._split: dict[tuple, list] = {}   # launch_elementwise's pieces: (Prepared on views, threads) each

    def prepare(self, kernel, dim: int, inputs: list) -> Prepared:
        """The recorded launch of ``kernel`` on these arrays and structs (recorded now if new), its scalars set
        to those in ``inputs``; ``run(dim)`` launches it."""
        key = (kernel, *_identities(inputs))
        prepared = self._recorded.get(key)
        if prepared is None:
            if len(self._recorded) >= self.capacity:
                self._recorded.clear()
            command = wp.launch(kernel, dim=max(dim, 1), inputs=inputs, device=self.device, record_cmd=True)
            prepared = self._recorded[key] = Prepared(self, command, inputs, max(dim, 1))
            return prepared
        for i in prepared.scalars:
            prepared.set(i, inputs[i])
        return prepared

    def launch(self, kernel, dim: int, inputs: list) -> None:
        """Run ``kernel`` over ``dim`` threads with ``inputs`` (arrays and scalars)."""
        if dim == 0:
            return
        self.prepare(kernel, dim, inputs).run(dim)

    def off_tape(self, kernel, dim: int, inputs: list) -> None:
        """launch() of a launch no wp.Tape may record (the guard's checks; core.tape keeps it off the tape)."""
        self.launch(kernel, dim, inputs)

    def launch_in_place(self, kernel, dim: int, inputs: list, written) -> None:
        """launch() of a kernel that overwrites ``written``, one of its inputs, in place (core.tape restores its
        values around the adjoint; here nothing more)."""
        self.launch(kernel, dim, inputs)

    def launch_elementwise(self, kernel, dim: int, inputs: list) -> None:
        """launch() of a kernel whose thread i writes element i of its arrays of length ``dim`` and reads only
        element i of them (other arrays: read whole). On the CPU's pool (core.cpu_threads), from 2 x
        elementwise_piece elements, it runs as pieces at once, each the same kernel over views of those arrays
        (recorded once per split); the same result element by element."""
        pool = self.pool
        pieces = 1 if pool is None else min(pool.threads, dim // self.elementwise_piece)
        if pieces <= 1 or self.capturing or self.log is not None or self.profile is not None:
            self.launch(kernel, dim, inputs)
            return
        key = (kernel, dim, pieces, *_identities(inputs))
        split = self._split.get(key)
        if split is None:
            if len(self._split) >= self.capacity:
                self._split.clear()
            cuts = [k * dim // pieces for k in range(pieces + 1)]
            split = self._split[key] = [
                (self.prepare(kernel, end - first, [a[first:end] if isinstance(a, wp.array) and a.shape[0] == dim
                                                    else a for a in inputs]), end - first)
                for first, end in zip(cuts, cuts[1:])]
        for prepared, _ in split:
            for i in prepared.scalars:
                prepared.set(i, inputs[i])
        if any(prepared.direct is None for prepared, _ in split):   # not yet launched once: one after another
            for prepared, threads in split:
                prepared.run(threads)
            return
        self.launches += 1
        pool.call([(p.direct[0], p.command.params[0], p.direct[1]) for p, _ in split])

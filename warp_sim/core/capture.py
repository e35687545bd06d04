"""Captured steps: a simulation's step recorded once as a Warp graph and replayed (CUDA graphs; on the CPU, Warp's
API capture, replayed in C++), so a step costs its kernels and one call instead of one Python call per launch.

A graph bakes in every launch's arrays, thread counts and scalars, so only steps whose launches are the same
every time can be captured: a fixed step size, no host read-back that sizes a launch (contact counts, colourings,
convergence tests), no scalar that changes from step to step (the time) and no array replaced after recording.
Each part says whether it qualifies (``capturable``); ``Simulator(capture=True)`` captures only where all of its
parts do. A graph is kept per (piece size, which of the two States is current). Parts whose buffers grow (the body
contacts) launch over headroom, gated on the device, and say after a replay whether it held (``Pass.replay_held``).
"""
from __future__ import annotations

import warp as wp


class StepGraphs:
    """The recorded graphs of one simulation's step, by key; ``step(key, record, prepare)`` replays or records.

    recorded: graphs recorded so far; replays: steps replayed from a graph; missed: replays whose launches did not
        hold the step (a buffer or colouring outgrew them), each done again uncaptured; every graph is recorded
        afresh once a buffer was reallocated or ``refresh`` misses came close together (each ``forgive`` replays
        that held forget one; until then the graphs are kept and replayed on)
    waiting: steps still to run uncaptured before the next recording (the first step runs uncaptured: it allocates
        what a capture would only record, and sizes the launches of what can grow; after graphs are dropped for
        misses, ``backoff`` steps)
    backoff: uncaptured steps after graphs are dropped: doubled each time (at most ``longest_backoff``), halved
        after every ``calm`` replays that held. A recording costs as much as a hundred steps on the CPU (Warp
        records each launch's arguments in Python), so a scene whose contacts change often (a pile landing) runs
        mostly uncaptured, and one that settles is captured again.
    """

    limit = 8   # graphs kept (distinct step sizes and parities); past it they are dropped and recorded again
    first_backoff, longest_backoff, calm, refresh, forgive = 64, 1024, 1000, 4, 100

    def __init__(self, model):
        self.model = model
        self.graphs: dict = {}
        self.recorded = 0
        self.replays = 0
        self.missed = 0
        self.waiting = 1
        self.backoff = self.first_backoff
        self._misses = 0   # since the last recording, less one per ``forgive`` replays that held

    def step(self, key, record, prepare) -> bool:
        """Launch the graph recorded under ``key``; the first time, call ``prepare()`` (True: the graphs recorded
        before are stale, and dropped), then record the graph from ``record()`` (which runs the step's host side
        once, its launches only recorded) and launch it. Returns True for a replay, after which the caller repeats
        the step's host-side effects (the State swap)."""
        graph = self.graphs.get(key)
        replay = graph is not None
        if not replay:
            if prepare():
                self.graphs.clear()
            if len(self.graphs) >= self.limit:
                self.graphs.clear()
            launcher = self.model.launcher
            launcher.capturing = True   # launches go through Warp, which records them
            try:
                with wp.ScopedCapture(device=self.model.device) as capture:
                    record()
            finally:
                launcher.capturing = False
            graph = self.graphs[key] = capture.graph
            self.recorded += 1
            self._misses = 0
        else:
            self.replays += 1
        wp.capture_launch(graph)
        return replay

    def held(self) -> None:
        """A replay's launches held its step (every ``forgive`` of them forget a miss, every ``calm`` halve the
        backoff)."""
        if self.replays % self.forgive == 0:
            self._misses = max(0, self._misses - 1)
        if self.replays % self.calm == 0:
            self.backoff = max(1, self.backoff // 2)

    def invalidate(self) -> None:
        """Drop every graph (an array they launch on was replaced): the next steps record afresh."""
        self.graphs.clear()

    def miss(self, intact: bool) -> None:
        """A replay's launches did not hold its step (the caller did it again uncaptured): count it, and drop every
        graph if a buffer they launch on was reallocated (not ``intact``) or ``refresh`` misses came since the
        last recording; the next recording then waits ``backoff`` steps."""
        self.missed += 1
        self._misses += 1
        if intact and self._misses < self.refresh:
            return
        self.waiting = self.backoff
        self.backoff = min(2 * self.backoff, self.longest_backoff)
        self.invalidate()

"""Captured steps: a simulation's step recorded once as a Warp graph and replayed (CUDA graphs; on the CPU, Warp's
API capture, replayed in C++), so a step costs its kernels and one call instead of one Python call per launch.

A graph bakes in every launch's arrays, thread counts and scalars, so only steps whose launches are the same
every time can be captured: a fixed step size, no host read-back that sizes a launch (contact counts, colourings,
convergence tests), no scalar that changes from step to step (the time) and no array replaced after recording.
Each part says whether it qualifies (``capturable``); ``Simulator(capture=True)`` captures only where all of its
parts do. A graph is kept per (step size, which of the two States is current) and remade when either changes.
"""
from __future__ import annotations

import warp as wp


class StepGraphs:
    """The recorded graphs of one simulation's step, by key; ``step(key, record)`` replays or records.

    recorded: graphs recorded so far; replays: steps replayed from a graph; missed: replays whose launches did not
        hold the step (a buffer or colouring outgrew them), each done again uncaptured, after which every graph is
        recorded afresh; primed: whether a step ran uncaptured since the start or the last miss (the first step
        runs uncaptured: it allocates what a capture would only record, and sizes the launches of what can grow)
    """

    limit = 8   # graphs kept (distinct step sizes and parities); past it they are dropped and recorded again

    def __init__(self, model):
        self.model = model
        self.graphs: dict = {}
        self.recorded = 0
        self.replays = 0
        self.missed = 0
        self.primed = False

    def step(self, key, record, prepare) -> bool:
        """Launch the graph recorded under ``key``; the first time, call ``prepare()``, then record the graph from
        ``record()`` (which runs the step's host side once, its launches only recorded) and launch it. Returns
        True for a replay, after which the caller repeats the step's host-side effects (the State swap)."""
        graph = self.graphs.get(key)
        replay = graph is not None
        if not replay:
            prepare()
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
        else:
            self.replays += 1
        wp.capture_launch(graph)
        return replay

    def invalidate(self) -> None:
        """Drop every graph (an array they launch on was replaced): the next steps record afresh."""
        self.graphs.clear()

    def miss(self) -> None:
        """A replay's launches did not hold its step: count it and drop every graph (the step done again
        uncaptured grows what was too small, and changes the launches)."""
        self.missed += 1
        self.primed = False
        self.invalidate()

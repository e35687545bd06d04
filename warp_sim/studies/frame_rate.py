"""Substeps at frame rate: the fewest equal substeps of a 1/60 s step at which each solver holds a scene, found by
bisection on the count, beside the count ``substeps="auto"`` chooses (``Simulator.substeps``).

A scene holds at n substeps when ``sim.step(FRAME, substeps=n)`` for its run's seconds (guard on) never diverges,
every particle stays within REACH of where the scene began (its bounding box grown by REACH) and no particle is
faster than MAX_SPEED. The search tries the auto count first, then bisects between 1 and it (or doubles it until
one holds), assuming that more substeps never hold worse.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..core.guards import SimulationDiverged
from ..demo import JOINT_STEP, demo_scene
from ..scene import Scene
from ..simulator import Simulator
from ..solvers.stability import unchecked_steps

FRAME = 1.0 / 60.0     # [s] the step a user takes
REACH = 10.0           # [m] how far outside the scene's starting bounding box a particle may go
MAX_SPEED = 200.0      # [m/s] the fastest a particle of these scenes may move (they move at a few m/s)
BENCHMARK_CLOTH = {"size": (1.0, 1.0), "position": (0.0, 1.0, 0.0), "density": 0.2, "pinned": ["top_corners"],
                   "stiffness": (1.0e4, 1.0e4, 1.0e3), "damping": (0.01, 0.01, 0.001)}   # benchmarks/cloth.py's


def benchmark_cloth(resolution: int) -> Scene:
    """The cloth of benchmarks/cloth.py: 1 m square, resolution^2 vertices, 0.2 kg/m^2, hanging from its top
    corners, stiffness 1e4, 1e4, 1e3 N/m, gravity, float32."""
    scene = Scene(gravity=(0.0, -9.81, 0.0), precision="float32")
    scene.add_cloth_grid(resolution=(resolution, resolution), **BENCHMARK_CLOTH)
    return scene


@dataclass(frozen=True)
class FrameScene:
    """One scene of the frame-rate cases: build() -> Scene, seconds [s] of each run, its title, and the Simulator
    options it runs with (the demo's joint_step, as `warp-sim demo` runs it)."""
    name: str
    title: str
    build: Callable[[], Scene]
    seconds: float
    options: dict = field(default_factory=dict)


FRAME_SCENES = {scene.name: scene for scene in (
    FrameScene("demo", "the demo scene (warp_sim.demo), 2 s", demo_scene, 2.0, {"joint_step": JOINT_STEP}),
    FrameScene("cloth_32", "the benchmark's 32 x 32 cloth, 1 s", lambda: benchmark_cloth(32), 1.0),
    FrameScene("cloth_64", "the benchmark's 64 x 64 cloth, 0.5 s", lambda: benchmark_cloth(64), 0.5),
    FrameScene("cloth_128", "the benchmark's 128 x 128 cloth, 0.25 s", lambda: benchmark_cloth(128), 0.25),
)}
QUICK_FRAME_SCENES = ("demo", "cloth_32")
FRAME_SOLVERS = ("rk4", "symplectic_euler", "verlet")


def holds(scene: FrameScene, integrator: str, substeps: int, device: str) -> bool:
    """Whether ``scene`` stays finite and in place for its seconds at sim.step(FRAME, substeps=substeps)."""
    built = scene.build()
    start = built.particle_array("position")
    low, high = start.min(axis=0) - REACH, start.max(axis=0) + REACH
    with unchecked_steps():   # the warning that substeps are too few is what is being measured
        sim = Simulator(built, integrator=integrator, device=device, **scene.options)
        try:
            for _ in range(round(scene.seconds / FRAME)):
                sim.step(FRAME, substeps=substeps)
                x = sim.state.particle_x.numpy()[:len(start)]
                v = sim.state.particle_v.numpy()[:len(start)]
                if (x < low).any() or (x > high).any() or (np.sum(v * v, axis=1) > MAX_SPEED**2).any():
                    return False
        except SimulationDiverged:
            return False
    return True


def frame_rate_row(name: str, integrator: str, device: str) -> dict:
    """{"scene", "integrator", "auto": substeps="auto"'s count at FRAME, "fewest": the fewest substeps that
    hold, "ratio": auto / fewest, "probes": runs made}."""
    scene = FRAME_SCENES[name]
    with unchecked_steps():
        auto = Simulator(scene.build(), integrator=integrator, device=device, **scene.options).substeps(FRAME)
    probes = 1
    high = auto
    while not holds(scene, integrator, high, device):   # auto fails: double until a count holds
        high, probes = 2 * high, probes + 1
    low = 0   # counts <= low fail (0: none tried)
    while high - low > 1:
        middle = (low + high) // 2
        probes += 1
        if holds(scene, integrator, middle, device):
            high = middle
        else:
            low = middle
    return {"scene": name, "integrator": integrator, "auto": auto, "fewest": high, "ratio": auto / high,
            "probes": probes}

"""Simulator: builds a scene on a device and advances it; step, run, guards, progress, USD."""
from __future__ import annotations

import warp as wp

from . import checks
from .collision import RESPONSES, PlaneImpacts, PlanePenalty
from .dynamics import Dynamics
from .guards import Guard, SimulationDiverged
from .integrators import make_integrator
from .model import Model
from .scene import Scene


def resolve_device(device: str | None) -> str:
    """The Warp device alias to run on: the given one, or "cuda" when a GPU is present, else "cpu"."""
    if device is None:
        return "cuda" if wp.get_cuda_device_count() > 0 else "cpu"
    valid = [d.alias for d in wp.get_devices()]
    if device == "cuda" and wp.get_cuda_device_count() > 0:
        return device
    if device not in valid:
        raise checks.fail("device", device, f"expected one of {', '.join(valid)} (or None for automatic)")
    return device


def stage_layout(scene: Scene):
    """The USD StageLayout of a scene: its particle groups, springs and planes."""
    from .stages import PlaneSpec, PointsGroup, StageLayout

    radius = scene.particle_array("radius")
    groups = tuple(PointsGroup(g.name, g.start, g.count, 2.0 * radius[g.start:g.start + g.count], g.color)
                   for g in scene.particle_groups)
    planes = tuple(PlaneSpec(p.name, tuple(p.normal), p.offset) for p in scene.planes)
    springs = scene.spring_array("pairs") if scene.spring_count else None
    return StageLayout(points_groups=groups, springs=springs, planes=planes)


class Simulator:
    """Runs a Scene on a device with one ODE solver.

    integrator: one of warp_sim.INTEGRATORS; device: a Warp device alias, or None
    for CUDA when present, else the CPU; contact: "impulse" (time of impact,
    default) or "penalty" (spring and damper on penetration); penalty_stiffness
    [N/m]; guard: check for non-finite values and speeds above max_speed [m/s]
    after every step (read every step() and every frame of run()).

    ``state`` holds the current State; it is a new object after each step (the
    solver writes into a second state and the two are swapped), so read
    ``sim.state.particle_x`` afresh rather than keeping the array.
    """

    def __init__(self, scene: Scene, integrator: str = "rk4", device: str | None = None,
                 contact: str = "impulse", penalty_stiffness: float = 1.0e4, guard: bool = True,
                 max_speed: float = 1.0e4):
        if not isinstance(scene, Scene):
            raise checks.fail("scene", scene, "expected a warp_sim.Scene")
        if scene.particle_count == 0:
            raise checks.fail("scene", scene, "the scene has nothing to simulate; add particles first")
        contact = checks.choice("contact", contact, RESPONSES)
        stiffness = checks.scalar("penalty_stiffness", penalty_stiffness, low=0.0, low_open=True)
        speed = checks.scalar("max_speed", max_speed, low=0.0, low_open=True)
        self.model = Model(scene, resolve_device(device))
        penalty = [PlanePenalty(self.model, stiffness)] if contact == "penalty" and self.model.plane_count else []
        self.dynamics = Dynamics(self.model, penalty)
        self.integrator = make_integrator(integrator, self.dynamics)
        self.impacts = PlaneImpacts(self.model) if contact == "impulse" and self.model.plane_count else None
        self.state = self.dynamics.initial_state()
        self._next = self.dynamics.new_state()
        self.guard = Guard(self.model, self.dynamics.components, speed) if guard else None
        self.time = 0.0
        self.step_count = 0

    @property
    def device(self):
        return self.model.device

    def step(self, dt: float) -> None:
        """Advance by one step of dt seconds, then check the guards."""
        self._advance(checks.scalar("dt", dt, low=0.0, low_open=True))
        self.check()

    def check(self) -> None:
        """Raise SimulationDiverged if any step so far went non-finite or too fast."""
        if self.guard is not None:
            self.guard.raise_if_diverged(self.state)

    def _advance(self, h: float) -> None:
        self.integrator.step(self.state, self._next, self.time, h)
        if self.impacts is not None:
            self.impacts.apply(self.state, self._next, h)
        self.dynamics.post_step(self._next)
        self.state, self._next = self._next, self.state
        self.step_count += 1
        self.time += h
        if self.guard is not None:
            self.guard.record(self.state, self.step_count, self.time)

    def run(self, seconds: float, fps: float = 60.0, substeps: int = 8, usd=None, progress: bool = True,
            chunk_frames: int = 240):
        """Simulate round(seconds * fps) frames of `substeps` steps each, writing each frame to USD.

        Frame k (time code k) holds the state at run start + k / fps; frame 0 is the
        state before the first step. usd: output path (.usdc, .usd or .usda) or None.
        On divergence the stage keeps every frame before the bad one and
        SimulationDiverged propagates; any other interruption leaves no file.
        Returns the written path (a pathlib.Path), or None without usd.
        """
        seconds = checks.scalar("seconds", seconds, low=0.0, low_open=True)
        fps = checks.scalar("fps", fps, low=0.0, low_open=True)
        if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
            raise checks.fail("substeps", substeps, "expected an integer >= 1")
        frames = int(round(seconds * fps))
        if frames < 1:
            raise checks.fail("seconds", seconds, f"covers no frame at fps={fps}; need seconds >= {0.5 / fps:g}")
        from tqdm.auto import tqdm

        from .stages import StageWriter

        h = 1.0 / (fps * substeps)
        start_time = self.time
        writer = StageWriter(usd, fps, stage_layout(self.model.scene), chunk_frames) if usd is not None else None
        try:
            with tqdm(total=frames, unit="frame", disable=None if progress else True, desc="simulating") as bar:
                for frame in range(frames):
                    if frame > 0:
                        for _ in range(substeps):
                            self._advance(h)
                        self.time = start_time + frame / fps
                        self.check()
                    if writer is not None:
                        writer.write_frame(frame, self.state.particle_x.numpy(), self.state.particle_v.numpy())
                    bar.update(1)
        except SimulationDiverged:
            if writer is not None:
                writer.close()
            raise
        except BaseException:
            if writer is not None:
                writer.abort()
            raise
        return writer.close() if writer is not None else None


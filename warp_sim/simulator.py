"""Simulator: the loop. Each step: the solver, then the passes in order, then the guard; frames() and run()."""
from __future__ import annotations

import warnings

import numpy as np
import warp as wp

from .adjoints import make_differentiable
from .assembly import RESPONSES, assemble
from .core import compiling, persistence
from .core.capture import StepGraphs
from .core.cpu_threads import CpuPool
from .core.cpu_threads import cpu_threads as cpu_threads_for
from .core.guards import Guard, SimulationDiverged
from .core.persistence import Persistent
from .kernels import rigid as rigid_kernels
from .scene import Scene
from .solvers.stability import step_limit
from .solvers.substeps import Substeps
from .stages import StageWriter, stage_layout
from .stages.overlay import Overlay
from .util import checks
from .util.fingerprint import fingerprint
from .util.interrupts import RunInterrupted, interruptions, raise_pending  # noqa: F401 (RunInterrupted: public here)
from .util.progress import tqdm
from .util.version import __version__


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


#: the largest finite float32 [-]: a frame with a larger value is divergence (a stage stores float32)
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: an adaptive solver taking more internal steps than this for one frame gets a warning (once per run)
SLOW_FRAME_STEPS = 1000


class Simulator(Persistent):
    """Runs a Scene on a device with one ODE solver.

    integrator: a solver name (one of warp_sim.INTEGRATORS) or a solver instance such as
        ``ws.RK45(rtol=1e-8, atol=1e-10)`` or ``ws.ImplicitEuler(tolerance=1e-8)`` (made for this Simulator)
    device: a Warp device alias, or None for CUDA when present, else the CPU
    contact: "impulse" (time of impact, default) or "penalty" (spring and damper on penetration)
    penalty_stiffness: the penalty contacts' spring [N/m]; their damper makes a contact rebound with its
        restitution e (kernels.penalty; e below exp(-2) = 0.135 gets critical damping and rebounds with 0.135)
    guard: check for non-finite values and speeds above max_speed after every step (read every step()
        and every frame of run())
    max_speed: the guard's speed bound [m/s]
    contact_margin: the gap at which bodies count as touching [m]
    collisions: False leaves contacts with bodies and colliders out (bodies pass through each other, colliders
        and planes, particles through bodies and colliders; particles still meet planes)
    contact_step: the longest step the impulse response between bodies takes [s]: a longer ``step(dt)`` is
        split into equal sub-steps inside step() (sim.step(1/60) takes two of 1/120 s), which is what holds
        stacks and landing piles at frame rate; None never splits (``sim.substeps(dt)`` says how many)
    joint_step: likewise the longest step a scene with joints takes [s] (by default 1/480 s: sim.step(1/60) takes
        eight), at which a 20-link chain holds within 0.5 mm and a 100:1 mass ratio within 0.6 %; None: no split
    fused: take the fused step where the scene has one (particles and cloth under symplectic_euler, with their
        plane impulses and guard in one launch; ``sim.fused`` is it, or None), the same states bit for bit as
        the generic path; False: always the generic path
    capture: record each step (each piece of it) as a Warp graph on its first use (per step size) and replay it
        (core.capture: CUDA graphs, Warp's API capture on the CPU), where every part of the scene allows it
        (``sim.captured``): fixed-step solvers, particles, cloth, bodies and their impulse contacts, planes,
        time-independent fields; the same states bit for bit. A step whose contacts outgrow the recorded launches is
        done again uncaptured and the graphs recorded afresh. Otherwise a warning names the parts that do not allow
        it, and it runs uncaptured
    cpu_threads: the CPU cores a launch over many independent elements may use at once (the fused particle step
        and the plane pass of 2 x 16384 particles or more, the solvers' elementwise kernels: core.cpu_threads),
        the same states bit for bit; None: the environment
        variable WARP_SIM_CPU_THREADS, else every core this process may use. A captured step (capture=True)
        runs each launch on one thread: Warp's CPU graph replays its launches one after another
    differentiable: every launch a ``wp.launch`` that an active ``wp.Tape`` records, every step's states new (nothing
        an adjoint reads is overwritten), the model's float arrays and every state with gradients (``.grad``), and
        the launched kernel modules compiled with their backward kernels (only then: a forward-only Simulator
        compiles none); fused steps off, capture refused. A part without an adjoint yet is refused
        (adjoints.NoAdjoint, a ValueError naming it): contacts, joints, emitters, strain limiting, kinematic
        bodies, penalty forces, force fields, aerodynamics, rk45, implicit_euler. ``ws.gradient`` runs on it

    With "rk45" each ``step(dt)`` lands exactly on t + dt, taking as many internal steps as the tolerance
    needs (``sim.integrator.stats()`` counts them), so ``run(..., substeps=1)`` is the natural choice.

    persistent: time, step_count; with the parts of ``persistent_parts()``, what a checkpoint of ``run()`` keeps

    Attributes: scene; settings (the options above); model (constants), control (held inputs), state (the current
    State; a new object after each step, so read ``sim.state.particle_x`` afresh), dynamics, integrator, passes (in
    order);
    body_contacts, particle_shapes, impacts, strain_limiter, emitters, joints (those passes, or None; the joints run
    inside body_contacts where it exists); guard; fused; captured; differentiable;
    time [s]; step_count; output: the stage the last run() wrote (a pathlib.Path), or None.
    """

    persistent = ("time", "step_count")

    def __init__(self, scene: Scene, integrator="rk4", device: str | None = None, contact: str = "impulse",
                 penalty_stiffness: float = 1.0e4, guard: bool = True, max_speed: float = 1.0e4,
                 contact_margin: float = 0.005, collisions: bool = True, contact_step: float | None = 1.0 / 120.0,
                 fused: bool = True, capture: bool = False, cpu_threads: int | None = None,
                 joint_step: float | None = 1.0 / 480.0, differentiable: bool = False):
        if not isinstance(scene, Scene):
            raise checks.fail("scene", scene, "expected a warp_sim.Scene")
        if scene.particle_count == 0 and scene.body_count == 0:
            raise checks.fail("scene", scene, "the scene has nothing to simulate; add particles or bodies first")
        contact = checks.choice("contact", contact, RESPONSES)
        stiffness = checks.scalar("penalty_stiffness", penalty_stiffness, low=0.0, low_open=True)
        speed = checks.scalar("max_speed", max_speed, low=0.0, low_open=True)
        margin = checks.scalar("contact_margin", contact_margin, low=0.0)
        if not isinstance(collisions, bool):
            raise checks.fail("collisions", collisions, "expected True or False")
        if not isinstance(guard, bool):
            raise checks.fail("guard", guard, "expected True or False")
        if not isinstance(fused, bool):
            raise checks.fail("fused", fused, "expected True or False")
        if not isinstance(capture, bool):
            raise checks.fail("capture", capture, "expected True or False")
        if not isinstance(differentiable, bool):
            raise checks.fail("differentiable", differentiable, "expected True or False")
        if differentiable and capture:
            raise checks.fail("capture", capture, "expected False with differentiable=True: a graph's replays "
                                                  "bypass the tape")
        if contact_step is not None:
            contact_step = checks.scalar("contact_step", contact_step, low=0.0, low_open=True)
        if joint_step is not None:
            joint_step = checks.scalar("joint_step", joint_step, low=0.0, low_open=True)
        threads = cpu_threads_for(cpu_threads)
        device = resolve_device(device)
        parts = assemble(scene, device, integrator, contact, stiffness, margin, collisions, contact_step,
                         fused and not differentiable, joint_step)
        if differentiable:
            make_differentiable(parts, "Simulator(differentiable=True)")
        self.differentiable = differentiable
        #: the options it was made with, which a checkpoint must match
        self.settings = dict(device=device, contact=contact, penalty_stiffness=stiffness, guard=guard, max_speed=speed,
                             contact_margin=margin, collisions=collisions, contact_step=contact_step, fused=fused,
                             capture=capture, **({"joint_step": joint_step} if scene.joints else {}),
                             **({"differentiable": True} if differentiable else {}))
        self.scene = scene
        self._scene_revision = scene.revision   # a scene changed after this is refused (scene.revisions)
        self.model = parts.model
        if self.model.device.is_cpu:
            self.model.launcher.pool = CpuPool.shared(threads)
        self.control = parts.control
        self.dynamics = parts.dynamics
        self.integrator = parts.integrator
        self.passes = parts.passes
        self.body_contacts = parts.body_contacts
        self.particle_shapes = parts.particle_shapes
        self.impacts = parts.impacts
        self.strain_limiter = parts.strain_limiter
        self.emitters = parts.emitters
        self.joints = parts.joints
        self.state = self.dynamics.initial_state(scene)
        self._next = self.dynamics.new_state()
        if self.emitters is not None:
            self.emitters.initial_births(self.state, 0.0)
        self.guard = Guard(self.model, self.dynamics.components, speed) if guard else None
        self.fused, self._after_fused = parts.fused, parts.after_fused
        #: whether the fused step checks the particles for the guard: where nothing runs after it and no graph
        #: bakes the step number in
        self._guard_folded = (self.fused is not None and self.guard is not None and not self._after_fused
                              and not capture)
        if self._guard_folded:
            self.fused.set_guard(*self.guard.record_of("particles"))
        self._first = self.state
        self._graphs = self._step_graphs() if capture else None
        #: the longest step the solver takes stably on this scene (solvers.stability), which substeps="auto" keeps to
        self.step_limit = step_limit(scene, self.integrator, stiffness if contact == "penalty" else None, collisions)
        self._substeps = Substeps(self.step_limit, [p.max_step for p in self.passes if p.max_step is not None],
                                  self.integrator.name)
        self._substeps.warn_if_growing()
        self._load_kernels()
        self.time = 0.0
        self.step_count = 0
        self.output = None

    def kernel_modules(self) -> list[str]:
        """The kernel modules (names in warp_sim.kernels) the parts that run this simulation launch, sorted."""
        parts = self._running_parts() + ([self.guard] if self.guard is not None and not self._guard_folded else [])
        return sorted({name for part in parts for name in part.kernels})

    def _running_parts(self) -> list:
        """The parts a step runs: the solver, components and passes (or the fused step and the passes after it),
        and the force terms."""
        if self.fused is None:
            parts = [self.integrator, *self.dynamics.components, *self.passes]
        else:
            parts = [self.fused, *self._after_fused]
        return parts + list(self.dynamics.force_terms)

    def _step_graphs(self):
        """The step's graphs (core.capture) when every part a step runs can be captured, else None with a warning
        naming the parts that cannot (their launches change from step to step)."""
        refusing = sorted({type(part).__name__ for part in self._running_parts() if not part.capturable})
        if refusing:
            warnings.warn(f"capture=True: this scene's steps are not captured: {', '.join(refusing)} "
                          "change their launches from step to step; it runs uncaptured", stacklevel=3)
            return None
        return StepGraphs(self.model)

    @property
    def captured(self) -> bool:
        """Whether steps are recorded as Warp graphs and replayed (``capture=True`` on a scene that allows it)."""
        return self._graphs is not None

    def _load_kernels(self) -> None:
        """Compile (or load from Warp's cache) every kernel module the simulation launches, in parallel on the
        available cores (core.compiling.load): a cold start compiles them side by side instead of one by one at
        their first launches, the longest first (kernels.COMPILE_SECONDS), so no core waits long at the end; and
        says so first, with how long it takes, on stderr. A differentiable Simulator first turns on the backward
        kernels of the modules its steps launch (compiling.enable_adjoints), the guard's aside."""
        if self.differentiable:
            compiling.enable_adjoints(sorted({name for part in self._running_parts() for name in part.kernels}))
        compiling.load(self.kernel_modules(), self.model.device)

    @property
    def device(self):
        return self.model.device

    # rigid bodies -------------------------------------------------------------
    def _body(self, body) -> int:
        if isinstance(body, bool) or not isinstance(body, (int, np.integer)) or not 0 <= body < self.model.body_count:
            raise checks.fail("body", body, f"expected a body index in [0, {self.model.body_count})")
        return int(body)

    def apply_impulse(self, body: int, impulse, point=None) -> None:
        """Apply impulse J [N s] at world point p [m] (default: the centre of mass) to a body now:
        P += J and L += (p - x) x J, changing v by J / M and omega by I^-1 ((p - x) x J)."""
        index = self._body(body)
        J = checks.vec3("impulse", impulse)
        x = self.state.body_x.numpy()[index].astype(np.float64)
        p = x if point is None else checks.vec3("point", point)
        m = self.model
        wp.launch(rigid_kernels.apply_impulse, 1, [index, m.vec3(*J), m.vec3(*p), self.state.bodies], device=m.device)

    def set_body_force(self, body: int, force=(0.0, 0.0, 0.0), point=None, torque=(0.0, 0.0, 0.0)) -> None:
        """Hold a force [N] at world point ``point`` [m] (default: the centre of mass) and a pure torque
        [N m] on a body from now until changed: it adds F and tau = (p - x) x F + torque, with x the
        centre of mass now. Replaces the body's previous held force; zero arguments clear it."""
        index = self._body(body)
        F = checks.vec3("force", force)
        tau = checks.vec3("torque", torque)
        if point is not None:
            x = self.state.body_x.numpy()[index].astype(np.float64)
            tau = tau + np.cross(checks.vec3("point", point) - x, F)
        self.control.set_body_wrench(index, F, tau)

    def body_velocities(self):
        """(v [m/s], omega [rad/s]): the current linear and angular velocities of every body, world
        frame, as new device arrays of vec3 (v = P / M, omega = R I_body^-1 R^T L)."""
        m = self.model
        v = wp.empty(m.body_count, dtype=m.vec3, device=m.device)
        omega = wp.empty(m.body_count, dtype=m.vec3, device=m.device)
        bodies = self.dynamics.component("bodies")
        if bodies is not None:
            bodies.velocities(self.state, v, omega)
        return v, omega

    def body_rotations(self):
        """R(t): every body's 3x3 rotation matrix (body to world), a new device array of mat33."""
        m = self.model
        R = wp.empty(m.body_count, dtype=m.mat33, device=m.device)
        if m.body_count:
            wp.launch(rigid_kernels.rotation_matrices, m.body_count, [self.state.body_q, R], device=m.device)
        return R

    def step(self, dt: float, steps: int = 1, substeps="auto") -> None:
        """Advance by ``steps`` steps of dt seconds each, then check the guards once.

        substeps: "auto" splits each step into ``sim.substeps(dt)`` equal pieces, as many as the scene's stability
        (``sim.step_limit``) and the contact step need; a count n takes n equal pieces (each split further only
        by contact_step), and warns once if they are longer than the stable step."""
        self.scene.require(self._scene_revision)
        h = checks.scalar("dt", dt, low=0.0, low_open=True)
        substeps = checks.substeps("substeps", substeps)
        for _ in range(checks.count("steps", steps)):
            self._advance(h, substeps)
        self.check()
        self._warn_solver()

    def check(self) -> None:
        """Raise SimulationDiverged if any step so far went non-finite or too fast; warn of each joint that broke
        since the last check (``joint_breaks`` lists them all)."""
        if self.guard is not None:
            self.guard.raise_if_diverged(self.state)
        self._report_breaks()

    def _report_breaks(self) -> None:
        if self.joints is not None:
            for index, name, time in self.joints.take_breaks():
                warnings.warn(f"joint {index} ({name!r}) broke at t = {time:.4g} s: its force or torque went over "
                              "its break_force or break_torque", RuntimeWarning, stacklevel=4)

    @property
    def joint_breaks(self) -> list[tuple[int, str, float]]:
        """Every joint that broke so far: (its index in scene.joints, its name, the time [s]), in order."""
        self._report_breaks()
        return list(self.joints.broken) if self.joints is not None else []

    def emitter_stats(self) -> list[dict]:
        """Per emitter: name, capacity, live, born, and skipped (births that found its pool full)."""
        return self.emitters.stats() if self.emitters is not None else []

    def substeps(self, h: float) -> int:
        """How many equal pieces a step of h seconds takes with substeps="auto": enough that none is longer than
        the solver's stable step on this scene (``step_limit``: its stiffest springs, penalty contacts) nor than
        any pass's max_step (a pile or stack at frame rate: the body contacts' 1/120 s by default); at least 1, at
        most MAX_AUTO_SUBSTEPS."""
        return self._substeps.auto(checks.scalar("h", h, low=0.0, low_open=True))

    def _advance(self, h: float, substeps="auto", asked: tuple | None = None) -> None:
        """One step of h seconds (in ``solvers.substeps.Substeps.pieces`` equal pieces): per piece the solver from
        state into the spare state, the passes on it and the swap (replayed from a graph where captured); then the
        guard."""
        pieces = self._substeps.pieces(h, substeps, asked)
        piece = h / pieces
        start_time = self.time
        for k in range(pieces):
            if self._graphs is None:
                self._piece(piece, k == pieces - 1)
            else:
                self._captured_piece(piece, k == pieces - 1)
            self.time = start_time + piece * (k + 1)
        self.time = start_time + h
        self.step_count += 1
        if self.guard is not None:
            folded = ("particles",) if self._guard_folded else ()
            self.guard.record(self.state, self.step_count, self.time, folded)

    def _captured_piece(self, piece: float, last: bool) -> None:
        """One piece of ``piece`` seconds from its graph (recorded on first use). Where a pass says the recorded
        launches did not hold it (contacts or colours outgrew them), the States go back as they were and the piece
        is done uncaptured (which grows what was too small); the graphs are kept unless that reallocated a buffer
        or misses keep coming, and then the next pieces run uncaptured for a while (core.capture.StepGraphs:
        waiting, as the first piece does) and record afresh."""
        graphs = self._graphs
        if graphs.waiting:
            graphs.waiting -= 1
            self._piece(piece, last)
            return
        after = self.passes if self.fused is None else self._after_fused
        start, end = self.state, self._next
        if graphs.step((piece, start is self._first), lambda: self._piece(piece, False),
                       lambda: any([step_pass.before_capture() for step_pass in after])):
            self.state, self._next = end, start   # a replay: the host side of the piece again
        if all(step_pass.replay_held() for step_pass in after):
            graphs.held()
            return
        self.state, self._next = start, end   # the piece left start as it was
        self._piece(piece, last)
        graphs.miss(all(step_pass.capture_intact() for step_pass in after))

    def _piece(self, piece: float, last: bool) -> None:
        """One piece of a step, ``piece`` seconds (the last of its step: ``last``), swapping the States (in a
        differentiable run, into a new State)."""
        for step_pass in self.passes:
            step_pass.check_step(piece)
        start, end = self.state, self.dynamics.new_state() if self.differentiable else self._next
        if self.fused is None:
            self.integrator.step(start, end, self.time, piece)
            after = self.passes
        else:   # the guard's check folded into the last piece, where nothing runs after it
            self.fused.step(start, end, self.time, piece, self.step_count + 1 if self._guard_folded and last else 0)
            after = self._after_fused
        for step_pass in after:
            step_pass.apply(start, end, self.time, piece)
        self.state, self._next = end, start

    def frame_arrays(self) -> dict:
        """The current state's arrays a frame holds, as numpy copies (they stay as they are when the simulation
        goes on): particle_x [m], particle_v [m/s], body_x [m], body_q (x, y, z, w) where present; with
        emitters also particle_alive, particle_id, particle_radius [m], particle_color (RGB) and
        particle_opacity of every slot."""
        names = [name for name, count in (("particle_x", self.model.particle_count),
                                          ("particle_v", self.model.particle_count),
                                          ("body_x", self.model.body_count), ("body_q", self.model.body_count))
                 if count]
        arrays = {name: np.array(getattr(self.state, name).numpy()) for name in names}
        if self.emitters is not None:
            pools = self.emitters
            arrays.update({name: np.array(array.numpy()) for name, array in (
                ("particle_alive", pools.alive), ("particle_id", pools.ids),
                ("particle_radius", self.model.particle_radius), ("particle_color", pools.color),
                ("particle_opacity", pools.opacity))})
        return arrays

    def frames(self, seconds: float, fps: float = 60.0, substeps="auto", arrays: bool = True):
        """Simulate round(seconds * fps) frames, yielding (frame, time, arrays).

        substeps: "auto" (default) steps each frame as ``step(1 / fps)`` does, in ``sim.substeps(1 / fps)`` pieces;
        a count n takes n steps of 1 / (fps n) a frame (each split further only by contact_step), and warns once
        if they are longer than the stable step.

        Frame k holds the state at run start + k / fps (frame 0: the state before the first step); time is
        the simulator's time then [s]; arrays are frame_arrays() (None with arrays=False: nothing is copied
        to the host). The guards are read at every frame, so a divergence raises SimulationDiverged before
        its frame is yielded."""
        self.scene.require(self._scene_revision)
        frames, fps, substeps = _frame_arguments(seconds, fps, substeps)
        if not isinstance(arrays, bool):
            raise checks.fail("arrays", arrays, "expected True or False")
        return self._frame_loop(frames, fps, substeps, arrays)

    def _frame_loop(self, frames: int, fps: float, substeps, arrays: bool, first: int = 0,
                    start_time: float | None = None):
        """Frames ``first`` to ``frames - 1`` of a run that started at ``start_time`` (default: now, from frame 0;
        a resumed run's state is that of frame ``first - 1``)."""
        self.scene.require(self._scene_revision)   # run() too
        steps, h, split = (1, 1.0 / fps, "auto") if substeps == "auto" else (substeps, 1.0 / (fps * substeps), 1)
        asked = None if substeps == "auto" else (substeps, 1.0 / fps)
        start_time = self.time if start_time is None else start_time
        accepted, warned = self.integrator.stats().get("accepted"), False
        for frame in range(first, frames):
            if frame > 0:
                for _ in range(steps):
                    self._advance(h, split, asked)
                self.time = start_time + frame / fps
                self.check()
                if accepted is not None and not warned:   # an adaptive solver: how hard did this frame make it work?
                    now = self.integrator.stats()["accepted"]
                    if now - accepted > SLOW_FRAME_STEPS:
                        warned = True
                        warnings.warn(f"{self.integrator!r} took {now - accepted} internal steps for frame {frame} "
                                      f"(more than {SLOW_FRAME_STEPS} a frame): this run will be slow; loosen rtol "
                                      "and atol, or use a fixed-step solver", RuntimeWarning, stacklevel=2)
                    accepted = now
            yield frame, self.time, self.frame_arrays() if arrays else None
        if self.emitters is not None:
            self.emitters.warn_if_skipped()
        self._warn_solver()

    def _warn_solver(self) -> None:
        """Issue the solver's pending warning (unconverged solves since the last one), if any."""
        message = self.integrator.pending_warning()
        if message is not None:
            warnings.warn(message, RuntimeWarning, stacklevel=3)

    def run(self, seconds: float, fps: float = 60.0, substeps="auto", usd=None, progress: bool = True,
            chunk_frames: int | None = None, resume: bool = False, keep_checkpoint: bool = False, over=None,
            flatten: bool = False):
        """Simulate the frames of ``frames(seconds, fps, substeps)``, writing each to USD (substeps: "auto", the
        default, or a count of steps per frame, as in frames()).

        usd: output path (.usdc, .usd or .usda) or None; checked before anything is simulated (an existing
        folder, a folder that cannot be made or written, a bad extension: ValueError or OSError naming it).
        chunk_frames: frames per chunk: every chunk is written to disk with a checkpoint of the simulation
        (default: 240, fewer for big scenes, so that a chunk holds at most about 256 MB)
        resume: go on from the checkpoint of an earlier run to the same path that was killed, stopped by a signal
        or a full disk, if there is one (else start at frame 0): the stage is then identical, in every time
        sample, to an uninterrupted run. The checkpoint must come from the same scene, simulator options and run
        arguments (a fingerprint of them all), or ValueError refuses it before anything is changed.
        keep_checkpoint: leave the run's folder of chunks and checkpoint beside the output (hidden, until the
        next run to the same path) instead of removing it when the stage is complete
        over: for a scene read by ``Scene.from_usd``, its stage (the path or the Usd.Stage): the output is then an
        animation layer of overrides on that stage's own prims, sublayering it, in its units, axes and time codes
        (``stages.overlay``); flatten: with over, write one standalone stage instead

        On divergence the stage keeps every frame before the bad one and SimulationDiverged propagates, with
        ``frames_written`` and ``usd`` set; with guard=False a frame holding a non-finite value counts as
        divergence, so nothing non-finite is written. A signal (Ctrl-C: KeyboardInterrupt; SIGTERM:
        RunInterrupted) or an OSError (a full disk) keeps the last checkpoint and propagates with
        ``frames_checkpointed`` (0: nothing was kept) and ``usd`` set; any other error leaves no file. Returns the
        written path (a pathlib.Path), or None without usd.
        """
        total, fps, substeps = _frame_arguments(seconds, fps, substeps)
        for name, flag in (("progress", progress), ("resume", resume), ("keep_checkpoint", keep_checkpoint),
                           ("flatten", flatten)):
            if not isinstance(flag, bool):
                raise checks.fail(name, flag, "expected True or False")
        if (resume or over is not None) and usd is None:
            raise checks.fail("resume" if resume else "over", resume if resume else over,
                              "needs usd=: the output path")
        if over is not None and self.scene.usd_source is None:
            raise checks.fail("over", over, "needs a scene read by Scene.from_usd (its prims are what it overrides)")
        if chunk_frames is None:   # a chunk of at most about 256 MB of samples
            frame_bytes = 40 * self.model.particle_count + 28 * self.model.body_count + 1
            chunk_frames = int(min(240, max(1, 256 * 2**20 // frame_bytes)))
        chunk_frames = checks.count("chunk_frames", chunk_frames)
        writer, first, start_time = None, 0, self.time
        if usd is not None:
            key = fingerprint(__version__, self.scene, self.settings, type(self.integrator).__name__,
                              persistence.settings(self.integrator), [total, fps, substeps, chunk_frames],
                              None if over is None else [str(over), flatten])
            overlay = None if over is None else Overlay(self.scene.usd_source, over, self.scene.bodies, flatten)
            source = self.scene.usd_source.path if self.scene.usd_source is not None else None
            reads = [] if source is None else [(f"the stage the scene was read from ({source!r})", source)]
            raise_pending()   # a signal a library swallowed: before the output is touched
            writer = StageWriter(usd, fps, stage_layout(self.scene) if overlay is None else None, chunk_frames,
                                 key=key, resume=resume, overlay=overlay, reads=reads)
            if writer.resumed is not None:
                arrays, meta = writer.resumed
                values = dict(meta["values"])
                start_time = values.pop("run.start_time")
                persistence.restore(self, arrays, values)
                first = writer.frames_written
        try:
            with interruptions():   # SIGTERM raises RunInterrupted to the end of the final stitch
                with tqdm(total=total, initial=first, unit="frame", disable=None if progress else True,
                          desc="simulating") as bar:
                    for frame, _, arrays in self._frame_loop(total, fps, substeps, usd is not None, first,
                                                             start_time):
                        if writer is not None:
                            self._refuse_unwritable(frame, arrays)
                            if writer.write_frame(frame, **arrays):
                                saved, values = persistence.save(self)
                                writer.checkpoint(saved, dict(values, **{"run.start_time": start_time}))
                        bar.update(1)
                raise_pending()
                self.output = writer.close(keep_checkpoint) if writer is not None else None
            return self.output
        except SimulationDiverged as error:
            if writer is not None and writer.frames_written:
                error.frames_written, error.usd = writer.frames_written, writer.close()
            elif writer is not None:
                writer.abort()
            raise
        except (KeyboardInterrupt, OSError) as error:   # a signal, a full disk: keep the last checkpoint
            if writer is not None:   # (a signal in close()'s rename waits until the stage is whole: complete)
                error.frames_checkpointed = 0 if writer.complete else writer.suspend()
                error.usd, error.complete = writer.path, writer.complete
                self.output = writer.path if writer.complete else None
            raise
        except BaseException:
            if writer is not None:
                writer.abort()
            raise

    def persistent_parts(self) -> dict:
        """The state, the held inputs, the solver and the passes that carry values from step to step. The guard is
        not among them: a checkpoint is taken only after it read clean, and a fresh guard is clean."""
        parts = {"state": self.state, "control": self.control, "integrator": self.integrator}
        parts.update({f"pass{k}.{type(p).__name__}": p for k, p in enumerate(self.passes) if p.persistent})
        return parts

    def _refuse_unwritable(self, frame: int, arrays: dict) -> None:
        """A frame holding a position, velocity or orientation that float32 cannot hold (non-finite, or beyond
        +-3.4e38: a float64 state on its way to infinity) raises SimulationDiverged, whatever the guard setting: the
        frames before it are kept, as with the guard, and a stage never holds an infinity."""
        alive = arrays.get("particle_alive")
        for component, names in (("particles", ("particle_x", "particle_v")), ("bodies", ("body_x", "body_q"))):
            for name in names:
                values = arrays.get(name)
                if values is None:
                    continue
                bad = ~(np.abs(values) <= FLOAT32_MAX).all(axis=1)   # NaN compares False
                if alive is not None and component == "particles":
                    bad &= alive.astype(bool)
                if bad.any():
                    element = int(np.flatnonzero(bad)[0])
                    part = next(c for c in self.dynamics.components if c.name == component)
                    raise SimulationDiverged(self.step_count, self.time, component, element,
                                             f"{name} beyond float32's finite range (+-3.4e38) or non-finite in "
                                             f"frame {frame}, which a USD stage cannot hold",
                                             where=part.locate(element))


def _frame_arguments(seconds, fps, substeps) -> tuple[int, float, int | str]:
    """(frames, fps, substeps) of frames(), checked."""
    seconds = checks.scalar("seconds", seconds, low=0.0, low_open=True)
    fps = checks.scalar("fps", fps, low=0.0, low_open=True)
    substeps = checks.substeps("substeps", substeps)
    frames = int(round(seconds * fps))
    if frames < 1:
        raise checks.fail("seconds", seconds, f"covers no frame at fps={fps}; need seconds >= {0.5 / fps:g}")
    return frames, fps, substeps

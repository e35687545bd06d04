"""Simulator: builds a scene on a device and advances it; step, run, guards, progress, USD."""
from __future__ import annotations

import numpy as np
import warp as wp

from . import checks
from .collision import RESPONSES, PlaneImpacts, PlanePenalty
from .contacts import BodyContacts, ContactGeometry, ContactPenalty, ParticleShapeContacts
from .dynamics import Dynamics
from .guards import Guard, SimulationDiverged
from .integrators import make_integrator
from .kernels import rigid as rigid_kernels
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


def _shape_drawing(shape, origin) -> dict:
    """The USD drawing fields of a shape (kind, size, points, faces, radius), points relative to ``origin`` [m]."""
    points = faces = None
    radius = 0.02
    if shape.kind == "mesh":
        points, faces = shape.vertices - origin, shape.faces
    elif shape.kind == "points":
        points, radius = shape.positions - origin, shape.radius
    return {"kind": shape.kind, "size": tuple(shape.size), "points": points, "faces": faces, "radius": radius}


def body_spec(index: int, body):
    """The USD BodySpec of one scene body: its shape drawn in the body frame (centre of mass at the origin)."""
    from .stages import BodySpec

    return BodySpec(body.name, index, **_shape_drawing(body.shape, body.mass.com), color=body.color)


def collider_spec(collider):
    """The USD ColliderSpec of one scene collider: its shape drawn in the shape frame (no centre-of-mass offset)."""
    from .stages import ColliderSpec

    return ColliderSpec(collider.name, **_shape_drawing(collider.shape, np.zeros(3)), color=collider.color,
                        position=tuple(collider.position.tolist()), orientation=tuple(collider.orientation.tolist()))


def stage_layout(scene: Scene):
    """The USD StageLayout of a scene: its particle groups, springs, bodies, planes, cloths, soft bodies and
    static colliders.

    A cloth's or soft body's particles and springs are drawn as its UsdGeom.Mesh only, not also
    as Points and spring curves."""
    from .stages import MeshSpec, PlaneSpec, PointsGroup, StageLayout

    radius = scene.particle_array("radius")
    meshed = {(m.start, m.count) for m in scene.meshes}
    groups = tuple(PointsGroup(g.name, g.start, g.count, 2.0 * radius[g.start:g.start + g.count], g.color,
                               pooled=g.pooled) for g in scene.particle_groups if (g.start, g.count) not in meshed)
    planes = tuple(PlaneSpec(p.name, tuple(p.normal), p.offset) for p in scene.planes)
    springs = None
    if scene.spring_count:
        drawn = np.ones(scene.spring_count, dtype=bool)
        for mesh in scene.meshes:
            for family in mesh.springs.values():
                drawn[np.asarray(family, dtype=np.int64)] = False
        springs = scene.spring_array("pairs")[drawn] if drawn.any() else None
    bodies = tuple(body_spec(index, body) for index, body in enumerate(scene.bodies))
    meshes = tuple(MeshSpec(m.name, m.start, m.count, m.face_counts, m.face_indices, m.color) for m in scene.meshes)
    colliders = tuple(collider_spec(collider) for collider in scene.colliders)
    return StageLayout(points_groups=groups, springs=springs, planes=planes, bodies=bodies, meshes=meshes,
                       colliders=colliders)


class Simulator:
    """Runs a Scene on a device with one ODE solver.

    integrator: one of warp_sim.INTEGRATORS; device: a Warp device alias, or None
    for CUDA when present, else the CPU; contact: "impulse" (time of impact,
    default) or "penalty" (spring and damper on penetration); penalty_stiffness
    [N/m]; guard: check for non-finite values and speeds above max_speed [m/s]
    after every step (read every step() and every frame of run()); contact_margin [m]:
    the gap at which bodies count as touching (warp_sim.contacts); collisions: False leaves
    contacts with bodies and colliders out (bodies pass through each other, colliders and
    planes, particles through bodies and colliders; particles still meet planes).
    rtol, atol: the relative and absolute error tolerances of the adaptive integrator "rk45"
    (warp_sim.integrators.RK45: 4 machine epsilons <= rtol < 1, default 1e-6; atol > 0 in the
    state's units, default 1e-9); None leaves the default. Giving either to a fixed-step
    integrator raises ValueError. With "rk45" each ``step(dt)`` lands exactly on t + dt, taking as
    many internal steps as the tolerance needs (``sim.integrator.accepted``, ``.rejected``,
    ``.evaluations`` count them), so ``run(..., substeps=1)`` is the natural choice.

    ``state`` holds the current State; it is a new object after each step (the
    solver writes into a second state and the two are swapped), so read
    ``sim.state.particle_x`` afresh rather than keeping the array.
    """

    def __init__(self, scene: Scene, integrator: str = "rk4", device: str | None = None,
                 contact: str = "impulse", penalty_stiffness: float = 1.0e4, guard: bool = True,
                 max_speed: float = 1.0e4, contact_margin: float = 0.005, rtol: float | None = None,
                 atol: float | None = None, collisions: bool = True):
        if not isinstance(scene, Scene):
            raise checks.fail("scene", scene, "expected a warp_sim.Scene")
        if scene.particle_count == 0 and scene.body_count == 0:
            raise checks.fail("scene", scene, "the scene has nothing to simulate; add particles or bodies first")
        contact = checks.choice("contact", contact, RESPONSES)
        stiffness = checks.scalar("penalty_stiffness", penalty_stiffness, low=0.0, low_open=True)
        speed = checks.scalar("max_speed", max_speed, low=0.0, low_open=True)
        margin = checks.scalar("contact_margin", contact_margin, low=0.0)
        self.model = Model(scene, resolve_device(device))
        m = self.model
        particle_planes = m.plane_count > 0 and m.particle_count > 0
        penalty = [PlanePenalty(m, stiffness)] if contact == "penalty" and particle_planes else []
        # bodies collide when there is something to hit; particles are pushed by bodies and colliders
        if not isinstance(collisions, bool):
            raise checks.fail("collisions", collisions, "expected True or False")
        colliders = len(scene.colliders) if collisions else 0
        bodies_collide = collisions and m.body_count > 0 and (
            m.plane_count > 0 or colliders > 0 or m.body_count > 1 or m.particle_count > 0)
        self.body_contacts = None
        detection = None
        if bodies_collide and contact == "impulse":
            self.body_contacts = BodyContacts(m, margin=margin)
            geometry, detection = self.body_contacts.geometry, self.body_contacts.detection
        elif bodies_collide:
            body_penalty = ContactPenalty(m, stiffness)
            penalty.append(body_penalty)
            geometry, detection = body_penalty.detection.geometry, body_penalty.detection
        elif colliders and m.particle_count:
            geometry = ContactGeometry(m)
        self.particle_shapes = None
        if m.particle_count and ((m.body_count and collisions) or colliders):
            self.particle_shapes = ParticleShapeContacts(m, geometry, detection)
        self.dynamics = Dynamics(m, penalty)
        tolerances = {key: value for key, value in (("rtol", rtol), ("atol", atol)) if value is not None}
        self.integrator = make_integrator(integrator, self.dynamics, **tolerances)
        if self.body_contacts is not None:
            self.body_contacts.position_response = self.integrator.position_response
        self.impacts = PlaneImpacts(m) if contact == "impulse" and particle_planes else None
        self.strain_limiter = None
        if any(mesh.max_stretch is not None for mesh in scene.meshes):
            from .strain import StrainLimiter

            self.strain_limiter = StrainLimiter(self.model)
        self.state = self.dynamics.initial_state()
        self._next = self.dynamics.new_state()
        self.emitters = None
        if scene.emitters:
            from .emitters import EmitterPools

            self.emitters = EmitterPools(self.model, scene)
            self.emitters.initial_births(self.state, 0.0)
            if self.emitters.touched is not None:
                for contact_pass in (self.impacts, self.particle_shapes):
                    if contact_pass is not None:
                        contact_pass.touched = self.emitters.touched
        self.guard = Guard(self.model, self.dynamics.components, speed) if guard else None
        self.time = 0.0
        self.step_count = 0

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
        wp.launch(rigid_kernels.apply_impulse, 1, [index, m.vec3(*J), m.vec3(*p), self.state.body_x,
                                                  self.state.body_P, self.state.body_L], device=m.device)

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
        m = self.model
        wp.copy(m.body_user_force, wp.array([F], dtype=m.vec3, device=m.device), dest_offset=index, count=1)
        wp.copy(m.body_user_torque, wp.array([tau], dtype=m.vec3, device=m.device), dest_offset=index, count=1)

    def body_velocities(self):
        """(v [m/s], omega [rad/s]): the current linear and angular velocities of every body, world
        frame, as new device arrays of vec3 (v = P / M, omega = R I_body^-1 R^T L)."""
        m = self.model
        v = wp.empty(m.body_count, dtype=m.vec3, device=m.device)
        omega = wp.empty(m.body_count, dtype=m.vec3, device=m.device)
        if self.dynamics.bodies is not None:
            self.dynamics.bodies.velocities(self.state, v, omega)
        return v, omega

    def body_rotations(self):
        """R(t): every body's 3x3 rotation matrix (body to world), a new device array of mat33."""
        m = self.model
        R = wp.empty(m.body_count, dtype=m.mat33, device=m.device)
        if m.body_count:
            wp.launch(rigid_kernels.rotation_matrices, m.body_count, [self.state.body_q, R], device=m.device)
        return R

    def step(self, dt: float, steps: int = 1) -> None:
        """Advance by ``steps`` steps of dt seconds each, then check the guards once."""
        h = checks.scalar("dt", dt, low=0.0, low_open=True)
        if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
            raise checks.fail("steps", steps, "expected an integer >= 1")
        for _ in range(steps):
            self._advance(h)
        self.check()

    def check(self) -> None:
        """Raise SimulationDiverged if any step so far went non-finite or too fast."""
        if self.guard is not None:
            self.guard.raise_if_diverged(self.state)

    def emitter_stats(self) -> list[dict]:
        """Per emitter: name, capacity, live, born, and skipped (births that found its pool full)."""
        return self.emitters.stats() if self.emitters is not None else []

    def _advance(self, h: float) -> None:
        if self.emitters is not None:
            self.emitters.check_step(h)
        self.integrator.step(self.state, self._next, self.time, h)
        if self.strain_limiter is not None:
            self.strain_limiter.apply(self.state, self._next, h)
        if self.body_contacts is not None:
            self.body_contacts.apply(self.state, self._next, h)
        if self.particle_shapes is not None:   # before the planes: a particle squeezed between a body and
            self.particle_shapes.apply(self._next)   # the ground ends on the ground, not below it
        if self.impacts is not None:
            self.impacts.apply(self.state, self._next, h)
        self.dynamics.post_step(self._next)
        self.state, self._next = self._next, self.state
        if self.emitters is not None:
            self.emitters.after_step(self.state, self.time, h)
        self.step_count += 1
        self.time += h
        if self.guard is not None:
            self.guard.record(self.state, self.step_count, self.time)

    def _frame_arrays(self) -> dict:
        """The current state's arrays the stage writer takes, as numpy."""
        names = [name for name, count in (("particle_x", self.model.particle_count),
                                          ("particle_v", self.model.particle_count),
                                          ("body_x", self.model.body_count), ("body_q", self.model.body_count))
                 if count]
        arrays = {name: getattr(self.state, name).numpy() for name in names}
        if self.emitters is not None:
            pools = self.emitters
            arrays.update(particle_alive=pools.alive.numpy(), particle_id=pools.ids.numpy(),
                          particle_radius=self.model.particle_radius.numpy(), particle_color=pools.color.numpy(),
                          particle_opacity=pools.opacity.numpy())
        return arrays

    def run(self, seconds: float, fps: float = 60.0, substeps: int = 8, usd=None, progress: bool = True,
            chunk_frames: int | None = None):
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
        if chunk_frames is None:   # save often enough that unsaved samples stay below about 256 MB
            frame_bytes = 40 * self.model.particle_count + 28 * self.model.body_count + 1
            chunk_frames = int(min(240, max(1, 256 * 2**20 // frame_bytes)))
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
                        writer.write_frame(frame, **self._frame_arrays())
                    bar.update(1)
        except SimulationDiverged:
            if writer is not None:
                writer.close()
            raise
        except BaseException:
            if writer is not None:
                writer.abort()
            raise
        if self.emitters is not None:
            self.emitters.warn_if_skipped()
        return writer.close() if writer is not None else None


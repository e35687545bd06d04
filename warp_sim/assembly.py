"""The one place that decides, from a Scene, which components, force terms and passes a simulation has.

Each part is one line below: its constructor, and the condition under which the scene needs it.
A part the scene does not need is never built, so its kernels are never compiled (Warp compiles
per module). Adding a force term or a pass is its module plus one line here (docs/architecture.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import warp as wp

from .core.components import Particles, RigidBodies
from .core.control import Control
from .core.dynamics import Dynamics
from .core.model import Model
from .core.protocols import Forces, Pass
from .detection import ContactGeometry, Detection
from .forces import AeroForces, BodyPenalty, FieldForces, PlanePenalty, Springs
from .passes import (
    BodyContacts,
    ComponentProjection,
    EmitterPools,
    Joints,
    KinematicBodies,
    ParticleShapeContacts,
    PlaneImpacts,
    StrainLimiter,
)
from .scene import Scene
from .solvers import Integrator, SymplecticEuler, make_integrator
from .solvers.fused import FusedParticleStep

RESPONSES = ("impulse", "penalty")


@dataclass
class Assembly:
    """What a Simulator runs: the model, the user's controls, the ODE right-hand side, the solver and the passes.

    passes: every after-step pass, in the order they run; body_contacts, particle_shapes, impacts,
    strain_limiter, emitters, joints: the same passes by name (None where absent; joints run inside body_contacts
    where there is one); fused: the fused step that replaces the
    solver and the plane impulses (None: the generic path), and after_fused: the passes that run after it.
    """
    model: Model
    control: Control
    dynamics: Dynamics
    integrator: Integrator
    passes: list[Pass]
    body_contacts: BodyContacts | None
    particle_shapes: ParticleShapeContacts | None
    impacts: PlaneImpacts | None
    strain_limiter: StrainLimiter | None
    emitters: EmitterPools | None
    joints: Joints | None = None
    fused: FusedParticleStep | None = None
    after_fused: list[Pass] | None = None


def _present(parts):
    return [part for part in parts if part is not None]


def assemble(scene: Scene, device, integrator, contact: str, penalty_stiffness: float, contact_margin: float,
             collisions: bool, contact_step: float | None = None, fused: bool = True,
             joint_step: float | None = None) -> Assembly:
    """Build every part ``scene`` needs on ``device`` (arguments as Simulator's, checked there)."""
    model = Model(scene, device)
    control = Control(model)
    impulse, penalty = contact == "impulse", contact == "penalty"
    particle_planes = model.plane_count > 0 and model.particle_count > 0
    colliders = len(scene.colliders) if collisions else 0
    # bodies collide when there is something to hit; particles are pushed by bodies and colliders
    bodies_collide = collisions and model.body_count > 0 and (
        model.plane_count > 0 or colliders > 0 or model.body_count > 1 or model.particle_count > 0)
    particles_meet_shapes = model.particle_count > 0 and ((model.body_count > 0 and collisions) or colliders > 0)
    geometry = ContactGeometry(model, scene) if bodies_collide or particles_meet_shapes else None
    detection = Detection(model, geometry, contact_margin if impulse else 0.0) if bodies_collide else None

    force_terms = _present([
        Springs(model) if model.spring_count else None,
        FieldForces(model, scene.fields) if scene.fields and model.particle_count else None,
        AeroForces(model, scene.meshes) if any(mesh.drag or mesh.lift for mesh in scene.meshes) else None,
        PlanePenalty(model, penalty_stiffness) if penalty and particle_planes else None,
        BodyPenalty(model, penalty_stiffness, detection) if penalty and bodies_collide else None,
    ])
    forces = Forces(model, set().union(*(term.targets for term in force_terms)))
    components = _present([
        Particles(model, forces) if model.particle_count else None,
        RigidBodies(model, forces, control) if model.body_count else None,
    ])
    dynamics = Dynamics(model, components, force_terms, forces)
    solver = make_integrator(integrator)

    strain_limiter = StrainLimiter(model, scene) if any(m.max_stretch is not None for m in scene.meshes) else None
    joints = Joints(model, scene, solver.position_response, max_step=joint_step) if scene.joints else None
    steps = [step for step in (contact_step, joints.max_step if joints is not None else None) if step is not None]
    body_contacts = (BodyContacts(model, detection, solver.position_response, max_step=min(steps, default=None),
                                  joints=joints) if impulse and bodies_collide else None)
    particle_shapes = (ParticleShapeContacts(model, geometry, detection, scene.colliders) if particles_meet_shapes
                       else None)
    impacts = PlaneImpacts(model) if impulse and particle_planes else None
    projection = ComponentProjection(dynamics) if model.body_count else None
    emitters = EmitterPools(model, scene) if scene.emitters else None
    # in this order: a particle squeezed between a body and the ground ends on the ground, not below it
    kinematic = KinematicBodies(model, scene) if any(body.track is not None for body in scene.bodies) else None
    # kinematic bodies are set before the contacts (which see them move) and after (which pushed them a little)
    # joints are rows of the body contacts' solve where there is one, else a pass of their own
    alone = joints if body_contacts is None else None
    passes = _present([kinematic, strain_limiter, alone, body_contacts, particle_shapes, impacts, projection,
                       emitters, kinematic])
    if emitters is not None and emitters.touched is not None:   # kill-on-contact emitters read the contact flags
        for contact_pass in _present([impacts, particle_shapes]):
            contact_pass.touched = emitters.touched
    solver.bind(dynamics)   # last: a solver instance stays unbound (reusable) if anything above refused the scene
    parts = Assembly(model, control, dynamics, solver, passes, body_contacts, particle_shapes, impacts,
                     strain_limiter, emitters, joints)
    if fused:
        parts.fused, parts.after_fused = fused_step(parts)
    return parts


def fused_step(parts: Assembly) -> tuple[FusedParticleStep | None, list[Pass] | None]:
    """The fused step for these parts and the passes after it, or (None, None) for the generic path.

    The rule (docs/architecture.md): a fused step replaces a solver's whole step and the passes it folds in, so it
    applies only where nothing else runs in between: symplectic_euler, particles the only component (cloth and
    springs are force terms), and no pass before the plane impulses (strain limiting, contacts with bodies and
    shapes, kinematic bodies); the passes after them (emitter pools) run after it.
    """
    only_particles = [component.name for component in parts.dynamics.components] == ["particles"]
    if type(parts.integrator) is not SymplecticEuler or not only_particles:
        return None, None
    folded = {id(parts.impacts)} if parts.impacts is not None else set()
    order = [p for p in parts.passes if id(p) not in folded]
    if any(p is not parts.emitters for p in order):
        return None, None
    touched = parts.impacts.touched if parts.impacts is not None else parts.model.empty(wp.int32)
    return FusedParticleStep(parts.dynamics, parts.impacts is not None, touched), order

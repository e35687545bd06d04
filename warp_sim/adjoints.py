"""Which assembled parts have an adjoint, and the switch of a simulation's parts to the differentiable mode.

A differentiable Simulator runs only parts whose every launch a wp.Tape can take back: the five explicit
solvers and implicit Euler (the adjoint of its linear solve, by the same CG), particles and rigid bodies
(gravity, drag, wind, held and per-frame forces and torques), springs, joints that cannot break
(``passes.joint_adjoint``), the orientations' renormalisation and
the particles' impacts on planes (at their time of impact, which the gradient goes through) and the body contacts
of a scene ``passes.contact_adjoint.refusal`` covers (spheres, and bodies on planes, with friction and
restitution). Every other part an assembly can hold is refused before anything compiles or runs, with what it
is and why it has no adjoint yet (``NoAdjoint``).
"""
from __future__ import annotations

from . import forces, passes
from .assembly import Assembly
from .core.components import Particles, RigidBodies
from .passes import contact_adjoint, joint_adjoint
from .solvers import RK45

#: the components, force terms and passes with adjoints (a solver says so itself: ``Integrator.differentiable``)
DIFFERENTIABLE = (Particles, RigidBodies, forces.Springs, passes.ComponentProjection, passes.PlaneImpacts)

FIXED_STEP = "use one of euler, midpoint, rk4, symplectic_euler, verlet, implicit_euler"
#: each part without an adjoint: what it is, and why
REFUSED = {
    passes.BodyContacts: ("body contacts", "only those between spheres and of any body on planes or static spheres "
                          "have one (pass collisions=False to leave them out)"),
    passes.ParticleShapeContacts: ("particle contacts with bodies and colliders",
                                   "their time-of-impact response is not differentiated (pass collisions=False)"),
    forces.PlanePenalty: ("penalty contacts of particles on planes",
                          "their switching springs are not differentiated (leave the planes out)"),
    forces.BodyPenalty: ("penalty contacts of bodies",
                         "their switching springs are not differentiated (pass collisions=False)"),
    passes.StrainLimiter: ("the strain limiter", "the exact adjoint of its over-relaxed sweeps grows without bound "
                           "over a run (a 6 x 6 hanging cloth's stiffness gradient reaches 1e32 within 1 s), and "
                           "plain Gauss-Seidel sweeps, whose adjoint stays bounded, stop unconverged at 50 a step "
                           "on a 12 x 12 cloth (make the cloth with max_stretch=None)"),
    passes.Joints: ("joints", "only those that cannot break have one"),
    passes.KinematicBodies: ("kinematic bodies", "their tracks reset the state every step, and the contacts they "
                             "drive are not differentiated"),
    passes.EmitterPools: ("emitters", "births and deaths switch particles on and off, which has no derivative"),
    forces.FieldForces: ("force fields", "their kernels are not differentiated yet"),
    forces.AeroForces: ("aerodynamic drag and lift",
                        "their kernels are not differentiated yet (make the cloth with drag=0 and lift=0)"),
    RK45: ("integrator 'rk45'", f"its step-size control chooses the steps from the state ({FIXED_STEP})"),
}


class NoAdjoint(ValueError):
    """A part of the simulation has no adjoint: ``caller`` (who asked), ``part`` (what it is) and ``reason``."""

    def __init__(self, caller: str, part: str, reason: str):
        self.caller, self.part, self.reason = caller, part, reason
        super().__init__(f"{caller}: no adjoint yet for {part}: {reason}")


def refusals(parts: Assembly) -> list[tuple[str, str]]:
    """(part, reason) for each part of ``parts`` without an adjoint, the solver first."""
    solver = parts.integrator
    found = [] if solver.differentiable else [
        REFUSED.get(type(solver), (f"integrator {type(solver).__name__}", f"it has no taped step ({FIXED_STEP})"))]
    for part in [*parts.dynamics.components, *parts.dynamics.force_terms, *parts.passes]:
        covers = {passes.BodyContacts: contact_adjoint.refusal, passes.Joints: joint_adjoint.refusal}.get(type(part))
        if covers is not None:   # covered or not by what its scene holds
            why = covers(part)
            if why is not None:
                name, scope = REFUSED[type(part)]
                found.append((name, f"{why}: {scope}"))
            continue
        if not isinstance(part, DIFFERENTIABLE) and REFUSED.get(type(part)) not in found:
            found.append(REFUSED.get(type(part), (type(part).__name__, "it is not known to be differentiable")))
    return found


def make_differentiable(parts: Assembly, caller: str) -> None:
    """Refuse ``parts`` holding a part without an adjoint (NoAdjoint, naming the first; ``caller`` starts the message);
    else switch them to the differentiable mode: the model launches through the tape and its arrays have gradients
    (``Model.make_differentiable``), so do the held inputs, and the solver launches through it too. Before anything
    is launched."""
    refused = refusals(parts)
    if refused:
        raise NoAdjoint(caller, *refused[0])
    parts.model.make_differentiable()
    parts.control.make_differentiable()
    parts.integrator.use_launcher(parts.model.launcher)

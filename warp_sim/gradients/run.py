"""ws.gradient: a loss over a whole run and its exact gradient, by the adjoint of a differentiable Simulator."""
from __future__ import annotations

import warp as wp

from ..adjoints import NoAdjoint
from ..scene import Scene
from ..simulator import Simulator
from ..util import checks
from . import controls as per_frame
from . import parameters
from .checkpoints import Checkpoints
from .trajectory import Trajectory


def _loss_value(loss, traj: Trajectory) -> wp.array:
    """``loss(traj)``, checked: a float wp.array of shape (1,) with a gradient."""
    value = loss(traj)
    if not isinstance(value, wp.array) or value.shape != (1,) or value.dtype not in (wp.float32, wp.float64):
        shown = value.shape if isinstance(value, wp.array) else type(value).__name__
        raise checks.fail("loss", loss, f"expected a function returning a float wp.array of shape (1,) computed "
                                        f"from the trajectory by Warp kernels; it returned {shown}")
    if not value.requires_grad:
        raise checks.fail("loss", loss, "expected its returned array made with requires_grad=True (the backward pass "
                                        "starts from its gradient)")
    return value


def gradient(scene: Scene, loss, wrt=(), *, seconds: float, fps: float = 60.0, substeps: int = 8, integrator=None,
             device: str | None = None, controls: dict | None = None, **options):
    """The loss of a run of ``scene`` from its initial state, and its gradient with respect to ``wrt``.

    The run is frames = round(seconds * fps) frames of 1 / fps seconds, each ``substeps`` steps of ``integrator``
    (default "rk4"; one of euler, midpoint, rk4, symplectic_euler, verlet, implicit_euler, or an instance) on a
    ``Simulator(scene, integrator, device, differentiable=True, **options)`` (options such as
    ``collisions=False``). Particles' impacts on planes are differentiated at their time of impact.

    loss(traj) gets a gradients.Trajectory (``traj.particle_x``, ``particle_v``, ``body_x``, ``body_q``: Warp arrays
    of shape (frames + 1, count), row k the state at t = k / fps, row 0 the initial state) and returns a float
    ``wp.array`` of shape (1,) with ``requires_grad=True`` computed from them by Warp kernels (it is called once
    first, on the initial state, to check that; the fields its launches read on that call's tape, whole or by any
    view, get gradients, the others none: a loss must read the same fields whatever the values).
    wrt: names of gradients.parameters.WRT: particle_x, particle_v, body_x, body_v, body_w (the initial state:
        positions, velocities, world-frame angular velocities), particle_mass, body_mass, spring_stiffness,
        spring_damping, spring_rest_length (scene.spring_array order), restitution (bodies,) and
        plane_restitution (planes,), friction (bodies,) and plane_friction (planes,) (each side's own; a contact
        takes the mean of its two), gravity (3,), and the per-frame controls body_force, body_torque (frames,
        bodies, 3), particle_force (frames, particles, 3).
    controls: per-frame controls held over each frame (row j from t = j / fps to (j + 1) / fps), by name, each of
        shape (frames, count, 3) (numpy or Warp); zero unless given.

    Returns (value, grads): the loss (a float) and a dict of float64 numpy arrays keyed by the names of ``wrt``;
    with an empty ``wrt`` the value alone. Memory follows frames, not substeps (gradients.checkpoints). A part of
    the scene without an adjoint yet (contacts with bodies, joints, emitters, ...: warp_sim.adjoints) is a
    ValueError naming it, before anything runs; so are unknown names, controls of the wrong shape and a loss that
    returns anything else.
    """
    if not isinstance(scene, Scene):
        raise checks.fail("scene", scene, "expected a warp_sim.Scene")
    if not callable(loss):
        raise checks.fail("loss", loss, "expected a function of the trajectory returning a wp.array of shape (1,)")
    if "differentiable" in options:
        raise checks.fail("differentiable", options["differentiable"], "ws.gradient sets it itself (True)")
    fps = checks.scalar("fps", fps, low=0.0, low_open=True)
    frames = int(round(checks.scalar("seconds", seconds, low=0.0, low_open=True) * fps))
    if frames < 1:
        raise checks.fail("seconds", seconds, f"covers no frame at fps={fps}; need seconds >= {0.5 / fps:g}")
    substeps = checks.count("substeps", substeps)
    names = parameters.names(wrt, scene)
    given = per_frame.check(controls, frames, scene)
    try:
        sim = Simulator(scene, "rk4" if integrator is None else integrator, device, differentiable=True, **options)
    except NoAdjoint as refusal:
        raise NoAdjoint("ws.gradient", refusal.part, refusal.reason) from None
    held = per_frame.Controls(sim.model, frames, given, parameters.controls_needed(names, sim.model))
    traj = Trajectory(sim.model, frames, fps)
    for frame in range(frames + 1):
        traj.store(frame, sim.state)
    if names:
        traj.probe()   # a trial call of the loss on a tape: the fields it reads get gradients, the others none
    with wp.Tape() as trial:
        _loss_value(loss, traj)
    traj.track(traj.read_by(trial) if names else ())
    del trial
    run = Checkpoints(sim, frames, fps, substeps, held)
    run.forward(traj)
    if not names:
        return float(_loss_value(loss, traj).numpy()[0])
    with wp.Tape() as tape:
        value = _loss_value(loss, traj)
    tape.backward(value)
    start = run.backward(traj)
    grads = {name: parameters.gradient(name, start, sim.model, held) for name in names}
    return float(value.numpy()[0]), grads

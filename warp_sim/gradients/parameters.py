"""What a gradient can be taken with respect to (the names of ``wrt``), and each gradient from the backward pass.

The adjoint lands on the initial state's fields, the model's arrays and the controls; each name turns those into
d loss / d (what the user set), float64 numpy:

- the initial state: ``particle_x``, ``particle_v``, ``body_x`` as they are; ``body_v`` from the momentum's,
  P0 = M v0; ``body_w`` from the angular momentum's, L0 = R I_body R^T w0 (world frame);
- ``particle_mass`` from 1/m's (a pinned particle's mass does not enter: 0); ``body_mass`` with the body's shape
  held, so its inertia scales with it, and its initial velocities held (P0 = M v0, L0 = M I_unit w0), as
  ``Scene.add_rigid_body(shape, mass=M)`` does;
- ``spring_stiffness``, ``spring_damping``, ``spring_rest_length`` in ``scene.spring_array`` order;
- ``restitution`` (bodies,) and ``plane_restitution`` (planes,), each side's own: a contact's restitution is the
  mean of its two sides' (a body and a body or a plane), so d/d e_body is half d/d e_pair of each of its
  contacts; the gradient flows through the taped body-contact response (passes.contact_adjoint) at the time of
  impact, and plane_restitution's through the particles' plane impacts too (not particles' own restitutions);
- ``friction`` (bodies,) and ``plane_friction`` (planes,) the same way, through the friction impulses of the
  taped response: where a contact slides, the Coulomb limit mu Jn moves with mu; where it sticks, friction is
  whatever stops the sliding and mu does not enter (its gradient there is 0, the one-sided derivative of a
  contact that stays stuck);
- ``gravity`` by the chain rule through the per-frame forces: g enters a free particle's acceleration as a force
  m g and a body's as M g, so d loss / d g = sum over frames of sum_i m_i dL/dF_i + sum_b M_b dL/dF_b (the
  kernels take g by value, which no tape differentiates);
- the controls (gradients.controls) as they are.
"""
from __future__ import annotations

import numpy as np

from ..core.model import Model
from ..core.state import State
from ..util import checks
from ..util.rotations import quat_to_matrix
from .controls import CONTROLS, Controls

#: each name: the model's count it needs (or None), and what it is (with its shape)
WRT = {
    "particle_x": ("particle_count", "the initial particle positions (particles, 3) [m]"),
    "particle_v": ("particle_count", "the initial particle velocities (particles, 3) [m/s]"),
    "body_x": ("body_count", "the initial centres of mass (bodies, 3) [m]"),
    "body_v": ("body_count", "the initial linear velocities (bodies, 3) [m/s], world frame"),
    "body_w": ("body_count", "the initial angular velocities (bodies, 3) [rad/s], world frame"),
    "particle_mass": ("particle_count", "the particle masses (particles,) [kg]"),
    "body_mass": ("body_count", "the body masses (bodies,) [kg], shapes held"),
    "spring_stiffness": ("spring_count", "the spring stiffnesses (springs,) [N/m]"),
    "spring_damping": ("spring_count", "the spring dampings (springs,) [N s/m]"),
    "spring_rest_length": ("spring_count", "the spring rest lengths (springs,) [m]"),
    "restitution": ("body_count", "the bodies' restitutions (bodies,) [1], a contact taking the mean of its sides'"),
    "plane_restitution": ("plane_count", "the planes' restitutions (planes,) [1]"),
    "friction": ("body_count", "the bodies' friction coefficients (bodies,) [1], a contact taking the mean of its "
                 "sides'"),
    "plane_friction": ("plane_count", "the planes' friction coefficients (planes,) [1]"),
    "gravity": (None, "the gravitational acceleration (3,) [m/s^2]"),
    "body_force": ("body_count", "the per-frame forces on the bodies (frames, bodies, 3) [N]"),
    "body_torque": ("body_count", "the per-frame torques on the bodies (frames, bodies, 3) [N m]"),
    "particle_force": ("particle_count", "the per-frame forces on the particles (frames, particles, 3) [N]"),
}

def _count(scene, count: str) -> int:
    """The scene's number of the parts ``count`` names (a Scene has no plane_count: its planes' length)."""
    return len(scene.planes) if count == "plane_count" else getattr(scene, count)


def names(wrt, scene) -> list[str]:
    """``wrt`` checked: a list (or tuple) of distinct names of WRT, each of a part the scene has (its counts)."""
    if isinstance(wrt, str) or not isinstance(wrt, (list, tuple)):
        raise checks.fail("wrt", wrt, f"expected a list of names among {', '.join(WRT)}")
    for name in wrt:
        if name not in WRT:
            raise checks.fail("wrt", name, f"no such name; expected names among {', '.join(WRT)}")
        count = WRT[name][0]
        if count is not None and _count(scene, count) == 0:
            raise checks.fail("wrt", name, f"it is {WRT[name][1]}, and the scene has none")
    if len(set(wrt)) != len(wrt):
        raise checks.fail("wrt", wrt, "expected each name once")
    return list(wrt)


def controls_needed(wrt: list[str], model: Model) -> set[str]:
    """The per-frame controls the backward pass must follow: those in ``wrt``, and for gravity the forces on every
    particle and body the scene has."""
    needed = {name for name in wrt if name in CONTROLS}
    if "gravity" in wrt:
        needed |= {name for name in ("particle_force", "body_force") if getattr(model, CONTROLS[name][1])}
    return needed


def _grad(array) -> np.ndarray:
    return array.grad.numpy().astype(np.float64)


def _masses(inv_mass: np.ndarray) -> np.ndarray:
    """m = 1 / w, 0 where w is 0 (pinned: no force moves it, so nothing flows through its mass)."""
    return np.divide(1.0, inv_mass, out=np.zeros_like(inv_mass), where=inv_mass != 0.0)


def gradient(name: str, start: State, model: Model, controls: Controls) -> np.ndarray:
    """d loss / d ``name`` from the adjoint of the initial state ``start`` (after the backward pass), the model's
    arrays' gradients and the controls'."""
    if name in ("particle_x", "particle_v", "body_x"):
        return _grad(getattr(start, name))
    if name in CONTROLS:
        return controls.gradient(name)
    if name in ("restitution", "friction"):
        return _grad(getattr(model, f"body_{name}"))
    if name.startswith("spring_") or name in ("plane_restitution", "plane_friction"):
        return _grad(getattr(model, name))
    if name == "particle_mass":
        w = model.particle_inv_mass.numpy().astype(np.float64)
        return -w * w * _grad(model.particle_inv_mass)
    if name == "gravity":
        total = np.zeros(3)
        for control, inv_mass in (("particle_force", model.particle_inv_mass), ("body_force", model.body_inv_mass)):
            if control in controls.arrays:
                masses = _masses(inv_mass.numpy().astype(np.float64))
                total += np.einsum("i,kij->j", masses, controls.gradient(control))
        return total
    w = model.body_inv_mass.numpy().astype(np.float64)
    if name == "body_v":
        return _grad(start.body_P) / w[:, None]
    q, L = start.body_q.numpy().astype(np.float64), start.body_L.numpy().astype(np.float64)
    inv_inertia = model.body_inv_inertia.numpy().astype(np.float64)
    if name == "body_w":
        rotations = np.array([quat_to_matrix(qi / np.linalg.norm(qi)) for qi in q])
        inertia = rotations @ np.linalg.inv(inv_inertia) @ rotations.transpose(0, 2, 1)
        return np.einsum("bij,bj->bi", inertia, _grad(start.body_L))   # I symmetric: I^T dL/dL0
    # body_mass: w = 1/M and I^-1 = I_unit^-1 / M change with M, and so do P0 = M v0 and L0 = M I_unit w0
    P = start.body_P.numpy().astype(np.float64)
    return (-w * w * _grad(model.body_inv_mass)
            - w * np.einsum("bij,bij->b", inv_inertia, _grad(model.body_inv_inertia))
            + w * np.einsum("bi,bi->b", P, _grad(start.body_P))
            + w * np.einsum("bi,bi->b", L, _grad(start.body_L)))

"""Per-frame controls: forces and torques held over each frame, whose gradients the backward pass fills."""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..util import checks

#: each control: the component it acts on, the model's count of it, and what it is
CONTROLS = {
    "body_force": ("bodies", "body_count", "a force at each body's centre of mass [N], world frame"),
    "body_torque": ("bodies", "body_count", "a torque about each body's centre of mass [N m], world frame"),
    "particle_force": ("particles", "particle_count", "a force on each particle [N]"),
}


def check(given, frames: int, scene) -> dict:
    """``controls`` checked against the scene (its counts) before anything runs: name -> (frames, count, 3) float64."""
    if given is None:
        return {}
    if not isinstance(given, dict):
        raise checks.fail("controls", given, f"expected a dict of per-frame controls, keys among {', '.join(CONTROLS)}")
    checked = {}
    for name, value in given.items():
        if name not in CONTROLS:
            raise checks.fail("controls", name, f"no such control; expected keys among {', '.join(CONTROLS)}")
        component, count_name, what = CONTROLS[name]
        count = getattr(scene, count_name)
        if count == 0:
            raise checks.fail("controls", name, f"{what}, and the scene has no {component}")
        if isinstance(value, wp.array):
            value = value.numpy()
        checked[name] = checks.finite_array(f"controls[{name!r}]", value, (frames, count, 3))
    return checked


class Controls:
    """The per-frame controls of a differentiable run: for each name, a (frames, count) array of vec3 with a gradient,
    row j held over frame j (from t = j / fps to (j + 1) / fps).

    values: name -> (frames, count, 3) numpy values (``check``'s); needed: names to follow even where not given
    arrays: name -> its array, for the controls given or needed (the others act as zero)
    """

    def __init__(self, model: Model, frames: int, values: dict, needed):
        self.model = model
        self.arrays = {}
        for name, (_, count_name, _) in CONTROLS.items():
            if name in values or name in needed:
                initial = values.get(name, np.zeros((frames, getattr(model, count_name), 3)))
                self.arrays[name] = wp.array(initial.astype(model.numpy_scalar), dtype=model.vec3,
                                             device=model.device, requires_grad=True)

    def apply(self, sim, frame: int) -> None:
        """Hold row ``frame`` of each control on ``sim`` (a differentiable Simulator) for its next frame."""
        force, torque = self.arrays.get("body_force"), self.arrays.get("body_torque")
        if force is not None or torque is not None:
            sim.control.hold(sim.control.body_force if force is None else force[frame],
                             sim.control.body_torque if torque is None else torque[frame])
        particles = self.arrays.get("particle_force")
        if particles is not None:
            sim.dynamics.particle_force = particles[frame]

    def gradient(self, name: str) -> np.ndarray:
        """d loss / d control ``name``, (frames, count, 3) float64 (after the backward pass)."""
        return self.arrays[name].grad.numpy().astype(np.float64)

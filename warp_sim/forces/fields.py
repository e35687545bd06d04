"""The scene's force fields (Attractor, Vortex, Turbulence) as one force term on the particles."""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..core.protocols import Forces, ForceTerm
from ..core.state import State
from ..kernels import blocks
from ..kernels import fields as field_kernels
from ..scene.fields import Attractor, Turbulence, Vortex
from ..util import checks
from .turbulence import TurbulenceGrids


class FieldForces(ForceTerm):
    """The scene's force fields as one force term: one launch per field kind present.

    fields: the scene's field descriptions (warp_sim.scene.fields).
    """

    targets = frozenset({"particles"})
    kernels = ("fields",)

    def __init__(self, model: Model, fields: list):
        self.model = model
        fields = list(fields)
        for field in fields:
            if not isinstance(field, (Attractor, Vortex, Turbulence)):   # e.g. a user's own Field subclass
                raise checks.fail("field", field, "expected a warp_sim force field: Attractor, Vortex or Turbulence")

        def array(values):
            values = np.ascontiguousarray(values, dtype=model.numpy_scalar)
            return wp.array(values, dtype=model.vec3 if values.ndim == 2 else model.scalar, device=model.device)

        attractors = [f for f in fields if isinstance(f, Attractor)]
        vortices = [f for f in fields if isinstance(f, Vortex)]
        turbulence = [f for f in fields if isinstance(f, Turbulence)]
        B = model.blocks
        self.attractors = self.vortices = self.turbulence = None
        if attractors:
            self.attractors = blocks.fill(B.Attractors, center=array([f.position for f in attractors]),
                                          strength=array([f.strength for f in attractors]),
                                          min_distance=array([f.min_distance for f in attractors]))
        if vortices:
            self.vortices = blocks.fill(B.Vortices, center=array([f.position for f in vortices]),
                                        axis=array([f.axis for f in vortices]),
                                        strength=array([f.strength for f in vortices]),
                                        core_radius=array([f.core_radius for f in vortices]))
        if turbulence:   # baked here, once: its grids are derived from the scene (nothing to checkpoint)
            self.turbulence = TurbulenceGrids(turbulence, model.scalar, model.device, model.launch)
        #: a time-varying turbulence blends its potentials at each step's time (host weights): not capturable
        self.capturable = not any(field.frequency > 0.0 for field in turbulence)

    def apply(self, state: State, t: float, forces: Forces) -> None:
        m, k = self.model, field_kernels
        x, w, f = state.particle_x, m.particle_inv_mass, forces.particle_f
        if self.attractors is not None:
            m.launch(k.attractor_forces, m.particle_count, [x, w, self.attractors, f])
        if self.vortices is not None:
            m.launch(k.vortex_forces, m.particle_count, [x, w, self.vortices, f])
        if self.turbulence is not None:
            m.launch(k.turbulence_forces, m.particle_count, [x, w, self.turbulence.block, self.turbulence.at(t), f])

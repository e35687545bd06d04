"""Aerodynamic drag and lift on the triangles of cloths in the wind (the scene's ``wind``). SI units.

Each triangle of a mesh with a drag or lift coefficient is a flat plate in the air,
the standard cloth model (Keckeisen et al. 2004, after Provot): with

    u = (v_a + v_b + v_c) / 3 - wind     the air's velocity relative to the triangle [m/s]
    n, A                                 its unit normal and area from the current positions
    cos(theta) = n . u / |u|             theta: the angle between the normal and u
    l = (n - cos(theta) u / |u|) / sin(theta)
                                         the unit vector normal to u in the plane of u and n,
                                         on n's side (l . n = sin(theta) >= 0)

the triangle feels

    drag  F_D = -1/2 rho C_D A |u| (u . n) n
              = -1/2 rho C_D A |u|^2 cos(theta) n
    lift  F_L = -1/2 rho C_L A |u|^2 cos(theta) sin(theta) l
              = -1/2 rho C_L A (u . n) (|u| n - (u . n) u / |u|)

Both are even in n, so the winding of the triangle does not matter. The drag is
along the normal and opposes the normal component of u: a triangle moving in its
own plane (u . n = 0) feels none, one moving face-on feels 1/2 rho C_D A |u|^2
against its motion. The lift is normal to u and pushes the triangle towards the side
the air's normal component points to (the wind lifts a tilted kite); it vanishes
face-on and edge-on and peaks at theta = 45 degrees. rho is the mesh's air_density
[kg/m^3], C_D and C_L its dimensionless drag and lift coefficients (>= 0). Each
triangle's force is split equally over its three vertices; a pinned vertex receives
its share and ignores it (its inverse mass is 0).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..core.protocols import Forces, ForceTerm
from ..core.state import State
from ..kernels import cloth as cloth_kernels
from ..util import checks


class AeroForces(ForceTerm):
    """Drag and lift on every triangle of every mesh whose drag or lift is non-zero: one launch.

    Per-triangle arrays are built once from ``meshes`` (the scene's SurfaceMeshes): ``triangles``
    (vec3i, global particle indices), ``drag`` and ``lift`` (1/2 rho C_D and
    1/2 rho C_L of the triangle's mesh [kg/m^3]), so meshes may differ. Raises
    ValueError for a negative drag or lift, an air_density <= 0, or triangles that are
    not (T, 3) particle indices.
    """

    kernels = ("cloth",)

    targets = frozenset({"particles"})

    def __init__(self, model: Model, meshes: list):
        self.model = model
        triangles, drag, lift = [np.zeros((0, 3), dtype=np.int64)], [np.zeros(0)], [np.zeros(0)]
        for mesh in meshes:
            c_drag = mesh.parameter("drag", low=0.0)
            c_lift = mesh.parameter("lift", low=0.0)
            rho = mesh.parameter("air_density", low=0.0, low_open=True)
            if c_drag == 0.0 and c_lift == 0.0:
                continue
            try:
                tris = checks.indices("triangles", mesh.triangles, model.particle_count, (-1, 3))
            except ValueError as error:
                raise ValueError(f"{error} (mesh {mesh.name!r})") from None
            triangles.append(tris)
            drag.append(np.full(len(tris), 0.5 * rho * c_drag))
            lift.append(np.full(len(tris), 0.5 * rho * c_lift))
        tris = np.concatenate(triangles)
        self.triangle_count = len(tris)
        self.triangles = wp.array(tris.astype(np.int32), dtype=wp.vec3i, device=model.device)
        self.drag = wp.array(np.concatenate(drag).astype(model.numpy_scalar), dtype=model.scalar,
                             device=model.device)
        self.lift = wp.array(np.concatenate(lift).astype(model.numpy_scalar), dtype=model.scalar,
                             device=model.device)

    def apply(self, state: State, t: float, forces: Forces) -> None:
        m = self.model
        m.launch(cloth_kernels.aerodynamic_forces, self.triangle_count,
                 [state.particle_x, state.particle_v, self.triangles, self.drag, self.lift, m.wind,
                  forces.particle_f])

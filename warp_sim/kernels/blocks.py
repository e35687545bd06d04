"""Structs for the argument blocks many kernels share, one set per precision.

A kernel takes a block as one argument (``bodies: Any``, ``springs: Any``) and reads its
arrays as fields (``bodies.q[i]``, ``springs.stiffness[s]``); Warp picks the overload from
the struct's type, so a kernel stays generic over precision. ``of(scalar)`` gives the
structs of one precision (``of(wp.float64).Springs()``); each field's dtype and unit:

- Bodies: rigid-body state or its rates, one row per body: x [m] (vec3, the centre of mass),
  q (quat x, y, z, w), P [kg m/s] (vec3), L [kg m^2/s] (vec3); as rates: [m/s], [1/s], [N], [N m]
- BodyMass: inv_mass [1/kg] (scalar), inv_inertia: I_body^-1 in the body frame [1/(kg m^2)] (mat33)
- Wrench: force [N] and torque [N m] about the centre of mass (vec3 each), one row per body
- Springs: pairs (vec2i, particle indices), stiffness [N/m], damping [N s/m], rest_length [m]
- Planes: normal (unit vec3), offset [m] (the plane normal . x = offset), restitution [1], friction [1]
- ParticleMaterial: inv_mass [1/kg] (0: pinned), radius [m], restitution [1] and friction [1]
  (empty arrays where no particle has its own value; else per particle, < 0 meaning "none")
- BodyVelocities (the contact response's working set): v [m/s], w [rad/s] (vec3), inv_inertia_world
  [1/(kg m^2)] (mat33), impact: the earliest impact of each body as a fraction of the step [1], stamp: the
  last sweep that changed the body (int32, -1: none; the sweeps skip manifolds nothing changed)
- ContactRows (one row per contact): anchor1, anchor2 [m] (body frames), rounding1, rounding2 [m],
  normal (unit vec3), impact_time [s], after_impact [m/s], min_normal_speed [m/s], restitution [1],
  friction [1], impulse_n [N s], impulse_t [N s] (vec3), target [m/s], collision_n [N s], collision_t [N s],
  and for the resting solve, fixed over it: lever1, lever2 [m] (world offsets from the centres to the contact at
  the end poses), tangent1, tangent2 (unit vec3, tangent1 along the slide), mass_n, mass_t1, mass_t2 [kg]
  (effective masses along n and the tangents)
- Attractors: center [m] (vec3), strength GM [m^3/s^2], min_distance [m]
- Vortices: center [m] (vec3), axis (unit vec3), strength [m^2/s^2], core_radius [m]
- Turbulences (made by warp_sim.forces.turbulence): strength [m/s^2], inv_period [1/m] (1 / the period of the
  field's grid), nodes (int32, the grid's nodes per axis), offset (int32, the grid's first node in the potential
  array turbulence_forces takes)
- ImpulseTable (warm starting, open addressing): used (int32), keys (vec2i), cells (vec3i), n [N s], t [N s]
- Joints (one row per joint, in colour order; passes.joints): ids (vec2i: parent, -1 for the world, and child),
  anchor_p, anchor_c [m] and frame_p, frame_c (quat) in each body's frame (the world's for -1); lin_mode,
  ang_mode (vec3i per joint-frame axis: 0 free, 1 locked, 2 limited), lin_lower, lin_upper [m], ang_lower,
  ang_upper [rad]; cone [rad] (< 0: none), dist_min, dist_max [m] (< 0: none); drive_lin, drive_ang (vec3i per
  axis: 0 none, 1 force, 2 acceleration), their lin_target, ang_target [m, rad], lin_speed, ang_speed [m/s,
  rad/s], lin_stiffness, ang_stiffness [N/m, N m/rad], lin_damping, ang_damping [N s/m, N m s/rad] and lin_max,
  ang_max [N, N m]; break_force [N], break_torque [N m] (< 0: never), enabled (int32:
  1 simulated, 0 broken or disabled); the step's accumulated impulses per joint-frame axis (warm-started from
  the last step's): lam_lin [N s], lam_ang [N m s], lam_drive_lin, lam_drive_ang, lam_cone, lam_dist
"""
import types

import warp as wp

__all__ = ["of", "fill"]


#: every block's fields and their element kinds: "scalar", "vec3", "quat", "mat33" (of the precision) or a Warp type
LAYOUTS = {
    "Bodies": {"x": "vec3", "q": "quat", "P": "vec3", "L": "vec3"},
    "BodyMass": {"inv_mass": "scalar", "inv_inertia": "mat33"},
    "Wrench": {"force": "vec3", "torque": "vec3"},
    "Springs": {"pairs": wp.vec2i, "stiffness": "scalar", "damping": "scalar", "rest_length": "scalar"},
    "Planes": {"normal": "vec3", "offset": "scalar", "restitution": "scalar", "friction": "scalar"},
    "ParticleMaterial": {"inv_mass": "scalar", "radius": "scalar", "restitution": "scalar", "friction": "scalar"},
    "BodyVelocities": {"v": "vec3", "w": "vec3", "inv_inertia_world": "mat33", "impact": "scalar",
                       "stamp": wp.int32},
    "ContactRows": {"anchor1": "vec3", "anchor2": "vec3", "rounding1": "scalar", "rounding2": "scalar",
                    "normal": "vec3", "impact_time": "scalar", "after_impact": "scalar", "min_normal_speed": "scalar",
                    "restitution": "scalar", "friction": "scalar", "impulse_n": "scalar", "impulse_t": "vec3",
                    "target": "scalar", "collision_n": "scalar", "collision_t": "vec3", "lever1": "vec3",
                    "lever2": "vec3", "tangent1": "vec3", "tangent2": "vec3", "mass_n": "scalar", "mass_t1": "scalar",
                    "mass_t2": "scalar"},
    "Attractors": {"center": "vec3", "strength": "scalar", "min_distance": "scalar"},
    "Vortices": {"center": "vec3", "axis": "vec3", "strength": "scalar", "core_radius": "scalar"},
    "Turbulences": {"strength": "scalar", "inv_period": "scalar", "nodes": wp.int32, "offset": wp.int32},
    "ImpulseTable": {"used": wp.int32, "keys": wp.vec2i, "cells": wp.vec3i, "n": "scalar", "t": "vec3"},
    "Joints": {"ids": wp.vec2i, "anchor_p": "vec3", "anchor_c": "vec3", "frame_p": "quat", "frame_c": "quat",
               "lin_mode": wp.vec3i, "ang_mode": wp.vec3i, "lin_lower": "vec3", "lin_upper": "vec3",
               "ang_lower": "vec3", "ang_upper": "vec3", "cone": "scalar", "dist_min": "scalar",
               "dist_max": "scalar", "drive_lin": wp.vec3i, "drive_ang": wp.vec3i, "lin_target": "vec3",
               "ang_target": "vec3", "lin_speed": "vec3", "ang_speed": "vec3", "lin_stiffness": "vec3",
               "ang_stiffness": "vec3", "lin_damping": "vec3", "ang_damping": "vec3", "lin_max": "vec3",
               "ang_max": "vec3", "break_force": "scalar", "break_torque": "scalar", "enabled": wp.int32,
               "lam_lin": "vec3", "lam_ang": "vec3", "lam_drive_lin": "vec3", "lam_drive_ang": "vec3",
               "lam_cone": "scalar", "lam_dist": "scalar"},
}


def _define(kinds: dict) -> types.SimpleNamespace:
    """The structs of LAYOUTS with the element kinds of one precision, e.g. {"scalar": wp.float64, ...}."""
    structs = {}
    for name, fields in LAYOUTS.items():
        annotations = {field: wp.array(dtype=kinds.get(kind, kind)) for field, kind in fields.items()}
        structs[name] = wp.struct(type(name, (), {"__annotations__": annotations, "__module__": __name__,
                                                  "__qualname__": name}))
    return types.SimpleNamespace(**structs)


_STRUCTS = {scalar: _define({"scalar": scalar, "vec3": vec3, "quat": quat, "mat33": mat33})
            for scalar, vec3, quat, mat33 in ((wp.float32, wp.vec3f, wp.quatf, wp.mat33f),
                                              (wp.float64, wp.vec3d, wp.quatd, wp.mat33d))}


def of(scalar) -> types.SimpleNamespace:
    """The block structs of one precision (wp.float32 or wp.float64), one per LAYOUTS entry: Bodies, BodyMass,
    Wrench, Springs, Planes, ParticleMaterial, BodyVelocities, ContactRows, Attractors, Vortices, Turbulences,
    ImpulseTable."""
    return _STRUCTS[scalar]


def fill(struct_type, **arrays):
    """A struct of ``struct_type`` with its fields set from ``arrays`` (every field must be given)."""
    block = struct_type()
    for name, array in arrays.items():
        setattr(block, name, array)
    return block

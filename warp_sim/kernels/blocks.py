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
  [1/(kg m^2)] (mat33), impact: the earliest impact of each body as a fraction of the step [1]
- ContactRows (one row per contact): anchor1, anchor2 [m] (body frames), rounding1, rounding2 [m],
  normal (unit vec3), impact_time [s], after_impact [m/s], min_normal_speed [m/s], restitution [1],
  friction [1], impulse_n [N s], impulse_t [N s] (vec3), target [m/s], collision_n [N s], collision_t [N s]
- ImpulseTable (warm starting, open addressing): used (int32), keys (vec2i), cells (vec3i), n [N s], t [N s]
"""
import types

import warp as wp

__all__ = ["of", "fill"]


def _define(scalar, vec3, quat, mat33) -> types.SimpleNamespace:
    @wp.struct
    class Bodies:
        x: wp.array(dtype=vec3)
        q: wp.array(dtype=quat)
        P: wp.array(dtype=vec3)
        L: wp.array(dtype=vec3)

    @wp.struct
    class BodyMass:
        inv_mass: wp.array(dtype=scalar)
        inv_inertia: wp.array(dtype=mat33)

    @wp.struct
    class Wrench:
        force: wp.array(dtype=vec3)
        torque: wp.array(dtype=vec3)

    @wp.struct
    class Springs:
        pairs: wp.array(dtype=wp.vec2i)
        stiffness: wp.array(dtype=scalar)
        damping: wp.array(dtype=scalar)
        rest_length: wp.array(dtype=scalar)

    @wp.struct
    class Planes:
        normal: wp.array(dtype=vec3)
        offset: wp.array(dtype=scalar)
        restitution: wp.array(dtype=scalar)
        friction: wp.array(dtype=scalar)

    @wp.struct
    class ParticleMaterial:
        inv_mass: wp.array(dtype=scalar)
        radius: wp.array(dtype=scalar)
        restitution: wp.array(dtype=scalar)
        friction: wp.array(dtype=scalar)

    @wp.struct
    class BodyVelocities:
        v: wp.array(dtype=vec3)
        w: wp.array(dtype=vec3)
        inv_inertia_world: wp.array(dtype=mat33)
        impact: wp.array(dtype=scalar)

    @wp.struct
    class ContactRows:
        anchor1: wp.array(dtype=vec3)
        anchor2: wp.array(dtype=vec3)
        rounding1: wp.array(dtype=scalar)
        rounding2: wp.array(dtype=scalar)
        normal: wp.array(dtype=vec3)
        impact_time: wp.array(dtype=scalar)
        after_impact: wp.array(dtype=scalar)
        min_normal_speed: wp.array(dtype=scalar)
        restitution: wp.array(dtype=scalar)
        friction: wp.array(dtype=scalar)
        impulse_n: wp.array(dtype=scalar)
        impulse_t: wp.array(dtype=vec3)
        target: wp.array(dtype=scalar)
        collision_n: wp.array(dtype=scalar)
        collision_t: wp.array(dtype=vec3)

    @wp.struct
    class ImpulseTable:
        used: wp.array(dtype=wp.int32)
        keys: wp.array(dtype=wp.vec2i)
        cells: wp.array(dtype=wp.vec3i)
        n: wp.array(dtype=scalar)
        t: wp.array(dtype=vec3)

    return types.SimpleNamespace(**{cls.__name__: cls for cls in (
        Bodies, BodyMass, Wrench, Springs, Planes, ParticleMaterial, BodyVelocities, ContactRows, ImpulseTable)})


_STRUCTS = {wp.float32: _define(wp.float32, wp.vec3f, wp.quatf, wp.mat33f),
            wp.float64: _define(wp.float64, wp.vec3d, wp.quatd, wp.mat33d)}


def of(scalar) -> types.SimpleNamespace:
    """The block structs of one precision (wp.float32 or wp.float64): Bodies, BodyMass, Wrench, Springs,
    Planes, ParticleMaterial, BodyVelocities, ContactRows, ImpulseTable."""
    return _STRUCTS[scalar]


def fill(struct_type, **arrays):
    """A struct of ``struct_type`` with its fields set from ``arrays`` (every field must be given)."""
    block = struct_type()
    for name, array in arrays.items():
        setattr(block, name, array)
    return block

"""Penalty contacts: a spring on the penetration depth and a damper chosen for the contact's restitution.

One damping model for every penalty contact (particles on planes, bodies on bodies, colliders
and planes): the contact is a linear spring-dashpot that cannot pull, and its damping ratio is
the one at which such a contact rebounds with restitution e (Schwager and Poeschel 2007).

Public (``__all__``): plane_penalty_forces.
Private: body_penalty_forces (it takes the simulator's own contact buffers) and the Warp
functions no_tension_log_restitution, restitution_damping_ratio and penalty_damping, for the
simulator's own use; their arguments may change between releases.
"""
from typing import Any

import warp as wp

from .contacts import body_point_velocity, pair_material
from .detection import ContactBuffer, Geoms, is_body
from .planes import contact_material
from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = ["plane_penalty_forces"]


@wp.func
def no_tension_log_restitution(zeta: Any):
    """-ln e of a linear spring-dashpot contact that cannot pull, at damping ratio zeta.

    The contact ends when the force k x + c x' reaches zero (before the spring is
    back at rest length), so e exceeds the free oscillator's exp(-zeta pi / sqrt(1 - zeta^2)):
    e = exp(-zeta/s (pi - atan2(2 zeta s, 1 - 2 zeta^2))), s = sqrt(1 - zeta^2), below
    critical damping; e = exp(-zeta/s atanh(2 zeta s / (2 zeta^2 - 1))), s = sqrt(zeta^2 - 1), above
    (Schwager and Poeschel, Phys. Rev. E 2007).
    """
    one = type(zeta)(1.0)
    two = type(zeta)(2.0)
    result = two
    if zeta < one:
        s = wp.sqrt(one - zeta * zeta)
        result = zeta / s * (type(zeta)(3.141592653589793) - wp.atan2(two * zeta * s, one - two * zeta * zeta))
    elif zeta > one:
        s = wp.sqrt(zeta * zeta - one)
        u = two * zeta * s / (two * zeta * zeta - one)
        result = zeta / s * type(zeta)(0.5) * wp.log((one + u) / (one - u))
    return result


@wp.func
def restitution_damping_ratio(e: Any):
    """The damping ratio zeta at which a no-tension penalty contact rebounds with restitution e, at most 1.

    Bisection on the monotone -ln e(zeta) over [0, 1]. A critically damped no-tension contact still
    rebounds with e = exp(-2) = 0.135; lower restitutions would need a damper far above critical, whose
    rate 2 zeta omega exceeds the explicit solvers' stability limit at ordinary steps, so e below
    exp(-2) (e = 0 included) gets critical damping, zeta = 1, and rebounds with e = 0.135.
    """
    target = -wp.log(wp.clamp(e, type(e)(1e-4), type(e)(1.0)))
    low = type(e)(0.0)
    high = type(e)(1.0)
    for _ in range(48):
        mid = type(e)(0.5) * (low + high)
        if no_tension_log_restitution(mid) < target:
            low = mid
        else:
            high = mid
    return type(e)(0.5) * (low + high)


@wp.func
def penalty_damping(stiffness: Any, mass: Any, e: Any):
    """The damper c [N s/m] of a no-tension spring-dashpot contact of stiffness k [N/m] on mass m [kg]
    that rebounds with restitution e: c = 2 zeta(e) sqrt(k m), zeta from restitution_damping_ratio.
    The one damping model of every penalty contact, particles and bodies alike."""
    return type(stiffness)(2.0) * restitution_damping_ratio(e) * wp.sqrt(stiffness * mass)


@wp.kernel
def plane_penalty_forces(
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    material: Any,
    planes: Any,
    stiffness: Any,
    force: wp.array(dtype=Any),
):
    """Accumulate penalty forces: a spring and damper on the penetration depth.

    depth = offset_k + r - n_k . x for each plane k the particle's sphere overlaps;
    f_n = max(0, k depth - c v_n) along n, with k the stiffness [N/m] and the damper c of
    penalty_damping, so that an isolated contact rebounds with the contact's restitution e. Friction opposes
    the tangential velocity with magnitude min(mu f_n, c |v_t|): Coulomb when
    sliding, viscous (slow creep) below the speed mu f_n / c. Restitution and friction
    are the plane's, averaged with the particle's own where it has one. Launch with
    dim = the number of particles; pinned particles are skipped.

    Args:
        x: particle positions (vec3) [m]
        v: particle velocities (vec3) [m/s]
        material: inverse masses (0: pinned, skipped), radii, own restitution and friction (ParticleMaterial) [1/kg]
        planes: unit normals n_k to the allowed side, offsets n_k . x = offset_k, restitution, friction (Planes) [m]
        stiffness: the penalty spring constant k [N/m]
        force: per-particle force accumulator, added to (vec3) [N]
    """
    i = wp.tid()
    w = material.inv_mass[i]
    zero = type(stiffness)(0.0)
    if w == zero:
        return
    mass = type(stiffness)(1.0) / w
    total = x[i] * zero
    for k in range(planes.normal.shape[0]):
        n = planes.normal[k]
        depth = planes.offset[k] + material.radius[i] - wp.dot(n, x[i])
        if depth > zero:
            e = contact_material(planes.restitution[k], material.restitution, i)
            c = penalty_damping(stiffness, mass, e)
            vn = wp.dot(v[i], n)
            fn = wp.max(stiffness * depth - c * vn, zero)
            vt = v[i] - vn * n
            speed = wp.length(vt)
            total = total + fn * n
            if speed > zero:
                mu = contact_material(planes.friction[k], material.friction, i)
                total = total - vt * (wp.min(mu * fn, c * speed) / speed)
    wp.atomic_add(force, i, total)


@wp.kernel
def body_penalty_forces(contacts: ContactBuffer, geoms: Geoms, bodies: Any, mass: Any, stiffness: Any,
                        accumulated: Any):
    """Spring and damper on each body contact's overlap: F_n = max(k depth - c v_n, 0) along n, with the damper
    of penalty_damping for the pair's reduced mass (the contact rebounds with its restitution e); friction
    opposes sliding with min(mu F_n, c |v_t|). bodies: Bodies; mass: BodyMass; accumulated: the force [N]
    and torque [N m] accumulators (Wrench)."""
    c = wp.tid()
    i = contacts.ids[c][0]
    j = contacts.ids[c][1]
    zero = type(stiffness)(0.0)
    n = type(bodies.x[0])(contacts.normal[c])
    p1 = type(n)(contacts.point1[c]) - n * type(stiffness)(contacts.radius1[c])   # the surface points
    p2 = type(n)(contacts.point2[c]) + n * type(stiffness)(contacts.radius2[c])
    depth = -wp.dot(n, p1 - p2)
    if depth <= zero:
        return
    r1 = p1 - bodies.x[i]
    rel = body_point_velocity(bodies, mass, i, r1)
    inverse_mass = mass.inv_mass[i]
    dynamic = is_body(j, geoms.body_count)
    r2 = p2 * zero
    if dynamic:
        r2 = p2 - bodies.x[j]
        rel -= body_point_velocity(bodies, mass, j, r2)
        inverse_mass += mass.inv_mass[j]
    e32, mu32 = pair_material(geoms, i, j)
    e = type(stiffness)(e32)
    mu = type(stiffness)(mu32)
    damping = penalty_damping(stiffness, type(stiffness)(1.0) / inverse_mass, e)
    vn = wp.dot(rel, n)
    fn = wp.max(stiffness * depth - damping * vn, zero)
    slide = rel - n * vn
    speed = wp.length(slide)
    F = n * fn
    if speed > type(stiffness)(1.0e-12):
        F -= slide * (wp.min(mu * fn, damping * speed) / speed)
    wp.atomic_add(accumulated.force, i, F)
    wp.atomic_add(accumulated.torque, i, wp.cross(r1, F))
    if dynamic:
        wp.atomic_sub(accumulated.force, j, F)
        wp.atomic_sub(accumulated.torque, j, wp.cross(r2, F))


register(globals())

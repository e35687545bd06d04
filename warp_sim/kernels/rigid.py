"""Rigid-body state updates: the lecture's S = [x, R, P, L] with R stored as a unit quaternion q.

Per body: x the centre of mass [m], q = (x, y, z, w) the orientation, P the linear
momentum [kg m/s], L the angular momentum [kg m^2/s], all in world coordinates.
Constants: 1/M [1/kg] and the body-space inverse inertia I_body^-1 [1/(kg m^2)].
Every derivative evaluation computes the auxiliaries as the lecture does:
v = P / M, I(t)^-1 = R I_body^-1 R^T, omega = I(t)^-1 L. Each kernel but apply_impulse
runs one thread per body: launch with dim = the number of bodies.

Public (``__all__``): body_momentum_rates, body_position_rates, normalize_orientations,
body_velocities, rotation_matrices, apply_impulse (all the module's kernels).
Private: the Warp functions angular_velocity and orientation_rate, for the simulator's own
use; their arguments may change between releases.
"""
from typing import Any

import warp as wp

from .precisions import register

__all__ = ["body_momentum_rates", "body_position_rates", "normalize_orientations", "body_velocities",
           "rotation_matrices", "apply_impulse"]

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.func
def angular_velocity(q: Any, inv_inertia_body: Any, L: Any):
    """omega = R I_body^-1 R^T L [rad/s], with R the rotation of q normalised."""
    unit = wp.normalize(q)
    return wp.quat_rotate(unit, inv_inertia_body * wp.quat_rotate_inv(unit, L))


@wp.func
def orientation_rate(q: Any, omega: Any):
    """dq/dt = 1/2 (omega, 0) q, the quaternion form of dR/dt = omega* R [1/s]."""
    half = type(omega[0])(0.5)
    spin = type(q)(omega[0], omega[1], omega[2], type(omega[0])(0.0))
    return (spin * q) * half


@wp.kernel
def body_position_rates(positions: Any, velocities: Any, mass: Any, rates: Any):
    """dx/dt = v = P / M [m/s] and dq/dt = 1/2 (omega, 0) q [1/s], omega = R I_body^-1 R^T L, into rates.x, rates.q.

    Args:
        positions: the orientations q read from here, its other fields unused (Bodies) [1]
        velocities: the momenta P, L read from here, its other fields unused (Bodies) [kg m/s]
        mass: inverse masses inv_mass and body-frame inverse inertia tensors inv_inertia (BodyMass) [1/kg]
        rates: x and q written with dx/dt and dq/dt, P and L untouched (Bodies) [m/s]
    """
    i = wp.tid()
    q = positions.q[i]
    rates.x[i] = velocities.P[i] * mass.inv_mass[i]
    rates.q[i] = orientation_rate(q, angular_velocity(q, mass.inv_inertia[i], velocities.L[i]))


@wp.kernel
def body_momentum_rates(bodies: Any, mass: Any, drag: wp.array(dtype=Any), angular_drag: wp.array(dtype=Any),
                        gravity: Any, wind: Any, held: Any, accumulated: Any, rates: Any):
    """dP/dt = F and dL/dt = tau, the total force [N] and torque about the centre of mass [N m], into rates.P, rates.L.

    F = M g + drag (wind - v) + held force + accumulated force; tau = -angular_drag omega + held
    torque + accumulated torque, with v = P / M and omega = R I_body^-1 R^T L.

    Args:
        bodies: orientations q and momenta P, L read (Bodies) [kg m/s]
        mass: inverse masses inv_mass (> 0) and body-frame inverse inertia tensors inv_inertia (BodyMass) [1/kg]
        drag: linear drag coefficients, per body [N s/m]
        angular_drag: angular drag coefficients, per body [N m s/rad]
        gravity: the gravitational acceleration g (vec3) [m/s^2]
        wind: the air's velocity (vec3) [m/s]
        held: the force and torque the user holds between steps, about the centres of mass (Wrench) [N]
        accumulated: the force terms' summed force and torque, or empty arrays when none acts on bodies (Wrench) [N]
        rates: P and L written with dP/dt = F and dL/dt = tau, x and q untouched (Bodies) [N]
    """
    i = wp.tid()
    w = mass.inv_mass[i]
    v = bodies.P[i] * w
    omega = angular_velocity(bodies.q[i], mass.inv_inertia[i], bodies.L[i])
    F = gravity / w + drag[i] * (wind - v) + held.force[i]
    tau = held.torque[i] - angular_drag[i] * omega
    if accumulated.force.shape[0] > 0:
        F = F + accumulated.force[i]
        tau = tau + accumulated.torque[i]
    rates.P[i] = F
    rates.L[i] = tau


@wp.kernel
def normalize_orientations(q: wp.array(dtype=Any)):
    """q[i] = q[i] / |q[i]|: the projection back onto unit quaternions after a step, in place.

    Args:
        q: orientations (x, y, z, w), normalised in place (quat) [1]
    """
    i = wp.tid()
    q[i] = wp.normalize(q[i])


@wp.kernel
def body_velocities(bodies: Any, mass: Any, v: wp.array(dtype=Any), omega: wp.array(dtype=Any)):
    """The auxiliaries v = P / M [m/s] and omega = I(t)^-1 L [rad/s], world frame.

    Args:
        bodies: orientations q and momenta P, L read (Bodies) [kg m/s]
        mass: inverse masses inv_mass and body-frame inverse inertia tensors inv_inertia (BodyMass) [1/kg]
        v: linear velocities of the centres of mass, written (vec3) [m/s]
        omega: angular velocities, world frame, written (vec3) [rad/s]
    """
    i = wp.tid()
    v[i] = bodies.P[i] * mass.inv_mass[i]
    omega[i] = angular_velocity(bodies.q[i], mass.inv_inertia[i], bodies.L[i])


@wp.kernel
def rotation_matrices(q: wp.array(dtype=Any), R: wp.array(dtype=Any)):
    """R[i] = the 3x3 rotation matrix (body to world) of the normalised quaternion q[i].

    Args:
        q: orientations (x, y, z, w) (quat) [1]
        R: rotation matrices, written (mat33) [1]
    """
    i = wp.tid()
    R[i] = wp.quat_to_matrix(wp.normalize(q[i]))


@wp.kernel
def apply_impulse(body: int, impulse: Any, point: Any, bodies: Any):
    """An impulse J [N s] at world point p [m] on one body: P += J, L += (p - x) x J. Launch with dim 1.

    Args:
        body: the index of the body [1]
        impulse: the impulse J, world frame (vec3) [N s]
        point: the world point p where it acts (vec3) [m]
        bodies: centres of mass x read, momenta P and L updated in place (Bodies) [kg m/s]
    """
    bodies.P[body] = bodies.P[body] + impulse
    bodies.L[body] = bodies.L[body] + wp.cross(point - bodies.x[body], impulse)


@wp.kernel
def set_kinematic(index: wp.array(dtype=wp.int32), x: wp.array(dtype=Any), q: wp.array(dtype=Any),
                  v: wp.array(dtype=Any), omega: wp.array(dtype=Any), mass: Any, bodies: Any):
    """Kinematic bodies follow their tracks: x, q set, and P = M v, L = R I_body R^T omega from the track's mean
    velocities over the step (what the contact response sees); one thread per kinematic body.

    Args:
        index: the body index of each kinematic body [1]
        x: its centre of mass at the step's end (vec3) [m]
        q: its orientation then (quat) [1]
        v: its mean linear velocity over the step (vec3) [m/s]
        omega: its mean angular velocity over the step, world frame (vec3) [rad/s]
        mass: inverse masses inv_mass and body-frame inverse inertia tensors inv_inertia (BodyMass) [1/kg]
        bodies: x, q, P and L written (Bodies) [kg m/s]
    """
    k = wp.tid()
    i = index[k]
    unit = wp.normalize(q[k])
    bodies.x[i] = x[k]
    bodies.q[i] = unit
    bodies.P[i] = v[k] / mass.inv_mass[i]
    bodies.L[i] = wp.quat_rotate(unit, wp.inverse(mass.inv_inertia[i]) * wp.quat_rotate_inv(unit, omega[k]))


register(globals())

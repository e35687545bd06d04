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
def body_position_rates(
    q: wp.array(dtype=Any),
    P: wp.array(dtype=Any),
    L: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia_body: wp.array(dtype=Any),
    dx: wp.array(dtype=Any),
    dq: wp.array(dtype=Any),
):
    """dx/dt = v = P / M [m/s] and dq/dt = 1/2 (omega, 0) q [1/s], omega = R I_body^-1 R^T L.

    Args:
        q: orientations, unit quaternions (x, y, z, w) (quat) [1]
        P: linear momenta (vec3) [kg m/s]
        L: angular momenta, world frame (vec3) [kg m^2/s]
        inv_mass: inverse masses 1/M [1/kg]
        inv_inertia_body: inverse inertia tensors I_body^-1, body frame (mat33) [1/(kg m^2)]
        dx: dx/dt = v, written (vec3) [m/s]
        dq: dq/dt, written (quat) [1/s]
    """
    i = wp.tid()
    dx[i] = P[i] * inv_mass[i]
    dq[i] = orientation_rate(q[i], angular_velocity(q[i], inv_inertia_body[i], L[i]))


@wp.kernel
def body_momentum_rates(
    q: wp.array(dtype=Any),
    P: wp.array(dtype=Any),
    L: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia_body: wp.array(dtype=Any),
    drag: wp.array(dtype=Any),
    angular_drag: wp.array(dtype=Any),
    gravity: Any,
    wind: Any,
    user_force: wp.array(dtype=Any),
    user_torque: wp.array(dtype=Any),
    force: wp.array(dtype=Any),
    torque: wp.array(dtype=Any),
    dP: wp.array(dtype=Any),
    dL: wp.array(dtype=Any),
):
    """dP/dt = F and dL/dt = tau, the total force [N] and torque about the centre of mass [N m].

    F = M g + drag (wind - v) + user_force + force; tau = -angular_drag omega +
    user_torque + torque, with v = P / M and omega = R I_body^-1 R^T L.

    Args:
        q: orientations, unit quaternions (x, y, z, w) (quat) [1]
        P: linear momenta (vec3) [kg m/s]
        L: angular momenta, world frame (vec3) [kg m^2/s]
        inv_mass: inverse masses 1/M, > 0 [1/kg]
        inv_inertia_body: inverse inertia tensors I_body^-1, body frame (mat33) [1/(kg m^2)]
        drag: linear drag coefficients, per body [N s/m]
        angular_drag: angular drag coefficients, per body [N m s/rad]
        gravity: the gravitational acceleration g (vec3) [m/s^2]
        wind: the air's velocity (vec3) [m/s]
        user_force: forces held by the user between steps, at the centre of mass (vec3) [N]
        user_torque: torques held by the user between steps (vec3) [N m]
        force: the force terms' force accumulators, or an empty array when none acts on bodies (vec3) [N]
        torque: the force terms' torque accumulators, or an empty array with force (vec3) [N m]
        dP: dP/dt = F, written (vec3) [N]
        dL: dL/dt = tau, written (vec3) [N m]
    """
    i = wp.tid()
    w = inv_mass[i]
    v = P[i] * w
    omega = angular_velocity(q[i], inv_inertia_body[i], L[i])
    F = gravity / w + drag[i] * (wind - v) + user_force[i]
    tau = user_torque[i] - angular_drag[i] * omega
    if force.shape[0] > 0:
        F = F + force[i]
        tau = tau + torque[i]
    dP[i] = F
    dL[i] = tau


@wp.kernel
def normalize_orientations(q: wp.array(dtype=Any)):
    """q[i] = q[i] / |q[i]|: the projection back onto unit quaternions after a step, in place.

    Args:
        q: orientations (x, y, z, w), normalised in place (quat) [1]
    """
    i = wp.tid()
    q[i] = wp.normalize(q[i])


@wp.kernel
def body_velocities(
    q: wp.array(dtype=Any),
    P: wp.array(dtype=Any),
    L: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    inv_inertia_body: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    omega: wp.array(dtype=Any),
):
    """The auxiliaries v = P / M [m/s] and omega = I(t)^-1 L [rad/s], world frame.

    Args:
        q: orientations, unit quaternions (x, y, z, w) (quat) [1]
        P: linear momenta (vec3) [kg m/s]
        L: angular momenta, world frame (vec3) [kg m^2/s]
        inv_mass: inverse masses 1/M [1/kg]
        inv_inertia_body: inverse inertia tensors I_body^-1, body frame (mat33) [1/(kg m^2)]
        v: linear velocities of the centres of mass, written (vec3) [m/s]
        omega: angular velocities, world frame, written (vec3) [rad/s]
    """
    i = wp.tid()
    v[i] = P[i] * inv_mass[i]
    omega[i] = angular_velocity(q[i], inv_inertia_body[i], L[i])


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
def apply_impulse(
    body: int,
    impulse: Any,
    point: Any,
    x: wp.array(dtype=Any),
    P: wp.array(dtype=Any),
    L: wp.array(dtype=Any),
):
    """An impulse J [N s] at world point p [m] on one body: P += J, L += (p - x) x J. Launch with dim 1.

    Args:
        body: the index of the body [1]
        impulse: the impulse J, world frame (vec3) [N s]
        point: the world point p where it acts (vec3) [m]
        x: centres of mass (vec3) [m]
        P: linear momenta, updated in place (vec3) [kg m/s]
        L: angular momenta, updated in place (vec3) [kg m^2/s]
    """
    P[body] = P[body] + impulse
    L[body] = L[body] + wp.cross(point - x[body], impulse)

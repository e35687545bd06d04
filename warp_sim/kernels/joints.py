"""Joints as constraints of the body contact response's Gauss-Seidel solve: velocities, then positions.

One thread per joint, the joints of one colour sharing no body (``passes.joints``), over the solver's
end-of-step state, as the contacts (``contacts``):

- ``solve_joints``: sequential impulses on the working velocities (``BodyVelocities``) that stop every locked
  axis's relative motion, hold limits (a limit not yet reached lets the gap close by the step's end, so a fast
  joint stops at it), and apply the drives as implicit PD servos (a soft row: the impulse a spring of the drive's
  stiffness and damping gives over the step at the end velocity, at most max_force h); the step's impulses
  accumulate per joint-frame axis and warm-start the next step (``warm_start_joints``);
- ``project_joints``: the positions and orientations moved so that the anchors meet and the locked axes and
  limits hold (non-linear Gauss-Seidel, velocities untouched, so no energy is added);
- ``break_joints``: a joint whose force or torque over the step exceeded its break force or torque is disabled.

A joint frame's x, y, z axes are the parent's (rotated with it): a linear axis k moves the child's anchor along
the parent frame's axis k, a rotation about it turns the child's frame relative to the parent's. The angle of a
hinge is the twist of the relative rotation about its free axis; other rotation axes use the components of the
relative rotation's log map.

The rows are functions on values (``warm_start_rows``, ``velocity_rows``, ``position_rows``, over the geometry of
``joint_frames``): each kernel here loads its joint's two bodies, iterates, and stores them once; the taped
launches of a differentiable run (``joint_adjoint``) call the same functions from arrays into new ones.

Private: every kernel and function here is for the simulator's own use (passes.joints, passes.body_contacts);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .contacts import response_mass
from .joint_frames import (
    FREE,
    LIMITED,
    LOCKED,
    drive_row,
    frame_side,
    held_spin,
    hinge_axis,
    joint_angle,
    joint_side,
    limit_row,
    load_poses,
    load_sides,
    point_block,
    pose_side,
    push_positions,
    push_velocities,
    relative_velocity,
    rotation_vector,
    side_inverse,
    side_mass,
    store_sides,
    twist,
    unit_axis,
    with_component,
    world_masses,
)
from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []

@wp.func
def warm_start_rows(joints: Any, j: int, start: Any, mass: Any, vp: Any, wq: Any, vc: Any, wc: Any):
    """Joint j's accumulated impulses of the last step applied to its bodies' velocities (vp, wq: the parent's,
    zeros for the world; vc, wc: the child's) at the levers of ``start``; returns them."""
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    zero = type(joints.cone[j])(0.0)
    pp, rp, fp = joint_side(start.x, start.q, p, joints.anchor_p[j], joints.frame_p[j])
    pc, rc, fc = joint_side(start.x, start.q, c, joints.anchor_c[j], joints.frame_c[j])
    imp, Bp = side_mass(mass, p, zero)
    imc, Bc = side_mass(mass, c, zero)
    qp = fp
    if p >= 0:
        qp = start.q[p]
    imp, Ip = side_inverse(imp, Bp, qp)
    imc, Ic = side_inverse(imc, Bc, start.q[c])
    linear = wp.quat_rotate(fp, joints.lam_lin[j] + joints.lam_drive_lin[j])
    angular = wp.quat_rotate(fp, joints.lam_ang[j] + joints.lam_drive_ang[j])
    d = pc - pp
    if wp.length(d) > zero:
        linear = linear + wp.normalize(d) * joints.lam_dist[j]
    xp = wp.quat_rotate(fp, unit_axis(d, 0))
    xc = wp.quat_rotate(fc, unit_axis(d, 0))
    swing = wp.cross(xp, xc)
    if wp.length(swing) > zero:
        angular = angular + wp.normalize(swing) * joints.lam_cone[j]
    return push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, linear, angular)


@wp.func
def velocity_rows(joints: Any, j: int, h: Any, beta: Any, start: Any, imp: Any, Ip: Any, imc: Any, Ic: Any,
                  vp: Any, wq: Any, vc: Any, wc: Any, lin: Any, ang: Any, dlin: Any, dang: Any, cone: Any,
                  dist: Any):
    """One iteration of joint j's velocity rows (h: the step [s]; beta: the solver's position response) on its
    parent's velocities vp, wq (zeros for the world) and its child's vc, wc, with the inverse masses and world
    inverse inertias imp, Ip, imc, Ic (the world's zeros) and the accumulated impulses of its locked and limited
    axes (lin, ang, in the joint frame), its drives (dlin, dang), its cone and its distance; returns all ten
    updated, (vp, wq, vc, wc, lin, ang, dlin, dang, cone, dist)."""
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    zero = type(h)(0.0)
    pp, rp, fp = joint_side(start.x, start.q, p, joints.anchor_p[j], joints.frame_p[j])
    pc, rc, fc = joint_side(start.x, start.q, c, joints.anchor_c[j], joints.frame_c[j])
    d = pc - pp
    lin_mode = joints.lin_mode[j]
    ang_mode = joints.ang_mode[j]
    hinge = hinge_axis(ang_mode)
    all_linear = lin_mode[0] == LOCKED and lin_mode[1] == LOCKED and lin_mode[2] == LOCKED
    all_angular = ang_mode[0] == LOCKED and ang_mode[1] == LOCKED and ang_mode[2] == LOCKED
    K_lin = point_block(imc, Ic, rc) + point_block(imp, Ip, rp)
    K_ang = Ic + Ip
    K_lin_inv = wp.inverse(K_lin)
    C, S = held_spin(wp.where(all_linear, 1, 0), K_lin_inv, imp, Ip, imc, Ic, rp, rc)
    K_lin_held = K_lin   # the linear rows' response with the rotation held (scales an acceleration drive)
    if all_angular:
        B = -(wp.skew(rc) * Ic + wp.skew(rp) * Ip)
        K_lin_held = K_lin - B * wp.inverse(K_ang) * wp.transpose(B)
    # linear rows
    rel = relative_velocity(vp, wq, vc, wc, rp, rc)
    if all_linear:
        impulse = -(K_lin_inv * rel)
        vp, wq, vc, wc = push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, impulse, rel * zero)
        lin = lin + wp.quat_rotate_inv(fp, impulse)
    else:
        for k in range(3):
            mode = lin_mode[k]
            drive = joints.drive_lin[j][k]
            if mode == FREE and drive == 0:
                continue
            e = wp.quat_rotate(fp, unit_axis(d, k))
            rate = wp.dot(relative_velocity(vp, wq, vc, wc, rp, rc), e)
            kk = response_mass(imc, Ic, rc, e) + response_mass(imp, Ip, rp, e)
            if drive != 0 and mode != LOCKED:
                new = drive_row(drive, wp.dot(d, e), rate, joints.lin_target[j][k], joints.lin_speed[j][k],
                                joints.lin_stiffness[j][k], joints.lin_damping[j][k], joints.lin_max[j][k], h,
                                beta, kk, wp.dot(e, K_lin_held * e), dlin[k])
                vp, wq, vc, wc = push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, e * (new - dlin[k]),
                                                 e * zero)
                dlin = with_component(dlin, k, new)
                rate = wp.dot(relative_velocity(vp, wq, vc, wc, rp, rc), e)
            if mode == FREE:
                continue
            new = lin[k] - rate / kk
            if mode == LIMITED:
                new = limit_row(wp.dot(d, e), joints.lin_lower[j][k], joints.lin_upper[j][k], h, rate,
                                type(h)(1.0) / kk, lin[k])
            vp, wq, vc, wc = push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, e * (new - lin[k]), e * zero)
            lin = with_component(lin, k, new)
    # the anchors' distance (a distance joint)
    if joints.dist_max[j] >= zero:
        length = wp.length(d)
        if length > type(h)(1.0e-9):
            n = d / length
            rate = wp.dot(relative_velocity(vp, wq, vc, wc, rp, rc), n)
            kk = response_mass(imc, Ic, rc, n) + response_mass(imp, Ip, rp, n)
            total = limit_row(length, joints.dist_min[j], joints.dist_max[j], h, rate, type(h)(1.0) / kk, dist)
            vp, wq, vc, wc = push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, n * (total - dist), n * zero)
            dist = total
    # angular rows
    if all_angular:
        impulse = -(wp.inverse(S) * (wc - wq))
        vp, wq, vc, wc = push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, C * impulse, impulse)
        ang = ang + wp.quat_rotate_inv(fp, impulse)
        lin = lin + wp.quat_rotate_inv(fp, C * impulse)
    else:
        for k in range(3):
            mode = ang_mode[k]
            drive = joints.drive_ang[j][k]
            if mode == FREE and drive == 0:
                continue
            e = wp.quat_rotate(fp, unit_axis(d, k))
            rate = wp.dot(wc - wq, e)
            kk = wp.dot(e, S * e)
            angle = joint_angle(fp, fc, hinge, k)
            if drive != 0 and mode != LOCKED:
                new = drive_row(drive, angle, rate, joints.ang_target[j][k], joints.ang_speed[j][k],
                                joints.ang_stiffness[j][k], joints.ang_damping[j][k], joints.ang_max[j][k], h,
                                beta, kk, kk, dang[k])
                tau = e * (new - dang[k])
                vp, wq, vc, wc = push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
                lin = lin + wp.quat_rotate_inv(fp, C * tau)
                dang = with_component(dang, k, new)
                rate = wp.dot(wc - wq, e)
            if mode == FREE:
                continue
            new = ang[k] - rate / kk
            if mode == LIMITED:
                new = limit_row(angle, joints.ang_lower[j][k], joints.ang_upper[j][k], h, rate,
                                type(h)(1.0) / kk, ang[k])
            tau = e * (new - ang[k])
            vp, wq, vc, wc = push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
            lin = lin + wp.quat_rotate_inv(fp, C * tau)
            ang = with_component(ang, k, new)
    # the swing cone (a ball joint's limit)
    if joints.cone[j] >= zero:
        xp = wp.quat_rotate(fp, unit_axis(d, 0))
        xc = wp.quat_rotate(fc, unit_axis(d, 0))
        swing = wp.cross(xp, xc)
        if wp.length(swing) > type(h)(1.0e-9):
            n = wp.normalize(swing)
            angle = wp.atan2(wp.length(swing), wp.dot(xp, xc))
            rate = wp.dot(wc - wq, n)
            kk = wp.dot(n, S * n)
            total = limit_row(angle, -joints.cone[j] - type(h)(1.0), joints.cone[j], h, rate, type(h)(1.0) / kk,
                              cone)
            tau = n * (total - cone)
            vp, wq, vc, wc = push_velocities(vp, wq, vc, wc, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
            lin = lin + wp.quat_rotate_inv(fp, C * tau)
            cone = total
    return vp, wq, vc, wc, lin, ang, dlin, dang, cone, dist


@wp.func
def position_rows(joints: Any, j: int, imp: Any, Bp: Any, imc: Any, Bc: Any, xp: Any, qp: Any, xc: Any, qc: Any):
    """One iteration of joint j's position projection on its parent's pose xp, qp (the world's: the origin and
    the identity) and its child's xc, qc, with their inverse masses and body-frame inverse inertias (side_mass:
    the world's zeros): the anchors brought together along the locked axes and back within the limits, the
    orientations likewise; returns the poses (xp, qp, xc, qc)."""
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    zero = type(joints.cone[j])(0.0)
    lin_mode = joints.lin_mode[j]
    ang_mode = joints.ang_mode[j]
    hinge = hinge_axis(ang_mode)
    all_linear = lin_mode[0] == LOCKED and lin_mode[1] == LOCKED and lin_mode[2] == LOCKED
    all_angular = ang_mode[0] == LOCKED and ang_mode[1] == LOCKED and ang_mode[2] == LOCKED
    # linear: the anchors together along the locked axes, within the limits
    pp, rp, fp = pose_side(xp, qp, p, joints.anchor_p[j], joints.frame_p[j])
    pc, rc, fc = pose_side(xc, qc, c, joints.anchor_c[j], joints.frame_c[j])
    imp, Ip = side_inverse(imp, Bp, qp)
    imc, Ic = side_inverse(imc, Bc, qc)
    d = pc - pp
    if all_linear:
        K = point_block(imc, Ic, rc) + point_block(imp, Ip, rp)
        xp, qp, xc, qc = push_positions(xp, qp, xc, qc, imp, Ip, imc, Ic, rp, rc, -(wp.inverse(K) * d), d * zero)
    else:
        for k in range(3):
            mode = lin_mode[k]
            if mode == FREE:
                continue
            e = wp.quat_rotate(fp, unit_axis(d, k))
            s = wp.dot(d, e)
            error = s
            if mode == LIMITED:
                error = s - wp.clamp(s, joints.lin_lower[j][k], joints.lin_upper[j][k])
            if error != zero:
                kk = response_mass(imc, Ic, rc, e) + response_mass(imp, Ip, rp, e)
                xp, qp, xc, qc = push_positions(xp, qp, xc, qc, imp, Ip, imc, Ic, rp, rc, e * (-error / kk),
                                                e * zero)
                pp, rp, fp = pose_side(xp, qp, p, joints.anchor_p[j], joints.frame_p[j])
                pc, rc, fc = pose_side(xc, qc, c, joints.anchor_c[j], joints.frame_c[j])
                d = pc - pp
    if joints.dist_max[j] >= zero:
        length = wp.length(d)
        if length > type(zero)(1.0e-9):
            error = length - wp.clamp(length, joints.dist_min[j], joints.dist_max[j])
            if error != zero:
                n = d / length
                kk = response_mass(imc, Ic, rc, n) + response_mass(imp, Ip, rp, n)
                xp, qp, xc, qc = push_positions(xp, qp, xc, qc, imp, Ip, imc, Ic, rp, rc, n * (-error / kk),
                                                n * zero)
    # angular: the frames aligned on the locked axes, within the limits and the cone
    pp, rp, fp = pose_side(xp, qp, p, joints.anchor_p[j], joints.frame_p[j])
    pc, rc, fc = pose_side(xc, qc, c, joints.anchor_c[j], joints.frame_c[j])
    imp, Ip = side_inverse(imp, Bp, qp)
    imc, Ic = side_inverse(imc, Bc, qc)
    K_lin_inv = wp.inverse(point_block(imc, Ic, rc) + point_block(imp, Ip, rp))
    C, K = held_spin(wp.where(all_linear, 1, 0), K_lin_inv, imp, Ip, imc, Ic, rp, rc)
    if all_angular:
        offset = fp * wp.quat_inverse(fc)   # turns the child's frame onto the parent's
        if offset[3] < zero:
            offset = -offset
        phi = wp.vector(offset[0], offset[1], offset[2]) * type(zero)(2.0)
        xp, qp, xc, qc = push_positions(xp, qp, xc, qc, imp, Ip, imc, Ic, rp, rc, C * (wp.inverse(K) * phi),
                                        wp.inverse(K) * phi)
    elif hinge >= 0:
        a_p = wp.quat_rotate(fp, unit_axis(d, hinge))
        a_c = wp.quat_rotate(fc, unit_axis(d, hinge))
        phi = wp.cross(a_c, a_p)
        xp, qp, xc, qc = push_positions(xp, qp, xc, qc, imp, Ip, imc, Ic, rp, rc, C * (wp.inverse(K) * phi),
                                        wp.inverse(K) * phi)
        if ang_mode[hinge] == LIMITED:
            fp = frame_side(qp, p, joints.frame_p[j])
            fc = frame_side(qc, c, joints.frame_c[j])
            angle = twist(fp, fc, hinge)
            error = angle - wp.clamp(angle, joints.ang_lower[j][hinge], joints.ang_upper[j][hinge])
            if error != zero:
                a = wp.quat_rotate(fp, unit_axis(d, hinge))
                tau = a * (-error / wp.dot(a, K * a))
                xp, qp, xc, qc = push_positions(xp, qp, xc, qc, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
    else:
        for k in range(3):
            mode = ang_mode[k]
            if mode == FREE:
                continue
            angle = rotation_vector(fp, fc)[k]
            error = angle
            if mode == LIMITED:
                error = angle - wp.clamp(angle, joints.ang_lower[j][k], joints.ang_upper[j][k])
            if error != zero:
                e = wp.quat_rotate(fp, unit_axis(d, k))
                tau = e * (-error / wp.dot(e, K * e))
                xp, qp, xc, qc = push_positions(xp, qp, xc, qc, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
                fp = frame_side(qp, p, joints.frame_p[j])
                fc = frame_side(qc, c, joints.frame_c[j])
    if joints.cone[j] >= zero:
        fp = frame_side(qp, p, joints.frame_p[j])
        fc = frame_side(qc, c, joints.frame_c[j])
        xa = wp.quat_rotate(fp, unit_axis(d, 0))
        xb = wp.quat_rotate(fc, unit_axis(d, 0))
        swing = wp.cross(xa, xb)
        angle = wp.atan2(wp.length(swing), wp.dot(xa, xb))
        if angle > joints.cone[j] and wp.length(swing) > type(zero)(1.0e-9):
            n = wp.normalize(swing)
            tau = n * (-(angle - joints.cone[j]) / wp.dot(n, K * n))
            xp, qp, xc, qc = push_positions(xp, qp, xc, qc, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
    return xp, qp, xc, qc


@wp.kernel
def warm_start_joints(joints: Any, first: int, start: Any, mass: Any, work: Any, enabled: wp.array(dtype=wp.int32)):
    """Apply each joint's accumulated impulses of the last step to the working velocities (one colour)."""
    j = first + wp.tid()
    if enabled[j] == 0:   # (enabled is joints.enabled, given directly: Warp's CPU code then specialises)
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    vp, wq, vc, wc = load_sides(work.v, work.w, p, c)
    vp, wq, vc, wc = warm_start_rows(joints, j, start, mass, vp, wq, vc, wc)
    store_sides(work.v, work.w, p, c, vp, wq, vc, wc)


@wp.kernel
def solve_joints(joints: Any, first: int, iterations: int, sweep: int, h: Any, beta: Any, start: Any, mass: Any,
                 work: Any, enabled: wp.array(dtype=wp.int32)):
    """One Gauss-Seidel sweep of the velocity rows of one colour of joints (thread t: joint first + t), each
    joint's rows iterated ``iterations`` times (velocity_rows; h: the step [s]; beta: the solver's position
    response); its bodies' work.stamp set to ``sweep``, so the contact sweeps after it look at them again."""
    j = first + wp.tid()
    if enabled[j] == 0:   # (enabled is joints.enabled, given directly: Warp's CPU code then specialises)
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    imp, Ip, imc, Ic = world_masses(mass.inv_mass, work.inv_inertia_world, p, c)
    vp, wq, vc, wc = load_sides(work.v, work.w, p, c)
    lin = joints.lam_lin[j]
    ang = joints.lam_ang[j]
    dlin = joints.lam_drive_lin[j]
    dang = joints.lam_drive_ang[j]
    cone = joints.lam_cone[j]
    dist = joints.lam_dist[j]
    for _iteration in range(iterations):
        vp, wq, vc, wc, lin, ang, dlin, dang, cone, dist = velocity_rows(joints, j, h, beta, start, imp, Ip, imc,
                                                                         Ic, vp, wq, vc, wc, lin, ang, dlin, dang,
                                                                         cone, dist)
    store_sides(work.v, work.w, p, c, vp, wq, vc, wc)
    joints.lam_lin[j] = lin
    joints.lam_ang[j] = ang
    joints.lam_drive_lin[j] = dlin
    joints.lam_drive_ang[j] = dang
    joints.lam_cone[j] = cone
    joints.lam_dist[j] = dist
    work.stamp[c] = sweep
    if p >= 0:
        work.stamp[p] = sweep


@wp.kernel
def project_joints(joints: Any, first: int, iterations: int, sweep: int, end: Any, mass: Any,
                   enabled: wp.array(dtype=wp.int32), stamp: wp.array(dtype=wp.int32)):
    """One Gauss-Seidel sweep of the position projection over one colour of joints (position_rows, ``iterations``
    times; positions only); stamp (per body, the last sweep that moved it) set to ``sweep`` for its bodies."""
    j = first + wp.tid()
    if enabled[j] == 0:   # (enabled is joints.enabled, given directly: Warp's CPU code then specialises)
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    zero = type(joints.cone[j])(0.0)
    imp, Bp = side_mass(mass, p, zero)
    imc, Bc = side_mass(mass, c, zero)
    xp, qp, xc, qc = load_poses(end.x, end.q, p, c)
    for _iteration in range(iterations):
        xp, qp, xc, qc = position_rows(joints, j, imp, Bp, imc, Bc, xp, qp, xc, qc)
    store_sides(end.x, end.q, p, c, xp, qp, xc, qc)
    stamp[c] = sweep
    if p >= 0:
        stamp[p] = sweep


@wp.kernel
def break_joints(joints: Any, h: Any, broken: wp.array(dtype=wp.int32)):
    """Disable every joint whose force [N] or torque [N m] over the step of h seconds exceeded its break force
    or torque (broken[j] = 1, its impulses cleared)."""
    j = wp.tid()
    if joints.enabled[j] == 0:
        return
    force = wp.length(joints.lam_lin[j] + joints.lam_drive_lin[j]) / h + wp.abs(joints.lam_dist[j]) / h
    torque = wp.length(joints.lam_ang[j] + joints.lam_drive_ang[j]) / h + wp.abs(joints.lam_cone[j]) / h
    zero = type(h)(0.0)
    if (joints.break_force[j] >= zero and force > joints.break_force[j]) or (
            joints.break_torque[j] >= zero and torque > joints.break_torque[j]):
        joints.enabled[j] = 0
        broken[j] = 1
        joints.lam_lin[j] = joints.lam_lin[j] * zero
        joints.lam_ang[j] = joints.lam_ang[j] * zero
        joints.lam_drive_lin[j] = joints.lam_drive_lin[j] * zero
        joints.lam_drive_ang[j] = joints.lam_drive_ang[j] * zero
        joints.lam_cone[j] = zero
        joints.lam_dist[j] = zero


register(globals())

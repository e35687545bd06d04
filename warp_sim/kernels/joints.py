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

Private: every kernel and function here is for the simulator's own use (passes.joints, passes.body_contacts);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .contacts import response_mass, turn
from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []

FREE = wp.constant(0)
LOCKED = wp.constant(1)
LIMITED = wp.constant(2)


@wp.func
def unit_axis(v: Any, k: int):
    """Unit vector k (0, 1, 2) of v's type."""
    e = v * type(v[0])(0.0)
    e[k] = type(v[0])(1.0)
    return e


@wp.func
def joint_side(x: wp.array(dtype=Any), q: wp.array(dtype=Any), b: int, anchor: Any, frame: Any):
    """(the anchor's world point [m], its lever from the centre of mass [m], the joint frame's world rotation) of
    body b's side (b < 0: the world, anchor and frame already world)."""
    if b < 0:
        return anchor, anchor * type(anchor[0])(0.0), frame
    r = wp.quat_rotate(wp.normalize(q[b]), anchor)
    return x[b] + r, r, wp.normalize(q[b]) * frame


@wp.func
def joint_frame(q: wp.array(dtype=Any), b: int, frame: Any):
    """The joint frame's world rotation on body b's side (b < 0: the world, frame already world)."""
    if b < 0:
        return frame
    return wp.normalize(q[b]) * frame


@wp.func
def side_inverse(mass: Any, q: wp.array(dtype=Any), b: int, zero: Any):
    """(1/m [1/kg], I^-1 in the world [1/(kg m^2)]) of body b at orientation q[b]; zeros for the world."""
    R = wp.quat_to_matrix(wp.normalize(q[0]))
    if b < 0:
        return zero, R * zero
    R = wp.quat_to_matrix(wp.normalize(q[b]))
    return mass.inv_mass[b], R * mass.inv_inertia[b] * wp.transpose(R)


@wp.func
def point_block(inv_mass: Any, inv_inertia: Any, r: Any):
    """The 3x3 inverse effective mass of a body point at lever r: 1/m I - [r]x I^-1 [r]x."""
    skew = wp.skew(r)
    return wp.identity(3, type(inv_mass)) * inv_mass - skew * inv_inertia * skew


@wp.func
def held_spin(held: int, K_lin_inv: Any, imp: Any, Ip: Any, imc: Any, Ic: Any, rp: Any, rc: Any):
    """(C, S) for angular rows while the anchor is held (held = 1: the joint's linear axes all locked): an
    angular impulse tau [N m s] on the child with the linear impulse C tau at the anchors leaves the anchors'
    relative velocity unchanged, and changes the relative spin by S tau (S = K_ang - B^T K_lin^-1 B, B the
    anchor velocity per unit tau: a hinged arm turns about its hinge, not its centre of mass). held = 0: C = 0,
    S = K_ang."""
    B = -(wp.skew(rc) * Ic + wp.skew(rp) * Ip)
    C = B * (imc * type(imc)(0.0))
    if held == 1:
        C = -(K_lin_inv * B)
    return C, Ic + Ip + wp.transpose(B) * C


@wp.func
def side_velocity(work: Any, b: int, r: Any):
    if b < 0:
        return r * type(r[0])(0.0)
    return work.v[b] + wp.cross(work.w[b], r)


@wp.func
def side_spin(work: Any, b: int, like: Any):
    if b < 0:
        return like * type(like[0])(0.0)
    return work.w[b]


@wp.func
def push_velocities(work: Any, p: int, c: int, imp: Any, Ip: Any, imc: Any, Ic: Any, rp: Any, rc: Any,
                    linear: Any, angular: Any):
    """The impulse ``linear`` [N s] at the child's anchor and ``angular`` [N m s] on the child, their opposites
    on the parent."""
    work.v[c] = work.v[c] + linear * imc
    work.w[c] = work.w[c] + Ic * (wp.cross(rc, linear) + angular)
    if p >= 0:
        work.v[p] = work.v[p] - linear * imp
        work.w[p] = work.w[p] - Ip * (wp.cross(rp, linear) + angular)


@wp.func
def push_positions(x: wp.array(dtype=Any), q: wp.array(dtype=Any), p: int, c: int, imp: Any, Ip: Any, imc: Any,
                   Ic: Any, rp: Any, rc: Any, linear: Any, angular: Any):
    """The position-level push ``linear`` [N s . s] at the child's anchor and ``angular`` on the child (the
    parent the opposite): moves and turns the bodies, velocities untouched."""
    x[c] = x[c] + linear * imc
    q[c] = turn(q[c], Ic * (wp.cross(rc, linear) + angular))
    if p >= 0:
        x[p] = x[p] - linear * imp
        q[p] = turn(q[p], -(Ip * (wp.cross(rp, linear) + angular)))


@wp.func
def twist(frame_p: Any, frame_c: Any, k: int):
    """The angle [rad] in (-pi, pi] of the child frame about the parent frame's axis k (a hinge's angle)."""
    rel = wp.quat_inverse(frame_p) * frame_c
    angle = type(rel[3])(2.0) * wp.atan2(rel[k], rel[3])
    pi = type(angle)(wp.pi)
    if angle > pi:
        angle = angle - type(angle)(2.0) * pi
    if angle < -pi:
        angle = angle + type(angle)(2.0) * pi
    return angle


@wp.func
def rotation_vector(frame_p: Any, frame_c: Any):
    """The relative rotation child-from-parent as a rotation vector in the parent's joint frame [rad]."""
    rel = wp.quat_inverse(frame_p) * frame_c
    if rel[3] < type(rel[3])(0.0):
        rel = -rel
    v = wp.vector(rel[0], rel[1], rel[2])
    s = wp.length(v)
    if s < type(s)(1.0e-9):
        return v * type(s)(2.0)
    return v * (type(s)(2.0) * wp.atan2(s, rel[3]) / s)


@wp.func
def hinge_axis(ang_mode: wp.vec3i):
    """The one rotation axis that is not locked (a hinge), or -1 (none, or more than one)."""
    axis = int(-1)
    open_axes = int(0)
    for k in range(3):
        if ang_mode[k] != LOCKED:
            axis = k
            open_axes += 1
    if open_axes != 1:
        axis = -1
    return axis


@wp.func
def joint_angle(frame_p: Any, frame_c: Any, hinge: int, k: int):
    if hinge >= 0:
        return twist(frame_p, frame_c, k)
    return rotation_vector(frame_p, frame_c)[k]


@wp.func
def limit_row(value: Any, lower: Any, upper: Any, h: Any, rate: Any, inv_k: Any, acc: Any):
    """The new accumulated impulse of a limited axis at ``value`` moving at ``rate``: the nearer bound is a
    one-sided row that lets the gap close by the step's end ((bound - value)/h) and no further."""
    zero = type(value)(0.0)
    if value - lower < upper - value:
        target = wp.min((lower - value) / h, zero)
        return wp.max(acc + (target - rate) * inv_k, zero)
    target = wp.max((upper - value) / h, zero)
    return wp.min(acc + (target - rate) * inv_k, zero)


@wp.func
def drive_row(kind: int, value: Any, rate: Any, target: Any, speed: Any, stiffness: Any, damping: Any,
              max_force: Any, h: Any, beta: Any, k: Any, held: Any, acc: Any):
    """The new accumulated impulse of a drive row (an implicit PD servo; k: the row's inverse effective mass;
    held: the axis's, with the joint's locked axes held, which scales an acceleration drive):
    lambda = h (stiffness (target - value - beta h dv) + damping (speed - rate_end)), at most max_force h."""
    ks = stiffness
    kd = damping
    if kind == 2:   # acceleration: per unit of the effective inertia (a hinged arm's about its hinge)
        ks = ks / held
        kd = kd / held
    b = h * (beta * h * ks + kd)
    a = h * (ks * (target - value) + kd * speed)
    delta = (a - b * rate - acc) / (type(h)(1.0) + b * k)
    bound = max_force * h
    return wp.clamp(acc + delta, -bound, bound)


@wp.kernel
def warm_start_joints(joints: Any, first: int, start: Any, mass: Any, work: Any, enabled: wp.array(dtype=wp.int32)):
    """Apply each joint's accumulated impulses of the last step to the working velocities (one colour)."""
    j = first + wp.tid()
    if enabled[j] == 0:   # (enabled is joints.enabled, given directly: Warp's CPU code then specialises)
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    zero = type(joints.cone[j])(0.0)
    pp, rp, fp = joint_side(start.x, start.q, p, joints.anchor_p[j], joints.frame_p[j])
    pc, rc, fc = joint_side(start.x, start.q, c, joints.anchor_c[j], joints.frame_c[j])
    imp, Ip = side_inverse(mass, start.q, p, zero)
    imc, Ic = side_inverse(mass, start.q, c, zero)
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
    push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, linear, angular)


@wp.kernel
def solve_joints(joints: Any, first: int, iterations: int, sweep: int, h: Any, beta: Any, start: Any, mass: Any,
                 work: Any, enabled: wp.array(dtype=wp.int32)):
    """One Gauss-Seidel sweep of the velocity rows of one colour of joints (thread t: joint first + t), each
    joint's rows iterated ``iterations`` times (h: the step [s]; beta: the solver's position response); its
    bodies' work.stamp set to ``sweep``, so the contact sweeps after it look at them again."""
    j = first + wp.tid()
    if enabled[j] == 0:   # (enabled is joints.enabled, given directly: Warp's CPU code then specialises)
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    zero = type(h)(0.0)
    pp, rp, fp = joint_side(start.x, start.q, p, joints.anchor_p[j], joints.frame_p[j])
    pc, rc, fc = joint_side(start.x, start.q, c, joints.anchor_c[j], joints.frame_c[j])
    imp = work.inv_inertia_world[c][0, 0] * zero
    Ip = work.inv_inertia_world[c] * zero
    if p >= 0:
        imp = mass.inv_mass[p]
        Ip = work.inv_inertia_world[p]
    imc = mass.inv_mass[c]
    Ic = work.inv_inertia_world[c]
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
    work.stamp[c] = sweep
    if p >= 0:
        work.stamp[p] = sweep
    for _iteration in range(iterations):
        # linear rows
        rel = side_velocity(work, c, rc) - side_velocity(work, p, rp)
        if all_linear:
            impulse = -(K_lin_inv * rel)
            push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, impulse, rel * zero)
            joints.lam_lin[j] = joints.lam_lin[j] + wp.quat_rotate_inv(fp, impulse)
        else:
            for k in range(3):
                mode = lin_mode[k]
                drive = joints.drive_lin[j][k]
                if mode == FREE and drive == 0:
                    continue
                e = wp.quat_rotate(fp, unit_axis(d, k))
                rel = side_velocity(work, c, rc) - side_velocity(work, p, rp)
                rate = wp.dot(rel, e)
                kk = response_mass(imc, Ic, rc, e) + response_mass(imp, Ip, rp, e)
                if drive != 0 and mode != LOCKED:
                    acc = joints.lam_drive_lin[j]
                    new = drive_row(drive, wp.dot(d, e), rate, joints.lin_target[j][k], joints.lin_speed[j][k],
                                    joints.lin_stiffness[j][k], joints.lin_damping[j][k], joints.lin_max[j][k], h,
                                    beta, kk, wp.dot(e, K_lin_held * e), acc[k])
                    push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, e * (new - acc[k]), e * zero)
                    acc[k] = new
                    joints.lam_drive_lin[j] = acc
                    rate = wp.dot(side_velocity(work, c, rc) - side_velocity(work, p, rp), e)
                if mode == FREE:
                    continue
                acc = joints.lam_lin[j]
                new = acc[k] - rate / kk
                if mode == LIMITED:
                    new = limit_row(wp.dot(d, e), joints.lin_lower[j][k], joints.lin_upper[j][k], h, rate,
                                    type(h)(1.0) / kk, acc[k])
                push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, e * (new - acc[k]), e * zero)
                acc[k] = new
                joints.lam_lin[j] = acc
        # the anchors' distance (a distance joint)
        if joints.dist_max[j] >= zero:
            length = wp.length(d)
            if length > type(h)(1.0e-9):
                n = d / length
                rate = wp.dot(side_velocity(work, c, rc) - side_velocity(work, p, rp), n)
                kk = response_mass(imc, Ic, rc, n) + response_mass(imp, Ip, rp, n)
                held = joints.lam_dist[j]
                total = limit_row(length, joints.dist_min[j], joints.dist_max[j], h, rate, type(h)(1.0) / kk, held)
                push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, n * (total - held), n * zero)
                joints.lam_dist[j] = total
        # angular rows
        if all_angular:
            spin = side_spin(work, c, rc) - side_spin(work, p, rc)
            impulse = -(wp.inverse(S) * spin)
            push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, C * impulse, impulse)
            joints.lam_ang[j] = joints.lam_ang[j] + wp.quat_rotate_inv(fp, impulse)
            joints.lam_lin[j] = joints.lam_lin[j] + wp.quat_rotate_inv(fp, C * impulse)
        else:
            for k in range(3):
                mode = ang_mode[k]
                drive = joints.drive_ang[j][k]
                if mode == FREE and drive == 0:
                    continue
                e = wp.quat_rotate(fp, unit_axis(d, k))
                rate = wp.dot(side_spin(work, c, rc) - side_spin(work, p, rc), e)
                kk = wp.dot(e, S * e)
                angle = joint_angle(fp, fc, hinge, k)
                if drive != 0 and mode != LOCKED:
                    acc = joints.lam_drive_ang[j]
                    new = drive_row(drive, angle, rate, joints.ang_target[j][k], joints.ang_speed[j][k],
                                    joints.ang_stiffness[j][k], joints.ang_damping[j][k], joints.ang_max[j][k], h,
                                    beta, kk, kk, acc[k])
                    tau = e * (new - acc[k])
                    push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
                    joints.lam_lin[j] = joints.lam_lin[j] + wp.quat_rotate_inv(fp, C * tau)
                    acc[k] = new
                    joints.lam_drive_ang[j] = acc
                    rate = wp.dot(side_spin(work, c, rc) - side_spin(work, p, rc), e)
                if mode == FREE:
                    continue
                acc = joints.lam_ang[j]
                new = acc[k] - rate / kk
                if mode == LIMITED:
                    new = limit_row(angle, joints.ang_lower[j][k], joints.ang_upper[j][k], h, rate,
                                    type(h)(1.0) / kk, acc[k])
                tau = e * (new - acc[k])
                push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
                joints.lam_lin[j] = joints.lam_lin[j] + wp.quat_rotate_inv(fp, C * tau)
                acc[k] = new
                joints.lam_ang[j] = acc
        # the swing cone (a ball joint's limit)
        if joints.cone[j] >= zero:
            xp = wp.quat_rotate(fp, unit_axis(d, 0))
            xc = wp.quat_rotate(fc, unit_axis(d, 0))
            swing = wp.cross(xp, xc)
            if wp.length(swing) > type(h)(1.0e-9):
                n = wp.normalize(swing)
                angle = wp.atan2(wp.length(swing), wp.dot(xp, xc))
                rate = wp.dot(side_spin(work, c, rc) - side_spin(work, p, rc), n)
                kk = wp.dot(n, S * n)
                held = joints.lam_cone[j]
                total = limit_row(angle, -joints.cone[j] - type(h)(1.0), joints.cone[j], h, rate,
                                  type(h)(1.0) / kk, held)
                tau = n * (total - held)
                push_velocities(work, p, c, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
                joints.lam_lin[j] = joints.lam_lin[j] + wp.quat_rotate_inv(fp, C * tau)
                joints.lam_cone[j] = total


@wp.kernel
def project_joints(joints: Any, first: int, iterations: int, sweep: int, end: Any, mass: Any,
                   enabled: wp.array(dtype=wp.int32), stamp: wp.array(dtype=wp.int32)):
    """One Gauss-Seidel sweep of the position projection over one colour of joints: each joint's anchors
    brought together along its locked axes and back within its limits, orientations likewise, positions only,
    ``iterations`` times; stamp (per body, the last sweep that moved it) set to ``sweep`` for its bodies."""
    j = first + wp.tid()
    if enabled[j] == 0:   # (enabled is joints.enabled, given directly: Warp's CPU code then specialises)
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    zero = type(joints.cone[j])(0.0)
    lin_mode = joints.lin_mode[j]
    ang_mode = joints.ang_mode[j]
    hinge = hinge_axis(ang_mode)
    all_linear = lin_mode[0] == LOCKED and lin_mode[1] == LOCKED and lin_mode[2] == LOCKED
    all_angular = ang_mode[0] == LOCKED and ang_mode[1] == LOCKED and ang_mode[2] == LOCKED
    stamp[c] = sweep
    if p >= 0:
        stamp[p] = sweep
    for _iteration in range(iterations):
        # linear: the anchors together along the locked axes, within the limits
        pp, rp, fp = joint_side(end.x, end.q, p, joints.anchor_p[j], joints.frame_p[j])
        pc, rc, fc = joint_side(end.x, end.q, c, joints.anchor_c[j], joints.frame_c[j])
        imp, Ip = side_inverse(mass, end.q, p, zero)
        imc, Ic = side_inverse(mass, end.q, c, zero)
        d = pc - pp
        if all_linear:
            K = point_block(imc, Ic, rc) + point_block(imp, Ip, rp)
            push_positions(end.x, end.q, p, c, imp, Ip, imc, Ic, rp, rc, -(wp.inverse(K) * d), d * zero)
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
                    push_positions(end.x, end.q, p, c, imp, Ip, imc, Ic, rp, rc, e * (-error / kk), e * zero)
                    pp, rp, fp = joint_side(end.x, end.q, p, joints.anchor_p[j], joints.frame_p[j])
                    pc, rc, fc = joint_side(end.x, end.q, c, joints.anchor_c[j], joints.frame_c[j])
                    d = pc - pp
        if joints.dist_max[j] >= zero:
            length = wp.length(d)
            if length > type(zero)(1.0e-9):
                error = length - wp.clamp(length, joints.dist_min[j], joints.dist_max[j])
                if error != zero:
                    n = d / length
                    kk = response_mass(imc, Ic, rc, n) + response_mass(imp, Ip, rp, n)
                    push_positions(end.x, end.q, p, c, imp, Ip, imc, Ic, rp, rc, n * (-error / kk), n * zero)
        # angular: the frames aligned on the locked axes, within the limits and the cone
        pp, rp, fp = joint_side(end.x, end.q, p, joints.anchor_p[j], joints.frame_p[j])
        pc, rc, fc = joint_side(end.x, end.q, c, joints.anchor_c[j], joints.frame_c[j])
        imp, Ip = side_inverse(mass, end.q, p, zero)
        imc, Ic = side_inverse(mass, end.q, c, zero)
        K_lin_inv = wp.inverse(point_block(imc, Ic, rc) + point_block(imp, Ip, rp))
        C, K = held_spin(wp.where(all_linear, 1, 0), K_lin_inv, imp, Ip, imc, Ic, rp, rc)
        if all_angular:
            offset = fp * wp.quat_inverse(fc)   # turns the child's frame onto the parent's
            if offset[3] < zero:
                offset = -offset
            phi = wp.vector(offset[0], offset[1], offset[2]) * type(zero)(2.0)
            push_positions(end.x, end.q, p, c, imp, Ip, imc, Ic, rp, rc, C * (wp.inverse(K) * phi), wp.inverse(K) * phi)
        elif hinge >= 0:
            a_p = wp.quat_rotate(fp, unit_axis(d, hinge))
            a_c = wp.quat_rotate(fc, unit_axis(d, hinge))
            phi = wp.cross(a_c, a_p)
            push_positions(end.x, end.q, p, c, imp, Ip, imc, Ic, rp, rc, C * (wp.inverse(K) * phi), wp.inverse(K) * phi)
            if ang_mode[hinge] == LIMITED:
                fp = joint_frame(end.q, p, joints.frame_p[j])
                fc = joint_frame(end.q, c, joints.frame_c[j])
                angle = twist(fp, fc, hinge)
                error = angle - wp.clamp(angle, joints.ang_lower[j][hinge], joints.ang_upper[j][hinge])
                if error != zero:
                    a = wp.quat_rotate(fp, unit_axis(d, hinge))
                    tau = a * (-error / wp.dot(a, K * a))
                    push_positions(end.x, end.q, p, c, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
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
                    push_positions(end.x, end.q, p, c, imp, Ip, imc, Ic, rp, rc, C * tau, tau)
                    fp = joint_frame(end.q, p, joints.frame_p[j])
                    fc = joint_frame(end.q, c, joints.frame_c[j])
        if joints.cone[j] >= zero:
            fp = joint_frame(end.q, p, joints.frame_p[j])
            fc = joint_frame(end.q, c, joints.frame_c[j])
            xp = wp.quat_rotate(fp, unit_axis(d, 0))
            xc = wp.quat_rotate(fc, unit_axis(d, 0))
            swing = wp.cross(xp, xc)
            angle = wp.atan2(wp.length(swing), wp.dot(xp, xc))
            if angle > joints.cone[j] and wp.length(swing) > type(zero)(1.0e-9):
                n = wp.normalize(swing)
                tau = n * (-(angle - joints.cone[j]) / wp.dot(n, K * n))
                push_positions(end.x, end.q, p, c, imp, Ip, imc, Ic, rp, rc, C * tau, tau)


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

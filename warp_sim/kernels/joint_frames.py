"""A joint's geometry and pushes on values, for the joint rows (``joints``) and their taped launches
(``joint_adjoint``): each side's anchor, lever and frame at a pose (the world's: already world), its inverse mass
and inertia, angles of the relative rotation, the limit and drive rows' impulses, and an impulse or a
position-level push applied to the two sides' values. Values in, values out: a kernel loads its joint's bodies,
calls these and stores them once, so that a tape's adjoint replays each launch on what it read.

Private: for the simulator's own use (kernels.joints, kernels.joint_adjoint); their arguments may change between
releases. There are no kernels. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .contacts import turn

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
def pose_side(x: Any, q: Any, b: int, anchor: Any, frame: Any):
    """joint_side() of body b at pose (x, q) (b < 0: the world, anchor and frame already world)."""
    if b < 0:
        return anchor, anchor * type(anchor[0])(0.0), frame
    r = wp.quat_rotate(wp.normalize(q), anchor)
    return x + r, r, wp.normalize(q) * frame


@wp.func
def with_component(v: Any, k: int, value: Any):
    """v with its component k (0, 1, 2) replaced by ``value``: selected, not assigned, so that the adjoint gives
    the replaced component no gradient (Warp's adjoint of ``v[k] = value`` passes it through as well)."""
    return type(v)(wp.where(k == 0, value, v[0]), wp.where(k == 1, value, v[1]), wp.where(k == 2, value, v[2]))


@wp.func
def joint_side(x: wp.array(dtype=Any), q: wp.array(dtype=Any), b: int, anchor: Any, frame: Any):
    """(the anchor's world point [m], its lever from the centre of mass [m], the joint frame's world rotation) of
    body b's side (b < 0: the world, anchor and frame already world)."""
    if b < 0:
        return anchor, anchor * type(anchor[0])(0.0), frame
    return pose_side(x[b], q[b], b, anchor, frame)


@wp.func
def frame_side(q: Any, b: int, frame: Any):
    """The joint frame's world rotation on body b's side at orientation q (b < 0: the world, frame already
    world)."""
    if b < 0:
        return frame
    return wp.normalize(q) * frame


@wp.func
def side_mass(mass: Any, b: int, zero: Any):
    """(1/m [1/kg], I_body^-1 [1/(kg m^2)]) of body b; zeros for the world (b < 0)."""
    if b < 0:
        return zero, wp.identity(3, type(zero)) * zero
    return mass.inv_mass[b], mass.inv_inertia[b]


@wp.func
def side_inverse(inv_mass: Any, inv_inertia: Any, q: Any):
    """(1/m [1/kg], I^-1 in the world [1/(kg m^2)]) of a body of side_mass() ``inv_mass``, ``inv_inertia`` at
    orientation q (the world's zeros stay zeros)."""
    R = wp.quat_to_matrix(wp.normalize(q))
    return inv_mass, R * inv_inertia * wp.transpose(R)


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
def world_masses(inv_mass: wp.array(dtype=Any), inv_inertia_world: wp.array(dtype=Any), p: int, c: int):
    """(1/m [1/kg], I^-1 in the world [1/(kg m^2)]) of a joint's parent, then its child, from the bodies' inverse
    masses and world inverse inertias; zeros for the world's (p < 0)."""
    imc = inv_mass[c]
    Ic = inv_inertia_world[c]
    imp = imc * type(imc)(0.0)
    Ip = Ic * type(imc)(0.0)
    if p >= 0:
        imp = inv_mass[p]
        Ip = inv_inertia_world[p]
    return imp, Ip, imc, Ic


@wp.func
def load_sides(a: wp.array(dtype=Any), b: wp.array(dtype=Any), p: int, c: int):
    """(a[p], b[p], a[c], b[c]) of a joint's parent and child; zeros for the world's (p < 0)."""
    ac = a[c]
    bc = b[c]
    ap = ac * type(ac[0])(0.0)
    bp = bc * type(bc[0])(0.0)
    if p >= 0:
        ap = a[p]
        bp = b[p]
    return ap, bp, ac, bc


@wp.func
def load_poses(x: wp.array(dtype=Any), q: wp.array(dtype=Any), p: int, c: int):
    """(x[p], q[p], x[c], q[c]) of a joint's parent and child; the origin and the identity for the world's."""
    xp, qp, xc, qc = load_sides(x, q, p, c)
    if p < 0:
        qp = type(qc)(qp[0], qp[1], qp[2], type(qc[3])(1.0))
    return xp, qp, xc, qc


@wp.func
def store_sides(a: wp.array(dtype=Any), b: wp.array(dtype=Any), p: int, c: int, ap: Any, bp: Any, ac: Any, bc: Any):
    """a[c], b[c] = ac, bc, and the parent's (not the world's)."""
    a[c] = ac
    b[c] = bc
    if p >= 0:
        a[p] = ap
        b[p] = bp


@wp.func
def relative_velocity(vp: Any, wq: Any, vc: Any, wc: Any, rp: Any, rc: Any):
    """The child's anchor velocity less the parent's [m/s] (levers rp, rc)."""
    return (vc + wp.cross(wc, rc)) - (vp + wp.cross(wq, rp))


@wp.func
def push_velocities(vp: Any, wq: Any, vc: Any, wc: Any, imp: Any, Ip: Any, imc: Any, Ic: Any, rp: Any, rc: Any,
                    linear: Any, angular: Any):
    """The impulse ``linear`` [N s] at the child's anchor and ``angular`` [N m s] on the child, their opposites
    on the parent (the world's zero masses leave its zero velocities): the velocities (vp, wq, vc, wc) after."""
    vc = vc + linear * imc
    wc = wc + Ic * (wp.cross(rc, linear) + angular)
    vp = vp - linear * imp
    wq = wq - Ip * (wp.cross(rp, linear) + angular)
    return vp, wq, vc, wc


@wp.func
def push_positions(xp: Any, qp: Any, xc: Any, qc: Any, imp: Any, Ip: Any, imc: Any, Ic: Any, rp: Any, rc: Any,
                   linear: Any, angular: Any):
    """The position-level push ``linear`` [N s . s] at the child's anchor and ``angular`` on the child (the
    parent the opposite): the poses (xp, qp, xc, qc) moved and turned, velocities untouched."""
    xc = xc + linear * imc
    qc = turn(qc, Ic * (wp.cross(rc, linear) + angular))
    xp = xp - linear * imp
    qp = turn(qp, -(Ip * (wp.cross(rp, linear) + angular)))
    return xp, qp, xc, qc


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

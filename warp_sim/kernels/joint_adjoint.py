"""Joint solve on a wp.Tape: the launches of ``passes.joint_adjoint``, whose adjoints Warp builds.

Each kernel is one update of one colour of joints (a thread per joint, no two of a colour sharing a body) from
arrays into new ones that the caller copied from them: a thread reads its joint's bodies from the inputs and
writes them, and its joint's impulses, into the outputs, so a tape's backward replays each on the values it saw.
The arithmetic is the forward's (``joints``: warm_start_rows, velocity_rows, position_rows, one iteration per
launch).

Private: every kernel here is for the simulator's own use (passes.joint_adjoint); their arguments may change
between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .joint_frames import load_poses, load_sides, side_mass, store_sides, world_masses
from .joints import position_rows, velocity_rows, warm_start_rows
from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []


@wp.kernel
def taped_warm_start(joints: Any, first: int, start: Any, mass: Any, enabled: wp.array(dtype=wp.int32),
                     v_in: wp.array(dtype=Any), w_in: wp.array(dtype=Any), v_out: wp.array(dtype=Any),
                     w_out: wp.array(dtype=Any)):
    """joints.warm_start_joints of one colour (``joints``: the impulses of the last step), velocities from the
    inputs into the outputs."""
    j = first + wp.tid()
    if enabled[j] == 0:
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    vp, wq, vc, wc = load_sides(v_in, w_in, p, c)
    vp, wq, vc, wc = warm_start_rows(joints, j, start, mass, vp, wq, vc, wc)
    store_sides(v_out, w_out, p, c, vp, wq, vc, wc)


@wp.kernel
def taped_solve(joints: Any, first: int, h: Any, beta: Any, start: Any, mass: Any,
                inv_inertia_world: wp.array(dtype=Any), enabled: wp.array(dtype=wp.int32), v_in: wp.array(dtype=Any),
                w_in: wp.array(dtype=Any), v_out: wp.array(dtype=Any), w_out: wp.array(dtype=Any),
                lin_out: wp.array(dtype=Any), ang_out: wp.array(dtype=Any), drive_lin_out: wp.array(dtype=Any),
                drive_ang_out: wp.array(dtype=Any), cone_out: wp.array(dtype=Any), dist_out: wp.array(dtype=Any)):
    """One iteration of joints.solve_joints over one colour: velocities from v_in, w_in into v_out, w_out, each
    joint's accumulated impulses from ``joints`` into the outputs (copies of its lam_lin, lam_ang, lam_drive_lin,
    lam_drive_ang, lam_cone, lam_dist: arrays, not a struct's fields, whose stores Warp's adjoint does not consume,
    so that a copy's adjoint would count their gradient twice)."""
    j = first + wp.tid()
    if enabled[j] == 0:
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    imp, Ip, imc, Ic = world_masses(mass.inv_mass, inv_inertia_world, p, c)
    vp, wq, vc, wc = load_sides(v_in, w_in, p, c)
    vp, wq, vc, wc, lin, ang, dlin, dang, cone, dist = velocity_rows(
        joints, j, h, beta, start, imp, Ip, imc, Ic, vp, wq, vc, wc, joints.lam_lin[j], joints.lam_ang[j],
        joints.lam_drive_lin[j], joints.lam_drive_ang[j], joints.lam_cone[j], joints.lam_dist[j])
    store_sides(v_out, w_out, p, c, vp, wq, vc, wc)
    lin_out[j] = lin
    ang_out[j] = ang
    drive_lin_out[j] = dlin
    drive_ang_out[j] = dang
    cone_out[j] = cone
    dist_out[j] = dist


@wp.kernel
def taped_project(joints: Any, first: int, mass: Any, enabled: wp.array(dtype=wp.int32), x_in: wp.array(dtype=Any),
                  q_in: wp.array(dtype=Any), x_out: wp.array(dtype=Any), q_out: wp.array(dtype=Any)):
    """One iteration of joints.project_joints over one colour: poses from x_in, q_in into x_out, q_out."""
    j = first + wp.tid()
    if enabled[j] == 0:
        return
    p = joints.ids[j][0]
    c = joints.ids[j][1]
    zero = type(joints.cone[j])(0.0)
    imp, Bp = side_mass(mass, p, zero)
    imc, Bc = side_mass(mass, c, zero)
    xp, qp, xc, qc = load_poses(x_in, q_in, p, c)
    xp, qp, xc, qc = position_rows(joints, j, imp, Bp, imc, Bc, xp, qp, xc, qc)
    store_sides(x_out, q_out, p, c, xp, qp, xc, qc)


register(globals(), lin_out="vec3", ang_out="vec3", drive_lin_out="vec3", drive_ang_out="vec3",
         cone_out="scalar", dist_out="scalar", v_in="vec3", w_in="vec3", v_out="vec3", w_out="vec3",
         inv_inertia_world="mat33",
         x_in="vec3", q_in="quat", x_out="vec3", q_out="quat")

"""Joints: the scene's joints as constraints of the coloured Gauss-Seidel solve the body contacts use.

The joints are coloured once (``colour_springs`` on their bodies, the world taking no colour), so that no two of
one colour share a body, and stored on the device colour by colour. Each step (``kernels.joints``):

1. the working velocities of the bodies at the end of the step (``contacts.load_velocities``), and each joint's
   impulses of the last step applied again (warm start);
2. ``velocity_sweeps`` Gauss-Seidel sweeps, each one launch per colour with a thread per joint (on the CPU,
   whose launch runs its threads in order, one launch for all the colours: the same sweep): locked axes, limits
   and drives; the velocities go back into the state as the contacts' do (``contacts.finish_response``: a
   velocity change moves the body by beta h times it, beta the solver's position response);
3. ``position_sweeps`` sweeps of the position projection, velocities untouched;
4. where a joint can break, those whose force or torque over the step exceeded the limit are disabled, and the
   step's breaks are kept for the simulator to report (``take_breaks``).

With body contacts in the scene, ``passes.body_contacts`` runs the same sweeps inside its own (``warm_start``,
``velocity_sweep``, ``position_sweep``, ``finish``): a joint and a contact are then rows of one Gauss-Seidel
solve, each sweep visiting the body-body contact colours, the joint colours, then the static contact colours.
The joints' pairs are left out of the broad phase unless a joint says ``collide``
(``detection.geometry.ContactGeometry``).
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..kernels import blocks
from ..kernels import contacts as contact_kernels
from ..kernels import joints as joint_kernels
from ..scene.joints import Joint
from ..util.rotations import quat_to_matrix
from .joint_adjoint import TapedJoints
from .strain import colour_springs

_NONE = -1.0   # the kernels' "no limit" for a break force, a cone or a distance


def joint_colours(joints: list[Joint], body_count: int) -> np.ndarray:
    """Per joint, a colour such that no two joints of one colour share a body (the world shares nothing)."""
    pairs = np.array([[j.parent if j.parent >= 0 else body_count + k, j.child] for k, j in enumerate(joints)],
                     dtype=np.int64).reshape(-1, 2)
    return colour_springs(pairs, body_count + len(joints))


def _kept_apart(joint: Joint) -> bool:
    """Whether a joint bounds its anchors' distance (a distance joint with a min, a max or both)."""
    return bool(np.isfinite(joint.distance[0]) or np.isfinite(joint.distance[1]))


def _rows(joints: list[Joint]) -> dict[str, np.ndarray]:
    """The kernels' per-joint fields (blocks.LAYOUTS["Joints"]) as numpy arrays, in the given order."""
    def finite(value):
        return value if np.isfinite(value) else _NONE

    def drive_fields(k0: int) -> dict:
        kinds = np.array([[0 if d is None else (2 if d.acceleration else 1) for d in j.drives[k0:k0 + 3]]
                          for j in joints], np.int32).reshape(-1, 3)
        out = {"kind": kinds}
        for name, attribute, fallback in (("target", "target", 0.0), ("speed", "velocity", 0.0),
                                          ("stiffness", "stiffness", 0.0), ("damping", "damping", 0.0),
                                          ("max", "max_force", 1.0e30)):
            out[name] = np.array([[fallback if d is None else min(float(getattr(d, attribute)), 1.0e30)
                                   for d in j.drives[k0:k0 + 3]] for j in joints], float).reshape(-1, 3)
        return out

    lin, ang = drive_fields(0), drive_fields(3)
    modes = np.array([j.modes for j in joints], np.int32).reshape(-1, 6)
    lower = np.array([j.lower for j in joints], float).reshape(-1, 6)
    upper = np.array([j.upper for j in joints], float).reshape(-1, 6)
    return dict(
        ids=np.array([[j.parent, j.child] for j in joints], np.int32).reshape(-1, 2),
        anchor_p=np.array([j.parent_anchor for j in joints], float).reshape(-1, 3),
        anchor_c=np.array([j.child_anchor for j in joints], float).reshape(-1, 3),
        frame_p=np.array([j.parent_frame for j in joints], float).reshape(-1, 4),
        frame_c=np.array([j.child_frame for j in joints], float).reshape(-1, 4),
        lin_mode=modes[:, :3], ang_mode=modes[:, 3:], lin_lower=lower[:, :3], lin_upper=upper[:, :3],
        ang_lower=lower[:, 3:], ang_upper=upper[:, 3:],
        cone=np.array([finite(j.cone) for j in joints], float),
        dist_min=np.array([finite(j.distance[0]) if _kept_apart(j) else _NONE for j in joints], float),
        dist_max=np.array([min(j.distance[1], 1.0e30) if _kept_apart(j) else _NONE for j in joints], float),
        drive_lin=lin["kind"], drive_ang=ang["kind"], lin_target=lin["target"], ang_target=ang["target"],
        lin_speed=lin["speed"], ang_speed=ang["speed"], lin_stiffness=lin["stiffness"],
        ang_stiffness=ang["stiffness"], lin_damping=lin["damping"], ang_damping=ang["damping"], lin_max=lin["max"],
        ang_max=ang["max"], break_force=np.array([finite(j.break_force) for j in joints], float),
        break_torque=np.array([finite(j.break_torque) for j in joints], float),
        enabled=np.array([1 if j.enabled else 0 for j in joints], np.int32),
    )


class Joints(Pass):
    """The scene's joints, solved after each step (see the module docstring), a Pass.

    position_response: the solver's beta (Solver.position_response)
    velocity_sweeps, position_sweeps: Gauss-Seidel sweeps of the velocity rows and of the position projection
        (each one launch per colour; on the CPU one launch for all of them)
    iterations: (velocity, position) iterations of a joint's own rows within one sweep
    max_step: the longest step it takes [s] (Pass.max_step: the Simulator's joint_step, by default 1/480 s)
    names: the joints' names, in the scene's order; order: each device row's scene index (colour order)
    colours: (first row, rows) per colour
    breakable: whether any joint has a break force or torque (then each step's breaks are read back)
    broken: the breaks so far, (scene index, name, time [s]) in the order they happened
    """

    capturable = True
    persistent = ("state.enabled", "state.lam_lin", "state.lam_ang", "state.lam_drive_lin", "state.lam_drive_ang",
                  "state.lam_cone", "state.lam_dist", "broken")

    def __init__(self, model: Model, scene, position_response: float, velocity_sweeps: int = 8,
                 position_sweeps: int = 8, iterations: tuple[int, int] = (1, 1), max_step: float | None = None):
        self.model = model
        self.max_step = max_step
        self.position_response = position_response
        self.velocity_sweeps = velocity_sweeps
        self.position_sweeps = position_sweeps
        self.iterations = iterations
        joints = list(scene.joints)
        self.names = [j.name for j in joints]
        colours = joint_colours(joints, scene.body_count)
        self.order = np.argsort(colours, kind="stable")
        counts = np.bincount(colours, minlength=int(colours.max()) + 1 if len(colours) else 0)
        firsts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int) if len(counts) else np.zeros(0, int)
        self.colours = [(int(f), int(n)) for f, n in zip(firsts, counts) if n > 0]
        rows = _rows([joints[k] for k in self.order])
        layout = blocks.LAYOUTS["Joints"]
        kinds = {"scalar": model.scalar, "vec3": model.vec3, "quat": model.quat, "mat33": model.mat33}
        arrays = {}
        for name, kind in layout.items():
            dtype = kinds.get(kind, kind)
            values = rows.get(name)
            if values is None:
                arrays[name] = model.zeros(len(joints), dtype)
            else:
                arrays[name] = wp.array(np.ascontiguousarray(values, dtype=np.int32 if dtype in (
                    wp.int32, wp.vec2i, wp.vec3i) else model.numpy_scalar()), dtype=dtype, device=model.device)
        self.state = blocks.fill(model.blocks.Joints, **arrays)
        self.breakable = bool(np.any(rows["break_force"] >= 0.0) or np.any(rows["break_torque"] >= 0.0))
        self.broken: list = []
        self._broken_flags = model.zeros(len(joints), wp.int32)
        B = model.body_count
        vec3, mat33, scalar = model.vec3, model.mat33, model.scalar
        zeros = model.zeros
        self.work = blocks.fill(model.blocks.BodyVelocities, v=zeros(B, vec3), w=zeros(B, vec3),
                                inv_inertia_world=zeros(B, mat33), impact=zeros(B, scalar), stamp=zeros(B, wp.int32))
        self.start_velocities = blocks.fill(model.blocks.BodyVelocities, v=zeros(B, vec3), w=zeros(B, vec3),
                                            inv_inertia_world=self.work.inv_inertia_world, impact=self.work.impact,
                                            stamp=self.work.stamp)
        held = np.zeros(B, np.int32)
        for joint in joints:
            if joint.enabled:
                held[[b for b in (joint.parent, joint.child) if b >= 0]] = 1
        #: per body, 1 where a joint holds it: it drifts as symplectic Euler does (contacts.finish_response)
        self.drift = wp.array(held, dtype=wp.int32, device=model.device)
        self._time = 0.0
        self.taped = TapedJoints(self)   # the solve of a differentiable run

    @property
    def kernels(self) -> tuple[str, ...]:
        """Its kernel modules: its taped solve's too in a differentiable run."""
        return ("contacts", "joints", *(("joint_adjoint",) if self.model.differentiable else ()))

    def carried(self) -> list:
        return self.taped.carried() if self.model.differentiable else []

    def carry(self, arrays: list) -> None:
        self.taped.carry(arrays)

    @property
    def count(self) -> int:
        return len(self.names)

    def _launch_colours(self, prepared) -> None:
        """One launch per colour (input 1: the colour's first row), or on the CPU, uncaptured, one for all."""
        m = self.model
        if m.device.is_cpu and not m.launcher.capturing:
            prepared.set(1, 0)
            prepared.run(self.count)
            return
        prepared.sweep(1, self.colours, 1)

    # the solve, in pieces a contact solve interleaves with its own sweeps ------------------------------------
    def warm_start(self, start: State, mass, work) -> None:
        """Apply the last step's impulses on ``work`` at the levers of ``start`` (as the velocity rows)."""
        self._launch_colours(self.model.launcher.prepare(joint_kernels.warm_start_joints, 1, [
            self.state, 0, start.bodies, mass, work, self.state.enabled]))

    def velocity_sweep(self, start: State, mass, work, h: float, sweep: int = 0) -> None:
        """One sweep of the velocity rows on ``work`` (the joints' levers and angles at ``start``); the bodies'
        work.stamp set to ``sweep``."""
        T = self.model.scalar
        self._launch_colours(self.model.launcher.prepare(joint_kernels.solve_joints, 1, [
            self.state, 0, self.iterations[0], sweep, T(h), T(self.position_response), start.bodies, mass, work,
            self.state.enabled]))

    def position_sweep(self, end: State, mass, stamp, sweep: int = 0) -> None:
        """One sweep of the position projection on ``end``; ``stamp`` set to ``sweep`` for the bodies moved."""
        self._launch_colours(self.model.launcher.prepare(joint_kernels.project_joints, 1, [
            self.state, 0, self.iterations[1], sweep, end.bodies, mass, self.state.enabled, stamp]))

    def finish(self, h: float, t: float) -> None:
        """After the velocity sweeps: break what was overloaded (where a joint can break)."""
        if not self.breakable:
            return
        self.model.launch(joint_kernels.break_joints, self.count, [self.state, self.model.scalar(h),
                                                                   self._broken_flags])
        self._time = t + h

    def take_breaks(self) -> list:
        """The breaks since the last call, (scene index, name, time [s]) each (one read-back; [] if unbreakable)."""
        if not self.breakable:
            return []
        flags = self._broken_flags.numpy()
        rows = np.flatnonzero(flags)
        if not len(rows):
            return []
        self._broken_flags.zero_()
        events = [(int(self.order[r]), self.names[self.order[r]], self._time) for r in rows]
        self.broken.extend(events)
        return events

    # the pass on its own (a scene without body contacts) ----------------------------------------------------
    def apply(self, start: State, end: State, t: float, h: float) -> None:
        m = self.model
        if m.differentiable:
            self.taped.apply(start, end, t, h)
            return
        mass, work = m.body_mass, self.work
        m.launch(contact_kernels.load_velocities, m.body_count, [end.bodies, mass, work])
        wp.copy(self.start_velocities.v, work.v)
        wp.copy(self.start_velocities.w, work.w)
        self.warm_start(start, mass, work)
        for _ in range(self.velocity_sweeps):
            self.velocity_sweep(start, mass, work, h)
        self.finish(h, t)
        m.launch(contact_kernels.finish_response, m.body_count, [m.scalar(h), m.scalar(self.position_response),
                                                                 mass, self.start_velocities, work, start.bodies,
                                                                 end.bodies, self.drift])
        for _ in range(self.position_sweeps):
            self.position_sweep(end, mass, work.stamp)

    def gaps(self, state: State) -> np.ndarray:
        """Per joint (scene order), the distance [m] between its two anchors along its locked axes in ``state``
        (host-side, for tests and reports)."""
        x, q = state.body_x.numpy().astype(float), state.body_q.numpy().astype(float)
        rows = {name: getattr(self.state, name).numpy() for name in ("ids", "anchor_p", "anchor_c", "frame_p",
                                                                    "lin_mode")}
        out = np.zeros(self.count)
        for r in range(self.count):
            p, c = rows["ids"][r]
            if p >= 0:
                Rp = quat_to_matrix(q[p])
                pp, frame = x[p] + Rp @ rows["anchor_p"][r], Rp @ quat_to_matrix(rows["frame_p"][r])
            else:
                pp, frame = rows["anchor_p"][r], quat_to_matrix(rows["frame_p"][r])
            pc = x[c] + quat_to_matrix(q[c]) @ rows["anchor_c"][r]
            local = frame.T @ (pc - pp)
            locked = rows["lin_mode"][r] == 1
            out[self.order[r]] = float(np.linalg.norm(local[locked])) if locked.any() else 0.0
        return out


"""Joints in a differentiable run: the joint solve of ``passes.joints`` recorded on the tape launch by launch
(``TapedJoints``), its impulses carried from step to step on the tape.

The forward solve updates the working velocities, the poses and the joints' accumulated impulses in place, which
no tape can take back. In a differentiable run the same solve (kernels.joints' rows) runs as launches that each
write arrays of their own (kernels.joint_adjoint): the warm start, then every iteration of every sweep of the
velocity rows, one launch per colour from the velocities and impulses before it into new ones; finish_response
(the jointed bodies' symplectic drift, contacts.finish_response) on a copy of the state; every iteration of the
position projection, one launch per colour from the poses into new ones; the result copied into the end state.

The impulses a step ends with warm-start the next (as forward), so they are part of what the gradient follows
from step to step: ``carried()`` names the arrays that hold them now, which a checkpointed gradient
(gradients.checkpoints) stores at each frame, starts a recomputed frame from (``carry``) and carries the
adjoint of across frames, as it does the state's.

What the gradient means: the derivative of the run's solve as it ran, every sweep and iteration of it (not of the
exact constraint solution the sweeps approach). A limit or a cone that starts or stops pushing within the run
switches a row on or off: the gradient holds that choice (one-sided where a change of the input would change
it). Breakable joints are refused (``refusal``): a break switches a joint off, which has no derivative.
"""
from __future__ import annotations

import warp as wp

from ..core.state import State
from ..core.tape import copies, paused
from ..kernels import blocks
from ..kernels import contacts as contact_kernels
from ..kernels import joint_adjoint as taped

#: the Joints block's accumulated impulses, carried from step to step
IMPULSES = ("lam_lin", "lam_ang", "lam_drive_lin", "lam_drive_ang", "lam_cone", "lam_dist")


def refusal(joints) -> str | None:
    """Why the taped solve does not cover the joints of ``joints`` (a Joints pass), or None where it does."""
    if joints.breakable:
        return "break forces and torques (a break switches a joint off; set break_force and break_torque to None)"
    return None


class TapedJoints:
    """The solve of a Joints pass (``joints``) in a differentiable run, on the tape (module docstring).

    impulses: the accumulated impulses the next step starts from, by name (IMPULSES), arrays with gradients
    """

    def __init__(self, joints):
        self.joints = joints
        self._impulses = None   # taken from the pass's own at the first step

    @property
    def impulses(self) -> dict:
        if self._impulses is None:
            with paused():
                self._impulses = {name: wp.clone(getattr(self.joints.state, name), requires_grad=True)
                                  for name in IMPULSES}
        return self._impulses

    @impulses.setter
    def impulses(self, arrays: dict) -> None:
        self._impulses = arrays

    def carried(self) -> list:
        """The arrays the next step reads that the State does not hold: the impulses, in IMPULSES order."""
        return [self.impulses[name] for name in IMPULSES]

    def carry(self, arrays: list) -> None:
        """Start the next step from ``arrays`` (as carried() gives them); the pass's own impulses too."""
        self.impulses = dict(zip(IMPULSES, arrays))
        self._keep()

    def _keep(self) -> None:
        """The impulses now into the pass's own arrays (off the tape: for its checkpoints and reports)."""
        with paused():
            for name, array in self.impulses.items():
                wp.copy(getattr(self.joints.state, name), array)

    def _block(self, impulses: dict):
        """The Joints block with ``impulses`` for its accumulated impulses."""
        state = self.joints.state
        return blocks.fill(self.joints.model.blocks.Joints, **{name: impulses.get(name, getattr(state, name))
                                                                for name in state._cls.vars})

    # the solve, in pieces the taped contact response interleaves with its own sweeps ------------------------
    def begin(self) -> None:
        """Start a step's solve from the impulses the last step ended with."""
        self._running = dict(self.impulses)

    def warm_start(self, start: State, v: wp.array, w: wp.array) -> tuple:
        """The last step's impulses applied to velocities v, w at the levers of ``start``; returns new ones."""
        J = self.joints
        m = J.model
        for first, size in J.colours:
            v_out, w_out = copies(v, w)
            m.launch(taped.taped_warm_start, size, [self._block(self._running), first, start.bodies, m.body_mass,
                                                    J.state.enabled, v, w, v_out, w_out])
            v, w = v_out, w_out
        return v, w

    def velocity_sweep(self, start: State, inv_inertia_world: wp.array, v: wp.array, w: wp.array, h: float) -> tuple:
        """One sweep of the velocity rows (each colour's iterations) on v, w, the bodies' world inverse inertias
        ``inv_inertia_world``; returns the new velocities (the running impulses move on with them)."""
        J = self.joints
        m = J.model
        T = m.scalar
        for first, size in J.colours:
            for _iteration in range(J.iterations[0]):
                outputs = copies(v, w, *(self._running[name] for name in IMPULSES))
                m.launch(taped.taped_solve, size, [self._block(self._running), first, T(h), T(J.position_response),
                                                   start.bodies, m.body_mass, inv_inertia_world, J.state.enabled, v,
                                                   w, *outputs])
                v, w = outputs[0], outputs[1]
                self._running = dict(zip(IMPULSES, outputs[2:]))
        return v, w

    def position_sweep(self, x: wp.array, q: wp.array) -> tuple:
        """One sweep of the position projection (each colour's iterations) on poses x, q; returns new ones."""
        J = self.joints
        m = J.model
        for first, size in J.colours:
            for _iteration in range(J.iterations[1]):
                x_out, q_out = copies(x, q)
                m.launch(taped.taped_project, size, [self._block(self._running), first, m.body_mass, J.state.enabled,
                                                     x, q, x_out, q_out])
                x, q = x_out, q_out
        return x, q

    def commit(self) -> None:
        """The step's impulses are what the next step starts from."""
        self.impulses = self._running
        self._keep()

    # the solve on its own (a scene without body contacts) -----------------------------------------------------
    def apply(self, start: State, end: State, t: float, h: float) -> None:
        """Solve the joints over the step from ``start`` to ``end`` (h seconds) and correct ``end``: what
        Joints.apply does, every launch that changes a float on the tape."""
        J = self.joints
        m = J.model
        T, B = m.scalar, m.body_count
        mass = m.body_mass
        pre = State(end.layout, m.scalar, m.device, requires_grad=True)
        wp.copy(pre.y, end.y)   # what the solver wrote (end is overwritten last)
        work = blocks.fill(m.blocks.BodyVelocities, **{name: wp.zeros(B, dtype=dtype, device=m.device,
                                                                      requires_grad=True)
                                                       for name, dtype in (("v", m.vec3), ("w", m.vec3),
                                                                           ("inv_inertia_world", m.mat33),
                                                                           ("impact", T))},
                           stamp=m.zeros(B, wp.int32))
        m.launch(contact_kernels.load_velocities, B, [self._bodies(pre), mass, work])
        self.begin()
        v, w = self.warm_start(start, work.v, work.w)
        for _sweep in range(J.velocity_sweeps):
            v, w = self.velocity_sweep(start, work.inv_inertia_world, v, w, h)
        fin = State(end.layout, m.scalar, m.device, requires_grad=True)
        wp.copy(fin.y, pre.y)
        solved = blocks.fill(m.blocks.BodyVelocities, v=v, w=w, inv_inertia_world=work.inv_inertia_world,
                             impact=work.impact, stamp=work.stamp)
        m.launcher.launch_in_place(contact_kernels.finish_response, B, [
            T(h), T(J.position_response), mass, work, solved, start.bodies, self._bodies(fin), J.drift], fin.y)
        x, q = fin.body_x, fin.body_q
        for _sweep in range(J.position_sweeps):
            x, q = self.position_sweep(x, q)
        for field, value in (("body_x", x), ("body_q", q), ("body_P", fin.body_P), ("body_L", fin.body_L)):
            wp.copy(getattr(end, field), value)
        self.commit()

    def _bodies(self, state: State):
        return blocks.fill(self.joints.model.blocks.Bodies, x=state.body_x, q=state.body_q, P=state.body_P,
                           L=state.body_L)




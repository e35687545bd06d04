"""The three kinds of part a simulation is assembled from: components, force terms and passes.

- A Component owns state fields and turns forces into rates (particles, rigid bodies).
- A ForceTerm adds forces into the components' accumulators (springs, fields, penalty contacts).
- A Pass runs after the solver's step on the step's start and end states (contacts, strain
  limiting, emitter pools), in the order ``warp_sim.assembly`` lists them.

``Forces`` holds the accumulators the force terms write and the components read.
"""
from __future__ import annotations

import warp as wp

from ..kernels import blocks
from .model import Model
from .persistence import Persistent
from .state import State, StateField


class Component:
    """Owner of some state fields. Subclasses set ``name`` and ``fields``.

    name: the component's name in messages ("particles", "bodies")
    fields: its StateFields
    position_rates_need_positions: whether its position-block rates read positions too (not only velocities)
    guard_reasons: the divergence guard's reason codes (see kernels.guards) in its words
    kernels: the kernel modules (names in warp_sim.kernels) it launches, compiled together when a Simulator starts
    capturable: whether its launches are the same every step, so a step can be captured (core.capture)
    """

    name = "component"
    kernels: tuple[str, ...] = ()
    capturable = True
    fields: list[StateField] = []
    position_rates_need_positions = False
    guard_reasons = {0: "non-finite position", 1: "non-finite velocity", 2: "speed above max_speed"}

    def attach(self, state: State) -> None:
        """Give a new state what the component's kernels take besides its field views (e.g. block structs)."""

    def set_initial(self, state: State, scene) -> None:
        """Write the scene's initial values into ``state``."""

    def velocity_derivative(self, state: State, t: float, out: State) -> None:
        """Write the rates of the velocity-block fields (accelerations, torques) into ``out``."""

    def position_derivative(self, positions: State, velocities: State, out: State) -> None:
        """Write the rates of the position-block fields into ``out``, reading the
        position fields of ``positions`` and the velocity fields of ``velocities``."""

    def post_step(self, state: State) -> None:
        """Project the state after a step (e.g. renormalise orientations)."""

    def guard_inputs(self, state: State):
        """(guard kernel, element count, its leading inputs): the kernel takes these, then max_speed, step and
        the record (kernels.guards)."""
        raise NotImplementedError

    def locate(self, element: int) -> str:
        """Element ``element`` as a user knows it (its group and index there, or its name), for messages."""
        return f"element {element}"

    def describe(self, state: State, element: int) -> str:
        """The current values of one element, for error messages."""
        raise NotImplementedError


class ForceTerm:
    """Something that adds forces into the accumulators, given a state.

    targets: the components whose accumulators it writes ("particles", "bodies")
    kernels: the kernel modules (names in warp_sim.kernels) it launches
    capturable: whether its launches are the same every step (no read-back, no time as a scalar: core.capture)
    """

    targets = frozenset({"particles"})
    kernels: tuple[str, ...] = ()
    capturable = True

    def apply(self, state: State, t: float, forces: "Forces") -> None:
        raise NotImplementedError


class Pass(Persistent):
    """Something run after each solver step: ``apply(start, end, t, h)`` corrects ``end`` in place.

    start: the state at t; end: the solver's state at t + h; h: the step [s].
    ``check_step(h)`` runs before the step and may refuse it (ValueError).
    max_step: the longest step the pass is accurate at [s] (None: any); the simulator splits a longer step
    into equal sub-steps, solver and passes each, inside ``step()``
    persistent: what it carries from one step to the next, for checkpoints (core.persistence; none by default)
    kernels: the kernel modules (names in warp_sim.kernels) it launches
    capturable: whether its launches are the same every step (core.capture); False unless a pass says so
    """

    max_step: float | None = None
    kernels: tuple[str, ...] = ()
    capturable = False

    def check_step(self, h: float) -> None:
        """Refuse a step of h seconds this pass cannot handle (ValueError); by default accept any."""

    def before_capture(self) -> bool:
        """Before a step is recorded as a graph, outside the capture: allocate or upload what its launches need
        (a capture records copies and allocations instead of doing them). Returns True where that changed what
        graphs recorded earlier read (they are dropped); by default nothing, False."""
        return False

    def replay_held(self) -> bool:
        """After a captured step's replay: whether its recorded launches held the whole step (a pass whose buffers
        can outgrow them says False, and the simulator does the step again uncaptured); by default True."""
        return True

    def capture_intact(self) -> bool:
        """After such a step was done again uncaptured: whether the arrays the recorded graphs launch on are still
        in place (False once a buffer was reallocated: the graphs are dropped); by default True."""
        return True

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        raise NotImplementedError

    def carried(self) -> list:
        """In a differentiable run, the arrays with gradients it carries from one step to the next outside the
        State (a warm start the gradient goes through), which a checkpointed gradient stores per frame and
        carries the adjoint of (gradients.checkpoints); none by default."""
        return []

    def carry(self, arrays: list) -> None:
        """Start the next step from ``arrays`` (as carried() gives them); nothing by default."""


class Forces:
    """Force accumulators, allocated only for components some force term writes (else empty arrays).

    particle_f: per particle [N]
    body_f: per body [N]
    body_t: per body, torque about the centre of mass [N m]
    body_wrench: body_f and body_t as a kernels.blocks Wrench
    """

    def __init__(self, model: Model, targets: set):
        self.model, self.targets = model, set(targets)
        self._fill(False)

    def _fill(self, requires_grad: bool, particles: bool = False) -> None:
        """New zeroed accumulators for the targets (and the particles where ``particles``)."""
        m = self.model

        def accumulator(component: str, count: int, wanted: bool = False):
            return wp.zeros(count if component in self.targets or wanted else 0, dtype=m.vec3, device=m.device,
                            requires_grad=requires_grad)

        self.particle_f = accumulator("particles", m.particle_count, particles)
        self.body_f = accumulator("bodies", m.body_count)
        self.body_t = accumulator("bodies", m.body_count)
        self.body_wrench = blocks.fill(blocks.of(m.scalar).Wrench, force=self.body_f, torque=self.body_t)
        self.arrays = [a for a in (self.particle_f, self.body_f, self.body_t) if a.shape[0] > 0]

    def clear(self) -> None:
        for array in self.arrays:
            array.zero_()

    def renew(self, particle_force=None) -> None:
        """A differentiable run's clear(): new zeroed accumulators with gradients, so that no evaluation overwrites
        what an earlier one's adjoint reads; with ``particle_force`` (vec3, one per particle [N]) the particles'
        starts from it (a copy, recorded by an active wp.Tape), even where no force term targets them."""
        self._fill(True, particle_force is not None)
        if particle_force is not None:
            wp.copy(self.particle_f, particle_force)

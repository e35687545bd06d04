"""A frame's scratch states, handed out in order and all taken back at the frame's end, so that frame after frame
a differentiable run reuses the same arrays instead of allocating new ones for every stage of every step."""
from __future__ import annotations

from ..core.dynamics import Dynamics
from ..core.state import State


class StatePool:
    """The states ``Dynamics.new_state`` hands out while this pool is set on the Dynamics (``using``): the k-th
    request of a frame gets the k-th state, zeroed with its gradient; ``release`` starts the next frame from the
    first. Only for states no live tape or state still needs once their frame is done (each frame's own tape is
    dropped before the next, gradients.checkpoints).

    size: the states made so far (the most one frame asked for)
    """

    def __init__(self, dynamics: Dynamics):
        self.dynamics = dynamics
        self.states: list[State] = []
        self.used = 0

    @property
    def size(self) -> int:
        return len(self.states)

    def take(self) -> State:
        """The next state of this frame, zeroed (values and gradient)."""
        if self.used == len(self.states):
            self.states.append(self.dynamics.fresh_state())
        state = self.states[self.used]
        self.used += 1
        state.y.zero_()
        if state.y.grad is not None:
            state.y.grad.zero_()
        return state

    def release(self) -> None:
        """Every state back: the next ``take`` is the frame's first again."""
        self.used = 0

    def __enter__(self) -> "StatePool":
        self.dynamics.pool = self
        return self

    def __exit__(self, *exc) -> None:
        self.dynamics.pool = None
        self.release()

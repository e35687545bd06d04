"""The components' own projection after each step (unit quaternions for rigid bodies), as a pass."""
from __future__ import annotations

from ..core.dynamics import Dynamics
from ..core.protocols import Pass
from ..core.state import State


class ComponentProjection(Pass):
    """Runs every component's ``post_step`` on the end state (e.g. renormalises body orientations)."""

    kernels = ("rigid",)
    capturable = True

    def __init__(self, dynamics: Dynamics):
        self.dynamics = dynamics

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        self.dynamics.post_step(end)

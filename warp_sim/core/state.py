"""State: the time-varying part of a simulation, one flat buffer of struct-of-arrays fields.

A State is one flat buffer of scalars: every component's position-like fields
first (the position block), then every velocity-like field (the velocity block).
Each StateField is also a typed view into that buffer (``state.particle_x`` is a
``wp.array`` of vec3), so the ODE solvers update the whole state with one launch
while components read and write their own named arrays.
"""
from __future__ import annotations

from dataclasses import dataclass

import warp as wp

from .persistence import Persistent

BLOCKS = ("position", "velocity")
# the canonical Warp vector types of a field, by scalar type and width (vector, quaternion)
ELEMENT_TYPES = {wp.float32: {3: wp.vec3f, 4: wp.quatf}, wp.float64: {3: wp.vec3d, 4: wp.quatd}}


@dataclass(frozen=True)
class StateField:
    """One named per-element array of a component's state.

    name: the State attribute it appears as (e.g. "particle_x")
    block: "position" (x-like: integrated from the position derivative) or "velocity" (v- or
        momentum-like: integrated from forces)
    width: scalars per element (3 for a vector, 4 for a quaternion)
    count: elements
    """
    name: str
    block: str
    width: int
    count: int


class StateLayout:
    """Where each StateField lies in the flat state buffer: position block, then velocity block."""

    def __init__(self, fields: list[StateField]):
        self.fields = list(fields)
        self.offsets: dict[str, int] = {}
        offset = 0
        self.block_start = {}
        for block in BLOCKS:
            self.block_start[block] = offset
            for field in self.fields:
                if field.block == block:
                    self.offsets[field.name] = offset
                    offset += field.width * field.count
        self.position_size = self.block_start["velocity"]
        self.size = offset


class State(Persistent):
    """The time-varying state on one device.

    y: the flat buffer of every field (scalars of the model's precision)
    position, velocity: views of its two blocks
    particle_x [m], particle_v [m/s], body_x [m], body_q (unit quaternion x, y, z, w), body_P [kg m/s],
        body_L [kg m^2/s]: typed views of the fields present (see StateField)
    requires_grad: whether y has a gradient (``y.grad``: a differentiable Simulator's states do), each view's
        ``.grad`` the same view of it
    """

    persistent = ("y",)

    def __init__(self, layout: StateLayout, scalar, device, requires_grad: bool = False):
        self.layout = layout
        self.y = wp.zeros(layout.size, dtype=scalar, device=device, requires_grad=requires_grad)
        self.position = self.y[: layout.position_size]
        self.velocity = self.y[layout.position_size:]
        vector_types = ELEMENT_TYPES[scalar]
        for field in layout.fields:
            start = layout.offsets[field.name]
            flat = self.y[start: start + field.width * field.count]
            setattr(self, field.name, flat.reshape((field.count, field.width)).view(vector_types[field.width]))

    def assign(self, other: "State") -> None:
        """Copy every value of another state of the same layout into this one."""
        wp.copy(self.y, other.y)

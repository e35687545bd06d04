"""Declaring both precisions of a module's generic kernels up front.

Warp rebuilds a module each time a launch needs a new overload; a large module whose kernels
a simulation first launches one by one then compiles many times over (minutes on a cold
cache). Registering the float32 and float64 overloads at import builds it once with all of them.
Argument names decide the array types (the kernels' naming convention).

Private: for the simulator's own use (there are no kernels); its arguments may change between
releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from . import blocks

__all__ = []

#: generic arguments that are blocks (kernels.blocks), by argument name
BLOCKS = {"bodies": "Bodies", "start": "Bodies", "end": "Bodies", "mass": "BodyMass", "accumulated": "Wrench",
          "planes": "Planes", "material": "ParticleMaterial", "work": "BodyVelocities", "collided": "BodyVelocities",
          "rows": "ContactRows", "table": "ImpulseTable"}

#: generic array arguments of vec3 elements, by name (the other generic arrays are of the scalar)
VECTORS = {"x", "v", "force"}


def declare_precisions(namespace: dict) -> None:
    """Register float32 and float64 overloads of every generic kernel in a module's namespace (``globals()``):
    arguments named in BLOCKS get that block struct, array arguments named in VECTORS vec3 arrays, other generic
    ones the scalar."""
    kinds = ((wp.float32, wp.vec3f), (wp.float64, wp.vec3d))
    for kernel in (value for value in list(namespace.values()) if isinstance(value, wp.Kernel)):
        generic = [a for a in kernel.adj.args
                   if a.type is Any or (isinstance(a.type, wp.array) and a.type.dtype is Any)]
        if not generic:
            continue
        for scalar, vec3 in kinds:
            types = {}
            for arg in generic:
                if arg.type is Any and arg.label in BLOCKS:
                    types[arg.label] = getattr(blocks.of(scalar), BLOCKS[arg.label])
                elif arg.type is Any:
                    types[arg.label] = scalar
                else:
                    types[arg.label] = wp.array(dtype=vec3 if arg.label in VECTORS else scalar)
            wp.overload(kernel, types)


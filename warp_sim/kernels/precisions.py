"""Declaring the overloads of the generic kernels, for the precision in use.

Every kernel module registers its generic kernels at import (``register(globals())``), with
the type of each generic argument read from its name (the kernels' naming convention,
KINDS below, which a module may override). ``declare(scalar)`` then declares the float32 or
float64 overload of every registered kernel at once (a Model does it for its precision), so
that:

- a module is built once with every kernel a simulation launches, instead of being rebuilt
  each time a launch needs a new overload (minutes on a cold cache), and only in the
  precision in use;
- ``wp.compile_aot_module`` (which compiles declared overloads only) compiles everything the
  simulator launches, so a CUDA build is checked on a machine without a GPU
  (tests/kernels/test_cuda_compile.py declares both precisions).

A kernel launched on arrays of other types (the public kernels on a user's own arrays) is
still instantiated by Warp at launch, as any generic kernel.

Private: for the simulator's own use (there are no kernels); its arguments may change between
releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from . import blocks

__all__ = []

#: the kind of a generic argument, by name: a block of kernels.blocks, "scalar", "vec3", "quat" or "mat33"
#: (of the precision); for an array argument, the kind of its elements. Names not listed are scalars.
KINDS = {
    # blocks
    "bodies": "Bodies", "start": "Bodies", "end": "Bodies", "positions": "Bodies", "velocities": "Bodies",
    "rates": "Bodies", "mass": "BodyMass", "accumulated": "Wrench", "held": "Wrench", "planes": "Planes",
    "material": "ParticleMaterial", "work": "BodyVelocities", "collided": "BodyVelocities", "rows": "ContactRows",
    "table": "ImpulseTable", "joints": "Joints", "springs": "Springs", "attractors": "Attractors",
    "vortices": "Vortices", "turbulences": "Turbulences",
    # vectors (values and arrays)
    "x": "vec3", "v": "vec3", "force": "vec3", "x_start": "vec3", "v_start": "vec3", "a": "vec3", "rhs": "vec3",
    "dv": "vec3", "v0": "vec3", "v1": "vec3", "omega": "vec3", "gravity": "vec3", "wind": "vec3",
    "impulse": "vec3", "point": "vec3",
    # rotations and 3x3 blocks
    "q": "quat", "R": "mat33", "diagonal": "mat33", "inverse": "mat33", "blocks": "mat33", "triplets": "mat33",
}

_TYPES = {wp.float32: {"scalar": wp.float32, "vec3": wp.vec3f, "quat": wp.quatf, "mat33": wp.mat33f},
          wp.float64: {"scalar": wp.float64, "vec3": wp.vec3d, "quat": wp.quatd, "mat33": wp.mat33d}}

_registered: list[tuple[wp.Kernel, dict[str, tuple[str, bool]]]] = []   # kernel, {argument: (kind, is array)}
_declared: list = []   # the precisions declared so far, in order


def _generic_arguments(kernel: wp.Kernel, kinds: dict) -> dict[str, tuple[str, bool]]:
    arguments = {}
    for arg in kernel.adj.args:
        if arg.type is Any:
            arguments[arg.label] = (kinds.get(arg.label, "scalar"), False)
        elif isinstance(arg.type, wp.array) and arg.type.dtype is Any:
            arguments[arg.label] = (kinds.get(arg.label, "scalar"), True)
    return arguments


def _overload(kernel: wp.Kernel, arguments: dict, scalar) -> None:
    types = {}
    for label, (kind, is_array) in arguments.items():
        element = _TYPES[scalar].get(kind) or getattr(blocks.of(scalar), kind)
        types[label] = wp.array(dtype=element) if is_array else element
    wp.overload(kernel, types)


def register(namespace: dict, **kinds) -> None:
    """Register the generic kernels of a module's namespace (``globals()``), their arguments' kinds from KINDS
    with ``kinds`` overriding by argument name (``y="vec3"``), or for one kernel by its name (``copy={"source":
    "vec3", "out": "vec3"}``); declares them at once for the precisions already declared."""
    table = {**KINDS, **{name: kind for name, kind in kinds.items() if isinstance(kind, str)}}
    for kernel in (value for value in list(namespace.values()) if isinstance(value, wp.Kernel)):
        if kernel.module.name != namespace["__name__"]:
            continue   # imported from another module, which registers it
        own = kinds.get(kernel.key)
        arguments = _generic_arguments(kernel, {**table, **(own if isinstance(own, dict) else {})})
        if arguments:
            _registered.append((kernel, arguments))
            for scalar in _declared:
                _overload(kernel, arguments, scalar)


def declare(scalar) -> None:
    """Declare the overloads of every registered kernel for wp.float32 or wp.float64 (once per precision)."""
    if scalar in _declared:
        return
    _declared.append(scalar)
    for kernel, arguments in _registered:
        _overload(kernel, arguments, scalar)

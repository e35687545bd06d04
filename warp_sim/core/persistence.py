"""What a checkpoint keeps of a running simulation: each part names its run-time values, which are saved as numpy
arrays (device arrays) and plain JSON values (numbers, flags), and restored in place. No pickle anywhere."""
from __future__ import annotations

import numpy as np
import warp as wp

from ..util import checks


class Persistent:
    """A part of a simulation whose run-time values a checkpoint keeps (the State, Control, the solvers' step sizes
    and warm starts, the contact response's impulse table, the emitter pools).

    persistent: attribute names, dotted for an attribute of an attribute ("table.used",
        "model.particle_radius"): device arrays, restored in place (recorded launches and the structs holding them
        stay valid), or plain values (int, float, bool, str, None; a list of numbers is kept as an array)
    """

    persistent: tuple[str, ...] = ()

    def persistent_parts(self) -> dict[str, Persistent]:
        """Nested parts with values of their own, by a name unique within this part."""
        return {}

    def before_restore(self, values: dict) -> None:
        """Make room before the arrays are restored (e.g. buffers that grew in the original run); ``values`` are
        this part's plain values."""


def settings(part) -> dict:
    """A part's plain public attributes that are not run-time values: the options it was made with (a solver's
    tolerances), for the fingerprint a checkpoint is checked against."""
    kept = set(getattr(part, "persistent", ()))
    return {name: value for name, value in vars(part).items()
            if not name.startswith("_") and name not in kept
            and (value is None or isinstance(value, (bool, int, float, str, tuple)))}


def _parts(part, prefix: str):
    yield prefix, part
    for name, child in part.persistent_parts().items():
        yield from _parts(child, f"{prefix}{name}.")


def _resolve(part, dotted: str):
    owner = part
    *path, name = dotted.split(".")
    for step in path:
        owner = getattr(owner, step)
    return owner, name


def save(root: Persistent) -> tuple[dict[str, np.ndarray], dict]:
    """(arrays, values) of ``root`` and its parts, keyed by dotted name."""
    arrays, values = {}, {}
    for prefix, part in _parts(root, ""):
        for dotted in part.persistent:
            owner, name = _resolve(part, dotted)
            value = getattr(owner, name)
            if isinstance(value, wp.array):
                arrays[prefix + dotted] = value.numpy().copy()
            elif isinstance(value, list):
                arrays[prefix + dotted] = np.asarray(value)
            elif value is None or isinstance(value, (bool, int, float, str)):
                values[prefix + dotted] = value
            else:
                raise TypeError(f"{type(part).__name__}.{dotted} is a {type(value).__name__}: not persistent data")
    return arrays, values


def restore(root: Persistent, arrays: dict[str, np.ndarray], values: dict) -> None:
    """Put saved (arrays, values) back into ``root`` and its parts, or raise ValueError naming the first value that
    does not fit (a missing name, another shape or type) before anything is changed."""
    parts = list(_parts(root, ""))
    for prefix, part in parts:
        part.before_restore({key[len(prefix):]: value for key, value in values.items() if key.startswith(prefix)})
    plan = []
    for prefix, part in parts:
        for dotted in part.persistent:
            key = prefix + dotted
            owner, name = _resolve(part, dotted)
            current = getattr(owner, name)
            if isinstance(current, (wp.array, list)):
                if key not in arrays:
                    raise checks.fail("checkpoint", key, "is missing from the checkpoint")
                saved = arrays[key]
                if isinstance(current, wp.array):
                    expected = current.numpy()
                    if saved.shape != expected.shape or saved.dtype != expected.dtype:
                        raise checks.fail("checkpoint", key, f"holds {saved.dtype}{list(saved.shape)}; this "
                                                             f"simulation has {expected.dtype}{list(expected.shape)}")
            elif key not in values:
                raise checks.fail("checkpoint", key, "is missing from the checkpoint")
            plan.append((owner, name, current, arrays.get(key, values.get(key))))
    for owner, name, current, saved in plan:
        if isinstance(current, wp.array):
            current.assign(saved)
        elif isinstance(current, list):
            setattr(owner, name, saved.tolist())
        else:
            setattr(owner, name, saved)

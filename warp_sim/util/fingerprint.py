"""A stable hash of a description: what a checkpoint is checked against before it is used."""
from __future__ import annotations

import hashlib
import math

import numpy as np


def fingerprint(*objects) -> str:
    """A hex digest (16 characters) of ``objects`` that is the same in every process and on every machine.

    Hashed: numbers (floats exactly, by their hex form), strings, None, numpy arrays (dtype, shape, bytes),
    lists, tuples, dicts, sets, and the attributes of warp_sim's own objects, recursively. A foreign object (a
    trimesh kept beside its vertices and faces) contributes its type name only."""
    digest = hashlib.sha256()
    for obj in objects:
        _feed(digest, obj)
    return digest.hexdigest()[:16]


def _feed(digest, obj) -> None:
    put = digest.update
    if obj is None or isinstance(obj, (bool, str)):
        put(f"{type(obj).__name__}:{obj};".encode())
    elif isinstance(obj, (int, np.integer)):
        put(f"int:{int(obj)};".encode())
    elif isinstance(obj, (float, np.floating)):
        value = float(obj)
        put(f"float:{value.hex() if math.isfinite(value) else value};".encode())
    elif isinstance(obj, np.ndarray):
        array = np.ascontiguousarray(obj)
        put(f"array:{array.dtype.str}:{array.shape};".encode())
        put(array.tobytes() if array.dtype != object else repr(array.tolist()).encode())
    elif isinstance(obj, (list, tuple)):
        put(f"{type(obj).__name__}[{len(obj)}];".encode())
        for item in obj:
            _feed(digest, item)
    elif isinstance(obj, (set, frozenset)):
        put(f"set[{len(obj)}];".encode())
        for item in sorted(obj, key=repr):
            _feed(digest, item)
    elif isinstance(obj, dict):
        put(f"dict[{len(obj)}];".encode())
        for key in sorted(obj, key=repr):
            _feed(digest, key)
            _feed(digest, obj[key])
    elif type(obj).__module__.split(".")[0] == "warp_sim" and hasattr(obj, "__dict__"):
        put(f"object:{type(obj).__qualname__};".encode())
        _feed(digest, vars(obj))
    else:
        put(f"foreign:{type(obj).__module__}.{type(obj).__qualname__};".encode())

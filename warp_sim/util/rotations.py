"""Host-side rotation helpers (numpy), with Warp's quaternion convention (x, y, z, w)."""
from __future__ import annotations

import numpy as np


def quat_to_matrix(q) -> np.ndarray:
    """The 3x3 rotation matrix of unit quaternion(s) q = (x, y, z, w); shape (..., 4) -> (..., 3, 3)."""
    q = np.asarray(q, dtype=np.float64)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)

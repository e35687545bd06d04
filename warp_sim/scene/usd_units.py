"""A USD stage's units and up axis against warp_sim's (SI, Y up): the map both ways for points, directions,
rotations, masses and inertias.

A stage point p (in its units, its axes) is the simulator's ``meters_per_unit * C p``, where C turns the stage's
up axis onto +Y (for a Z-up stage: (x, y, z) -> (x, z, -y)). A prim's local frame keeps its axes: only lengths
in it scale, so a world rotation R of the stage is ``C R`` in the simulator, and back ``C^T R``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# C for each up axis: the rotation taking the stage's axes to warp_sim's (Y up)
TO_Y_UP = {"Y": np.eye(3), "Z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])}


@dataclass(frozen=True)
class StageUnits:
    """meters_per_unit [m], kilograms_per_unit [kg], up_axis ("Y" or "Z") of a stage; C: its axes to Y up."""

    meters_per_unit: float = 1.0
    kilograms_per_unit: float = 1.0
    up_axis: str = "Y"

    @property
    def C(self) -> np.ndarray:
        return TO_Y_UP[self.up_axis]

    def point(self, p) -> np.ndarray:
        """A stage point (or (N, 3) points) [units] as warp_sim's [m]."""
        return self.meters_per_unit * (np.asarray(p, dtype=np.float64) @ self.C.T)

    def direction(self, d) -> np.ndarray:
        """A stage direction (unitless) in warp_sim's axes."""
        return np.asarray(d, dtype=np.float64) @ self.C.T

    def rotation(self, R) -> np.ndarray:
        """A stage world rotation (local frame to stage world) as local frame to warp_sim world."""
        return self.C @ np.asarray(R, dtype=np.float64)

    def length(self, value) -> np.ndarray:
        return self.meters_per_unit * np.asarray(value, dtype=np.float64)

    def mass(self, value) -> float:
        return self.kilograms_per_unit * float(value)

    def inertia(self, value) -> np.ndarray:
        return self.kilograms_per_unit * self.meters_per_unit ** 2 * np.asarray(value, dtype=np.float64)

    def stage_point(self, p) -> np.ndarray:
        """A warp_sim point (or (N, 3) points) [m] in the stage's units and axes."""
        return (np.asarray(p, dtype=np.float64) @ self.C) / self.meters_per_unit

    def stage_rotation(self, R) -> np.ndarray:
        """A warp_sim world rotation of a local frame as the stage's."""
        return self.C.T @ np.asarray(R, dtype=np.float64)

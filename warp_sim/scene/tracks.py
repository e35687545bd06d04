"""Kinematic tracks: a body's keyframed motion (times, centres of mass, orientations), sampled on the host.

Between keys the position is linear and the orientation a slerp; before the first key and after the last the
body holds still. ``Track.velocities(t0, t1)`` gives the mean linear and angular velocity over a step, which is
what the contact response sees of a kinematic body.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..util import checks
from ..util.rotations import quat_to_matrix


def _slerp(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    if float(a @ b) < 0.0:
        b = -b
    dot = min(1.0, float(a @ b))
    angle = np.arccos(dot)
    if angle < 1e-9:
        q = a + s * (b - a)
    else:
        q = (np.sin((1.0 - s) * angle) * a + np.sin(s * angle) * b) / np.sin(angle)
    return q / np.linalg.norm(q)


@dataclass(frozen=True)
class Track:
    """times (K,) [s], increasing; positions (K, 3): the centre of mass [m]; orientations (K, 4) unit (x, y, z, w)."""

    times: np.ndarray
    positions: np.ndarray
    orientations: np.ndarray

    @staticmethod
    def of(times, positions, orientations, com) -> Track:
        """A track from keys of the shape's origin (``positions``) and orientations, for a body whose centre of
        mass lies at ``com`` in the shape's frame; checked (ValueError naming ``kinematic``)."""
        t = np.atleast_1d(checks.finite_array("kinematic", times, (-1,)))
        p = checks.finite_array("kinematic", positions, (len(t), 3))
        q = checks.finite_array("kinematic", orientations, (len(t), 4))
        if len(t) == 0 or np.any(np.diff(t) <= 0.0):
            raise checks.fail("kinematic", times, "needs one key or more, at strictly increasing times [s]")
        norms = np.linalg.norm(q, axis=1)
        if np.any(norms < 1e-12):
            raise checks.fail("kinematic", orientations, "orientations must be non-zero quaternions (x, y, z, w)")
        q = q / norms[:, None]
        return Track(t, p + np.einsum("kij,j->ki", quat_to_matrix(q), np.asarray(com, dtype=np.float64)), q)

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(centre of mass [m], orientation) at time t [s]."""
        times = self.times
        if t <= times[0]:
            return self.positions[0], self.orientations[0]
        if t >= times[-1]:
            return self.positions[-1], self.orientations[-1]
        k = int(np.searchsorted(times, t, side="right")) - 1
        s = (t - times[k]) / (times[k + 1] - times[k])
        x = self.positions[k] + s * (self.positions[k + 1] - self.positions[k])
        return x, _slerp(self.orientations[k], self.orientations[k + 1], s)

    def velocities(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """(v [m/s], omega [rad/s]): the mean velocities from t0 to t1 (world frame)."""
        (x0, q0), (x1, q1) = self.pose(t0), self.pose(t1)
        R = quat_to_matrix(q1) @ quat_to_matrix(q0).T      # the turn over the step, as an axis and an angle
        angle = np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))
        if angle < 1e-12:
            omega = np.zeros(3)
        else:
            axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / (2.0 * np.sin(angle))
            omega = axis * angle / (t1 - t0)
        return (x1 - x0) / (t1 - t0), omega

"""The stiffest mode of a scene's springs: how fast it oscillates and how fast it is damped, for the step an
explicit solver can take (``solvers.stability``).

The springs linearised about the scene's initial positions give a stiffness K and a damping C (3 x 3 blocks per
spring: k d d^T plus the geometric k (1 - L0/L)(I - d d^T) of a stretched spring, and kd d d^T), with pinned
particles fixed. The fastest mode has omega^2 = the top eigenvalue of W^1/2 K W^1/2 (W the inverse masses), and the
fastest damping rate is the top eigenvalue of W^1/2 C W^1/2 plus the linear drag over the lightest particle. Both
come from a few dozen Lanczos iterations on the sparse operator (numpy, no matrix is formed), which converge fast
on the top of a spectrum; the top Ritz value is raised by its residual, so it is an estimate from above of the top
eigenvalue once the iteration has converged (tests/scene/test_stiffness.py compares it with dense eigenvalues).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LANCZOS_STEPS = 48     # iterations at most: the top Ritz value of a 128^2 cloth is within 1e-6 of the top after 24
CONVERGED = 1e-6       # stop once the top Ritz value moves less than this, relatively, over CHECK_EVERY iterations
CHECK_EVERY = 4
SEED = 0               # the start vector's random seed: the estimate is the same every time


@dataclass(frozen=True)
class StiffestMode:
    """omega: the fastest angular frequency of the linearised springs [rad/s]; damping: the fastest damping rate
    of their dampers and the linear drag [1/s] (c in x'' = -omega^2 x - c x'); particle: the particle that moves
    most in that mode (where to look)."""
    omega: float
    damping: float
    particle: int


def stiffest_mode(scene) -> StiffestMode | None:
    """The stiffest mode of ``scene``'s springs (None without springs between free particles)."""
    pairs = scene.spring_array("pairs")
    if len(pairs) == 0:
        return None
    x = scene.particle_array("position").astype(np.float64)
    mass = scene.particle_array("mass").astype(np.float64)
    free = ~scene.particle_array("pinned").astype(bool)
    root_w = np.where(free, 1.0 / np.sqrt(np.where(free, mass, 1.0)), 0.0)
    i, j = pairs[:, 0], pairs[:, 1]
    if not (root_w[i] + root_w[j]).any():
        return None
    delta = x[j] - x[i]
    length = np.linalg.norm(delta, axis=1)
    rest = scene.spring_array("rest_length").astype(np.float64)
    k = scene.spring_array("stiffness").astype(np.float64)
    touching = length > 1e-12 * np.maximum(rest, 1.0)
    d = np.where(touching[:, None], delta / np.where(touching, length, 1.0)[:, None], 0.0)
    # the geometric stiffness of a stretched spring; a compressed one is softer across (clamped at 0), and a
    # spring of zero length is k I in every direction
    across = np.where(touching, k * np.clip(1.0 - rest / np.where(touching, length, 1.0), 0.0, None), k)
    n = len(x)
    stiffness = _SpringOperator(i, j, d, k, across, root_w, n)
    omega2, shape = _top_eigenvalue(stiffness, n)
    damping = scene.spring_array("damping").astype(np.float64)
    rate = _top_eigenvalue(_SpringOperator(i, j, d, damping, np.zeros(len(k)), root_w, n), n)[0] if damping.any() \
        else 0.0
    rate += scene.drag * float(np.max(root_w) ** 2)
    return StiffestMode(math.sqrt(max(omega2, 0.0)), max(rate, 0.0), int(np.argmax(np.sum(shape**2, axis=1))))


class _SpringOperator:
    """u -> W^1/2 K W^1/2 u over (n, 3) arrays, K = sum over springs of (e_i - e_j)(e_i - e_j)^T (x) B, with
    B = along d d^T + across (I - d d^T)."""

    def __init__(self, i, j, d, along, across, root_w, n):
        self.i, self.j, self.d, self.along, self.across, self.root_w, self.n = i, j, d, along, across, root_w, n

    def __call__(self, u: np.ndarray) -> np.ndarray:
        scaled = u * self.root_w[:, None]
        du = scaled[self.i] - scaled[self.j]
        axial = np.sum(du * self.d, axis=1)
        force = self.across[:, None] * du + ((self.along - self.across) * axial)[:, None] * self.d
        out = np.empty_like(u)
        for axis in range(3):
            out[:, axis] = (np.bincount(self.i, force[:, axis], self.n) - np.bincount(self.j, force[:, axis], self.n))
        return out * self.root_w[:, None]


def _top_eigenvalue(operator, n: int) -> tuple[float, np.ndarray]:
    """(estimate of the top eigenvalue, its Ritz vector (n, 3)) of a symmetric positive semi-definite operator
    by Lanczos with full reorthogonalisation; the top Ritz value plus its residual bound."""
    start = np.random.default_rng(SEED).standard_normal((n, 3))
    q = operator(start)   # start inside the operator's range (pinned particles' rows are zero)
    norm = np.linalg.norm(q)
    if norm == 0.0:
        return 0.0, start
    basis, alphas, betas, last = [q / norm], [], [], None
    for step in range(1, min(LANCZOS_STEPS, 3 * n) + 1):
        w = operator(basis[-1])
        alphas.append(float(np.sum(w * basis[-1])))
        for v in basis:   # full reorthogonalisation: a few dozen vectors, and no ghost eigenvalues
            w = w - np.sum(w * v) * v
        beta = float(np.linalg.norm(w))
        if beta <= 1e-12 * max(abs(alphas[-1]), 1e-300):
            betas.append(0.0)
            break
        betas.append(beta)
        basis.append(w / beta)
        if step % CHECK_EVERY == 0:   # converged: the top Ritz value has stopped moving
            top = float(np.linalg.eigvalsh(_tridiagonal(alphas, betas))[-1])
            if last is not None and abs(top - last) <= CONVERGED * top:
                break
            last = top
    m = len(alphas)
    values, vectors = np.linalg.eigh(_tridiagonal(alphas, betas))
    top = vectors[:, -1]
    ritz = sum(c * v for c, v in zip(top, basis[:m]))
    return float(values[-1] + betas[m - 1] * abs(top[-1])), ritz


def _tridiagonal(alphas: list, betas: list) -> np.ndarray:
    """Lanczos's tridiagonal matrix T of the first len(alphas) steps."""
    m = len(alphas)
    return np.diag(alphas) + np.diag(betas[:m - 1], 1) + np.diag(betas[:m - 1], -1)

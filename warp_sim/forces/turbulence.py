"""The scene's Turbulence fields as baked periodic grids of vector potential, moved in time.

A field's potential psi lives on a periodic grid of n^3 nodes spanning PERIOD x PERIOD x
PERIOD scale units, so the field repeats every PERIOD * scale [m] along each axis. It is
baked once, at construction, on the model's device (kernels.fields.bake_potentials): each
component the sum over the octaves k of Warp's periodic Perlin noise ``wp.pnoise`` of
lattice spacing scale / 2^k and weight 4^-k, so that octave k adds eddies of half the size
and half the acceleration of octave k - 1 (as Warp's curl noise, with lacunarity 2 and gain
1/2). n = NODES_PER_CELL nodes per lattice cell of the finest octave, at most MAX_NODES per
axis (one grid: (n + 3)^3 vec3f, 2 MiB); an octave with fewer than MIN_NODES_PER_CELL nodes
per lattice cell is left out, with a warning: at most 3 octaves are kept.

The grid is read as a quadratic B-spline and differentiated analytically
(kernels.fields.turbulence_forces); the baked grids are scaled (and, for a time-varying
field, orthonormalised) with their exact curl inner products (``curl_gram``), so that the
acceleration's RMS over the period is exactly ``strength``.

Time (frequency f > 0): three independent potentials psi_0, psi_1, psi_2, orthonormal in
the curl inner product, and with tau = f t, j = floor(tau), theta = pi/2 (tau - j):
psi(t) = s_j cos(theta) psi_{j mod 3} + s_{j+1} sin(theta) psi_{(j+1) mod 3}, s_j = +-1 a
hash of (seed, j). A linear combination of curls, so still divergence-free; its RMS is
constant in time (cos^2 + sin^2 = 1 on orthonormal slices); it passes through a fresh slice
every 1/f seconds, with a random sign, so it never repeats and decorrelates over a few 1/f.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import warp as wp

from ..kernels import blocks
from ..kernels import fields as field_kernels
from ..scene.fields import Turbulence

#: the grid spans PERIOD scale units per axis; the field repeats after PERIOD * scale [m]
PERIOD = 4
#: grid nodes per Perlin lattice cell of the finest octave
NODES_PER_CELL = 4
#: octaves resolved by fewer nodes per lattice cell than this are left out
MIN_NODES_PER_CELL = 3
#: the most nodes per axis: (52 + 3)^3 vec3f is 2 MiB a grid (a time-varying field has four: 8 MiB)
MAX_NODES = 52
#: the independent potentials of a time-varying field
SLICES = 3
GHOSTS = (1, 2)   # ghost nodes stored before and after the n periodic ones on each axis

#: 1-D integrals of the quadratic B-spline b at node offsets d = -2 .. 2 [grid units]: int b(s) b(s - d) ds,
#: int b'(s) b(s - d) ds and int b'(s) b'(s - d) ds over the line
OVERLAP = np.array([1.0, 26.0, 66.0, 26.0, 1.0]) / 120.0
SLOPE = np.array([5.0, 50.0, 0.0, -50.0, -5.0]) / 120.0
BENDING = np.array([-20.0, -40.0, 120.0, -40.0, -20.0]) / 120.0


def grid_size(octaves: int) -> tuple[int, int]:
    """(nodes per axis, octaves kept) of the grid of a Turbulence of ``octaves``."""
    nodes = min(PERIOD * NODES_PER_CELL * 2 ** (octaves - 1), MAX_NODES)
    kept = sum(1 for k in range(octaves) if nodes >= MIN_NODES_PER_CELL * PERIOD * 2**k)
    return nodes, kept


def _stencils() -> np.ndarray:
    """W[p, q, d] = delta_pq tr K(d) - K_pq(d), K_pq(d) = int d_p B(g) d_q B(g - d) dg over R^3 (B = b(x) b(y) b(z)),
    for the node offsets d in {-2 .. 2}^3: int curl(B psi) . curl(B(. - d) phi) = psi . W(d) phi."""
    K = np.empty((3, 3, 5, 5, 5))
    for p in range(3):
        for q in range(3):
            factors = [OVERLAP, OVERLAP, OVERLAP]
            if p == q:
                factors[p] = BENDING
            else:
                factors[p], factors[q] = SLOPE, -SLOPE
            K[p, q] = np.einsum("i,j,k->ijk", *factors)
    return np.eye(3)[:, :, None, None, None] * (K[0, 0] + K[1, 1] + K[2, 2]) - K


STENCILS = _stencils()


def curl_gram(slices: np.ndarray) -> np.ndarray:
    """G[a, b]: the mean over the period of curl psi_a . curl psi_b [grid units^-2] for the B-spline potentials whose
    periodic node values are ``slices`` (S, n, n, n, 3), exact up to rounding (float64).

    With u = sum_m grad B(g - m) x psi_m, the integral of u_a . u_b over the period is
    sum_m sum_d psi_a(m) . W(d) psi_b(m + d) (W: STENCILS, even in d), which Parseval's theorem
    turns into sum_k conj(psi_a^(k)) . W^(k) psi_b^(k) / n^3 over the grid's DFT.
    """
    count, n = slices.shape[0], slices.shape[1]
    spectra = np.fft.fftn(slices, axes=(1, 2, 3))
    placed = np.zeros((3, 3, n, n, n))
    placed[(slice(None), slice(None)) + np.ix_(*(np.arange(-2, 3) % n,) * 3)] = STENCILS
    symbols = np.fft.fftn(placed, axes=(2, 3, 4)).real   # W even in d: its symbol is real
    gram = np.empty((count, count))
    for a in range(count):
        for b in range(a, count):
            total = np.einsum("xyzq,xyzp,pqxyz->", np.conj(spectra[a]), spectra[b], symbols).real
            gram[a, b] = gram[b, a] = total / n**6
    return gram


def orthonormal(slices: np.ndarray) -> np.ndarray:
    """The slices (S, n, n, n, 3) recombined, L^-1 psi with G = L L^T (curl_gram), so that their curls are
    orthonormal: mean curl psi_a . curl psi_b = delta_ab over the period."""
    A = np.linalg.inv(np.linalg.cholesky(curl_gram(slices)))
    out = np.zeros_like(slices)
    for j in range(len(slices)):
        for i in range(j + 1):
            out[j] += A[j, i] * slices[i]
    return out


def sign(seed: int, j: int) -> float:
    """+1 or -1, the sign of slice passage j of a time-varying field (splitmix64 of seed and j)."""
    z = (seed * 0x9E3779B97F4A7C15 + j * 0xD1B54A32D192ED03 + 0x632BE59BD9B4E019) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    return 1.0 if (z ^ (z >> 31)) >> 63 else -1.0


def blend(field: Turbulence, t: float) -> tuple[int, int, float, float]:
    """(first slice, second slice, their weights) of a time-varying field's potential at time t [s]."""
    tau = float(t) * field.frequency
    j = math.floor(tau)
    theta = 0.5 * math.pi * (tau - j)
    c_first, c_second = sign(field.seed, j) * math.cos(theta), sign(field.seed, j + 1) * math.sin(theta)
    return j % SLICES, (j + 1) % SLICES, c_first, c_second


class TurbulenceGrids:
    """The baked grids of a scene's Turbulence fields: the Turbulences block and the potential array that
    kernels.fields.turbulence_forces takes.

    fields: the Turbulence fields; scalar: the precision (wp.float32 or wp.float64); device: where the grids live;
    launch: launch(kernel, dim, inputs) runs the per-step blends (a Model's ``launch``; default wp.launch).
    block: the Turbulences block; potential: every field's current grid (``at(t)`` sets it to time t)
    nodes, octaves: per field its grid's nodes per axis and the octaves it keeps; bytes: the grids' memory [B]
    """

    def __init__(self, fields: list, scalar, device, launch=None):
        self.fields = list(fields)
        self.device = device
        self.launch = launch or (lambda kernel, dim, inputs: wp.launch(kernel, dim, inputs, device=device))
        sizes = [grid_size(field.octaves) for field in self.fields]
        self.nodes = [nodes for nodes, _ in sizes]
        self.octaves = [kept for _, kept in sizes]
        for field, kept in zip(self.fields, self.octaves):
            if kept < field.octaves:
                warnings.warn(f"Turbulence octaves={field.octaves}: its grid resolves {kept}; the finer "
                              f"{field.octaves - kept} are left out (about 1% of the energy)", UserWarning,
                              stacklevel=2)
        baked = [self._bake(field, nodes, kept) for field, nodes, kept in zip(self.fields, self.nodes, self.octaves)]
        cube = [(nodes + sum(GHOSTS)) ** 3 for nodes in self.nodes]   # nodes per grid, ghosts included
        self.offsets = np.cumsum([0] + cube[:-1]).tolist()
        moving = [k for k, field in enumerate(self.fields) if field.frequency > 0.0]
        self.slice_offsets = dict(zip(moving, np.cumsum([0] + [SLICES * cube[k] for k in moving[:-1]]).tolist()))
        current = [np.zeros_like(grid[0]) if k in moving else grid[0] for k, grid in enumerate(baked)]  # at(t) sets
        self.potential = wp.array(np.concatenate([grid.reshape(-1, 3) for grid in current]), dtype=wp.vec3f,
                                  device=device)
        self.slices = wp.array(np.concatenate([baked[k].reshape(-1, 3) for k in moving] or [np.zeros((0, 3))]),
                               dtype=wp.vec3f, device=device)
        self.bytes = self.potential.capacity + self.slices.capacity
        self._times = [None] * len(self.fields)

        np_scalar = wp.dtype_to_numpy(scalar)

        def values(x):
            return wp.array(np.asarray(x, dtype=np_scalar), dtype=scalar, device=device)

        def integers(x):
            return wp.array(np.asarray(x, dtype=np.int32), dtype=wp.int32, device=device)

        self.block = blocks.fill(blocks.of(scalar).Turbulences, strength=values([f.strength for f in self.fields]),
                                 inv_period=values([1.0 / (PERIOD * f.scale) for f in self.fields]),
                                 nodes=integers(self.nodes), offset=integers(self.offsets))

    def _bake(self, field: Turbulence, nodes: int, octaves: int) -> np.ndarray:
        """The field's slices (S, n + 3, n + 3, n + 3, 3) float32 with ghosts, curls orthonormal."""
        count = SLICES if field.frequency > 0.0 else 1
        raw = wp.empty(count * nodes**3, dtype=wp.vec3f, device=self.device)
        wp.launch(field_kernels.bake_potentials, raw.shape[0], [field.seed, nodes, PERIOD, octaves, raw],
                  device=self.device)
        slices = orthonormal(raw.numpy().astype(np.float64).reshape(count, nodes, nodes, nodes, 3))
        ghosts = ((0, 0), GHOSTS, GHOSTS, GHOSTS, (0, 0))
        return np.pad(slices, ghosts, mode="wrap").astype(np.float32)

    def at(self, t: float) -> wp.array:
        """The potential array, each time-varying field's grid set to its value at time t [s] (one launch each, over
        its grid's nodes, skipped when t is the time it was last set to)."""
        for k, start in self.slice_offsets.items():
            if self._times[k] == t:
                continue
            first, second, c_first, c_second = blend(self.fields[k], t)
            cube = (self.nodes[k] + sum(GHOSTS)) ** 3
            self.launch(field_kernels.blend_potentials, cube,
                        [self.slices, start + first * cube, start + second * cube, c_first, c_second,
                         self.potential, self.offsets[k]])
            self._times[k] = t
        return self.potential

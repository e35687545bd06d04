"""Force fields acting on every particle (add them with ``Scene.add_field``). SI units.

Each field is an acceleration a(x, t) [m/s^2], the same for every particle
whatever its mass (the force applied is m a); pinned particles feel nothing.
Fields of one kind are evaluated together, in one kernel launch per kind.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass

import numpy as np

from ..util import checks

#: octaves of Turbulence: 1 .. MAX_OCTAVES (octave k: eddies 2^k times smaller; its grid keeps 3 at most)
MAX_OCTAVES = 16
SEED_LIMIT = 2**31


def _integer(name: str, value, low: int, high: int) -> int:
    """An integer (not a bool, not a float) in [low, high]."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise checks.fail(name, value, f"expected an integer in [{low}, {high}]")
    if not low <= int(value) <= high:
        raise checks.fail(name, value, f"must lie in [{low}, {high}]")
    return int(value)


def _vector(array: np.ndarray) -> tuple:
    return tuple(float(c) for c in array)


def _point(name: str, value) -> tuple:
    return _vector(checks.vec3(name, value))


def _direction(name: str, value) -> tuple:
    return _vector(checks.unit_vec3(name, value))


def _number(name: str, value) -> float:
    return checks.scalar(name, value)


def _non_negative(name: str, value) -> float:
    return checks.scalar(name, value, low=0.0)


def _positive(name: str, value) -> float:
    return checks.scalar(name, value, low=0.0, low_open=True)


class Field:
    """Base of the force fields: Attractor, Vortex, Turbulence. Each lists in ``RULES`` how each of its
    attributes is checked and normalised on creation (a ValueError naming the attribute otherwise)."""

    RULES: dict = {}

    def __post_init__(self):
        for name, rule in self.RULES.items():
            object.__setattr__(self, name, rule(name, getattr(self, name)))


@dataclass(frozen=True)
class Attractor(Field):
    """Point attractor, inverse square: a = -strength (x - c) / |x - c|^3; outside min_distance exactly Newton's.

    position: the centre c [m]
    strength: GM [m^3/s^2]; > 0 attracts, < 0 repels, 0 does nothing
    min_distance: inside it the field is that of a uniform ball of that radius, a = -strength (x - c) /
        min_distance^3 (continuous, zero at c, no singularity) [m], > 0
    """
    position: tuple
    strength: float
    min_distance: float = 1e-3
    RULES = {"position": _point, "strength": _number, "min_distance": _positive}


@dataclass(frozen=True)
class Vortex(Field):
    """Swirl about the line through ``position`` along ``axis``: a = strength (n x r) / (|r|^2 + core_radius^2),
    r the part of x - position normal to the unit axis n; purely tangential (no pull towards the axis).

    position: a point on the line [m]
    axis: its direction (normalised to n)
    strength: [m^2/s^2]; > 0 swirls counter-clockwise seen from the tip of n (right-hand rule), < 0 the other way
    core_radius: smooths the axis: the swirl is strength / |r| far from it and peaks at strength /
        (2 core_radius) at |r| = core_radius [m], > 0
    """
    position: tuple
    axis: tuple
    strength: float
    core_radius: float = 0.1
    RULES = {"position": _point, "axis": _direction, "strength": _number, "core_radius": _positive}


@dataclass(frozen=True)
class Turbulence(Field):
    """Divergence-free turbulence: a = strength curl psi(x / scale, t), psi a random vector potential baked once on
    a periodic grid and read as a quadratic B-spline (a is continuous); float32 grid, also in float64 scenes. Its
    spectrum, period, normalisation and cost: docs/fields.md.

    strength: the RMS of |a| over space, exactly, at every instant [m/s^2], >= 0; |a| averages about 0.92 strength
    scale: the Perlin lattice spacing of the largest octave [m], > 0: the energy peaks at wavelengths of about
        1.1 scale; the field repeats every 4 scale along each axis
    frequency: how fast the field changes (0: steady) [1/s], >= 0: every 1/frequency seconds the potential has
        turned a quarter circle onto the next of three orthonormal potentials, with a random sign, so the field
        decorrelates over a few 1/frequency seconds, never repeats, and keeps its RMS
    seed: selects the field, an integer in [0, 2^31); one seed gives one field, bit for bit, on a device
    octaves: an integer in [1, 16], each adding eddies at half the size and half the acceleration; the grid
        (16, 32, 52 nodes per axis for 1, 2, 3 octaves) resolves 3: more are left out, with a warning (they
        would carry about 1% of the energy)
    """
    strength: float
    scale: float = 1.0
    frequency: float = 0.5
    seed: int = 0
    octaves: int = 1
    RULES = {"strength": _non_negative, "scale": _positive, "frequency": _non_negative,
             "seed": lambda name, value: _integer(name, value, 0, SEED_LIMIT - 1),
             "octaves": lambda name, value: _integer(name, value, 1, MAX_OCTAVES)}

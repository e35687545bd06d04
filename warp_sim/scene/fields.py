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

#: octaves of Turbulence: 1 .. MAX_OCTAVES (octave k samples the noise at 2^k times the coordinate)
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
    """Divergence-free curl noise: a = strength curlnoise(seed, (x / scale, t frequency), octaves), evaluated in
    float32 (Warp's noise), also in float64 scenes.

    strength: scales Warp's curl noise, whose magnitude averages about 1 and stays below 4 (largest seen: 3.1
        with one octave, 3.6 with several) [m/s^2], >= 0
    scale: the size of the eddies [m], > 0
    frequency: how fast the field changes in time (0: steady, and then Warp's 3-D curl noise, about 3x cheaper
        than the 4-D one) [1/s], >= 0
    seed: selects the field, an integer in [0, 2^31)
    octaves: an integer in [1, 16], each adding detail at half the size and half the weight
    """
    strength: float
    scale: float = 1.0
    frequency: float = 0.5
    seed: int = 0
    octaves: int = 1
    RULES = {"strength": _non_negative, "scale": _positive, "frequency": _non_negative,
             "seed": lambda name, value: _integer(name, value, 0, SEED_LIMIT - 1),
             "octaves": lambda name, value: _integer(name, value, 1, MAX_OCTAVES)}

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


class Field:
    """Base of the force fields: Attractor, Vortex, Turbulence."""


@dataclass(frozen=True)
class Attractor(Field):
    """Point attractor, inverse square: a = -strength (x - c) / |x - c|^3.

    position: the centre c [m]; strength: GM [m^3/s^2], > 0 attracts, < 0 repels, 0
    does nothing; min_distance [m] > 0: inside it the field is that of a uniform ball
    of that radius, a = -strength (x - c) / min_distance^3 (continuous, zero at c, no
    singularity). Outside min_distance the field is exactly Newton's.
    """
    position: tuple
    strength: float
    min_distance: float = 1e-3

    def __post_init__(self):
        object.__setattr__(self, "position", _vector(checks.vec3("position", self.position)))
        object.__setattr__(self, "strength", checks.scalar("strength", self.strength))
        object.__setattr__(self, "min_distance", checks.scalar("min_distance", self.min_distance, low=0.0,
                                                               low_open=True))


@dataclass(frozen=True)
class Vortex(Field):
    """Swirl about the line through ``position`` along ``axis``: a = strength (n x r) / (|r|^2 + core_radius^2).

    r: the part of x - position normal to the unit axis n (normalised from ``axis``);
    strength [m^2/s^2]: > 0 swirls counter-clockwise seen from the tip of n (right-hand
    rule), < 0 the other way; core_radius [m] > 0 smooths the axis: the swirl is
    strength / |r| far from it and peaks at strength / (2 core_radius) at |r| = core_radius.
    The field is purely tangential (no pull towards the axis).
    """
    position: tuple
    axis: tuple
    strength: float
    core_radius: float = 0.1

    def __post_init__(self):
        object.__setattr__(self, "position", _vector(checks.vec3("position", self.position)))
        object.__setattr__(self, "axis", _vector(checks.unit_vec3("axis", self.axis)))
        object.__setattr__(self, "strength", checks.scalar("strength", self.strength))
        object.__setattr__(self, "core_radius", checks.scalar("core_radius", self.core_radius, low=0.0,
                                                              low_open=True))


@dataclass(frozen=True)
class Turbulence(Field):
    """Divergence-free curl noise: a = strength curlnoise(seed, (x / scale, t frequency), octaves).

    strength [m/s^2] >= 0 scales Warp's curl noise, whose magnitude averages about 1
    and stays below 4 (largest seen: 3.1 with one octave, 3.6 with several); scale [m]
    > 0: the size of the eddies; frequency [1/s] >= 0: how fast the field changes in
    time (0: steady, and then Warp's 3-D curl noise, about 3x cheaper than the 4-D one);
    seed: integer in [0, 2^31) selecting the field; octaves: integer in [1, 16], each
    adding detail at half the size and half the weight.
    Evaluated in float32 (Warp's noise), also in float64 scenes.
    """
    strength: float
    scale: float = 1.0
    frequency: float = 0.5
    seed: int = 0
    octaves: int = 1

    def __post_init__(self):
        object.__setattr__(self, "strength", checks.scalar("strength", self.strength, low=0.0))
        object.__setattr__(self, "scale", checks.scalar("scale", self.scale, low=0.0, low_open=True))
        object.__setattr__(self, "frequency", checks.scalar("frequency", self.frequency, low=0.0))
        object.__setattr__(self, "seed", _integer("seed", self.seed, 0, SEED_LIMIT - 1))
        object.__setattr__(self, "octaves", _integer("octaves", self.octaves, 1, MAX_OCTAVES))

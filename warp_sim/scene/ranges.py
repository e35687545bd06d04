"""What a scene's precision holds: every value a Scene is given, and what a simulation derives from it (1/m, the
springs' k/m and c/m, the drag's c/m, the inverse inertia), refused where it enters when it would not fit.

float32 ends at 3.4e38, so a particle of 1e-300 kg (1/m = 1e300), a radius or a stiffness of 1e300, or gravity of
1e39 m/s^2 would be infinite on the device and stop the run at its first step as a "non-finite position"; each is
a ValueError here instead, naming the argument and the precision (util.checks.fits, reciprocal_fits).
"""
from __future__ import annotations

import numpy as np

from ..util import checks


def particles(precision: str, mass, masses: np.ndarray, radius, radii: np.ndarray, drag: float) -> None:
    """Masses [kg] and radii [m] of new particles: each, 1/m and the scene's drag / m [1/s] must fit."""
    checks.fits("mass", masses, precision, given=mass)
    checks.reciprocal_fits("mass", masses, precision, given=mass)
    if drag > 0.0:
        checks.fits("mass", drag / masses, precision, given=mass, derived="drag/mass")
    checks.fits("radius", radii, precision, given=radius)


def springs(precision: str, stiffness, ks: np.ndarray, damping, kd: np.ndarray, pairs: np.ndarray,
            masses: np.ndarray, pinned: np.ndarray) -> None:
    """Springs' stiffness [N/m] and damping [N s/m]: each, and each over its ends' masses (k (1/m1 + 1/m2), 1/s^2;
    c (1/m1 + 1/m2), 1/s; a pinned end has 1/m = 0), must fit."""
    inverse = np.where(pinned, 0.0, 1.0 / masses)
    both = inverse[pairs[:, 0]] + inverse[pairs[:, 1]]
    for name, given, values in (("stiffness", stiffness, ks), ("damping", damping, kd)):
        checks.fits(name, values, precision, given=given)
        checks.fits(name, values * both, precision, given=given, derived=f"{name}/mass")


def body(precision: str, properties, shape, drag: float, angular_drag: float) -> None:
    """A rigid body's mass [kg], inertia [kg m^2], their inverses, its size [m] and drags must fit."""
    given = properties.mass
    checks.fits("mass", given, precision)
    checks.reciprocal_fits("mass", given, precision)
    moments = np.linalg.eigvalsh(properties.inertia)
    checks.fits("inertia", moments, precision, given=properties.inertia, derived="principal moment")
    checks.reciprocal_fits("inertia", moments, precision, given=properties.inertia,
                           derived="1/principal moment")
    if drag > 0.0:
        checks.fits("drag", drag / given, precision, given=drag, derived="drag/mass")
    if angular_drag > 0.0:
        checks.fits("angular_drag", angular_drag / moments, precision, given=angular_drag,
                    derived="angular_drag/moment")
    sized(precision, shape)


def sized(precision: str, shape) -> None:
    """A shape's extent (its bounding radius [m], for a surface mesh about its origin) must fit."""
    checks.fits("shape", shape.bounding_radius, precision, given=shape, derived="its bounding radius [m]")


def emitter(precision: str, made) -> None:
    """An emitter's particle masses [kg] (and 1/m), sizes [m], speeds [m/s] and position [m] must fit."""
    checks.fits("mass", made.mass, precision)
    checks.reciprocal_fits("mass", made.mass, precision)
    checks.fits("size", made.size, precision)
    checks.fits("speed", made.speed, precision)
    checks.fits("position", made.position, precision)

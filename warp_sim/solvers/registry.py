"""The solvers by name, and ``make_integrator``: a name with options, or a solver instance, to an unbound solver."""
from __future__ import annotations

import inspect

from ..util import checks
from .adaptive import RK45
from .base import Integrator
from .explicit import RK4, Euler, Midpoint
from .implicit import ImplicitEuler
from .partitioned import SymplecticEuler, VelocityVerlet

INTEGRATORS = {cls.name: cls for cls in (Euler, Midpoint, RK4, SymplecticEuler, VelocityVerlet, RK45, ImplicitEuler)}


def options(cls) -> list[str]:
    """The keyword options a solver class takes (its constructor's arguments)."""
    return [p for p in inspect.signature(cls.__init__).parameters if p != "self"]


def make_integrator(integrator, **settings) -> Integrator:
    """An unbound solver: ``integrator`` is a solver instance (returned as it is; then no settings), or a name
    in INTEGRATORS made with ``settings`` (e.g. ``rtol`` and ``atol`` for "rk45", ``tolerance`` for
    "implicit_euler"). A setting the solver does not take raises ValueError naming the solvers that do."""
    if isinstance(integrator, Integrator):
        if settings:
            raise checks.fail(next(iter(settings)), next(iter(settings.values())),
                              f"give solver options to the solver itself, e.g. {type(integrator).__name__}(...)")
        return integrator
    if not isinstance(integrator, str):
        raise checks.fail("integrator", integrator, f"expected a solver name ({', '.join(INTEGRATORS)}) or a solver "
                                                    "instance such as ws.RK45(rtol=1e-8)")
    cls = INTEGRATORS[checks.choice("integrator", integrator, tuple(INTEGRATORS))]
    takes = options(cls)
    for key, value in settings.items():
        if key not in takes:
            owners = [n for n, c in INTEGRATORS.items() if key in options(c)]
            where = f"{key!r} is an option of {', '.join(repr(o) for o in owners)} only" if owners else \
                f"no integrator takes {key!r}"
            accepted = f"it takes {', '.join(takes)}" if takes else "it takes no options (a fixed-step solver)"
            raise checks.fail(key, value, f"integrator={integrator!r} does not take it: {where}; {accepted}")
    return cls(**settings)

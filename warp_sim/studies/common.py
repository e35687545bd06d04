"""What both studies share: argument checks and how a solver is driven (by a step or a tolerance)."""
from __future__ import annotations

import inspect

import numpy as np

from ..solvers import INTEGRATORS
from ..util import checks

#: solvers whose step costs about 20x an explicit one on these small scenes (a conjugate-gradient solve):
#: the studies give them fewer steps per run (each study says how many)
COSTLY = ("implicit_euler",)


def is_adaptive(integrator: str) -> bool:
    """True for a solver driven by a tolerance (its constructor takes ``rtol``, e.g. "rk45"), not a step."""
    return "rtol" in inspect.signature(INTEGRATORS[integrator].__init__).parameters


def names(argument: str, given, valid) -> list[str]:
    """``given`` (one name or several) checked against ``valid``; all of ``valid`` when None."""
    if given is None:
        return list(valid)
    given = [given] if isinstance(given, str) else list(given)
    bad = [name for name in given if name not in valid]
    if bad or not given:
        shown = f"unknown {', '.join(repr(b) for b in bad)}; " if bad else ""
        raise checks.fail(argument, given, f"{shown}expected a non-empty list of names from {', '.join(valid)}")
    return given


def positive_list(argument: str, values, what: str) -> list[float] | None:
    """A non-empty list of finite numbers > 0 (None stays None)."""
    if values is None:
        return None
    listed = [values] if np.ndim(values) == 0 else list(values)
    if not listed:
        raise checks.fail(argument, values, f"expected a non-empty list of {what} > 0")
    for i, value in enumerate(listed):
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = float("nan")
        if not np.isfinite(number) or number <= 0.0:
            raise checks.fail(argument, values, f"every entry must be a finite number of {what} > 0; "
                                                f"entry {i} is {value!r}")
    return [float(value) for value in listed]

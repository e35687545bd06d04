"""How many equal pieces a step takes: with substeps="auto", enough for the solver's stable step on the scene
(``stability.StepLimit``) and for every pass's longest step (the body contacts' contact_step); with a count n, n
pieces, each split further only by the passes, and a warning (once) when they are longer than the stable step."""
from __future__ import annotations

import math
import warnings

from .stability import MAX_AUTO_SUBSTEPS, StepLimit


class Substeps:
    """The pieces of a step of h seconds, remembered per (h, setting).

    limit: the solver's StepLimit on the scene; max_steps: each pass's longest step [s] (contact_step); solver:
    the solver's name, for the warnings."""

    def __init__(self, limit: StepLimit, max_steps: list[float], solver: str):
        self.limit, self.max_steps, self.solver = limit, list(max_steps), solver
        self._counts: dict = {}
        self._warned = False

    def warn_if_growing(self, stacklevel: int = 3) -> None:
        """Say so when the solver grows the scene's stiffest (undamped) mode at any step: euler and midpoint."""
        if self.limit.grows_at_any_step:
            warnings.warn(f"integrator={self.solver!r} grows an undamped oscillator at any step, and this scene has "
                          f"one ({self.limit.cause}): substeps='auto' keeps the growth to 1 % a second with steps of "
                          f"{self.limit.step:.3g} s; symplectic_euler, verlet, rk4 or implicit_euler hold it at far "
                          "longer steps", UserWarning, stacklevel=stacklevel)

    def for_passes(self, h: float) -> int:
        """The fewest equal pieces of h seconds no longer than any pass's longest step."""
        return max([1] + [math.ceil(h / limit * (1.0 - 1e-12)) for limit in self.max_steps])

    def auto(self, h: float) -> int:
        """The pieces substeps="auto" takes for a step of h seconds (at most MAX_AUTO_SUBSTEPS)."""
        return min(max(self.limit.pieces(h), self.for_passes(h)), MAX_AUTO_SUBSTEPS)

    def pieces(self, h: float, substeps, asked: tuple | None = None) -> int:
        """The pieces of a step of h seconds under ``substeps`` ("auto" or a count). ``asked``: the count the user
        gave and the step [s] it divides, for the warning (default: substeps and h)."""
        key = (h, substeps)
        count = self._counts.get(key)
        if count is None:
            if substeps == "auto":
                count = self.auto(h)
                needed = max(self.limit.pieces(h), self.for_passes(h))
                if needed > MAX_AUTO_SUBSTEPS:
                    warnings.warn(f"substeps='auto': a step of {h:.4g} s needs {needed} substeps to stay stable with "
                                  f"{self.solver} ({self.limit.cause}); it takes {MAX_AUTO_SUBSTEPS}, and may "
                                  "diverge: use implicit_euler, or a shorter step", RuntimeWarning, stacklevel=4)
            else:
                count = substeps * self.for_passes(h / substeps)
                if h / count > self.limit.longest and not self._warned:
                    self._warned = True
                    self._warn_too_few(h / count, *(asked or (substeps, h)))
            self._counts[key] = count
        return count

    def _warn_too_few(self, piece: float, asked: int, whole: float) -> None:
        """``asked`` substeps of a ``whole``-second step give pieces of ``piece`` seconds, longer than the stable
        step: a warning with the count that would be stable."""
        stable = max(self.limit.pieces(whole), self.for_passes(whole))
        advice = ("(substeps='auto' chooses them)" if stable <= MAX_AUTO_SUBSTEPS else
                  f"(more than the {MAX_AUTO_SUBSTEPS} substeps='auto' takes: a solver stable at longer steps suits "
                  "this scene)")
        warnings.warn(f"substeps={asked} gives steps of {piece:.4g} s, longer than {self.solver}'s stable step on "
                      f"this scene, {self.limit.longest:.4g} s ({self.limit.cause}); {stable} substeps of a "
                      f"{whole:.4g} s step would be stable {advice}", RuntimeWarning, stacklevel=5)

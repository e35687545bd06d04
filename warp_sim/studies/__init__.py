"""Accuracy and stability studies, run on the simulator itself (scenes and ``ws.Simulator``).

``accuracy(...)``: error against wall time for every integrator and step size on reference problems
(``PROBLEMS``), with observed orders. ``stability(...)``: the largest stable step of every integrator
on stiff and extreme cases (``CASES``), by bisection, next to theory. Both return results with
``.rows``, ``.to_csv(path)``, ``.to_markdown(path)`` and ``.plot(directory)`` (PNG paths).
"""
from .accuracy import AccuracyResult, accuracy
from .cases import CASES
from .problems import PROBLEMS
from .stability import StabilityResult, stability

__all__ = ["accuracy", "stability", "AccuracyResult", "StabilityResult", "PROBLEMS", "CASES"]

"""The accuracy study: error against run time for every integrator and step size, and observed orders.

Each point is one run of a reference problem (``problems.PROBLEMS``) with one integrator at one
step size h = duration / N, or, for an adaptive solver (one that takes ``rtol``, such as "rk45"),
at one tolerance with a call per 1/60 s frame. Its error is the problem's relative max-norm error
at the end; its cost is wall time per simulated second, the median of up to ``repeats`` runs
(kernels compiled by a warm-up first; the first step of each run, which records the kernel
launches, is left out of the clock).
"""
from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import warp as wp

from .. import cluster
from ..core.guards import SimulationDiverged
from ..simulator import Simulator, resolve_device
from ..solvers import INTEGRATORS, make_integrator
from ..solvers.stability import unchecked_steps
from ..util import checks
from . import report
from .common import COSTLY, is_adaptive, names, positive_list
from .plots import work_precision
from .problems import PENDULUM_PERIOD, PROBLEMS, flip_period, intermediate_axis_period, swing_period
from .settings import (
    ADAPTIVE_CALLS,
    ATOL_PER_RTOL,
    CEILING,
    COSTLY_STEPS,
    FLOOR,
    QUICK_COSTLY_STEPS,
    QUICK_REFINE,
    QUICK_REPEAT_SECONDS,
    QUICK_TOLERANCES,
    REFINE,
    REPEAT_SECONDS,
    TOLERANCES,
    UNTIMED,
)


def _sync(device) -> None:
    wp.synchronize_device(device)


def _simulate(problem, integrator: str, calls: int, device: str, tolerance=None):
    """One run: (observed vector or None if it diverged, seconds per simulated second, internal steps)."""
    options = {} if tolerance is None else {"rtol": tolerance, "atol": tolerance * ATOL_PER_RTOL}
    with unchecked_steps():   # coarse steps are part of the study: their error (or divergence) is measured
        sim = Simulator(problem.build(), integrator=make_integrator(integrator, **options), device=device,
                        guard=False)
    h = problem.duration / calls
    try:
        with unchecked_steps():
            sim.step(h, UNTIMED, substeps=1)
        _sync(sim.device)
        started = time.perf_counter()
        sim.step(h, calls - UNTIMED, substeps=1)
        _sync(sim.device)
        elapsed = time.perf_counter() - started
    except SimulationDiverged:                    # an adaptive solver that could not meet its tolerance
        return None, math.nan, math.nan
    cost = elapsed / (h * (calls - UNTIMED))
    steps = calls
    if tolerance is not None:
        steps = getattr(sim.integrator, "accepted", 0) + getattr(sim.integrator, "rejected", 0)
    observed = problem.observe(sim)
    return (observed if np.all(np.isfinite(observed)) else None), cost, steps


@lru_cache(maxsize=64)
def _reference(name: str, calls: int, device: str) -> tuple:
    observed, _, _ = _simulate(PROBLEMS[name], "rk4", calls, device)
    return tuple(observed)


def _point(problem, integrator, calls, device, repeats, budget, expected, tolerance=None) -> dict:
    observed, cost, steps = _simulate(problem, integrator, calls, device, tolerance)
    costs, spent = [cost], cost * problem.duration
    while len(costs) < repeats and spent < budget and observed is not None:
        costs.append(_simulate(problem, integrator, calls, device, tolerance)[1])
        spent += costs[-1] * problem.duration
    error = math.inf if observed is None else float(np.max(np.abs(observed - expected)))
    return {"problem": problem.name, "integrator": integrator, "knob": "rtol" if tolerance else "h",
            "h": math.nan if tolerance else problem.duration / calls, "rtol": tolerance or math.nan,
            "steps": steps, "error": error, "seconds_per_simulated_second": statistics.median(costs),
            "repeats": len(costs), "status": "ok" if observed is not None else "diverged"}


def observed_order(knobs, errors) -> dict:
    """Slope of log error against log knob over the asymptotic range: points with FLOOR < error <
    CEILING; while the local slopes disagree with the fit by more than 0.3, the coarsest point is
    dropped (at least 3 kept). Returns order (None when fewer than 3 usable points), points, range,
    finest_slope (the local slope of the two finest points) and a note ("exact (rounding level)" when
    every error is below FLOOR)."""
    pairs = sorted((k, e) for k, e in zip(knobs, errors) if math.isfinite(e) and FLOOR < e < CEILING)
    if all(math.isfinite(e) and e <= FLOOR for e in errors):
        return {"order": None, "points": 0, "range": None, "note": "exact (rounding level)", "finest_slope": None}
    if len(pairs) < 3:
        return {"order": None, "points": len(pairs), "range": None, "note": "no asymptotic range",
                "finest_slope": None}
    while True:
        x, y = np.log([p[0] for p in pairs]), np.log([p[1] for p in pairs])
        slope = float(np.polyfit(x, y, 1)[0])
        local = np.diff(y) / np.diff(x)
        if len(pairs) <= 3 or np.max(np.abs(local - slope)) <= 0.3:
            break
        pairs.pop()
    finest = math.log(pairs[1][1] / pairs[0][1]) / math.log(pairs[1][0] / pairs[0][0])
    return {"order": slope, "points": len(pairs), "range": (pairs[0][0], pairs[-1][0]), "note": "",
            "finest_slope": finest}


@dataclass
class AccuracyResult(report.Report):
    """rows: one dict per run (problem, integrator, knob, h [s] or rtol, steps, error,
    seconds_per_simulated_second, repeats, status, observed_order); orders: one dict per
    (problem, integrator); wall_seconds: the study's own wall time; settings: how it ran; checks:
    periods measured against their closed forms (full runs only)."""
    rows: list
    orders: list
    wall_seconds: float
    settings: dict = field(default_factory=dict)
    checks: list = field(default_factory=list)

    def order(self, problem: str, integrator: str):
        """The observed order (or, for an adaptive solver, the exponent of error against rtol)."""
        return next(o["order"] for o in self.orders if o["problem"] == problem and o["integrator"] == integrator)

    def markdown(self, images, path) -> str:
        return report.accuracy_markdown(self, images, path)

    def plot(self, directory) -> list:
        """Work-precision plots, one PNG per problem, into ``directory``; [] without matplotlib."""
        return work_precision(self, directory)


def integrator_points(name: str, integrator: str, counts: list, exact, device: str, repeats: int, budget: float,
                      tols: list, divide: bool, cap: int) -> tuple[list[dict], dict]:
    """(points, fitted order) of one integrator on problem ``name`` (a task of its own on a cluster)."""
    problem = PROBLEMS[name]
    exact = np.asarray(exact)
    _simulate(problem, integrator, UNTIMED + 1, device, 1e-3 if is_adaptive(integrator) else None)  # warm-up
    if is_adaptive(integrator):
        points = [_point(problem, integrator, ADAPTIVE_CALLS, device, repeats, budget, exact, tol) for tol in tols]
        fit = observed_order([p["rtol"] for p in points], [p["error"] for p in points])
    else:
        divisor = 1
        while integrator in COSTLY and divide and max(counts) // divisor > cap:
            divisor *= 2
        points = [_point(problem, integrator, max(UNTIMED + 1, n // divisor), device, repeats, budget, exact)
                  for n in counts]
        fit = observed_order([p["h"] for p in points], [p["error"] for p in points])
    for point in points:
        point["observed_order"] = fit["order"] if fit["order"] is not None else math.nan
    return points, {"problem": name, "integrator": integrator, "expected": INTEGRATORS[integrator].order,
                    "knob": "rtol" if is_adaptive(integrator) else "h", **fit}


def _exact(name: str, counts: list, quick: bool, device: str) -> list:
    """The reference answer of a problem: its closed form, or a run at a much finer step."""
    problem = PROBLEMS[name]
    if problem.exact is not None:
        return np.asarray(problem.exact()).tolist()
    return np.asarray(_reference(name, (QUICK_REFINE if quick else REFINE) * max(counts), device)).tolist()


def accuracy(problems=None, integrators=None, steps=None, quick=False, device="cpu", repeats=3,
             tolerances=None, log=None, client=None, workers=None, scheduler=None) -> AccuracyResult:
    """Run the accuracy study; returns an AccuracyResult.

    problems, integrators: names (default: all of PROBLEMS and INTEGRATORS); steps: step sizes h [s]
    used for every problem (default: each problem's own six, or four with quick), rounded to
    duration / N; tolerances: rtol values for adaptive solvers; repeats >= 1 timed runs per point;
    log: a callable given one line of progress per problem; client, scheduler or workers: run each reference and
    each (problem, integrator) as a task on a Dask cluster (``cluster.connect``): the same rows but for the
    measured times.
    """
    started = time.perf_counter()
    chosen = names("problems", problems, list(PROBLEMS))
    solvers = names("integrators", integrators, list(INTEGRATORS))
    if "rk4" in solvers:     # adaptive solvers next to rk4, whose cost they are compared with
        fixed = [n for n in solvers if not is_adaptive(n)]
        at = fixed.index("rk4") + 1
        solvers = fixed[:at] + [n for n in solvers if is_adaptive(n)] + fixed[at:]
    sizes = positive_list("steps", steps, "seconds (step sizes)")
    tols = positive_list("tolerances", tolerances, "tolerances") or list(QUICK_TOLERANCES if quick else TOLERANCES)
    repeats = checks.count("repeats", repeats)
    device = resolve_device(device)
    cap = QUICK_COSTLY_STEPS if quick else COSTLY_STEPS
    budget = QUICK_REPEAT_SECONDS if quick else REPEAT_SECONDS
    counts = {name: sorted({max(UNTIMED + 1, round(PROBLEMS[name].duration / h)) for h in sizes}) if sizes else
              list(PROBLEMS[name].quick_steps if quick else PROBLEMS[name].steps) for name in chosen}
    where = (client, scheduler, workers)
    exact = dict(zip(chosen, cluster.map_tasks(_exact, [(f"reference-{name}", (name, counts[name], quick, device))
                                                        for name in chosen], *where, "references")))
    tasks = [(f"{name}-{integrator}", (name, integrator, counts[name], exact[name], device, repeats, budget, tols,
                                       not sizes, cap)) for name in chosen for integrator in solvers]
    arrived: dict[str, dict] = {}

    def logged(key, result):   # a line per problem, once all its integrators are in
        fit = result[1]
        arrived.setdefault(fit["problem"], {})[fit["integrator"]] = fit
        if log is not None and len(arrived[fit["problem"]]) == len(solvers):
            found = ", ".join(i + " " + report.number(arrived[fit["problem"]][i]["order"]) for i in solvers)
            log(f"{fit['problem']}: orders {found} ({time.perf_counter() - started:.0f} s)")
    results = cluster.map_tasks(integrator_points, tasks, *where, "accuracy points", logged)
    rows = [point for points, _ in results for point in points]
    orders = [fit for _, fit in results]
    closed_forms = [] if quick else closed_form_checks(chosen, device)
    settings = {"quick": quick, "device": device, "repeats": repeats, "tolerances": tols}
    return AccuracyResult(rows, orders, time.perf_counter() - started, settings, closed_forms)


def closed_form_checks(chosen: list, device: str) -> list[dict]:
    """Periods measured with rk4 against their closed forms: the spring-rod pendulum at rod stiffnesses
    1e4, 1e5 and 1e6 N/m (its period tends to the rigid rod's as 1/k; Richardson extrapolation in 1/k
    from the two stiffest), and the intermediate-axis flip at h = 1e-3 s."""
    found = []
    if "pendulum_170" in chosen:
        periods = {k: swing_period(k, h=1e-3 if k < 1e6 else 5e-4, device=device) for k in (1e4, 1e5, 1e6)}
        for k, period in periods.items():
            found.append({"check": f"pendulum period, rod k = {k:.0e} N/m [s]", "measured": period,
                          "closed_form": PENDULUM_PERIOD})
        found.append({"check": "pendulum period, extrapolated to a rigid rod [s]",
                      "measured": periods[1e6] - (periods[1e5] - periods[1e6]) / 9.0, "closed_form": PENDULUM_PERIOD})
    if "intermediate_axis" in chosen:
        found.append({"check": "intermediate-axis flip period, rk4 at h = 1e-3 s [s]",
                      "measured": flip_period("rk4", 1e-3, device), "closed_form": intermediate_axis_period()})
    for check in found:
        check["relative_error"] = check["measured"] / check["closed_form"] - 1.0
    return found

"""Plots of the studies as PNG files, when matplotlib imports (otherwise none: every function returns [])."""
from __future__ import annotations

import math
import pathlib

from .cases import CASES
from .settings import THEORY


def _figure(width: float = 6.4, height: float = 4.8):
    """A matplotlib Figure with an Agg canvas (no pyplot: no backend or GUI state is touched), or None."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        return None
    figure = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def _save(figure, directory, name: str) -> pathlib.Path:
    path = pathlib.Path(directory) / f"{name}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    return path


def _finish(figure, axes, directory, name: str, xlabel: str, ylabel: str, title: str, grid: str = "both"):
    """Label, grid and legend the axes, then save the figure as <name>.png; returns the path."""
    axes.set_xlabel(xlabel)
    axes.set_ylabel(ylabel)
    axes.set_title(title)
    axes.grid(True, axis=grid, which="both", alpha=0.3)
    axes.legend(fontsize="small")
    return _save(figure, directory, name)


def work_precision(result, directory) -> list:
    """One PNG per problem, accuracy_<problem>.png: error against wall time per simulated second, log-log,
    one line per integrator (adaptive ones dashed)."""
    paths = []
    for problem in dict.fromkeys(r["problem"] for r in result.rows):
        figure = _figure()
        if figure is None:
            return []
        axes = figure.add_subplot()
        rows = [r for r in result.rows if r["problem"] == problem]
        for integrator in dict.fromkeys(r["integrator"] for r in rows):
            points = sorted((r["seconds_per_simulated_second"], r["error"]) for r in rows
                            if r["integrator"] == integrator and math.isfinite(r["error"]) and r["error"] > 0
                            and math.isfinite(r["seconds_per_simulated_second"]))
            if points:
                adaptive = rows and any(r["knob"] == "rtol" for r in rows if r["integrator"] == integrator)
                axes.loglog(*zip(*points), "s--" if adaptive else "o-", label=integrator, markersize=4)
        axes.set_ylim(top=10.0)      # unstable runs (errors far above 1) are left off the top
        paths.append(_finish(figure, axes, directory, f"accuracy_{problem}", "wall time per simulated second [s]",
                             "relative error (runs above 10 not shown)", f"{problem}: work-precision"))
    return paths


def stability_plots(result, directory) -> list:
    """stability_springs.png (largest stable h against ks/m, with theory), stability_cases.png (the
    extreme cases), stability_damping.png (implicit Euler's damping per step against theory)."""
    paths = []
    solvers = list(dict.fromkeys(r["integrator"] for r in result.rows))
    springs = [r for r in result.rows if CASES[r["case"]].group == "spring"]
    if springs:
        figure = _figure()
        if figure is None:
            return []
        axes = figure.add_subplot()
        ratios = sorted({CASES[r["case"]].omega ** 2 for r in springs})
        for k, integrator in enumerate(solvers):
            mine = [r for r in springs if r["integrator"] == integrator and math.isfinite(r["limit"])]
            points = [(CASES[r["case"]].omega ** 2, r["limit"]) for r in mine]
            if points:
                bounded = all(math.isfinite(r["unstable"]) for r in mine)
                line = axes.loglog(*zip(*sorted(points)), "o-" if bounded else "^--", markersize=4,
                                   label=integrator if bounded else f"{integrator} (stable at every h tried)")[0]
                theory = THEORY.get(integrator)
                if theory is not None and math.isfinite(theory):
                    axes.loglog(ratios, [theory / math.sqrt(r) for r in ratios], ":", color=line.get_color())
        paths.append(_finish(figure, axes, directory, "stability_springs", "ks / m [1/s^2]",
                             "largest stable step h [s]", "single spring (dotted: theory)"))
    extreme = list(dict.fromkeys(r["case"] for r in result.rows if CASES[r["case"]].group != "spring"))
    if extreme:
        figure = _figure(7.5, max(3.0, 0.8 + 0.15 * len(extreme) * max(1, len(solvers))))
        if figure is None:
            return paths
        axes = figure.add_subplot()
        width = 0.8 / max(1, len(solvers))
        for k, integrator in enumerate(solvers):
            found = [next((r for r in result.rows if r["case"] == c and r["integrator"] == integrator), None)
                     for c in extreme]
            values = [r["limit"] if r is not None and math.isfinite(r["limit"]) else 0.0 for r in found]
            bars = axes.barh([i + k * width for i in range(len(extreme))], values, height=width, label=integrator)
            for bar, r in zip(bars, found):
                if r is not None and not math.isfinite(r["unstable"]):
                    bar.set_hatch("//")     # a lower bound: stable at every step tried
        axes.set_xscale("log")
        axes.set_yticks([i + 0.4 - width / 2 for i in range(len(extreme))], extreme)
        axes.invert_yaxis()
        paths.append(_finish(figure, axes, directory, "stability_cases", "largest stable step h [s] (hatched: stable "
                             "at every h tried; none: unstable at every h)", "", "extreme cases", grid="x"))
    if result.damping:
        figure = _figure()
        if figure is None:
            return paths
        axes = figure.add_subplot()
        x = [d["omega_h"] for d in result.damping]
        axes.semilogx(x, [d["amplitude_per_step"] for d in result.damping], "o", label="measured")
        axes.semilogx(x, [d["theory"] for d in result.damping], "-", label="1 / sqrt(1 + (omega h)^2)")
        paths.append(_finish(figure, axes, directory, "stability_damping", "omega h", "amplitude factor per step",
                             "implicit Euler's numerical damping"))
    return paths

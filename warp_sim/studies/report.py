"""Writing study results: CSV files and markdown tables (the plots are in ``plots``)."""
from __future__ import annotations

import csv
import math
import pathlib

from .cases import CASES
from .problems import PROBLEMS
from .settings import (
    BISECTIONS,
    BLOWUP,
    CEILING,
    COSTLY_DIVISOR,
    COSTLY_STEPS,
    FLOOR,
    GROWTH,
    H_MAX,
    QUICK_BISECTIONS,
    QUICK_COSTLY_STEPS,
    TARGETS,
)


class Report:
    """What both study results share: ``rows`` written as CSV, and a markdown report written from the
    subclass's ``markdown(images, path)``."""

    rows: list

    def to_csv(self, path) -> pathlib.Path:
        """Write ``rows`` as CSV; returns the path."""
        return write_csv(self.rows, path)

    def to_markdown(self, path, images=()) -> pathlib.Path:
        """Write the markdown report, linking ``images`` (PNG paths, e.g. from ``plot``); returns the path."""
        return write_text(self.markdown(images, path), path)


def number(value, digits: int = 3) -> str:
    """A compact text form of a number: '-' for None or NaN, 'inf', else ``digits`` significant digits."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return "inf"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return str(value)


def table(headers, rows) -> str:
    """A markdown table; cells are formatted with ``number``."""
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(number(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def write_csv(rows: list[dict], path) -> pathlib.Path:
    """Write dict rows (the keys of the first row are the columns) to ``path``; returns the path."""
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]) if rows else [])
        writer.writeheader()
        writer.writerows(rows)
    return path


def write_text(text: str, path) -> pathlib.Path:
    path = pathlib.Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


def images_md(paths, relative_to) -> str:
    """Markdown image links to ``paths``, relative to the folder of the markdown file."""
    base = pathlib.Path(relative_to).resolve().parent
    links = []
    for path in paths:
        path = pathlib.Path(path).resolve()
        try:
            shown = path.relative_to(base)
        except ValueError:
            shown = path
        links.append(f"![{path.stem}]({shown.as_posix()})")
    return "\n\n".join(links) + ("\n" if links else "")


def _cost_at(points: list, target: float) -> float:
    """The cheapest measured cost [s per simulated s] among points with error <= target (NaN if none)."""
    costs = [p["seconds_per_simulated_second"] for p in points if p["error"] <= target]
    return min(costs) if costs else math.nan


def _order_text(order: dict) -> str:
    if order["order"] is None:
        return "exact" if order["note"].startswith("exact") else "-"
    return f"{order['order']:.2f}"


def accuracy_markdown(result, images, path) -> str:
    """The accuracy report: how it ran, observed orders, and per problem the cheapest integrator per error."""
    settings = result.settings
    solvers = list(dict.fromkeys(o["integrator"] for o in result.orders))
    problems = list(dict.fromkeys(o["problem"] for o in result.orders))
    orders = {(o["problem"], o["integrator"]): o for o in result.orders}
    lines = ["# Accuracy study\n",
             f"`warp-sim study accuracy{' --quick' if settings.get('quick') else ''}` on `{settings.get('device')}`: "
             f"{len(result.rows)} runs in {result.wall_seconds:.0f} s of wall time.\n",
             "Every run is a `ws.Scene` stepped by `ws.Simulator` (float64, guard off) for the problem's duration. "
             "Error: the largest entry of |state - reference| over the problem's scales (below). Cost: wall time "
             f"per simulated second, the median of up to {settings.get('repeats')} runs (kernels compiled by a "
             "warm-up; the first two steps of each run, which record the kernel launches, are not timed). "
             "Observed order: the slope of log error against log h over the asymptotic range (errors between "
             f"{FLOOR:g} and {CEILING:g}; coarse points dropped while local slopes stray more than 0.3 from the "
             "fit). Adaptive solvers (`rk45`) are driven by their tolerance rtol (atol = rtol / 100) with one "
             "`Simulator.step` call per tenth of the run; their column gives the slope of log error against "
             "log rtol instead. `implicit_euler` (a conjugate-gradient solve per step) gets longer steps, "
             "halved until its finest run has at most "
             f"{QUICK_COSTLY_STEPS if settings.get('quick') else COSTLY_STEPS} steps.\n",
             "## Observed orders\n",
             table(["problem", *solvers], [[p, *(_order_text(orders[p, s]) for s in solvers)] for p in problems]
                   + [["expected", *(orders[problems[0], s]["expected"] if orders[problems[0], s]["knob"] == "h"
                                     else "~1 (in rtol)" for s in solvers)]]),
             f"\n`exact`: every error below {FLOOR:g} (rounding level); `-`: fewer than three errors between "
             f"{FLOOR:g} and {CEILING:g}, no asymptotic range (unstable or saturated at the steps tried).\n",
             "## Cheapest integrator for a given error\n",
             "The cheapest measured run reaching each relative error, and its cost in seconds of wall time per "
             "simulated second. Per problem below: every integrator's cost at each error (`-`: not reached "
             "in the runs made).\n",
             table(["problem", *(f"error <= {t:g}" for t in TARGETS)],
                   [[p, *(_winner([r for r in result.rows if r["problem"] == p], solvers, t) for t in TARGETS)]
                    for p in problems])]
    adaptive = [s for s in solvers if orders[problems[0], s]["knob"] == "rtol"]
    if adaptive and "rk4" in solvers:
        lines += ["\n## Adaptive against rk4\n",
                  "Wall time per simulated second to reach each error: the cheapest rk4 run (fixed step) against "
                  f"the cheapest {', '.join(adaptive)} run (tolerance); `-`: not reached.\n",
                  table(["problem", *(f"{s} at {t:g}" for t in TARGETS[1:] for s in ("rk4", *adaptive))],
                        [[p, *(_cost_at([r for r in result.rows if r["problem"] == p and r["integrator"] == s], t)
                               for t in TARGETS[1:] for s in ("rk4", *adaptive))] for p in problems])]
    if result.checks:
        lines += ["\n## Closed-form checks\n",
                  table(["check", "measured", "closed form", "relative error"],
                        [[c["check"], f"{c['measured']:.10g}", f"{c['closed_form']:.10g}", c["relative_error"]]
                         for c in result.checks])]
    pictures = {pathlib.Path(i).stem: i for i in images}
    for name in problems:
        problem = PROBLEMS[name]
        rows = [r for r in result.rows if r["problem"] == name]
        lines += [f"\n## {name}\n", f"{problem.title}; {problem.duration:.6g} s. Error: {problem.error}. "
                  f"{problem.notes}.\n"]
        body = []
        for s in solvers:
            points = [r for r in rows if r["integrator"] == s]
            best = min(points, key=lambda r: r["error"])
            fit = orders[name, s]
            knob = "rtol" if fit["knob"] == "rtol" else "h [s]"
            span = f"{fit['range'][0]:.3g} .. {fit['range'][1]:.3g}" if fit["range"] else "-"
            finest = f"{fit['finest_slope']:.2f}" if fit.get("finest_slope") is not None else "-"
            body.append([s, _order_text(fit), finest, f"{knob} {span}", best["error"],
                         best["seconds_per_simulated_second"], *(_cost_at(points, t) for t in TARGETS)])
        lines.append(table(["integrator", "order", "finest slope", "fit range", "smallest error", "its cost",
                            *(f"cost at {t:g}" for t in TARGETS)], body))
        lines.append("\nCheapest: " + "; ".join(f"error <= {t:g}: {_winner(rows, solvers, t)}" for t in TARGETS)
                     + ".\n")
        if f"accuracy_{name}" in pictures:
            lines.append("\n" + images_md([pictures[f"accuracy_{name}"]], path))
    lines.append("\nAll runs: `accuracy.csv` (h or rtol, steps, error, cost, repeats, status, observed order).\n")
    return "\n".join(lines)


def _winner(rows, solvers, target) -> str:
    costs = {s: _cost_at([r for r in rows if r["integrator"] == s], target) for s in solvers}
    reached = {s: c for s, c in costs.items() if math.isfinite(c)}
    if not reached:
        return "none reached"
    best = min(reached, key=reached.get)
    return f"{best} ({reached[best]:.3g})"


def stability_markdown(result, images, path) -> str:
    """The stability report: the ks/m sweep against theory, the extreme cases, implicit Euler's damping."""
    settings = result.settings
    solvers = list(dict.fromkeys(r["integrator"] for r in result.rows))
    rows = {(r["case"], r["integrator"]): r for r in result.rows}
    cases = list(dict.fromkeys(r["case"] for r in result.rows))
    springs = [c for c in cases if CASES[c].group == "spring"]
    extreme = [c for c in cases if CASES[c].group != "spring"]
    quick = settings.get("quick")
    lines = ["# Stability study\n",
             f"`warp-sim study stability{' --quick' if quick else ''}` on `{settings.get('device')}`: "
             f"{len(result.rows)} searches in {result.wall_seconds:.0f} s of wall time.\n",
             "Every run is a `ws.Scene` stepped by `ws.Simulator` (float64, guard off). A run is unstable when "
             f"it goes non-finite or its size (an energy above the ground state; for the orbit the distance "
             f"from the attractor) grows: the largest value over the second half of the run exceeds {GROWTH:g} "
             f"times the largest over the first half (or any value exceeds {BLOWUP:g} times the initial one: "
             "growth fast enough to saturate within the first half). The search starts at h = 1/omega (or the "
             f"case's own start), up to {H_MAX:g} / omega at most, "
             "moves by factors of 4 until a stable step and an unstable one are found, then bisects "
             f"geometrically {QUICK_BISECTIONS if quick else BISECTIONS} times; `limit` is the largest stable "
             "step found. Linear cases run a fixed number of steps; nonlinear ones a fixed simulated time. "
             f"`implicit_euler` runs {COSTLY_DIVISOR}x fewer steps per run (a conjugate-gradient solve per step). "
             "Adaptive "
             "solvers choose their own step and are not searched.\n",
             "Theory (undamped linear oscillator of frequency omega): `rk4` 2 sqrt 2 / omega, `symplectic_euler` "
             "and `verlet` 2 / omega, `implicit_euler` none (unconditionally stable, with numerical damping). "
             "`euler` and `midpoint` have no stable step (they gain energy by a factor per step, "
             "1 + (omega h)^2 and 1 + (omega h)^4 / 4); their measured limit is where that growth reaches "
             f"{GROWTH:g} over the run, which the theory column gives for the run's length.\n"]
    if springs:
        lines += ["## Single stiff spring\n",
                  "Largest stable omega h (omega = sqrt(ks/m)); in brackets the ratio to theory.\n",
                  table(["ks/m [1/s^2]", *solvers],
                        [[f"{CASES[c].omega ** 2:.0e}".replace("+0", ""), *(_cell(rows[c, s]) for s in solvers)]
                         for c in springs]
                        + [["theory", *(rows[springs[0], s]["theory_omega_h"] for s in solvers)]])]
    if extreme:
        lines += ["\n## Extreme cases\n",
                  "Largest stable step h [s]; below it omega h and the ratio to theory where the case has a "
                  "linear frequency. `>= h` (stable at every step tried up to h), `< h` (unstable at every "
                  "step tried down to h).\n",
                  table(["case", "omega [rad/s]", *solvers],
                        [[c, CASES[c].omega, *(_limit(rows[c, s]) for s in solvers)] for c in extreme]),
                  "\n" + "\n".join(f"- `{c}`: {CASES[c].title}." + (f" {CASES[c].notes}." if CASES[c].notes else "")
                                   + _in_unit(CASES[c], [rows[c, s] for s in solvers]) for c in extreme) + "\n"]
    if result.frame_rate:
        lines += ["\n## Substeps at frame rate: auto against the fewest that hold\n",
                  "`sim.step(1/60)` splits each step into `sim.substeps(1/60)` pieces (`substeps=\"auto\"`, the "
                  "default), from the solver's stable step on the scene's stiffest spring mode. Beside it, the fewest "
                  "substeps at which the scene holds (no divergence, every particle within 10 m of the scene's start "
                  "and slower than 200 m/s), bisected on the count with `sim.step(1/60, substeps=n)`.\n",
                  table(["scene", "integrator", "auto", "fewest that hold", "auto / fewest", "probes"],
                        [[r["scene"], r["integrator"], r["auto"], r["fewest"], r["ratio"], r["probes"]]
                         for r in result.frame_rate])]
    if result.damping:
        lines += ["\n## Implicit Euler's numerical damping\n",
                  "On the ks/m = 1e4 spring: the amplitude factor per step, measured from the energy after N "
                  "steps, (E_N / E_0)^(1/2N), against the theory 1 / sqrt(1 + (omega h)^2).\n",
                  table(["omega h", "steps", "measured per step", "theory"],
                        [[d["omega_h"], d["steps"], d["amplitude_per_step"], d["theory"]] for d in result.damping])]
    if images:
        lines += ["\n## Plots\n", images_md(images, path)]
    lines.append("\nAll searches: `stability.csv` (limit and smallest unstable h [s], the longest piece "
                 "`substeps=\"auto\"` takes (auto_step [s]), omega, omega h, theory, ratio, steps per run, probes).\n")
    return "\n".join(lines)


def _in_unit(case, rows) -> str:
    """The limits in the case's own unit (e.g. sqrt(m/k) for the cloth), where it has one."""
    if case.unit is None:
        return ""
    size, name = case.unit
    shown = ", ".join(f"{r['integrator']} {r['limit'] / size:.4g}" for r in rows if math.isfinite(r["limit"]))
    return f" In units of {name}: {shown}."


def _cell(row) -> str:
    if not math.isfinite(row["limit"]):
        return f"< {number(row['unstable'] * row['omega'])}"
    text = f"{row['limit_omega_h']:.4g}"
    if not math.isfinite(row["unstable"]):
        text = ">= " + text
    return text + (f" ({row['ratio']:.3f})" if math.isfinite(row["ratio"]) else "")


def _limit(row) -> str:
    if not math.isfinite(row["limit"]):
        return f"< {number(row['unstable'])}"
    text = ("" if math.isfinite(row["unstable"]) else ">= ") + number(row["limit"])
    if math.isfinite(row["limit_omega_h"]):
        text += f" (omega h {row['limit_omega_h']:.3g}" + (f", {row['ratio']:.3f}" if math.isfinite(row["ratio"])
                                                             else "") + ")"
    return text

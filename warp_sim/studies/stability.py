"""The stability study: the largest stable step of every integrator on stiff and extreme cases, by bisection.

A run at step h is unstable when it goes non-finite, when a bounded case's size passes its bound
(a contact scene stands while no box has moved 5 mm), or when the case's size (an energy, or a
distance) grows: its largest value over the run's second half exceeds GROWTH times its largest
over the first half. Not a fixed bound, so a stable scheme that loses or keeps energy passes and
one that gains it by a factor per step fails. (A size past BLOWUP times its initial value also
counts: growth so fast that it could saturate, nonlinearly, within the first half.) The search
starts at 1 / omega (or the case's h0), moves by factors of 4 until one step is stable and the
next is not, then bisects geometrically.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from .. import cluster
from ..simulator import Simulator, resolve_device
from ..solvers import INTEGRATORS
from ..solvers.stability import unchecked_steps
from ..util import checks
from . import report
from .cases import CASES, QUICK_SPRING_RATIOS, SPRING_RATIOS, spring_name
from .common import COSTLY, is_adaptive, names
from .frame_rate import FRAME_SCENES, FRAME_SOLVERS, QUICK_FRAME_SCENES, frame_rate_row
from .plots import stability_plots
from .settings import (
    BISECTIONS,
    BLOWUP,
    COSTLY_DIVISOR,
    DAMPING_STEPS,
    GROWTH,
    H_MAX,
    MAX_STEPS,
    QUICK_BISECTIONS,
    QUICK_MAX_STEPS,
    QUICK_STEPS,
    SAMPLES,
    STEPS,
    THEORY,
)


def run_length_limit(integrator: str, steps: int, growth: float = GROWTH) -> float | None:
    """omega h at which explicit Euler or midpoint, unstable at any step on an undamped oscillator, first
    grow their energy by ``growth`` between the halves of a ``steps``-step run: their measured limit."""
    per_step = math.exp(2.0 * math.log(growth) / steps) - 1.0    # rho^2 - 1 with rho^steps = growth
    if integrator == "euler":                # rho^2 = 1 + (omega h)^2
        return math.sqrt(per_step)
    if integrator == "midpoint":             # rho^2 = 1 + (omega h)^4 / 4
        return (4.0 * per_step) ** 0.25
    return None


def grows(case, integrator: str, h: float, steps: int, device: str) -> tuple[bool, list]:
    """(unstable, sizes): one run of ``steps`` steps of h seconds each (one piece each: substeps=1), its size
    sampled along the way."""
    with unchecked_steps():   # too long a step for the scene is what is being measured
        sim = Simulator(case.build(), integrator=integrator, device=device, guard=False, **case.options)
        return _grows(sim, case, h, steps)


def auto_step(case, integrator: str, device: str) -> float:
    """The longest piece substeps="auto" takes on the case (``Simulator.step_limit``) [s]; inf: none binds."""
    with unchecked_steps():
        return Simulator(case.build(), integrator=integrator, device=device, guard=False,
                         **case.options).step_limit.step


def _grows(sim, case, h: float, steps: int) -> tuple[bool, list]:
    stride = 1 if case.duration is None else max(1, steps // SAMPLES)   # a sampled energy can alias
    sizes, first = [case.size(sim)], None
    for done in range(stride, steps + 1, stride):
        sim.step(h, stride, substeps=1)
        size = case.size(sim)
        sizes.append(size)
        if case.bound is not None:   # a bounded case: unstable once past its bound (its size starts at 0)
            if not math.isfinite(size) or size > case.bound:
                return True, sizes
            continue
        if not math.isfinite(size) or size > BLOWUP * sizes[0]:
            return True, sizes
        if first is None and done >= steps // 2:
            first = max(sizes)
        elif first is not None and size > GROWTH * first:
            return True, sizes
    return False, sizes


def _run_steps(case, integrator: str, h: float, quick: bool) -> int:
    divisor = COSTLY_DIVISOR if integrator in COSTLY else 1
    if case.duration is None:
        return (QUICK_STEPS if quick else STEPS) // divisor
    return min(math.ceil(case.duration / h), (QUICK_MAX_STEPS if quick else MAX_STEPS) // divisor)


def largest_stable_step(case, integrator: str, device: str = "cpu", quick: bool = False) -> dict:
    """Bisection for the largest stable h [s]: {"limit": largest stable h found (None: unstable at every h
    tried), "unstable": smallest unstable h (None: stable at every h tried), "probes": runs made}."""
    h0 = case.h0 or 1.0 / case.omega
    h_max = case.h_max or H_MAX * h0
    h_min = case.duration / ((QUICK_MAX_STEPS if quick else MAX_STEPS) // (COSTLY_DIVISOR if integrator in COSTLY
                                                                              else 1)) if case.duration else 1e-4 * h0
    probes = 0

    def stable(h: float) -> bool:
        nonlocal probes
        probes += 1
        steps = max(2, _run_steps(case, integrator, h, quick))
        return not grows(case, integrator, h, steps, device)[0]

    low = high = None
    h = min(max(h0, h_min), h_max)
    while low is None or high is None:
        if h > h_max or h < h_min:
            break
        if stable(h):
            low, h = h, 4.0 * h
        else:
            high, h = h, 0.25 * h
    if low is not None and high is not None:
        for _ in range(QUICK_BISECTIONS if quick else BISECTIONS):
            middle = math.sqrt(low * high)
            if stable(middle):
                low = middle
            else:
                high = middle
    return {"limit": low, "unstable": high, "probes": probes}


def implicit_damping(device: str = "cpu", quick: bool = False) -> list[dict]:
    """Implicit Euler's numerical damping on the ks/m = 1e4 spring: the measured amplitude factor per step,
    (E_end / E_0)^(1 / 2N), next to the theory 1 / sqrt(1 + (omega h)^2), at each omega h of DAMPING_STEPS."""
    case = CASES["spring_1e4"]
    rows = []
    for omega_h in DAMPING_STEPS:
        theory = 1.0 / math.sqrt(1.0 + omega_h**2)     # measured until the amplitude has fallen by about 1e6
        steps = max(1, min((QUICK_STEPS if quick else STEPS) // COSTLY_DIVISOR, int(math.log(1e-6) / math.log(theory))))
        _, sizes = grows(case, "implicit_euler", omega_h / case.omega, steps, device)
        measured = (sizes[-1] / sizes[0]) ** (1.0 / (2.0 * steps)) if sizes[-1] > 0 else 0.0
        rows.append({"omega_h": omega_h, "steps": steps, "amplitude_per_step": measured, "theory": theory})
    return rows


@dataclass
class StabilityResult(report.Report):
    """rows: one dict per (case, integrator): limit [s] (largest stable step found, NaN if none),
    auto_step [s] (the longest piece substeps="auto" takes there), unstable [s] (smallest unstable step found, NaN
    if none), omega [rad/s], limit_omega_h, theory_omega_h, ratio (measured / theory), probes; damping: implicit
    Euler's measured numerical damping; frame_rate: per (scene, integrator) of studies.frame_rate, the substeps
    "auto" takes at 1/60 s beside the fewest that hold (bisected); wall_seconds; settings."""
    rows: list
    damping: list
    wall_seconds: float
    settings: dict = field(default_factory=dict)
    frame_rate: list = field(default_factory=list)

    def limit(self, case: str, integrator: str) -> float:
        return next(r["limit"] for r in self.rows if r["case"] == case and r["integrator"] == integrator)

    def markdown(self, images, path) -> str:
        return report.stability_markdown(self, images, path)

    def plot(self, directory) -> list:
        """The limits against ks/m and the extreme cases as PNGs into ``directory``; [] without matplotlib."""
        return stability_plots(self, directory)


def stability_row(name: str, integrator: str, device: str, quick: bool) -> dict:
    """One row of the study: the largest stable step of ``integrator`` on case ``name``, next to theory (a task of
    its own when the study runs on a cluster)."""
    case = CASES[name]
    found = largest_stable_step(case, integrator, device, quick)
    steps = _run_steps(case, integrator, found["limit"] or case.h0 or 1.0, quick)
    theory = THEORY[integrator] if case.omega is not None else None
    if theory is None and case.omega is not None and case.duration is None:
        theory = run_length_limit(integrator, steps)
    limit, unstable = found["limit"] or math.nan, found["unstable"] or math.nan
    omega_h = limit * case.omega if case.omega else math.nan
    return {"case": name, "group": case.group, "integrator": integrator, "limit": limit,
            "auto_step": auto_step(case, integrator, device),
            "unstable": unstable, "omega": case.omega or math.nan, "limit_omega_h": omega_h,
            "theory_omega_h": math.nan if theory is None else theory,
            "ratio": omega_h / theory if theory and math.isfinite(theory) else math.nan,
            "steps_per_run": steps if case.duration is None else math.nan, "probes": found["probes"]}


def stability(cases=None, integrators=None, quick=False, device="cpu", log=None, client=None, workers=None,
              scheduler=None, frame_scenes=None) -> StabilityResult:
    """Run the stability study; returns a StabilityResult.

    cases: names from CASES (default: all; with quick, the springs at ks/m = 1e2 and 1e8 and every
    extreme case); integrators: names from INTEGRATORS (default: all fixed-step ones; adaptive
    solvers choose their own step and are skipped); log: a callable given a line per case;
    client, scheduler or workers: run each (case, integrator) as a task on a Dask cluster (``cluster.connect``),
    which gives the same rows; frame_scenes: names from frame_rate.FRAME_SCENES, whose fewest stable substeps at
    1/60 s are bisected for the chosen solvers among rk4, symplectic_euler and verlet (default: all of them where
    ``cases`` is None, the demo and the 32^2 cloth with quick; none where cases are named).
    """
    started = time.perf_counter()
    chosen = names("cases", cases, list(CASES))
    if cases is None and quick:
        skipped = {spring_name(r) for r in SPRING_RATIOS if r not in QUICK_SPRING_RATIOS}
        chosen = [name for name in chosen if name not in skipped]
    fixed = [n for n in INTEGRATORS if not is_adaptive(n)]
    solvers = names("integrators", integrators, list(INTEGRATORS)) if integrators is not None else fixed
    adaptive = [n for n in solvers if n not in fixed]
    if adaptive:
        raise checks.fail("integrators", integrators, f"{', '.join(adaptive)} choose their own step from a tolerance; "
                                                      f"expected fixed-step solvers from {', '.join(fixed)}")
    device = resolve_device(device)
    tasks = [(f"{name}-{integrator}", (name, integrator, device, quick)) for name in chosen for integrator in solvers]
    if frame_scenes is None:
        frame_scenes = [] if cases is not None else list(QUICK_FRAME_SCENES if quick else FRAME_SCENES)
    frame_scenes = names("frame_scenes", frame_scenes, list(FRAME_SCENES)) if frame_scenes else []
    frame_tasks = [(f"{name}-{integrator}", (name, integrator, device)) for name in frame_scenes
                   for integrator in solvers if integrator in FRAME_SOLVERS]
    arrived: dict[str, dict] = {}

    def logged(key, row):   # a line per case, once all its integrators are in
        arrived.setdefault(row["case"], {})[row["integrator"]] = row
        if log is not None and len(arrived[row["case"]]) == len(solvers):
            shown = ", ".join(f"{i} {report.number(arrived[row['case']][i]['limit'])}" for i in solvers)
            log(f"{row['case']}: largest stable h [s] {shown} ({time.perf_counter() - started:.0f} s)")
    rows = cluster.map_tasks(stability_row, tasks, client, scheduler, workers, "stability cases", logged)
    damping = implicit_damping(device, quick) if "implicit_euler" in solvers else []

    def frame_logged(key, row):
        if log is not None:
            log(f"{row['scene']} at 1/60 s, {row['integrator']}: auto {row['auto']} substeps, fewest that hold "
                f"{row['fewest']} ({time.perf_counter() - started:.0f} s)")
    frame_rate = cluster.map_tasks(frame_rate_row, frame_tasks, client, scheduler, workers, "frame-rate scenes",
                                   frame_logged) if frame_tasks else []
    settings = {"quick": quick, "device": device, "growth": GROWTH}
    return StabilityResult(rows, damping, time.perf_counter() - started, settings, frame_rate)

"""Sweeps: many variants of a scene, each a task on a Dask worker, each written to its own USD stage.

``sweep(build, grid, seconds=...)`` crosses ``grid`` into variants (or takes a list of dicts), gives each a stable
id (a readable name plus a hash of its parameters), runs ``build(**params)`` in its own task on a worker
(``cluster``), simulates it into ``out/<id>.usdc``, and records one row per variant in ``out/sweep.json`` (and
flattened in ``out/sweep.csv``): id, params, status ("done", "diverged" or "failed", with ``error``), wall_s,
worker, measures (what ``measure(sim)`` returned) and usd (relative to ``out``). The JSON is rewritten after every
variant, so a rerun with the same ``out`` skips the variants already done (their stage still there and their
parameters' hash the same), and a worker killed mid-task only costs that task, which Dask runs again; the stage
writer's atomic writes keep anything half-written out of ``out``.

``build`` (and ``measure``) is an importable function, a function of a script (run again on each worker, so it
may refer to its script's own helpers), or ``"path/to/script.py"`` naming a script that defines ``build`` and
optionally ``measure``. Results are bit for bit the same on 1 worker or many, in any order: a variant depends on
its parameters only (seeds are parameters).
"""
from __future__ import annotations

import csv
import inspect
import io
import itertools
import json
import math
import os
import pathlib
import re
import runpy
import time

from . import cluster
from .core.guards import SimulationDiverged
from .simulator import Simulator, resolve_device
from .solvers import INTEGRATORS
from .stages.folders import folder_problem
from .stages.runs import write_atomically
from .util import checks
from .util.fingerprint import fingerprint

FIELDS = ("id", "status", "wall_s", "worker", "usd", "error")


def variants(grid) -> list[dict]:
    """The variants of ``grid``: a dict of parameter lists, crossed (in key order, the last key fastest), or a list
    of dicts taken as they are."""
    if isinstance(grid, dict):
        if not grid or not all(isinstance(values, (list, tuple)) and values for values in grid.values()):
            raise checks.fail("grid", grid, "expected a dict of non-empty parameter lists, or a list of dicts")
        keys = list(grid)
        return [dict(zip(keys, combination)) for combination in itertools.product(*(grid[k] for k in keys))]
    if isinstance(grid, (list, tuple)) and grid and all(isinstance(item, dict) for item in grid):
        return [dict(item) for item in grid]
    raise checks.fail("grid", grid, "expected a dict of non-empty parameter lists, or a non-empty list of dicts")


def variant_id(params: dict) -> str:
    """A stable id: the parameters as a readable name, and 8 characters of their hash."""
    readable = "_".join(f"{key}-{value}" for key, value in params.items())
    readable = re.sub(r"[^A-Za-z0-9_.-]+", "", readable)[:80] or "variant"
    return f"{readable}-{params_hash(params)[:8]}"


def params_hash(params: dict) -> str:
    return fingerprint(sorted((str(key), value) for key, value in params.items()))


def _functions(build, measure):
    """(build, measure) callables from what the user gave (functions, or a script's path)."""
    if isinstance(build, (str, os.PathLike)):
        path = os.fspath(build)
        if not os.path.isfile(path):
            raise checks.fail("build", path, "no such script: expected a function, or a .py file defining build()")
        namespace = runpy.run_path(path, run_name="warp_sim_sweep_script")
        if not callable(namespace.get("build")):
            raise checks.fail("build", path, "the script defines no function build(**params)")
        return namespace["build"], namespace.get("measure") if measure is None else measure
    if not callable(build):
        raise checks.fail("build", build, "expected a function build(**params) -> Scene, or a script's path")
    if measure is not None and not callable(measure):
        raise checks.fail("measure", measure, "expected a function measure(sim) -> dict, or None")
    return build, measure


def run_variant(build, measure, params: dict, run: dict, out: str) -> dict:
    """One variant, on whichever worker runs it: build, simulate into out/<id>.usdc, measure; its row."""
    vid = variant_id(params)
    row = {"id": vid, "params": params, "params_hash": params_hash(params), "status": "done", "error": None,
           "worker": cluster.worker_name(), "measures": {}, "usd": f"{vid}.usdc"}
    started = time.perf_counter()
    try:
        build_fn, measure_fn = _functions(build, measure)
        sim = Simulator(build_fn(**params), integrator=run["integrator"], device=run["device"])
        sim.run(run["seconds"], run["fps"], run["substeps"], usd=pathlib.Path(out) / row["usd"], progress=False)
        if measure_fn is not None:
            row["measures"] = {str(k): _plain(v) for k, v in dict(measure_fn(sim)).items()}
    except SimulationDiverged as error:
        row.update(status="diverged", error=str(error))
        if error.usd is None:
            row["usd"] = None
    except Exception as error:   # a bad variant (a ValueError from build, ...) is recorded; the others go on
        row.update(status="failed", error=f"{type(error).__name__}: {error}", usd=None)
    row["wall_s"] = time.perf_counter() - started
    return row


def _plain(value):
    """A measure as JSON: numbers, strings, bools, None, and lists of them (numpy values become Python ones)."""
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise checks.fail("measure", value, "a measure must be a number, a string, a bool, None or a list of them")


class SweepResult:
    """The rows of a sweep (one dict per variant, in the grid's order), as written to sweep.json.

    rows: the rows; out: the folder; to_dataframe(): a pandas DataFrame of the flattened rows (pandas needed);
    table(): a plain-text summary; csv_text(): the rows flattened, one column per parameter and per measure
    """

    def __init__(self, rows: list[dict], out: pathlib.Path):
        self.rows, self.out = rows, out

    def flat(self) -> tuple[list[str], list[dict]]:
        params = list(dict.fromkeys(k for row in self.rows for k in row["params"]))
        measures = list(dict.fromkeys(k for row in self.rows for k in row["measures"]))
        clash = set(params) & set(measures) | (set(params) | set(measures)) & set(FIELDS)
        if clash:
            raise checks.fail("measure", sorted(clash), "names a column twice (parameters, measures and "
                                                        f"{', '.join(FIELDS)} must differ)")
        columns = ["id", *params, *measures, "status", "wall_s", "worker", "usd", "error"]
        flat = [{**{k: row.get(k) for k in FIELDS}, **row["params"], **row["measures"]} for row in self.rows]
        return columns, flat

    def csv_text(self) -> str:
        columns, flat = self.flat()
        text = io.StringIO()
        writer = csv.DictWriter(text, columns, extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: ("" if v is None else v) for k, v in row.items()} for row in flat)
        return text.getvalue()

    def to_dataframe(self):
        import pandas  # optional: only for users who ask for a DataFrame

        columns, flat = self.flat()
        return pandas.DataFrame(flat, columns=columns)

    def table(self) -> str:
        columns, flat = self.flat()
        shown = [c for c in columns if c not in ("usd", "error", "worker")]
        cells = [[_cell(row.get(c)) for c in shown] for row in flat]
        widths = [max(len(c), *(len(r[i]) for r in cells)) for i, c in enumerate(shown)]
        lines = ["  ".join(c.ljust(w) for c, w in zip(shown, widths))]
        lines += ["  ".join(v.ljust(w) for v, w in zip(r, widths)) for r in cells]
        done = sum(row["status"] == "done" for row in self.rows)
        lines.append(f"{done} of {len(self.rows)} variants done; stages and sweep.json in {self.out}")
        return "\n".join(lines)


def _cell(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else str(value)
    return "" if value is None else str(value)


def _load(out: pathlib.Path) -> dict[str, dict]:
    """The done rows of an earlier sweep into ``out`` whose stages are still there, by id (data: JSON only)."""
    try:
        rows = json.loads((out / "sweep.json").read_text())
    except (OSError, ValueError):
        return {}
    done = {}
    for row in rows if isinstance(rows, list) else []:
        if isinstance(row, dict) and row.get("status") == "done" and row.get("usd") and \
                (out / str(row["usd"])).is_file() and row.get("params_hash") == params_hash(row.get("params", {})):
            done[row["id"]] = row
    return done


def _save(out: pathlib.Path, rows: list[dict]) -> SweepResult:
    result = SweepResult(rows, out)
    write_atomically(out / "sweep.json", lambda path: path.write_text(json.dumps(rows, indent=1) + "\n"))
    write_atomically(out / "sweep.csv", lambda path: path.write_text(result.csv_text()))
    return result


def check_run(seconds, fps, substeps, integrator, device, local: bool = True) -> dict:
    """The run arguments every variant gets, checked once before any cluster starts: seconds and fps > 0 covering
    at least one frame, substeps "auto" or a count, integrator one of INTEGRATORS' names (each worker makes its
    own solver), device None or a device of this machine (``local``: the embedded cluster's workers are its
    processes) or, for a remote cluster, of the form cpu, cuda or cuda:N."""
    seconds = checks.scalar("seconds", seconds, low=0.0, low_open=True)
    fps = checks.scalar("fps", fps, low=0.0, low_open=True)
    if round(seconds * fps) < 1:
        raise checks.fail("seconds", seconds, f"covers no frame at fps={fps:g}; need seconds >= {0.5 / fps:g}")
    if not isinstance(integrator, str):
        raise checks.fail("integrator", integrator, "expected a solver name (each worker makes its own solver)")
    checks.choice("integrator", integrator, sorted(INTEGRATORS))
    if device is not None:
        if not isinstance(device, str) or not re.fullmatch(r"cpu|cuda(:\d+)?", device):
            raise checks.fail("device", device, "expected None, 'cpu', 'cuda' or 'cuda:N'")
        if local:
            resolve_device(device)
    return {"seconds": seconds, "fps": fps, "substeps": checks.substeps("substeps", substeps),
            "integrator": integrator, "device": device}


def _check_params(build_fn, grid, rows: list[dict]) -> None:
    """Every variant's parameters: names build() takes, values sweep.json holds as they are."""
    try:
        signature = inspect.signature(build_fn)
    except (TypeError, ValueError):   # a builtin or a C function: nothing to check against
        signature = None
    for params in rows:
        for name, value in params.items():
            if not isinstance(name, str) or not name.isidentifier():
                raise checks.fail("grid", grid, f"parameter name {name!r} is not a Python identifier "
                                                "(build(**params) takes it as a keyword)")
            try:
                same = json.loads(json.dumps(value)) == value
            except (TypeError, ValueError):
                same = False
            if not same:
                raise checks.fail("grid", grid, f"{name}={value!r} is not a number, string, bool or None (or a list "
                                                "of them): each variant's parameters are written to sweep.json")
        if signature is not None:
            try:
                signature.bind(**params)
            except TypeError as error:
                raise checks.fail("grid", grid, f"build{signature} does not take {params}: {error}") from None


def _check_where(client, scheduler, workers, progress, on_start) -> None:
    if client is not None and scheduler is not None:
        raise checks.fail("scheduler", scheduler, "give a client or a scheduler's address, not both")
    if scheduler is not None and (not isinstance(scheduler, str) or not scheduler.strip()):
        raise checks.fail("scheduler", scheduler, "expected a scheduler address such as 'tcp://host:8786'")
    if workers is not None:
        checks.count("workers", workers)
    if not isinstance(progress, bool):
        raise checks.fail("progress", progress, "expected True or False")
    if on_start is not None and not callable(on_start):
        raise checks.fail("on_start", on_start, "expected a function on_start(client), or None")


def sweep(build, grid, *, seconds: float, fps: float = 60.0, substeps="auto", integrator="rk4", measure=None,
          out="sweep", client=None, workers: int | None = None, device: str | None = None,
          scheduler: str | None = None, progress: bool = True, on_start=None) -> SweepResult:
    """Run every variant of ``grid`` (see the module docstring) on a Dask cluster; returns a SweepResult.

    build: function(**params) -> Scene, or a script's path; measure: function(sim) -> dict of numbers (or None);
    seconds, fps, substeps, integrator (a name), device: as Simulator.run and Simulator; out: the folder of the
    stages and of sweep.json / sweep.csv; client: a dask.distributed.Client to run on, or scheduler: its address,
    or neither: an embedded LocalCluster of ``workers`` processes (default: the cores), closed at the end;
    on_start: called with the client once connected (the command line prints the dashboard's link). Every argument
    is checked before a cluster starts (a bad one is a ValueError naming it), and ``out`` is made or refused then."""
    build_fn, _ = _functions(build, measure)
    rows_by_params = variants(grid)
    ids = [variant_id(params) for params in rows_by_params]
    if len(set(ids)) != len(ids):
        raise checks.fail("grid", grid, "holds the same variant twice")
    _check_params(build_fn, grid, rows_by_params)
    run = check_run(seconds, fps, substeps, integrator, device, local=client is None and scheduler is None)
    _check_where(client, scheduler, workers, progress, on_start)
    problem = folder_problem(out)   # made now, or refused: before minutes of work, not after
    if problem is not None:
        raise checks.fail("out", os.fspath(out), problem)
    out = pathlib.Path(out)
    done = _load(out)
    rows = {vid: done[vid] for vid in ids if vid in done}
    script = os.fspath(build) if isinstance(build, (str, os.PathLike)) else None
    task_build = os.path.abspath(script) if script else build_fn
    todo = [(vid, (task_build, measure, params, run, str(out.resolve())))
            for vid, params in zip(ids, rows_by_params) if vid not in rows]

    def finished(vid, row):
        rows[vid] = row
        _save(out, [rows[i] for i in ids if i in rows])
    if todo:
        with cluster.connect(client, scheduler, workers) as connected:
            if on_start is not None:
                on_start(connected)
            cluster.run_tasks(connected, run_variant, todo, progress="variants" if progress else None,
                              on_result=finished)
    return _save(out, [rows[i] for i in ids])

"""The `warp-sim` command."""
from __future__ import annotations

import argparse
import pathlib
import sys
import time

from . import cluster, studies
from .core.guards import SimulationDiverged
from .demo import demo_scene
from .scene import Scene
from .simulator import RunInterrupted, Simulator
from .solvers import INTEGRATORS, RK45
from .studies import CASES, PROBLEMS
from .sweep import sweep
from .util.verbosity import set_verbose


def _integrator(args):
    """The solver the options name: rk45 with --rtol/--atol, or a name (tolerances for another solver: an error)."""
    if args.rtol is None and args.atol is None:
        return args.integrator
    if args.integrator != "rk45":
        raise ValueError(f"--rtol/--atol are rk45's tolerances; --integrator {args.integrator} takes none")
    options = {key: value for key, value in (("rtol", args.rtol), ("atol", args.atol)) if value is not None}
    return RK45(**options)


def _demo(args) -> int:
    sim = Simulator(demo_scene(), integrator=_integrator(args), device=args.device)
    print(f"warp-sim demo: {sim.scene!r} on {sim.device.alias}, {args.integrator}, "
          f"{args.seconds:g} s at {args.fps:g} fps x {args.substeps} substeps")
    started = time.perf_counter()
    path = sim.run(seconds=args.seconds, fps=args.fps, substeps=args.substeps, usd=args.out,
                   progress=not args.no_progress, chunk_frames=args.chunk_frames, resume=args.resume,
                   keep_checkpoint=args.keep_checkpoint)
    elapsed = time.perf_counter() - started
    print(f"wrote {path} ({round(args.seconds * args.fps)} frames) in {elapsed:.2f} s wall time")
    return 0


def _run(args) -> int:
    """warp-sim run: a UsdPhysics stage simulated into an animation layer over it (or one flattened stage)."""
    scene = Scene.from_usd(args.scene, precision=args.precision)
    source = scene.usd_source
    fps = args.fps or source.time_codes_per_second
    sim = Simulator(scene, integrator=_integrator(args), device=args.device)
    print(f"warp-sim run: {args.scene} -> {sim.scene!r} on {sim.device.alias}, {args.integrator}, "
          f"{args.seconds:g} s at {fps:g} fps x {args.substeps} substeps")
    started = time.perf_counter()
    path = sim.run(seconds=args.seconds, fps=fps, substeps=args.substeps, usd=args.out,
                   progress=not args.no_progress, chunk_frames=args.chunk_frames, resume=args.resume,
                   keep_checkpoint=args.keep_checkpoint, over=args.scene, flatten=args.flatten)
    kind = "stage" if args.flatten else f"animation layer over {args.scene}"
    print(f"wrote {path} ({round(args.seconds * fps)} frames, {kind}) in {time.perf_counter() - started:.2f} s "
          "wall time")
    return 0


def _grid(items: list[str]) -> dict:
    """--grid name=v1,v2,... options as a dict of lists: numbers where they parse, strings otherwise."""
    grid = {}
    for item in items:
        name, sep, values = item.partition("=")
        if not sep or not name.strip() or not values:
            raise ValueError(f"--grid {item!r} is invalid: expected name=value1,value2,...")
        grid[name.strip()] = [_number(value.strip()) for value in values.split(",")]
    return grid


def _number(text: str):
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _sweep(args) -> int:
    """warp-sim sweep: the variants of a script's build() over a grid, on a Dask cluster."""
    if not args.grid:
        raise ValueError("--grid is required: name=value1,value2,... (repeat it for more parameters)")

    def started(client):
        link = cluster.dashboard(client)
        if link:
            print(f"warp-sim sweep: Dask dashboard at {link}", flush=True)
    clock = time.perf_counter()
    result = sweep(args.script, _grid(args.grid), seconds=args.seconds, fps=args.fps, substeps=args.substeps,
                   integrator=args.integrator, out=args.out, workers=args.workers, device=args.device,
                   scheduler=args.scheduler, progress=not args.no_progress, on_start=started)
    print(result.table())
    print(f"in {time.perf_counter() - clock:.1f} s wall time")
    return 0 if all(row["status"] == "done" for row in result.rows) else 1


def _study(args) -> int:
    out = pathlib.Path(args.out or f"out/{args.study}")
    started = time.perf_counter()
    log = None if args.quiet else (lambda line: print(line, flush=True))
    where = {"workers": args.workers, "scheduler": args.scheduler}
    if args.study == "accuracy":
        result = studies.accuracy(problems=args.problems, integrators=args.integrators, quick=args.quick,
                                  device=args.device, repeats=args.repeats, log=log, **where)
    else:
        result = studies.stability(cases=args.cases, integrators=args.integrators, quick=args.quick,
                                   device=args.device, log=log, **where)
    images = result.plot(out)
    result.to_csv(out / f"{args.study}.csv")
    report = result.to_markdown(out / f"{args.study}.md", images=images)
    print(f"wrote {report}, {out / f'{args.study}.csv'} and {len(images)} plots"
          + ("" if images else " (matplotlib not installed: pip install 'warp-sim[plots]')")
          + f" in {time.perf_counter() - started:.1f} s wall time")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="warp-sim",
        description="Physically based animation in NVIDIA Warp kernels, written to USD stages.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    demo = commands.add_parser(
        "demo", help="simulate the demo scene and write it to a USD stage",
        description="Simulate particles bouncing on the ground, a spring chain hanging from a pinned "
                    "particle, rigid bodies thrown tumbling into the air and a particle fountain, and write "
                    "the animation to a USD stage.")
    _run_options(demo, fps=60.0, out="demo.usdc")
    demo.set_defaults(run=_demo)
    run = commands.add_parser(
        "run", help="simulate a UsdPhysics stage and write the animation as a layer over it",
        description="Read the rigid bodies, colliders, materials and warpSim cloth, particles and emitters of a "
                    "UsdPhysics stage (any units and up axis), simulate them, and write an animation layer of "
                    "overrides on the stage's own prims that sublayers it (or, with --flatten, one stage).")
    run.add_argument("scene", help="the input stage (.usd, .usda, .usdc)")
    _run_options(run, fps=None, out=None)
    run.add_argument("--precision", default="float32", choices=["float32", "float64"],
                     help="the simulated state's precision (default: float32)")
    run.add_argument("--flatten", action="store_true",
                     help="write one standalone stage (the input composed with the animation) instead of a layer")
    run.set_defaults(run=_run)
    sweeping = commands.add_parser(
        "sweep", help="run the variants of a scene over a grid of parameters, in parallel on a Dask cluster",
        description="Run build(**params) of a script for every combination of the --grid values, each variant a "
                    "task on a Dask worker (an embedded local cluster, or --scheduler), each written to "
                    "OUT/<variant>.usdc, with OUT/sweep.json and OUT/sweep.csv holding one row per variant (and "
                    "measure(sim) per variant when the script defines it). A rerun skips what is done.")
    sweeping.add_argument("script", help="a .py file defining build(**params) -> Scene, and optionally measure(sim)")
    sweeping.add_argument("--grid", action="append", default=[], metavar="NAME=V1,V2,...",
                          help="a parameter and its values (numbers where they parse, else strings); repeatable")
    sweeping.add_argument("--seconds", type=float, required=True, help="simulated seconds per variant")
    sweeping.add_argument("--fps", type=float, default=60.0, help="frames per second (default: 60)")
    sweeping.add_argument("--substeps", type=int, default=8, help="solver steps per frame (default: 8)")
    sweeping.add_argument("--integrator", default="rk4", choices=sorted(INTEGRATORS), help="ODE solver (default: rk4)")
    sweeping.add_argument("--device", default=None, help="Warp device on each worker (default: cuda when present)")
    _cluster_options(sweeping)
    sweeping.add_argument("--out", default="sweep", help="output folder (default: sweep)")
    sweeping.add_argument("--no-progress", action="store_true", help="no progress bar")
    sweeping.add_argument("--verbose", action="store_true", help="a traceback with any error")
    sweeping.set_defaults(run=_sweep)
    _study_parser(commands, INTEGRATORS)
    return parser


def _run_options(parser, fps: float | None, out: str | None) -> None:
    """The options demo and run share: device, solver, time, output, checkpoints, progress, verbosity."""
    parser.add_argument("--device", default=None,
                        help="Warp device, e.g. cpu or cuda:0 (default: cuda when present, else cpu)")
    parser.add_argument("--integrator", default="rk4", choices=sorted(INTEGRATORS), help="ODE solver (default: rk4)")
    parser.add_argument("--seconds", type=float, default=4.0, help="simulated seconds (default: 4)")
    parser.add_argument("--fps", type=float, default=fps,
                        help="frames per second of the output (default: " + (f"{fps:g})" if fps else
                                                                              "the stage's timeCodesPerSecond)"))
    parser.add_argument("--substeps", type=int, default=8, help="solver steps per frame (default: 8)")
    parser.add_argument("--out", default=out, required=out is None,
                        help="output stage, .usdc/.usd (binary) or .usda (text)" + (f" (default: {out})" if out
                                                                                     else ""))
    parser.add_argument("--rtol", type=float, default=None, help="rk45's relative tolerance (default: 1e-6)")
    parser.add_argument("--atol", type=float, default=None, help="rk45's absolute tolerance (default: 1e-8)")
    parser.add_argument("--chunk-frames", type=int, default=None, metavar="N",
                        help="frames per chunk written to disk with a checkpoint (default: 240, fewer for big scenes)")
    parser.add_argument("--resume", action="store_true",
                        help="go on from the checkpoint of an interrupted run to the same --out (else start over)")
    parser.add_argument("--keep-checkpoint", action="store_true",
                        help="keep the run's chunks and checkpoint beside the output when it completes")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--verbose", action="store_true",
                        help="show Warp's compilation messages, and a traceback with any error")


def _cluster_options(parser, alone: bool = False) -> None:
    parser.add_argument("--workers", type=int, default=None,
                        help="worker processes of an embedded local Dask cluster (default: "
                             + ("none: one process)" if alone else "the cores)"))
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run on this Dask scheduler instead (e.g. tcp://host:8786)")


def _study_parser(commands, integrators) -> None:
    study = commands.add_parser(
        "study", help="run the accuracy or the stability study and write its report",
        description="Run a study on the simulator itself and write a markdown report, a CSV and PNG plots "
                    "(plots need matplotlib).")
    kinds = study.add_subparsers(dest="study", required=True, metavar="STUDY")
    for name, text in (("accuracy", "error against run time and observed orders of every integrator on "
                                    "reference problems"),
                       ("stability", "the largest stable step of every integrator on stiff springs and "
                                     "extreme cases, by bisection, next to theory")):
        kind = kinds.add_parser(name, help=text, description=text[0].upper() + text[1:] + ".")
        kind.add_argument("--quick", action="store_true", help="fewer and coarser runs (under a minute)")
        kind.add_argument("--out", default=None, help=f"output folder (default: out/{name})")
        kind.add_argument("--device", default="cpu", help="Warp device, e.g. cpu or cuda:0 (default: cpu)")
        kind.add_argument("--integrators", nargs="+", metavar="NAME", choices=sorted(integrators),
                          help="integrators to study (default: all)")
        if name == "accuracy":
            kind.add_argument("--problems", nargs="+", metavar="NAME", choices=list(PROBLEMS),
                              help=f"problems (default: all): {', '.join(PROBLEMS)}")
            kind.add_argument("--repeats", type=int, default=3, help="timed runs per point (default: 3)")
        else:
            kind.add_argument("--cases", nargs="+", metavar="NAME", choices=list(CASES),
                              help=f"cases (default: all): {', '.join(CASES)}")
        kind.add_argument("--quiet", action="store_true", help="no progress lines")
        _cluster_options(kind, alone=True)
        kind.add_argument("--verbose", action="store_true",
                          help="show Warp's compilation messages, and a traceback with any error")
        kind.set_defaults(run=_study)


def _diverged(error: SimulationDiverged) -> str:
    kept = (f"; the {error.frames_written} frames before it are in {error.usd}" if error.usd is not None
            else "; no frame was written")
    return f"warp-sim: {error}{kept}"


def _kept(error: BaseException, then: str) -> str:
    """What an interrupted run left: its checkpoint and how to go on, or nothing."""
    frames = getattr(error, "frames_checkpointed", 0)
    if not frames:
        return "; nothing was written"
    return f"; its first {frames} frames are checkpointed: {then}run the same command with --resume to go on"


def main(argv=None) -> int:
    """Entry point of the `warp-sim` console script: one line and a non-zero exit for every expected failure
    (bad input 2, divergence or an unwritable output 1, Ctrl-C 130, SIGTERM 143; an interrupted run says how to
    resume), a traceback only with --verbose."""
    args = build_parser().parse_args(argv)
    verbose = getattr(args, "verbose", False)
    set_verbose(verbose)
    try:
        return args.run(args)
    except (ValueError, SimulationDiverged, OSError, KeyboardInterrupt, ImportError) as error:
        if verbose:
            raise
        if isinstance(error, KeyboardInterrupt):
            name = str(error) if isinstance(error, RunInterrupted) else "interrupted (Ctrl-C)"
            print(f"warp-sim: {name}{_kept(error, '')}", file=sys.stderr)
            return error.exit_code if isinstance(error, RunInterrupted) else 130
        if isinstance(error, SimulationDiverged):
            print(_diverged(error), file=sys.stderr)
            return 1
        kept = _kept(error, "free some space (or fix the cause), then ") if isinstance(error, OSError) else ""
        print(f"warp-sim: error: {error}{'' if kept == '; nothing was written' else kept}", file=sys.stderr)
        return 2 if isinstance(error, (ValueError, ImportError)) else 1


if __name__ == "__main__":
    sys.exit(main())

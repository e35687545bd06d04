"""The `warp-sim` command (and ``python -m warp_sim``).

Every argument is checked before anything is printed or built: the numbers by their argparse types, then the
paths, the device and their combinations (``_check``), each refusal one line naming the flag or the path as typed
(exit 2). A ValueError from the library is said in the command line's words too: its parameter names become the
flags that fed them (FLAGS). Warp starts with its "no CUDA driver" line kept off stderr (``_start_warp``).
"""
from __future__ import annotations

import argparse
import functools
import math
import os
import pathlib
import re
import signal
import subprocess
import sys
import threading
import time
import warnings

import warp as wp

from . import cluster, studies
from .core import compiling
from .core.guards import SimulationDiverged
from .demo import JOINT_STEP, demo_scene
from .examples import command as example_command
from .scene import Scene
from .simulator import RunInterrupted, Simulator
from .solvers import INTEGRATORS, RK45
from .stages.folders import folder_problem
from .stages.inputs import overwrite_problem
from .stages.specs import USD_EXTENSIONS
from .studies import CASES, PROBLEMS
from .sweep import sweep
from .util import interrupts
from .util.verbosity import set_verbose
from .util.version import __version__

#: the library's parameter names, and the command line's words for what fed them
FLAGS = {"seconds": "--seconds", "fps": "--fps", "substeps": "--substeps", "usd": "--out", "device": "--device",
         "chunk_frames": "--chunk-frames", "rtol": "--rtol", "atol": "--atol", "integrator": "--integrator",
         "precision": "--precision", "workers": "--workers", "repeats": "--repeats", "path_or_stage": "scene",
         "script": "script", "arches": "--cuda-arch", "outputs": "--cuda-output", "folder": "--out"}
#: --fps defaults to the stage's time codes per second [1/s] up to MAX_DEFAULT_FPS, else to FALLBACK_FPS (said)
MAX_DEFAULT_FPS, FALLBACK_FPS = 240.0, 60.0
#: the first words of Warp's line at start-up on a machine without the NVIDIA driver (printed by its native library)
DRIVER_WARNING = b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver"


class UsageError(ValueError):
    """A bad command line, said in its own terms: the flag or the path, and the value as typed."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):   # argparse's usage lines and exit, as one line (main prints it)
        raise UsageError(f"{message} (see {self.prog} --help)")


def _in_cli_terms(message: str) -> str:
    """A library message with its parameter names (``seconds=-1``) as the flags that fed them (``--seconds -1``)."""
    return re.sub(r"(?<![\w-])(\w+)=", lambda m: f"{FLAGS[m.group(1)]} " if m.group(1) in FLAGS else m.group(0),
                  message)


# argument types: each refusal is "<value> is invalid: <what is valid>", argparse adds "argument --flag: "
def _positive(text: str) -> float:
    number = _number(text)
    if isinstance(number, str) or not (math.isfinite(number) and number > 0):
        raise argparse.ArgumentTypeError(f"{text} is invalid: expected a number > 0")
    return float(number)


def _count(text: str) -> int:
    number = _number(text)
    if not isinstance(number, int) or number < 1:
        raise argparse.ArgumentTypeError(f"{text} is invalid: expected a whole number >= 1")
    return number


def _substeps(text: str):
    number = _number(text)
    if text != "auto" and not (isinstance(number, int) and number >= 1):
        raise argparse.ArgumentTypeError(f"{text} is invalid: expected auto or a whole number >= 1")
    return number


def _arches(text: str) -> list[int]:
    arches = []
    for item in text.split(","):
        found = re.fullmatch(r"\s*(?:sm_?)?(\d+)\s*", item)
        if found is None:
            raise argparse.ArgumentTypeError(f"{text} is invalid: expected architectures such as sm_80,sm_90")
        arches.append(int(found.group(1)))
    return arches


def _start_warp(verbose: bool) -> bool:
    """``wp.init()`` with Warp's line that it found no NVIDIA CUDA driver kept off stderr (unless verbose): it is
    written by Warp's native library as it starts, and says nothing a CPU run needs. Everything else written to
    stderr meanwhile passes through as it comes. Returns whether that line came (no driver)."""
    seen = []
    sys.stderr.flush()
    try:
        saved = None if verbose else os.dup(2)
    except OSError:   # no stderr to keep clean
        saved = None
    if saved is None:
        wp.init()
        return False
    read, write = os.pipe()

    def forward():
        with os.fdopen(read, "rb") as pipe:
            for line in pipe:
                if line.startswith(DRIVER_WARNING):
                    seen.append(line)
                else:
                    os.write(saved, line)
    thread = threading.Thread(target=forward, name="warp-sim stderr", daemon=True)
    thread.start()
    os.dup2(write, 2)
    os.close(write)
    try:
        wp.init()
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)   # the pipe's last write end closes: the thread reads to its end
        thread.join()
        os.close(saved)
    return bool(seen)


def _check_device(device: str | None, no_driver: bool) -> None:
    if device is None:
        return
    aliases = [d.alias for d in wp.get_devices()]
    gpus = wp.get_cuda_device_count()
    if device in aliases or (device == "cuda" and gpus):
        return
    if device == "cuda" or device.startswith("cuda:"):
        if not gpus:
            why = " (the NVIDIA CUDA driver could not be loaded)" if no_driver else ""
            raise UsageError(f"--device {device}: no CUDA device found; use --device cpu{why}")
        raise UsageError(f"--device {device}: no such device; this machine has {', '.join(aliases)}")
    raise UsageError(f"--device {device} is invalid: expected cpu, cuda or cuda:N (this machine has "
                     f"{', '.join(aliases)})")


def _check_out(out: str) -> None:
    """--out: a USD file path (no extension: .usdc) that is not a folder, in a folder that exists or can be made
    in a writable one."""
    given = pathlib.Path(out)
    path = given if given.suffix else given.with_suffix(".usdc")
    if path.suffix.lower() not in USD_EXTENSIONS:
        raise UsageError(f"--out {out} is invalid: expected a file ending in {', '.join(USD_EXTENSIONS)}")
    if given.is_dir() or path.is_dir():
        raise UsageError(f"--out {out} is an existing folder; give a file path such as {given / 'out.usdc'}")
    folder = path.absolute().parent
    while not folder.exists():
        folder = folder.parent
    if not folder.is_dir():
        raise UsageError(f"--out {out} is invalid: {folder} is a file, not a folder")
    if not os.access(folder, os.W_OK):
        raise UsageError(f"--out {out}: cannot write in {folder}")


def _check_frames(seconds: float, fps: float) -> None:
    if round(seconds * fps) < 1:
        raise UsageError(f"--seconds {seconds:g} covers no frame at --fps {fps:g}; give --seconds >= {0.5 / fps:g}")


def _check_file(path: str) -> None:
    if not pathlib.Path(path).is_file():
        raise UsageError(f"{path}: " + ("is a folder, not a file" if pathlib.Path(path).is_dir() else "no such file"))


def _check_not_an_input(out: str, scene: str) -> None:
    """--out is neither the input stage nor a file it reads (its layers, references, payloads: stages.inputs)."""
    problem = overwrite_problem(pathlib.Path(out if pathlib.Path(out).suffix else f"{out}.usdc"), scene,
                                f"the input {scene}")
    if problem is not None:
        raise UsageError(f"--out {out} is invalid: {problem}")


def _check_arches(arches: list[int]) -> None:
    supported = wp.get_cuda_supported_archs()
    if not supported:
        raise UsageError("--cuda-arch: this build of Warp has no CUDA compiler (NVRTC); prepare for the CPU only")
    bad = [arch for arch in arches if arch not in supported]
    if bad:
        raise UsageError(f"--cuda-arch {','.join(f'sm_{arch}' for arch in bad)} is invalid: Warp "
                         f"{wp.config.version} compiles for {', '.join(f'sm_{arch}' for arch in supported)}")


def _check(args, no_driver: bool) -> None:
    """Every argument the argparse types cannot check alone, before anything is printed or built."""
    _check_device(getattr(args, "device", None) if getattr(args, "scheduler", None) is None else None, no_driver)
    if args.command in ("demo", "run"):
        _check_out(args.out)
        if args.fps is not None:
            _check_frames(args.seconds, args.fps)
        if (args.rtol is not None or args.atol is not None) and args.integrator != "rk45":
            raise UsageError(f"--rtol/--atol are rk45's tolerances; --integrator {args.integrator} takes none")
    if args.command == "run":
        _check_file(args.scene)
        _check_not_an_input(args.out, args.scene)
    if args.command == "prepare" and args.cuda_arch:
        _check_arches(args.cuda_arch)
    if args.command == "sweep":
        _check_file(args.script)
        _check_frames(args.seconds, args.fps)
        if not args.grid:
            raise UsageError("--grid is required: name=value1,value2,... (repeat it for more parameters)")
    if args.command in ("sweep", "study", "example"):   # made now, or refused: before minutes of work, not after
        out = args.out or f"out/{args.study}"
        problem = folder_problem(out)
        if problem is not None:
            raise UsageError(f"--out {out} is invalid: {problem}")


def _integrator(args):
    """The solver the options name: rk45 with --rtol/--atol, or a name."""
    options = {key: value for key, value in (("rtol", args.rtol), ("atol", args.atol)) if value is not None}
    return RK45(**options) if options else args.integrator


def _substeps_text(sim: Simulator, substeps, fps: float) -> str:
    return f"auto substeps ({sim.substeps(1.0 / fps)} per frame)" if substeps == "auto" else f"{substeps} substeps"


def _process_age() -> float:
    """Seconds since this process started (its interpreter and imports too), from /proc; 0 where there is none."""
    try:
        ticks = int(pathlib.Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()[19])   # field 22
        return max(0.0, float(pathlib.Path("/proc/uptime").read_text().split()[0]) - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, AttributeError):
        return 0.0


def _wall_time(args) -> str:
    """Seconds since the command started, and how many of them compiled kernels (if any)."""
    compiled = compiling.seconds_compiling() - args.compiled_before
    return (f"{time.perf_counter() - args.started:.2f} s wall time"
            + (f", of which {compiled:.1f} s compiling kernels (once)" if compiled > 0 else ""))


def _demo(args) -> int:
    sim = Simulator(demo_scene(), integrator=_integrator(args), device=args.device, joint_step=JOINT_STEP)
    print(f"warp-sim demo: {sim.scene!r} on {sim.device.alias}, {args.integrator}, "
          f"{args.seconds:g} s at {args.fps:g} fps x {_substeps_text(sim, args.substeps, args.fps)}", flush=True)
    path = sim.run(seconds=args.seconds, fps=args.fps, substeps=args.substeps, usd=args.out,
                   progress=not args.no_progress, chunk_frames=args.chunk_frames, resume=args.resume,
                   keep_checkpoint=args.keep_checkpoint)
    print(f"wrote {path} ({round(args.seconds * args.fps)} frames) in {_wall_time(args)}")
    return 0


def _run(args) -> int:
    """warp-sim run: a UsdPhysics stage simulated into an animation layer over it (or one flattened stage)."""
    scene = Scene.from_usd(args.scene, precision=args.precision)
    fps = args.fps or scene.usd_source.time_codes_per_second
    if args.fps is None and fps > MAX_DEFAULT_FPS:   # Newton's 1000: 60 fps, said (the overlay keeps the 1000)
        print(f"{args.scene}: {fps:g} time codes per second; running at {FALLBACK_FPS:g} fps (--fps to choose)")
        fps = FALLBACK_FPS
    _check_frames(args.seconds, fps)
    sim = Simulator(scene, integrator=_integrator(args), device=args.device)
    print(f"warp-sim run: {args.scene} -> {sim.scene!r} on {sim.device.alias}, {args.integrator}, "
          f"{args.seconds:g} s at {fps:g} fps x {_substeps_text(sim, args.substeps, fps)}", flush=True)
    path = sim.run(seconds=args.seconds, fps=fps, substeps=args.substeps, usd=args.out,
                   progress=not args.no_progress, chunk_frames=args.chunk_frames, resume=args.resume,
                   keep_checkpoint=args.keep_checkpoint, over=args.scene, flatten=args.flatten)
    kind = "stage" if args.flatten else f"animation layer over {args.scene}"
    print(f"wrote {path} ({round(args.seconds * fps)} frames, {kind}) in {_wall_time(args)}")
    return 0


def _prepare(args) -> int:
    """warp-sim prepare: every kernel module into Warp's kernel cache, for the CPU and --cuda-arch; each precision
    in a process of its own (a module's cache entry holds the overloads its process declared: one precision)."""
    targets = ", ".join(["cpu"] + [f"sm_{arch}" for arch in args.cuda_arch or []])
    if args.precision == "both":
        passed = ["--cuda-output", args.cuda_output]
        passed += ["--cuda-arch", ",".join(map(str, args.cuda_arch))] if args.cuda_arch else []
        passed += ["--workers", str(args.workers)] if args.workers else []
        passed += ["--verbose"] if args.verbose else []
        for precision in ("float32", "float64"):
            code = subprocess.call([sys.executable, "-m", "warp_sim", "prepare", "--precision", precision, *passed])
            if code:
                return code
        print(f"prepared every kernel module for {targets} in float32 and float64 in {_wall_time(args)}; "
              f"Warp's kernel cache: {wp.config.kernel_cache_dir}")
        return 0
    outputs = compiling.CUDA_OUTPUTS if args.cuda_output == "both" else (args.cuda_output,)

    def report(row):
        name, target, what, seconds = row
        print(f"  {args.precision} {target:>5} {name:<16} {what}" + (f" in {seconds:.1f} s" if seconds else ""),
              flush=True)

    rows = compiling.prepare(args.precision, arches=args.cuda_arch or [], workers=args.workers, outputs=outputs,
                             report=report)
    compiled = sum(1 for row in rows if row[2] != "cached")
    print(f"{args.precision}: {len({row[0] for row in rows})} kernel modules for {targets}: {compiled} compiled, "
          f"{len(rows) - compiled} cached, in {_wall_time(args)}; Warp's kernel cache: {wp.config.kernel_cache_dir}",
          flush=True)
    return 0


def _grid(items: list[str]) -> dict:
    """--grid name=v1,v2,... options as a dict of lists: numbers where they parse, strings otherwise."""
    grid = {}
    for item in items:
        name, sep, values = item.partition("=")
        if not sep or not name.strip() or not values:
            raise UsageError(f"--grid {item} is invalid: expected name=value1,value2,...")
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
    grid = _grid(args.grid)

    def started(client):
        if args.scheduler is None:   # the command's own workers: their warnings one line each too
            client.run(_worker_warnings, args.verbose)
        link = cluster.dashboard(client)
        if link:
            print(f"warp-sim sweep: Dask dashboard at {link}", flush=True)
    result = sweep(args.script, grid, seconds=args.seconds, fps=args.fps, substeps=args.substeps,
                   integrator=args.integrator, out=args.out, workers=args.workers, device=args.device,
                   scheduler=args.scheduler, progress=not args.no_progress, on_start=started)
    print(result.table())
    print(f"in {_wall_time(args)}")
    return 0 if all(row["status"] == "done" for row in result.rows) else 1


def _worker_warnings(verbose: bool) -> None:
    """On a worker process of the command's own Dask cluster: its warnings shown as the command's (_one_line)."""
    warnings.showwarning = functools.partial(_one_line, verbose=verbose)


def _study(args) -> int:
    out = pathlib.Path(args.out or f"out/{args.study}")
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
          + f" in {_wall_time(args)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="warp-sim",
                     description="Physically based animation in NVIDIA Warp kernels, written to USD stages.")
    parser.add_argument("--version", action="version", version=f"warp-sim {__version__} (Warp {wp.config.version})")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    demo = commands.add_parser(
        "demo", help="simulate the demo scene and write it to a USD stage",
        description="Simulate particles bouncing on the ground, a spring chain hanging from a pinned "
                    "particle, rigid bodies thrown tumbling into the air, a chain of capsules on ball joints "
                    "swinging from a pivot and a particle fountain, and write the animation to a USD stage.")
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
    example_command.add_parser(commands)
    _prepare_parser(commands)
    _sweep_parser(commands)
    _study_parser(commands, INTEGRATORS)
    return parser


def _run_options(parser, fps: float | None, out: str | None) -> None:
    """The options demo and run share: device, solver, time, output, checkpoints, progress, verbosity."""
    parser.add_argument("--device", default=None,
                        help="Warp device, e.g. cpu or cuda:0 (default: cuda when present, else cpu)")
    parser.add_argument("--integrator", default="rk4", choices=sorted(INTEGRATORS), help="ODE solver (default: rk4)")
    parser.add_argument("--seconds", type=_positive, default=4.0, help="simulated seconds (default: 4)")
    shown = f"{fps:g}" if fps else f"the stage's timeCodesPerSecond up to {MAX_DEFAULT_FPS:g}, else {FALLBACK_FPS:g}"
    parser.add_argument("--fps", type=_positive, default=fps,
                        help=f"frames per second of the output (default: {shown})")
    parser.add_argument("--substeps", type=_substeps, default="auto", metavar="{auto,N}",
                        help="solver steps per frame: auto (default: as many as the scene's stiffest springs and "
                             "contacts need to stay stable, shown when it starts) or a whole number")
    parser.add_argument("--out", default=out, required=out is None,
                        help="output stage, .usdc/.usd (binary) or .usda (text)" + (f" (default: {out})" if out
                                                                                     else ""))
    parser.add_argument("--rtol", type=_positive, default=None, help="rk45's relative tolerance (default: 1e-6)")
    parser.add_argument("--atol", type=_positive, default=None, help="rk45's absolute tolerance (default: 1e-8)")
    parser.add_argument("--chunk-frames", type=_count, default=None, metavar="N",
                        help="frames per chunk written to disk with a checkpoint (default: 240, fewer for big scenes)")
    parser.add_argument("--resume", action="store_true",
                        help="go on from the checkpoint of an interrupted run to the same --out (else start over)")
    parser.add_argument("--keep-checkpoint", action="store_true",
                        help="keep the run's chunks and checkpoint beside the output when it completes")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--verbose", action="store_true",
                        help="show Warp's start-up and compilation messages, and a traceback with any error")


def _prepare_parser(commands) -> None:
    prepare = commands.add_parser(
        "prepare", help="compile every kernel module ahead of time into Warp's kernel cache (e.g. in a container)",
        description="Compile every kernel module of warp_sim into Warp's kernel cache (~/.cache/warp/<version>, or "
                    "the folder in WARP_CACHE_PATH) for this machine's CPU, in float32 and float64 (each in a "
                    "process of its own), and with --cuda-arch for those CUDA architectures too (NVRTC compiles "
                    "them without a GPU or a driver): a later run then compiles nothing. One line per module and "
                    "target, and a total.")
    prepare.add_argument("--precision", default="both", choices=["float32", "float64", "both"],
                         help="the precision to compile (default: both)")
    prepare.add_argument("--cuda-arch", type=_arches, default=None, metavar="ARCHES",
                         help="CUDA architectures to compile for as well, e.g. sm_80,sm_90 (default: none)")
    prepare.add_argument("--cuda-output", default="both", choices=["ptx", "cubin", "both"],
                         help="what to compile for CUDA: Warp loads PTX where the driver is as new as its CUDA "
                              "toolkit, else CUBIN (default: both)")
    prepare.add_argument("--workers", type=_count, default=None,
                         help="modules compiled at once (default: the available cores, or WARP_SIM_CPU_THREADS)")
    prepare.add_argument("--verbose", action="store_true",
                         help="show Warp's start-up and compilation messages, and a traceback with any error")
    prepare.set_defaults(run=_prepare)


def _sweep_parser(commands) -> None:
    sweeping = commands.add_parser(
        "sweep", help="run the variants of a scene over a grid of parameters, in parallel on a Dask cluster",
        description="Run build(**params) of a script for every combination of the --grid values, each variant a "
                    "task on a Dask worker (an embedded local cluster, or --scheduler), each written to "
                    "OUT/<variant>.usdc, with OUT/sweep.json and OUT/sweep.csv holding one row per variant (and "
                    "measure(sim) per variant when the script defines it). A rerun skips what is done.")
    sweeping.add_argument("script", help="a .py file defining build(**params) -> Scene, and optionally measure(sim)")
    sweeping.add_argument("--grid", action="append", default=[], metavar="NAME=V1,V2,...",
                          help="a parameter and its values (numbers where they parse, else strings); repeatable")
    sweeping.add_argument("--seconds", type=_positive, required=True, help="simulated seconds per variant")
    sweeping.add_argument("--fps", type=_positive, default=60.0, help="frames per second (default: 60)")
    sweeping.add_argument("--substeps", type=_substeps, default="auto", metavar="{auto,N}",
                          help="solver steps per frame: auto (default: as many as each variant needs to stay "
                               "stable) or a whole number")
    sweeping.add_argument("--integrator", default="rk4", choices=sorted(INTEGRATORS), help="ODE solver (default: rk4)")
    sweeping.add_argument("--device", default=None, help="Warp device on each worker (default: cuda when present)")
    _cluster_options(sweeping)
    sweeping.add_argument("--out", default="sweep", help="output folder (default: sweep)")
    sweeping.add_argument("--no-progress", action="store_true", help="no progress bar")
    sweeping.add_argument("--verbose", action="store_true", help="a traceback with any error")
    sweeping.set_defaults(run=_sweep)


def _cluster_options(parser, alone: bool = False) -> None:
    parser.add_argument("--workers", type=_count, default=None,
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
            kind.add_argument("--repeats", type=_count, default=3, help="timed runs per point (default: 3)")
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
    if getattr(error, "complete", False):
        return f"; {error.usd} was already written whole"
    frames = getattr(error, "frames_checkpointed", 0)
    if not frames:
        return "; nothing was written"
    return f"; its first {frames} frames are checkpointed: {then}run the same command with --resume to go on"


def _interrupted(error: BaseException) -> int:
    """The one line of a stopped command (the signal, what was kept) and its exit status, 128 + the signal."""
    signum = error.signal if isinstance(error, RunInterrupted) else interrupts.pending() or signal.SIGINT
    name = "interrupted (Ctrl-C)" if signum == signal.SIGINT else f"interrupted by {signal.Signals(signum).name}"
    print(f"warp-sim: {name}{_kept(error, '')}", file=sys.stderr)
    return 128 + signum


def _one_line(message, category, filename, lineno, file=None, line=None, verbose=False) -> None:
    """A warning as one line in the command line's words, never its source line (--verbose: where, at its end)."""
    where = f" ({category.__name__} at {filename}:{lineno})" if verbose else ""
    print(f"warp-sim: warning: {' '.join(_in_cli_terms(str(message)).split())}{where}",
          file=sys.stderr if file is None else file)


def main(argv=None) -> int:
    """Entry point of the `warp-sim` console script and of ``python -m warp_sim``: one line and a non-zero exit
    for every expected failure (a bad command line or input 2, divergence or an unwritable output 1, Ctrl-C 130,
    SIGTERM 143, from the first instant: util.interrupts; an interrupted run says how to resume), a traceback
    only with --verbose; every argument is checked before anything is printed or built."""
    # the command's wall time: from the process's start for the console script, from this call when called
    started = time.perf_counter() - (_process_age() if argv is None else 0.0)
    argv = sys.argv[1:] if argv is None else [str(item) for item in argv]
    verbose = "--verbose" in argv
    try:
        with interrupts.armed():   # a signal while warp_sim imported stops it here, before anything is touched
            return _main(argv, started, verbose)
    except KeyboardInterrupt as error:
        if verbose:
            raise
        return _interrupted(error)


def _main(argv: list[str], started: float, verbose: bool) -> int:
    compiled_before = compiling.seconds_compiling()
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as done:   # --help, --version
        return done.code if isinstance(done.code, int) else 0
    except UsageError as error:
        print(f"warp-sim: error: {error}", file=sys.stderr)
        return 2
    args.started, args.compiled_before = started, compiled_before
    set_verbose(verbose)
    try:
        with warnings.catch_warnings():   # showwarning and the filters back at the end
            warnings.showwarning = functools.partial(_one_line, verbose=verbose)
            _check(args, _start_warp(verbose) if args.command != "example" else False)
            return args.run(args)
    except Exception as error:
        if verbose:
            raise
        if interrupts.pending() is not None:   # a Ctrl-C a library caught, surfacing as another error
            return _interrupted(error)
        if isinstance(error, SimulationDiverged):
            print(_diverged(error), file=sys.stderr)
            return 1
        if not isinstance(error, (ValueError, OSError, ImportError)):
            raise
        kept = _kept(error, "free some space (or fix the cause), then ") if isinstance(error, OSError) else ""
        text = str(error) if isinstance(error, UsageError) else _in_cli_terms(str(error))
        print(f"warp-sim: error: {text}{'' if kept == '; nothing was written' else kept}", file=sys.stderr)
        return 2 if isinstance(error, (ValueError, ImportError)) else 1


if __name__ == "__main__":
    sys.exit(main())

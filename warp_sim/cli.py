"""The `warp-sim` command."""
from __future__ import annotations

import argparse
import sys
import time


def _demo(args) -> int:
    from .demo import demo_scene
    from .simulator import Simulator

    sim = Simulator(demo_scene(), integrator=args.integrator, device=args.device)
    print(f"warp-sim demo: {sim.model.scene!r} on {sim.device.alias}, {args.integrator}, "
          f"{args.seconds:g} s at {args.fps:g} fps x {args.substeps} substeps")
    started = time.perf_counter()
    path = sim.run(seconds=args.seconds, fps=args.fps, substeps=args.substeps, usd=args.out,
                   progress=not args.no_progress)
    elapsed = time.perf_counter() - started
    print(f"wrote {path} ({round(args.seconds * args.fps)} frames) in {elapsed:.2f} s wall time")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from .integrators import INTEGRATORS

    parser = argparse.ArgumentParser(
        prog="warp-sim",
        description="Physically based animation in NVIDIA Warp kernels, written to USD stages.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    demo = commands.add_parser(
        "demo", help="simulate the demo scene and write it to a USD stage",
        description="Simulate particles bouncing on the ground, a spring chain hanging from a pinned "
                    "particle, rigid bodies thrown tumbling into the air and a particle fountain, and write "
                    "the animation to a USD stage.")
    demo.add_argument("--device", default=None,
                      help="Warp device, e.g. cpu or cuda:0 (default: cuda when present, else cpu)")
    demo.add_argument("--integrator", default="rk4", choices=sorted(INTEGRATORS),
                      help="ODE solver (default: rk4)")
    demo.add_argument("--seconds", type=float, default=4.0, help="simulated seconds (default: 4)")
    demo.add_argument("--fps", type=float, default=60.0, help="frames per second of the stage (default: 60)")
    demo.add_argument("--substeps", type=int, default=8, help="solver steps per frame (default: 8)")
    demo.add_argument("--out", default="demo.usdc",
                      help="output stage, .usdc/.usd (binary) or .usda (text) (default: demo.usdc)")
    demo.add_argument("--no-progress", action="store_true", help="no progress bar")
    demo.add_argument("--verbose", action="store_true", help="show Warp's compilation messages")
    demo.set_defaults(run=_demo)
    return parser


def main(argv=None) -> int:
    """Entry point of the `warp-sim` console script."""
    args = build_parser().parse_args(argv)
    import warp as wp

    wp.config.log_level = wp.LOG_INFO if args.verbose else wp.LOG_WARNING
    try:
        return args.run(args)
    except ValueError as error:
        print(f"warp-sim: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

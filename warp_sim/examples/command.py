"""``warp-sim example NAME --out DIR``: an example stage, and every file it reads, copied into a folder of one's
own; prints the stage's new path (``warp-sim run PATH`` then simulates it)."""
from __future__ import annotations

from . import copy, names


def add_parser(commands) -> None:
    """The ``example`` command on the CLI's subparsers (a bad NAME: argparse's one line listing the names)."""
    example = commands.add_parser(
        "example", help="copy an example stage shipped with warp_sim into a folder, to run or open",
        description="Copy an example UsdPhysics stage shipped inside the package (and every file it reads) into a "
                    "folder, and print its path: warp-sim run PATH then simulates it.")
    example.add_argument("name", choices=names(), metavar="NAME", help=f"the example: {', '.join(names())}")
    example.add_argument("--out", default=".", help="the folder to write it in, made if missing (default: .)")
    example.add_argument("--verbose", action="store_true", help="a traceback with any error")
    example.set_defaults(run=run)


def run(args) -> int:
    """Copy the example ``args.name`` into ``args.out`` and print its path; exit status 0."""
    print(copy(args.name, args.out))
    return 0

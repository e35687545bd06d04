"""``python -m warp_sim``: the `warp-sim` command (warp_sim.cli)."""
import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())

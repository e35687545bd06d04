"""How much Warp prints: nothing by default, its banner and module-load lines when asked for.

Importing warp_sim sets Warp quiet (``wp.config.quiet``, and its log level to warnings), so a
script's output is its own; ``ws.set_verbose(True)`` (or ``warp-sim ... --verbose``) shows
Warp's initialisation banner and each module's "load ... (compiled)" line again. Warp's own
configuration, set after the import, wins as usual.
"""
from __future__ import annotations

import warp as wp

__all__ = ["set_verbose"]


def set_verbose(verbose: bool = True) -> None:
    """Show (True) or hide (False) Warp's banner and its module-load and compilation messages."""
    if not isinstance(verbose, bool):
        raise ValueError(f"verbose={verbose!r} is invalid: expected True or False")
    wp.config.quiet = not verbose
    wp.config.log_level = wp.LOG_INFO if verbose else wp.LOG_WARNING
    wp.config.verbose = False


set_verbose(False)

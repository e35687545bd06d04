"""No signal is lost: Ctrl-C (SIGINT) and SIGTERM recorded while warp_sim imports, and held while an output is
renamed into place.

Libraries catch a KeyboardInterrupt raised while they load and carry on as if nothing happened: pxr's script
module loader prints its traceback as a warning ("Error loading lib vt's module 'pxr.Vt'", "Error occurred
postprocessing module pxr.Gf._gf") and goes on; trimesh keeps an ``ExceptionWrapper`` in place of an optional
module (scipy's) whose import was interrupted, which fails later with a TypeError. A Ctrl-C in the first second of
``warp-sim`` went unseen that way, and the run then overwrote the output the user meant to keep. So:

- ``defer()``, called as this module is imported, the first thing ``import warp_sim`` does: SIGINT (and, in the
  ``warp-sim`` command, SIGTERM) only records its number (``record``) while the libraries load, so nothing can
  swallow it;
- ``release()``, the last thing it does: in a library user's process the previous handlers come back and a
  recorded Ctrl-C raises KeyboardInterrupt there, at the end of the import; in the command the recording goes on
  until ``warp_sim.cli.main`` takes over, which says "interrupted" and exits 130 (143) before touching anything;
- ``armed()``: the command's handling while its ``main`` runs: what was recorded raises at once, later signals
  raise and are recorded too;
- ``pending()``: the first signal recorded (None: none), which a run checks before it opens its output
  (``raise_pending``);
- ``interruptions()``: SIGTERM raises ``RunInterrupted`` inside a run, as Ctrl-C raises KeyboardInterrupt;
- ``held()``: SIGINT and SIGTERM wait while the block runs (the rename of a finished stage onto the user's path,
  so the path holds the old file or the whole new one) and are delivered to their own handlers after it.

Only the main thread handles signals; elsewhere every function here does nothing.
"""
from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

__all__ = ["RunInterrupted", "armed", "defer", "held", "interruptions", "is_command", "pending", "raise_pending",
           "record", "release"]

#: the modules that are the command when run with ``python -m``
COMMAND_MODULES = ("warp_sim", "warp_sim.cli", "warp_sim.__main__")
#: the command's console script (pip's launcher on Windows adds -script.py or .exe)
COMMAND_SCRIPT = "warp-sim"
#: the interpreter's options that take a value (``-X importtime``, ``-W ignore``)
VALUED_OPTIONS = ("-X", "-W", "-Q")

_recorded: list[int] = []
_previous: dict[int, object] = {}


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by a signal: SIGINT (Ctrl-C) or SIGTERM (``timeout``, a scheduler, a container stop).

    signal: the signal's number; exit_code: what a process should exit with, 128 + signal (130, 143)."""

    def __init__(self, signum: int):
        self.signal, self.exit_code = signum, 128 + signum
        super().__init__(f"interrupted by {signal.Signals(signum).name}")


def record(signum: int, _frame=None) -> None:
    """A signal handler that only records the signal's number."""
    _recorded.append(signum)


def pending() -> int | None:
    """The number of the first signal recorded and not yet cleared, or None."""
    return _recorded[0] if _recorded else None


def raise_pending() -> None:
    """RunInterrupted for a signal recorded and not raised since (a library may have swallowed its
    KeyboardInterrupt): a run calls it before it opens its output and before its final stitch."""
    signum = pending()
    if signum is not None:
        raise RunInterrupted(signum)


def is_command() -> bool:
    """Whether this process is the ``warp-sim`` command: its console script, or ``python -m warp_sim`` (or
    ``warp_sim.cli``), read from the interpreter's own command line (``sys.orig_argv``)."""
    script = os.path.basename(sys.argv[0]) if sys.argv else ""
    if script == COMMAND_SCRIPT or script.startswith(f"{COMMAND_SCRIPT}-script.") or script == f"{COMMAND_SCRIPT}.exe":
        return True
    argv = list(getattr(sys, "orig_argv", []))[1:]
    skip = False
    for k, item in enumerate(argv):
        if skip:
            skip = False
        elif item == "-m":
            return k + 1 < len(argv) and argv[k + 1] in COMMAND_MODULES
        elif item.startswith("-m"):
            return item[2:] in COMMAND_MODULES
        elif item in VALUED_OPTIONS:
            skip = True
        elif not item.startswith("-") or item == "-c":
            return False
    return False


def _main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def defer() -> None:
    """While warp_sim imports: SIGINT (and SIGTERM in the command) recorded instead of raised, where they still have
    Python's default handling (an ignored SIGINT stays ignored)."""
    if not _main_thread():
        return
    signums = (signal.SIGINT, signal.SIGTERM) if is_command() else (signal.SIGINT,)
    for signum in signums:
        if signal.getsignal(signum) in (signal.default_int_handler, signal.SIG_DFL):
            _previous[signum] = signal.signal(signum, record)


def release() -> None:
    """The end of warp_sim's import: in the command, the recording goes on (``armed`` takes over); elsewhere the
    previous handlers come back and a Ctrl-C recorded meanwhile raises KeyboardInterrupt now."""
    if not _main_thread() or is_command():
        return
    for signum, previous in _previous.items():
        if signal.getsignal(signum) is record:
            signal.signal(signum, previous)
    _previous.clear()
    if _recorded:
        _recorded.clear()
        raise KeyboardInterrupt


@contextlib.contextmanager
def interruptions():
    """SIGTERM raises RunInterrupted inside the block, as Ctrl-C raises KeyboardInterrupt, so a run cleans up
    the same way for both. Only in the main thread (where Python delivers signals); elsewhere a no-op."""
    if not _main_thread():
        yield
        return

    def stop(signum, _frame):
        raise RunInterrupted(signum)

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def armed():
    """The command's handling for its whole ``main``: a signal recorded before it (while warp_sim imported) raises
    RunInterrupted at once; inside it, SIGINT raises KeyboardInterrupt and SIGTERM RunInterrupted, and both are
    recorded too (``pending``), so one that a library swallows still stops the run before it touches its output.
    At the end the handlers before it come back (in the command itself, SIG_IGN: the work is done and its status
    known, and Python's own exit would put back the default action, a kill) and the record is cleared."""
    if not _main_thread():
        yield
        return

    def stop(signum, _frame):
        record(signum)
        raise KeyboardInterrupt if signum == signal.SIGINT else RunInterrupted(signum)

    previous = {signum: signal.signal(signum, stop) for signum in (signal.SIGINT, signal.SIGTERM)
                if signal.getsignal(signum) not in (signal.SIG_IGN, None)}   # an ignored signal stays ignored
    try:
        raise_pending()
        yield
    finally:   # the command has its exit status: a signal from now on (Python's exit included) changes nothing
        for signum, handler in previous.items():
            signal.signal(signum, signal.SIG_IGN if is_command() else handler)
        _recorded.clear()


@contextlib.contextmanager
def held():
    """SIGINT and SIGTERM wait while the block runs, then go to the handlers they had (raised at once after the
    block, in the order they came). Handlers set outside Python are left alone."""
    if not _main_thread():
        yield
        return
    came: list[int] = []
    previous = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(signum) is not None:
            previous[signum] = signal.signal(signum, lambda number, _frame: came.append(number))
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum in came:
            signal.raise_signal(signum)


defer()   # on import: warp_sim/__init__ imports this module before anything else

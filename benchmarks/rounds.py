"""Timed rounds taken in turn by implementations that each live in a subprocess of their own.

The implementations of a benchmark must not share a process (a crash, a Taichi init or a compile in one cannot
touch another's numbers), yet a shared machine's speed drifts by tens of percent within minutes, so timing them
one after the other compares different machines. Here the parent starts one worker per implementation, has each
prepare a size in turn (build, check, warm up: one at a time, so that nothing runs beside a timed round), then
asks them for timed rounds in turn (A B C A B C ...), so that a drift reaches every implementation alike. The
ratio of two implementations is then taken round by round (``paired_ratio``), a median of per-round ratios.

The protocol, one line each way (parent to the worker's stdin, worker to its stdout; other lines are ignored):
- PREPARE: the worker builds, checks and warms up its next size, then answers READY, or RESULT {json} if that
  size failed (it is then done);
- ROUND: one timed round, answered TIME <seconds>, or RESULT {json} if it failed (the size is then done);
- FINISH: the size's result, RESULT {json} (its check, the rounds' seconds, steps/s).
A worker ends at the end of its stdin. ``serve`` is the worker's side, ``interleave`` the parent's.
"""
from __future__ import annotations

import json
import os
import queue
import signal
import statistics
import subprocess
import sys
import tempfile
import threading


def serve(sizes, prepare, failure) -> None:
    """The worker's side: for each size, at PREPARE, ``prepare(size)`` gives (round, finish): round() times one
    round [s], finish(seconds) is the size's result (a dict); an exception from either becomes RESULT
    ``failure(error)`` (a dict with its status)."""
    commands = (line.strip() for line in sys.stdin)
    for size in sizes:
        if next(commands, None) != "PREPARE":
            return
        try:
            round_, finish = prepare(size)
        except Exception as error:  # reported in its row; the next size goes on
            _answer("RESULT", json.dumps({"size": size, **failure(error)}))
            continue
        _answer("READY", str(size))
        seconds = []
        for command in commands:
            try:
                if command == "ROUND":
                    seconds.append(round_())
                    _answer("TIME", repr(seconds[-1]))
                    continue
                result = finish(seconds)
            except Exception as error:
                result = failure(error)
            _answer("RESULT", json.dumps({"size": size, **result}))
            break


def _answer(kind: str, text: str) -> None:
    print(f"{kind} {text}", flush=True)


class Worker:
    """One implementation's subprocess (a session of its own, so that a kill ends it and whatever it started)."""

    def __init__(self, command: list[str]):
        self.stderr = tempfile.TemporaryFile(mode="w+")
        self.process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self.stderr,
                                        text=True, start_new_session=True)
        self.lines: queue.Queue = queue.Queue()
        self.reason: str | None = None   # why it is gone, once it is
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for line in self.process.stdout:
            self.lines.put(line)
        self.lines.put(None)

    def ask(self, command: str, timeout: float) -> tuple[str, str] | None:
        """Send ``command``; its answer (kind, text), or None with ``reason`` set if the worker died or timed out."""
        if self.reason is not None:
            return None
        try:
            self.process.stdin.write(command + "\n")
            self.process.stdin.flush()
            while True:
                line = self.lines.get(timeout=timeout)
                if line is None:
                    break
                kind, _, text = line.strip().partition(" ")
                if kind in ("READY", "TIME", "RESULT"):
                    return kind, text
        except queue.Empty:
            self.kill()
            self.reason = f"failed: timed out after {timeout:.0f} s"
            return None
        except (BrokenPipeError, OSError):
            pass
        self.reason = self._death()
        return None

    def _death(self) -> str:
        code = self.process.wait()
        self.stderr.seek(0)
        lines = [line.strip() for line in self.stderr.read().splitlines() if line.strip()]
        last = lines[-1][:160] if lines else "(no output)"
        return f"failed: {signal.Signals(-code).name}; {last}" if code < 0 else f"failed: {last}"

    def kill(self) -> None:
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:  # it had just ended
            pass

    def close(self) -> None:
        """End the worker (its stdin closed; killed if it is still there after a few seconds)."""
        try:
            self.process.stdin.close()
            self.process.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            self.kill()
            self.process.wait()
        self.stderr.close()


def interleave(commands: dict, sizes, repeats: int, timeout: float, report=None) -> dict:
    """Run every worker command of ``commands`` (key -> argv) over ``sizes``: each prepared in turn, then
    ``repeats`` rounds taken in turn. {key: {size: result}}; a worker that dies or takes longer than ``timeout``
    seconds for one answer has "failed: ..." for the sizes it did not finish. ``report(key, size, result)`` is
    called as each result comes."""
    workers = {key: Worker(command) for key, command in commands.items()}
    results = {key: {} for key in commands}

    def done(key, size, result):
        results[key][size] = result
        if report is not None:
            report(key, size, result)

    try:
        for size in sizes:
            ready = []
            for key, worker in workers.items():
                answer = worker.ask("PREPARE", timeout)
                if answer is None:
                    done(key, size, {"status": worker.reason})
                elif answer[0] == "READY":
                    ready.append(key)
                else:
                    done(key, size, _result(answer))
            for _ in range(repeats):
                for key in list(ready):
                    answer = workers[key].ask("ROUND", timeout)
                    if answer is None or answer[0] != "TIME":
                        ready.remove(key)
                        done(key, size, {"status": workers[key].reason} if answer is None else _result(answer))
            for key in ready:
                answer = workers[key].ask("FINISH", timeout)
                done(key, size, {"status": workers[key].reason} if answer is None else _result(answer))
    finally:
        for worker in workers.values():
            worker.close()
    return results


def _result(answer: tuple[str, str]) -> dict:
    result = json.loads(answer[1])
    result.pop("size", None)
    return result


def paired_ratio(seconds: list[float] | None, reference_seconds: list[float] | None) -> float | None:
    """The median over rounds of (this round's seconds / the reference's in the same round): how many times
    faster the reference is, each round against the one beside it; None unless both have the same rounds."""
    if not seconds or not reference_seconds or len(seconds) != len(reference_seconds):
        return None
    return statistics.median(s / r for s, r in zip(seconds, reference_seconds))

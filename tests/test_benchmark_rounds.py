"""benchmarks/rounds.py: workers in subprocesses of their own take their timed rounds in turn, and a failing
size, a crash or a hung worker is reported in its place without stopping the others."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import rounds  # noqa: E402

WORKER = """
import os, sys, time
sys.path.insert(0, {benchmarks!r})
import rounds
name, log, behaviour = sys.argv[1], sys.argv[2], sys.argv[3]

def prepare(size):
    if behaviour == "bad-size" and size == 2:
        raise ValueError("no size 2 here")
    count = [0]
    def round_():
        count[0] += 1
        if behaviour == "crash" and count[0] == 2:
            os._exit(3)
        if behaviour == "hang" and count[0] == 2:
            time.sleep(60)
        with open(log, "a") as f:
            f.write(f"{{name}} {{size}} {{count[0]}}\\n")
        return 0.5 * size if name == "slow" else 0.25 * size
    return round_, lambda seconds: {{"status": "ok", "seconds": seconds}}

rounds.serve([1, 2, 3], prepare, lambda error: {{"status": f"failed: {{error}}"}})
"""


def commands(tmp_path, behaviours):
    script = tmp_path / "worker.py"
    script.write_text(WORKER.format(benchmarks=str(Path(rounds.__file__).parent)))
    log = tmp_path / "log.txt"
    return log, {name: [sys.executable, str(script), name, str(log), behaviour] for name, behaviour in behaviours}


def test_rounds_are_taken_in_turn_and_a_bad_size_is_reported(tmp_path):
    log, argv = commands(tmp_path, [("fast", "ok"), ("slow", "bad-size")])
    seen = []
    results = rounds.interleave(argv, [1, 2, 3], repeats=3, timeout=60, report=lambda *a: seen.append(a[:2]))
    assert results["fast"][1] == {"status": "ok", "seconds": [0.25] * 3}
    assert results["slow"][3] == {"status": "ok", "seconds": [1.5] * 3}
    assert results["slow"][2] == {"status": "failed: no size 2 here"}
    assert results["fast"][2]["seconds"] == [0.5] * 3
    # the turns: fast, slow, fast, slow, ... for each size (size 2: fast alone)
    turns = [tuple(line.split()) for line in log.read_text().splitlines()]
    assert turns == ([("fast", "1", str(k)) if w == 0 else ("slow", "1", str(k)) for k in (1, 2, 3) for w in (0, 1)]
                     + [("fast", "2", str(k)) for k in (1, 2, 3)]
                     + [("fast", "3", str(k)) if w == 0 else ("slow", "3", str(k)) for k in (1, 2, 3) for w in (0, 1)])
    assert len(seen) == 6


def test_a_crash_fails_its_sizes_and_the_others_go_on(tmp_path):
    _, argv = commands(tmp_path, [("fast", "ok"), ("slow", "crash")])
    results = rounds.interleave(argv, [1, 2, 3], repeats=3, timeout=60)
    assert all(results["fast"][size]["status"] == "ok" for size in (1, 2, 3))
    assert all(results["slow"][size]["status"].startswith("failed: ") for size in (1, 2, 3))


def test_a_hung_worker_is_killed_after_the_timeout(tmp_path):
    _, argv = commands(tmp_path, [("fast", "ok"), ("slow", "hang")])
    results = rounds.interleave(argv, [1], repeats=3, timeout=3)
    assert results["fast"][1]["status"] == "ok"
    assert results["slow"][1] == {"status": "failed: timed out after 3 s"}


def test_paired_ratio_is_the_median_of_per_round_ratios():
    # rounds where the machine ran at 1x, 2x and 0.5x speed: the pair's ratio is 2 every time
    assert rounds.paired_ratio([2.0, 1.0, 4.0], [1.0, 0.5, 2.0]) == pytest.approx(2.0)
    assert rounds.paired_ratio([3.0, 1.0, 1.0], [1.0, 1.0, 1.0]) == pytest.approx(1.0)
    assert rounds.paired_ratio([1.0], [1.0, 2.0]) is None
    assert rounds.paired_ratio(None, [1.0]) is None

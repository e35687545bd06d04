"""The `warp-sim` command as a user meets it: real processes of the console script (or ``python -m warp_sim``), one
check per message. Every expected failure is one line on stderr, names the flag or the path as typed, and comes
before anything is printed or built."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import warp as wp

from warp_sim.cli import UsageError, _in_cli_terms, main
from warp_sim.kernels import COMPILE_SECONDS
from warp_sim.util.version import __version__

EXE = shutil.which("warp-sim", path=os.path.dirname(sys.executable))
EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "tabletop_cm.usda"


def warp_sim(*args, cache=None, module=False, timeout=600):
    """The command's completed process; ``cache``: a WARP_CACHE_PATH of its own."""
    command = [sys.executable, "-m", "warp_sim"] if module or EXE is None else [EXE]
    env = dict(os.environ, **({"WARP_CACHE_PATH": str(cache)} if cache is not None else {}))
    return subprocess.run(command + [str(a) for a in args], capture_output=True, text=True, timeout=timeout, env=env)


def one_error(done, code=2) -> str:
    lines = done.stderr.strip().splitlines()
    assert done.returncode == code and len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert lines[0].startswith("warp-sim: error: ")
    return lines[0]


def test_a_missing_scene_is_named_as_typed(tmp_path):
    line = one_error(warp_sim("run", tmp_path / "missing.usda", "--out", tmp_path / "x.usdc"))
    assert f"{tmp_path / 'missing.usda'}: no such file" in line and "path_or_stage" not in line
    assert not (tmp_path / "x.usdc").exists()


@pytest.mark.skipif(wp.get_cuda_device_count() > 0, reason="a CUDA device is present")
def test_cuda_without_a_gpu_says_to_use_the_cpu(tmp_path):
    line = one_error(warp_sim("demo", "--device", "cuda", "--out", tmp_path / "x.usdc"))
    assert "--device cuda: no CUDA device found; use --device cpu" in line


def test_a_negative_duration_is_refused_before_the_banner(tmp_path):
    done = warp_sim("demo", "--seconds", "-1", "--out", tmp_path / "x.usdc")
    line = one_error(done)
    assert "--seconds" in line and "-1" in line and done.stdout == ""


def test_version_and_python_dash_m():
    assert warp_sim("--version").stdout.strip() == f"warp-sim {__version__} (Warp {wp.config.version})"
    done = warp_sim("--help", module=True)
    assert done.returncode == 0 and done.stdout.startswith("usage: warp-sim")
    assert all(command in done.stdout for command in ("demo", "run", "prepare", "sweep", "study"))


def test_console_script_help_lists_the_options():
    out = warp_sim("demo", "--help").stdout
    for option in ("--device", "--integrator", "--seconds", "--fps", "--substeps", "--out", "auto"):
        assert option in out


@pytest.fixture(scope="module")
def demo_on_cpu(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "demo.usda"
    return warp_sim("demo", "--device", "cpu", "--seconds", "0.1", "--substeps", "4", "--out", out, "--no-progress")


def test_the_demo_on_the_cpu_shows_its_substeps_and_wall_time(demo_on_cpu):
    assert demo_on_cpu.returncode == 0, demo_on_cpu.stderr
    banner, wrote = demo_on_cpu.stdout.strip().splitlines()
    assert banner.startswith("warp-sim demo: Scene(") and banner.endswith("0.1 s at 60 fps x 4 substeps")
    assert re.fullmatch(r"wrote .*demo\.usda \(6 frames\) in [0-9.]+ s wall time(, of which [0-9.]+ s compiling "
                        r"kernels \(once\))?", wrote)


def test_no_cuda_driver_warning_on_the_cpu(demo_on_cpu):
    assert "CUDA" not in demo_on_cpu.stderr, demo_on_cpu.stderr


def test_auto_substeps_are_the_default_and_shown(tmp_path):
    done = warp_sim("demo", "--device", "cpu", "--seconds", "0.05", "--out", tmp_path / "d.usdc", "--no-progress")
    assert done.returncode == 0, done.stderr
    assert re.search(r"0\.05 s at 60 fps x auto substeps \([1-9][0-9]* per frame\)$", done.stdout.splitlines()[0])


@pytest.mark.parametrize("argv, shown", [
    (["demo", "--substeps", "zero"], "argument --substeps: zero is invalid: expected auto or a whole number >= 1"),
    (["demo", "--fps", "0"], "argument --fps: 0 is invalid"),
    (["demo", "--out", "demo.txt"], "--out demo.txt is invalid: expected a file ending in .usd"),
    (["demo", "--seconds", "0.001"], "--seconds 0.001 covers no frame at --fps 60"),
    (["demo", "--chunk-frames", "0"], "argument --chunk-frames: 0 is invalid"),
    (["demo", "--device", "tpu"], "--device tpu is invalid: expected cpu, cuda or cuda:N"),
    (["demo", "--rtol", "1e-3"], "--rtol/--atol are rk45's tolerances"),
    (["prepare", "--cuda-arch", "sm_9x"], "argument --cuda-arch: sm_9x is invalid"),
    (["prepare", "--cuda-arch", "sm_10"], "--cuda-arch sm_10 is invalid: Warp"),
    (["sweep", "none.py", "--grid", "a=1", "--seconds", "1"], "none.py: no such file"),
])
def test_bad_arguments_are_one_line_naming_the_flag(capsys, argv, shown):
    assert main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and shown in lines[0] and captured.out == "", captured.err


def test_verbose_shows_the_traceback(tmp_path):
    with pytest.raises(UsageError, match="no such file"):
        main(["run", str(tmp_path / "missing.usda"), "--out", str(tmp_path / "x.usdc"), "--verbose"])


def test_library_errors_are_said_with_flags():
    assert _in_cli_terms("seconds=-1 is invalid: must be > 0.0") == "--seconds -1 is invalid: must be > 0.0"
    assert _in_cli_terms("path_or_stage='a.usda' is invalid: no") == "scene 'a.usda' is invalid: no"
    assert _in_cli_terms("substeps=1 gives steps (substeps='auto' chooses them); mass=2") == \
        "--substeps 1 gives steps (--substeps 'auto' chooses them); mass=2"


@pytest.mark.slow
def test_prepare_fills_a_fresh_cache_so_no_run_compiles(tmp_path):
    """A cold demo says it compiles and how long that took; ``prepare`` then compiles every other module in both
    precisions (one line each, the demo's cached); after it neither the demo nor a float64 scene compiles."""
    cache, out = tmp_path / "cache", tmp_path / "out.usdc"
    cold = warp_sim("demo", "--device", "cpu", "--seconds", "0.05", "--out", out, "--no-progress", cache=cache)
    assert cold.returncode == 0, cold.stderr
    assert re.fullmatch(r"compiling kernels for cpu, once, about [0-9]+ s", cold.stderr.strip()), cold.stderr
    assert re.search(r"in [0-9.]+ s wall time, of which [0-9.]+ s compiling kernels \(once\)$", cold.stdout.strip())
    prepared = warp_sim("prepare", cache=cache)
    assert prepared.returncode == 0, prepared.stderr
    lines = prepared.stdout.splitlines()
    modules = [line.split() for line in lines if line.startswith("  ")]
    assert len(modules) == 2 * len(COMPILE_SECONDS) and {row[1] for row in modules} == {"cpu"}
    cached = {precision: {row[2] for row in modules if row[0] == precision and row[3] == "cached"}
              for precision in ("float32", "float64")}
    demo = cached["float32"]   # the demo's modules, compiled by the cold demo
    assert {"detection", "contacts", "particles"} <= demo and len(demo) < len(COMPILE_SECONDS)
    assert "detection" not in cached["float64"] and cached["float64"] <= cached["float32"]   # none generic: the same
    assert lines[-1].startswith("prepared every kernel module for cpu in float32 and float64 in ")
    warm = warp_sim("demo", "--device", "cpu", "--seconds", "0.05", "--out", out, "--no-progress", cache=cache)
    assert warm.returncode == 0 and "compiling" not in warm.stderr + warm.stdout, warm.stderr
    double = warp_sim("run", EXAMPLE, "--precision", "float64", "--device", "cpu", "--seconds", "0.05", "--out",
                      tmp_path / "table.usdc", "--no-progress", cache=cache)
    assert double.returncode == 0 and "compiling" not in double.stderr + double.stdout, double.stderr

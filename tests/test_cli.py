"""The `warp-sim` command as a user meets it: real processes of the console script (or ``python -m warp_sim``), one
check per message. Every expected failure is one line on stderr, names the flag or the path as typed, and comes
before anything is printed or built."""
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import warp as wp
from pxr import Gf, Usd, UsdGeom, UsdPhysics, UsdShade

import warp_sim as ws
from warp_sim.cli import UsageError, _in_cli_terms, _one_line, main
from warp_sim.kernels import COMPILE_SECONDS
from warp_sim.util.version import __version__

EXE = shutil.which("warp-sim", path=os.path.dirname(sys.executable))
EXAMPLE = Path(ws.examples.path("tabletop_cm.usda"))
G = 9.81   # [m/s^2] the stages' gravity here


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
    (["example", "nope.usda"], "argument NAME: invalid choice: 'nope.usda' (choose from 'tabletop_cm.usda')"),
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


# --------------------------------------------------------------------------- examples, time base, warnings


def test_an_example_is_copied_where_run_takes_it(tmp_path):
    """``warp-sim example`` prints the path of its copy (the package's file, byte for byte); ``warp-sim run``
    simulates it there: the crate falls between the first two frames (24 time codes per second from 1)."""
    done = warp_sim("example", "tabletop_cm.usda", "--out", tmp_path / "mine")
    assert done.returncode == 0 and done.stderr == "", done.stderr
    copy = Path(done.stdout.strip())
    assert done.stdout == f"{tmp_path / 'mine' / 'tabletop_cm.usda'}\n" and copy.read_bytes() == EXAMPLE.read_bytes()
    ran = warp_sim("run", copy, "--seconds", "0.1", "--out", tmp_path / "anim.usdc", "--no-progress", "--device",
                   "cpu")
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.splitlines()[-1].startswith(f"wrote {tmp_path / 'anim.usdc'} (2 frames, animation layer over")
    stage = Usd.Stage.Open(str(tmp_path / "anim.usdc"))
    crate = UsdGeom.Xformable(stage.GetPrimAtPath("/World/crate"))
    heights = [crate.ComputeLocalToWorldTransform(code).ExtractTranslation()[2] for code in (1.0, 2.0)]
    assert heights[1] < heights[0] - 0.5 * 981.0 / 24 ** 2 * 0.99    # [cm] at least its free fall, within 1 %


def falling_sphere(path: Path, codes_per_second: float, physics: bool = True) -> Path:
    """A pxr stage, Y up in metres: a 10 cm, 1 kg sphere (RigidBodyAPI, CollisionAPI, MassAPI) at y = 2 m with
    nothing under it, under G along -y (no UsdPhysics.Scene with ``physics=False``: Earth's, and a warning)."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(codes_per_second)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    if physics:
        scene = UsdPhysics.Scene.Define(stage, "/World/physicsScene")
        scene.CreateGravityDirectionAttr(Gf.Vec3f(0.0, -1.0, 0.0))
        scene.CreateGravityMagnitudeAttr(G)
    ball = UsdGeom.Sphere.Define(stage, "/World/ball")
    ball.CreateRadiusAttr(0.1)
    ball.AddTranslateOp().Set(Gf.Vec3d(0.0, 2.0, 0.0))
    for api in (UsdPhysics.RigidBodyAPI, UsdPhysics.CollisionAPI):
        api.Apply(ball.GetPrim())
    UsdPhysics.MassAPI.Apply(ball.GetPrim()).CreateMassAttr(1.0)
    stage.Save()
    return path


def test_a_fine_time_base_runs_at_60_fps_and_keeps_its_time_codes(tmp_path):
    """A stage at 1000 time codes per second (Newton's) runs at 60 fps by default, said in one line: 0.5 s is 30
    frames at time codes 1000 k / 60 (frame k at t = k / 60 s, the last at 29/60 s), and the sphere's height there
    is 2 m - G t^2 / 2 within 0.01 mm (free fall: rk4 is exact for it; float32 rounding, measured 0.0003 mm)."""
    source = falling_sphere(tmp_path / "stage.usda", 1000.0)
    done = warp_sim("run", source, "--seconds", "0.5", "--out", tmp_path / "anim.usda", "--no-progress", "--device",
                    "cpu")
    assert done.returncode == 0, done.stderr
    said, banner, wrote = done.stdout.strip().splitlines()
    assert said == f"{source}: 1000 time codes per second; running at 60 fps (--fps to choose)"
    assert " 0.5 s at 60 fps x " in banner and " (30 frames, " in wrote
    stage = Usd.Stage.Open(str(tmp_path / "anim.usda"))
    assert stage.GetTimeCodesPerSecond() == 1000.0 and stage.GetStartTimeCode() == 0.0
    ball = stage.GetPrimAtPath("/World/ball")
    codes = np.array(ball.GetAttribute("xformOp:translate").GetTimeSamples())
    np.testing.assert_allclose(codes, 1000.0 * np.arange(30) / 60.0, rtol=1e-12, atol=1e-9)
    assert stage.GetEndTimeCode() == pytest.approx(codes[-1])
    heights = np.array([UsdGeom.Xformable(ball).ComputeLocalToWorldTransform(code).ExtractTranslation()[1]
                        for code in codes])
    t = codes / 1000.0
    np.testing.assert_allclose(heights, 2.0 - 0.5 * G * t ** 2, rtol=0, atol=1e-5)


def test_a_time_base_up_to_240_is_the_default_fps(tmp_path):
    """240 time codes per second: 240 fps, nothing said; 1000 with --fps 100: 100 fps, nothing said."""
    at_240 = warp_sim("run", falling_sphere(tmp_path / "s240.usda", 240.0), "--seconds", "0.05", "--out",
                      tmp_path / "a240.usda", "--no-progress", "--device", "cpu")
    assert at_240.returncode == 0, at_240.stderr
    banner, wrote = at_240.stdout.strip().splitlines()
    assert " 0.05 s at 240 fps x " in banner and " (12 frames, " in wrote
    told = warp_sim("run", falling_sphere(tmp_path / "s1000.usda", 1000.0), "--seconds", "0.05", "--fps", "100",
                    "--out", tmp_path / "a1000.usda", "--no-progress", "--device", "cpu")
    assert told.returncode == 0, told.stderr
    assert len(told.stdout.strip().splitlines()) == 2 and " 0.05 s at 100 fps x " in told.stdout
    stage = Usd.Stage.Open(str(tmp_path / "a1000.usda"))
    codes = stage.GetPrimAtPath("/World/ball").GetAttribute("xformOp:translate").GetTimeSamples()
    assert codes == pytest.approx([10.0 * k for k in range(5)])


def warning_stage(path: Path) -> Path:
    """The falling sphere without a UsdPhysics.Scene, bound to a material whose two frictions differ: two of the
    reader's warnings (Earth's gravity; the dynamic friction used)."""
    falling_sphere(path, 24.0, physics=False)
    stage = Usd.Stage.Open(str(path))
    material = UsdShade.Material.Define(stage, "/World/Looks/sticky")
    api = UsdPhysics.MaterialAPI.Apply(material.GetPrim())
    api.CreateDynamicFrictionAttr(0.3)
    api.CreateStaticFrictionAttr(0.7)
    ball = stage.GetPrimAtPath("/World/ball")
    UsdShade.MaterialBindingAPI.Apply(ball).Bind(material, UsdShade.Tokens.weakerThanDescendants, "physics")
    stage.Save()
    return path


@pytest.mark.parametrize("verbose", [False, True])
def test_warnings_are_one_line_each(tmp_path, verbose):
    """Each warning is one line on stderr, ``warp-sim: warning: <message>``, never followed by its source line;
    with --verbose its category and the file and line that warned close that same line. Anything else on stderr is
    Warp's own one-line notices."""
    source = warning_stage(tmp_path / "stage.usda")
    done = warp_sim("run", source, "--seconds", "0.05", "--out", tmp_path / "anim.usda", "--no-progress",
                    "--device", "cpu", *(["--verbose"] if verbose else []))
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    warned = [line for line in lines if line.startswith("warp-sim: warning: ")]
    assert all(line.startswith("Warp ") for line in lines if line not in warned), done.stderr   # no source line
    assert len(warned) == 2, done.stderr
    assert warned[0].startswith(f"warp-sim: warning: '{source}': no UsdPhysics.Scene, so Earth's gravity")
    assert "material /World/Looks/sticky has staticFriction 0.7 and dynamicFriction 0.3" in warned[1]
    where = r" \(UserWarning at \S+/warp_sim/\S+\.py:[0-9]+\)$"
    assert all(bool(re.search(where, line)) == verbose for line in warned), warned


def test_a_warning_of_several_lines_is_one(capsys):
    _one_line("frame 3:\n  substeps=2 is too few\n", UserWarning, "x.py", 7)
    assert capsys.readouterr().err == "warp-sim: warning: frame 3: --substeps 2 is too few\n"
    _one_line("a  b", RuntimeWarning, "x.py", 7, verbose=True)
    assert capsys.readouterr().err == "warp-sim: warning: a b (RuntimeWarning at x.py:7)\n"


def test_a_sweeps_workers_warn_in_one_line_each(tmp_path):
    """The workers of the command's own Dask cluster show their warnings as the command does: one line each."""
    pytest.importorskip("distributed", reason="sweeps need the cluster extra")
    script = tmp_path / "variants.py"
    script.write_text("import warnings\n\nimport warp_sim as ws\n\n\ndef build(k=1):\n"
                      "    warnings.warn(f'variant {k}: a warning of the script')\n"
                      "    scene = ws.Scene()\n    scene.add_particles([[0.0, 1.0, 0.0]], mass=[1.0])\n"
                      "    return scene\n")
    done = warp_sim("sweep", script, "--grid", "k=1,2", "--seconds", "0.05", "--workers", "1", "--out",
                    tmp_path / "out", "--no-progress", "--device", "cpu")
    assert done.returncode == 0, done.stderr
    warned = sorted(line for line in done.stderr.splitlines() if "a warning of the script" in line)
    assert warned == [f"warp-sim: warning: variant {k}: a warning of the script" for k in (1, 2)], done.stderr
    assert "warnings.warn(" not in done.stderr and "UserWarning" not in done.stderr, done.stderr

"""Long runs that fail cleanly: the USD file grows linearly, bad output paths fail before simulating, a close that
fails leaves nothing, strays of dead runs are removed, guard=False keeps the frames before a bad one, the command
line prints one line per expected failure, and bad input is refused (checkpoints and resume: test_resume.py)."""
import os
import subprocess
import sys

import numpy as np
import pytest
from pxr import Sdf, Usd

import warp_sim as ws
from warp_sim.cli import main
from warp_sim.stages.runs import run_folder


def particles(count=100, precision="float32"):
    scene = ws.Scene(precision=precision)
    scene.add_ground(restitution=0.5)
    scene.add_particles(np.random.default_rng(0).uniform(0.0, 1.0, (count, 3)) + [0.0, 0.5, 0.0], radius=0.01)
    return scene


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def test_file_size_stays_linear_in_frames(tmp_path):
    """20,000 frames of 100 particles, saved every 240 frames: within 1.1x of the same stage exported once (the
    quadratic growth measured before: 109.6 MB against 13.5 MB)."""
    path = ws.Simulator(particles()).run(20000 / 600.0, fps=600.0, substeps=1, usd=tmp_path / "long.usdc",
                                         progress=False)
    once = tmp_path / "once.usdc"
    assert Sdf.Layer.FindOrOpen(str(path)).Export(str(once))
    size, compact = path.stat().st_size, once.stat().st_size
    print(f"20,000 frames: {size / 1e6:.2f} MB written, {compact / 1e6:.2f} MB exported once")
    assert size <= 1.1 * compact
    stage = Usd.Stage.Open(str(path))
    assert stage.GetEndTimeCode() == 19999.0
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("make, error, shown", [
    (lambda tmp: tmp / "adir.usdc", ValueError, "existing folder"),
    (lambda tmp: tmp / "plain", ValueError, "existing folder; give a file path such as '.*plain/out.usdc'"),
    (lambda tmp: "", ValueError, "usd=''"),
    (lambda tmp: tmp / "x.obj", ValueError, "must end in"),
])
def test_bad_output_path_fails_before_the_first_step(tmp_path, make, error, shown):
    (tmp_path / "adir.usdc").mkdir()
    (tmp_path / "plain").mkdir()
    sim = ws.Simulator(particles(4))
    with pytest.raises(error, match=shown):
        sim.run(1.0, usd=make(tmp_path), progress=False)
    assert sim.step_count == 0
    assert leftovers(tmp_path) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes anywhere")
def test_read_only_folder_names_the_users_path(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    sim = ws.Simulator(particles(4))
    with pytest.raises(OSError, match=str(folder / "out.usdc")):
        sim.run(0.1, usd=folder / "out.usdc", progress=False)
    assert sim.step_count == 0


def test_failed_close_leaves_nothing(tmp_path, monkeypatch):
    """A close whose export fails (a full disk) removes every temporary file and names the user's path."""
    sim = ws.Simulator(particles(4))
    monkeypatch.setattr(Sdf.Layer, "Export", lambda self, path, *args: False)
    with pytest.raises(OSError, match="out.usdc"):
        sim.run(0.1, usd=tmp_path / "out.usdc", progress=False)
    assert list(tmp_path.iterdir()) == []


def test_strays_of_dead_runs_are_removed_and_live_ones_kept(tmp_path):
    out = tmp_path / "out.usdc"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stray = run_folder(out, int(dead.stdout))
    stray.mkdir()
    (stray / "chunk-000000.usdc").write_bytes(b"left by a killed run")
    alive = run_folder(out, os.getppid())
    alive.mkdir()
    ws.Simulator(particles(4)).run(0.05, usd=out, progress=False)
    assert not stray.exists() and alive.exists()


def test_guard_off_keeps_the_frames_before_a_non_finite_one(tmp_path):
    """A stiff spring under explicit Euler at a large step blows up; with guard=False the frames before the first
    non-finite one are kept, and nothing non-finite is written."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0))
    scene.add_particles([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0]])
    scene.add_springs([[0, 1]], stiffness=1e6, rest_length=1.0)
    sim = ws.Simulator(scene, integrator="euler", guard=False)
    with pytest.raises(ws.SimulationDiverged, match="non-finite") as caught:
        sim.run(10.0, fps=60, substeps=1, usd=tmp_path / "blow.usdc", progress=False)
    kept = caught.value.frames_written
    assert kept > 1 and caught.value.usd == tmp_path / "blow.usdc"
    stage = Usd.Stage.Open(str(caught.value.usd))
    points = stage.GetPrimAtPath("/World/Particles/group0").GetAttribute("points")
    times = points.GetTimeSamples()
    assert len(times) == kept
    assert all(np.isfinite(np.array(points.Get(t))).all() for t in times)


@pytest.mark.filterwarnings("ignore:integrator='euler'", "ignore:substeps=1")
@pytest.mark.parametrize("guard", [True, False])
def test_a_float64_run_beyond_float32s_range_stops_before_an_infinity_reaches_the_stage(tmp_path, guard):
    """A float64 state still finite but beyond float32's range (|x| > 3.4e38) would be written as +-inf: the run
    stops at that frame with SimulationDiverged, whatever the guard, and keeps the frames before it, all within
    float32's range. The spring is so stiff (euler, 1e6 N/m at 1/60 s) that the speed bound is passed only after
    the positions are (the guard on sees the frame first, as it did before)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_particles([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0]], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=1e6, rest_length=1.0)
    sim = ws.Simulator(scene, integrator="euler", guard=guard, max_speed=1e300)
    with pytest.raises(ws.SimulationDiverged, match="float32") as caught:
        sim.run(100.0, fps=60, substeps=1, usd=tmp_path / "far.usdc", progress=False)
    state = np.concatenate([sim.state.particle_x.numpy(), sim.state.particle_v.numpy()])
    assert np.isfinite(state).all() and np.abs(state).max() > np.finfo(np.float32).max   # finite in float64 only
    stage = Usd.Stage.Open(str(caught.value.usd))
    points = stage.GetPrimAtPath("/World/Particles/group0").GetAttribute("points")
    assert len(points.GetTimeSamples()) == caught.value.frames_written > 10
    assert all(np.isfinite(np.array(points.Get(t))).all() for t in points.GetTimeSamples())


@pytest.mark.parametrize("argv, code, shown", [
    (["demo", "--integrator", "euler", "--seconds", "2", "--substeps", "1"], 1, "diverged"),
    (["demo", "--seconds", "-1"], 2, "seconds"),
    (["demo", "--integrator", "rk4", "--rtol", "1e-3"], 2, "--rtol"),
])
def test_command_line_prints_one_line_per_expected_failure(tmp_path, capsys, argv, code, shown):
    assert main(argv + ["--out", str(tmp_path / "d.usdc"), "--no-progress"]) == code
    err = [line for line in capsys.readouterr().err.strip().splitlines()
           if not line.startswith("warp-sim: warning:")]   # warnings (euler on springs, too few substeps) aside
    assert len(err) == 1 and shown in err[0] and "Traceback" not in err[0]


def test_command_line_names_an_unwritable_output(tmp_path, capsys):
    (tmp_path / "d.usdc").mkdir()
    assert main(["demo", "--seconds", "0.1", "--out", str(tmp_path / "d.usdc"), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "existing folder" in err[0] and str(tmp_path / "d.usdc") in err[0]


def test_divergence_names_the_group_and_its_local_index():
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0))
    scene.add_particles([[5.0, 0.0, 0.0]], name="still")
    scene.add_particles([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0]], name="chain")
    scene.add_springs([[1, 2]], stiffness=1e8, rest_length=1.0)
    sim = ws.Simulator(scene, integrator="euler")
    with pytest.raises(ws.SimulationDiverged, match="particle [01] of group 'chain'") as caught:
        sim.step(1.0 / 60.0, steps=50)
    assert caught.value.element in (1, 2) and "chain" in caught.value.where


def test_rk45_warns_when_a_frame_takes_over_a_thousand_steps():
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_particles([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0]], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=1e7, rest_length=1.0)
    sim = ws.Simulator(scene, integrator=ws.RK45(rtol=1e-9, atol=1e-12))
    with pytest.warns(RuntimeWarning, match="internal steps for frame 1"):
        sim.run(2.0 / 30.0, fps=30, substeps=1, progress=False)


@pytest.mark.parametrize("call, argument", [
    (lambda s: s.add_springs([[0, 1], [1, 0]], 10.0), "pairs"),
    (lambda s: s.add_particles([[0, 0, 0]], color=(2, 0, 0)), "color"),
    (lambda s: s.add_particles([[0, 0, 0]], mass=True), "mass"),
    (lambda s: s.add_particles([[1e300, 0, 0]]), "positions"),
    (lambda s: s.add_emitter(rate=1e9), "rate"),
    (lambda s: ws.Ramp([0, 1], [1.0, (1.0, 2.0, 3.0)]), "values"),
    (lambda s: s.add_emitter(kill_planes=[0]), "kill_planes"),
])
def test_bad_scene_input_names_the_argument(call, argument):
    scene = ws.Scene()
    scene.add_particles(np.zeros((3, 3)) + [[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    with pytest.raises(ValueError, match=f"^{argument}="):
        call(scene)


def test_springs_repeated_across_calls_are_refused():
    scene = ws.Scene()
    scene.add_particles([[0, 0, 0], [1, 0, 0], [2, 0, 0]])
    scene.add_springs([[0, 1]], 10.0)
    with pytest.raises(ValueError, match=r"spring 1 joins particles \(1, 0\), already joined by a spring added"):
        scene.add_springs([[1, 2], [1, 0]], 10.0)


def test_step_refuses_a_string_and_messages_show_plain_numbers():
    sim = ws.Simulator(particles(2))
    with pytest.raises(ValueError, match="^dt='0.01'"):
        sim.step("0.01")
    with pytest.raises(ValueError, match=r"^steps=0 is invalid"):
        sim.step(0.01, steps=np.int64(0))
    sim.step(0.01, steps=np.int64(2))
    sim.run(0.05, substeps=np.int64(2), progress=False)

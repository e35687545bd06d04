"""Late errors said early: every argument of ws.sweep is checked once before any cluster starts (a ValueError naming
it, its value and what is valid), and the output folders of sweeps and studies are made or refused before minutes
of work. No Dask cluster here: one starting is a failure."""
import os
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import warp_sim as ws
from warp_sim import cluster
from warp_sim.cli import main

SCRIPT = textwrap.dedent("""
    import warp_sim as ws

    def build(restitution, seed=0):
        scene = ws.Scene()
        scene.add_ground(restitution=restitution)
        scene.add_particles([[0.0, 1.0, 0.0]], radius=0.01)
        return scene
""")


@pytest.fixture
def script(tmp_path, monkeypatch):
    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started before the arguments were checked")
    monkeypatch.setattr(cluster, "connect", no_cluster)
    path = tmp_path / "balls.py"
    path.write_text(SCRIPT)
    return path


@pytest.mark.parametrize("change, shown", [
    (dict(integrator="leapfrog"), "integrator='leapfrog' is invalid: expected one of "),
    (dict(integrator=ws.RK4()), "integrator=RK4"),
    (dict(fps=0), "fps=0 is invalid: must be > 0.0"),
    (dict(seconds=-1.0), "seconds=-1.0 is invalid: must be > 0.0"),
    (dict(seconds=0.001), "seconds=0.001 is invalid: covers no frame at fps=60"),
    (dict(substeps=0), "substeps=0 is invalid: expected 'auto' or an integer >= 1"),
    (dict(substeps="many"), "substeps='many' is invalid"),
    (dict(device="gpu"), "device='gpu' is invalid: expected None, 'cpu', 'cuda' or 'cuda:N'"),
    (dict(device="cuda:7"), "device='cuda:7' is invalid: expected one of"),
    (dict(grid={"restitution": [0.5], "sede": [1]}), "does not take {'restitution': 0.5, 'sede': 1}"),
    (dict(grid={"restitution": [np.int64(1)]}), "restitution=np.int64(1) is not a number, string, bool or None"),
    (dict(grid={"restitution": [object()]}), "is not a number, string, bool or None"),
    (dict(grid={"restitution": []}), "grid={'restitution': []} is invalid: expected a dict of non-empty"),
    (dict(workers=0), "workers=0 is invalid: expected an integer >= 1"),
    (dict(progress="yes"), "progress='yes' is invalid: expected True or False"),
    (dict(scheduler=""), "scheduler='' is invalid"),
])
def test_a_bad_sweep_argument_is_refused_before_the_cluster_starts(script, tmp_path, change, shown):
    options = dict(grid={"restitution": [0.5, 0.8]}, seconds=0.5, fps=60, out=tmp_path / "out", progress=False)
    options.update(change)
    grid = options.pop("grid")
    with pytest.raises(ValueError) as refused:
        ws.sweep(script, grid, **options)
    assert shown in str(refused.value)
    if "integrator" in change and isinstance(change["integrator"], str):
        assert all(name in str(refused.value) for name in ws.INTEGRATORS)


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="needs /proc")
@pytest.mark.parametrize("out, shown", [
    ("/proc/nope", "out='/proc/nope' is invalid: the folder cannot be made"),
    ("{file}", "is invalid: it is an existing file; expected a folder"),
])
def test_a_sweep_output_folder_that_cannot_be_made_is_refused_at_once(script, tmp_path, out, shown):
    (tmp_path / "file").write_text("")
    started = time.perf_counter()
    with pytest.raises(ValueError, match=shown):
        ws.sweep(script, {"restitution": [0.5]}, seconds=0.5, out=out.format(file=tmp_path / "file"), progress=False)
    assert time.perf_counter() - started < 5.0


def test_a_missing_sweep_output_folder_is_made_before_the_cluster(script, tmp_path):
    with pytest.raises(AssertionError, match="a cluster was started"):   # the arguments passed: a cluster is next
        ws.sweep(script, {"restitution": [0.5]}, seconds=0.5, out=tmp_path / "new" / "out", progress=False)
    assert (tmp_path / "new" / "out").is_dir() and list((tmp_path / "new" / "out").iterdir()) == []


@pytest.mark.parametrize("argv, shown", [
    (["study", "stability", "--quick", "--out", "/proc/nope"],
     "--out /proc/nope is invalid: the folder cannot be made (No such file or directory)"),
    (["study", "accuracy", "--quick", "--out", "{file}"], "--out {file} is invalid: it is an existing file"),
    (["sweep", "{script}", "--grid", "restitution=0.5", "--seconds", "1", "--out", "/proc/nope"],
     "--out /proc/nope is invalid: the folder cannot be made"),
])
def test_the_command_line_refuses_an_output_folder_within_seconds(tmp_path, argv, shown):
    """As a user meets it (a real process): the refusal comes in about a second, one line, exit 2; before, the
    quick stability study ran for 49 s and then failed, its results lost."""
    (tmp_path / "file").write_text("")
    (tmp_path / "balls.py").write_text(SCRIPT)
    argv = [item.format(file=tmp_path / "file", script=tmp_path / "balls.py") for item in argv]
    started = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "warp_sim", *argv], capture_output=True, text=True, timeout=300)
    elapsed = time.perf_counter() - started
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert lines[0].startswith(f"warp-sim: error: {shown.format(file=tmp_path / 'file')}"), lines[0]
    assert elapsed < 20.0, f"refused after {elapsed:.1f} s"


def test_the_command_line_sweep_names_a_bad_grid_in_its_words(tmp_path, capsys):
    (tmp_path / "balls.py").write_text(SCRIPT)
    code = main(["sweep", str(tmp_path / "balls.py"), "--grid", "restitutoin=0.5", "--seconds", "1", "--out",
                 str(tmp_path / "out"), "--no-progress"])
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and line.startswith("warp-sim: error: grid=") and "does not take {'restitutoin': 0.5}" in line

"""Sweeps on a real Dask LocalCluster of worker processes (no mock): bounces against e^2 h0, bad and diverging
variants recorded while the others finish, reruns that skip what is done, a worker killed mid-sweep, the same USD
samples on 1 worker and on 2, the command line, and the stability study spread over workers."""
import json
import os
import signal
import textwrap
import threading
import time

import pytest
from helpers import stage_samples
from pxr import Usd

distributed = pytest.importorskip("distributed")

import warp_sim as ws  # noqa: E402
from warp_sim import cluster, studies  # noqa: E402
from warp_sim.cli import main  # noqa: E402
from warp_sim.core.cpu_threads import VARIABLE, available_cores  # noqa: E402

pytestmark = pytest.mark.slow   # real Dask LocalClusters of worker processes: seconds each to start

H0, RADIUS = 1.0, 0.01   # drop height of the ball's bottom [m], its radius [m]

SCRIPT = textwrap.dedent(f"""
    import numpy as np
    import warp_sim as ws
    from pxr import Usd, UsdGeom

    def build(restitution, speed=0.0, seed=0):
        scene = ws.Scene(precision="float64")
        scene.add_ground(restitution=restitution, friction=0.0)
        scene.add_particles([[0.0, {H0} + {RADIUS}, 0.0]], [[0.0, speed, 0.0]], radius={RADIUS},
                            restitution=restitution, name="ball")
        return scene

    def measure(sim):
        stage = Usd.Stage.Open(str(sim.output))
        points = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/ball")).GetPointsAttr()
        heights = np.array([points.Get(t)[0][1] for t in points.GetTimeSamples()]) - {RADIUS}
        first = int(np.argmax(np.diff(heights) > 0.0))        # the first impact: the fall turns into a rise
        return {{"apex": float(heights[first:].max()), "frames": len(heights)}}
""")


def script(tmp_path, text=SCRIPT):
    path = tmp_path / "balls.py"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def two_workers():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=":0") as cluster, distributed.Client(cluster) as client:
        yield client


def test_a_bouncing_ball_sweep_gives_e_squared_apexes(tmp_path, two_workers):
    """Restitution 0.2, 0.5 and 0.8 on 2 workers: each first apex is e^2 h0 within 1e-3 m; rows in grid order,
    each from a worker, its stage at out/<id>.usdc; sweep.json and sweep.csv hold the same rows."""
    result = ws.sweep(script(tmp_path), {"restitution": [0.2, 0.5, 0.8]}, seconds=1.5, fps=600, substeps=2,
                      out=tmp_path / "out", client=two_workers, progress=False)
    assert [row["params"]["restitution"] for row in result.rows] == [0.2, 0.5, 0.8]
    for row in result.rows:
        e = row["params"]["restitution"]
        assert row["status"] == "done", row["error"]
        assert abs(row["measures"]["apex"] - e ** 2 * H0) <= 1e-3
        assert (tmp_path / "out" / row["usd"]).is_file() and row["worker"] != "local"
    assert json.loads((tmp_path / "out" / "sweep.json").read_text()) == result.rows
    lines = (tmp_path / "out" / "sweep.csv").read_text().splitlines()
    assert lines[0].split(",")[:4] == ["id", "restitution", "apex", "frames"] and len(lines) == 4


def test_bad_and_diverging_variants_are_recorded_and_the_rest_done(tmp_path, two_workers):
    """e = 1.5 is refused by the scene (failed, with its ValueError), a ball thrown at 10^5 m/s trips the guard
    (diverged, with the SimulationDiverged message); the other variants finish."""
    grid = [{"restitution": 0.5}, {"restitution": 1.5}, {"restitution": 0.5, "speed": 1e5}]
    result = ws.sweep(script(tmp_path), grid, seconds=0.2, fps=60, out=tmp_path / "out", client=two_workers,
                      progress=False)
    done, failed, diverged = result.rows
    assert done["status"] == "done"
    assert failed["status"] == "failed" and "restitution" in failed["error"] and failed["usd"] is None
    assert diverged["status"] == "diverged" and "diverged at step 1" in diverged["error"]


def test_a_rerun_skips_what_is_done_and_gives_the_same_table(tmp_path, two_workers):
    out = tmp_path / "out"
    first = ws.sweep(script(tmp_path), {"restitution": [0.3, 0.6]}, seconds=0.3, fps=60, out=out,
                     client=two_workers, progress=False)
    stamps = {row["id"]: (out / row["usd"]).stat().st_mtime_ns for row in first.rows}
    table = (out / "sweep.csv").read_text()
    again = ws.sweep(script(tmp_path), {"restitution": [0.3, 0.6]}, seconds=0.3, fps=60, out=out,
                     client=None, workers=1, progress=False)   # would start a cluster if anything were left
    assert again.rows == first.rows and (out / "sweep.csv").read_text() == table
    assert {row["id"]: (out / row["usd"]).stat().st_mtime_ns for row in again.rows} == stamps


def test_one_worker_and_two_give_identical_stages(tmp_path, two_workers):
    grid = {"restitution": [0.4, 0.7], "seed": [1]}
    one = ws.sweep(script(tmp_path), grid, seconds=0.5, fps=120, out=tmp_path / "one", workers=1, progress=False)
    two = ws.sweep(script(tmp_path), grid, seconds=0.5, fps=120, out=tmp_path / "two", client=two_workers,
                   progress=False)
    for a, b in zip(one.rows, two.rows):
        assert a["id"] == b["id"] and a["measures"] == b["measures"]
        assert stage_samples(tmp_path / "one" / a["usd"]) == stage_samples(tmp_path / "two" / b["usd"])


def test_a_worker_killed_mid_sweep_still_finishes_every_variant_once(tmp_path):
    """SIGKILL one of two worker processes while variants run: Dask runs its task again on a worker (the nanny
    restarts the killed one); every variant ends done, once, with its stage and nothing half-written beside it."""
    out = tmp_path / "out"
    killed = []

    def kill_one(client):
        def later():
            deadline = time.monotonic() + 60.0
            while not any(p.name.startswith(".") and ".run-" in p.name for p in out.glob(".*")):
                if time.monotonic() > deadline:
                    return
                time.sleep(0.05)
            pids = client.run(os.getpid)
            victim = sorted(pids.values())[0]
            os.kill(victim, signal.SIGKILL)
            killed.append(victim)
        threading.Thread(target=later, daemon=True).start()
    grid = {"restitution": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]}
    result = ws.sweep(script(tmp_path), grid, seconds=2.0, fps=240, out=out, workers=2, progress=False,
                      on_start=kill_one)
    assert killed, "no worker was killed"
    assert [row["status"] for row in result.rows] == ["done"] * 6
    assert len({row["id"] for row in result.rows}) == 6
    assert sorted(p.name for p in out.iterdir()) == sorted([row["usd"] for row in result.rows] +
                                                           ["sweep.csv", "sweep.json"])
    for row in result.rows:
        assert Usd.Stage.Open(str(out / row["usd"])).GetEndTimeCode() == 479.0
    assert abs(result.rows[2]["measures"]["apex"] - 0.09 * H0) <= 1e-3


def test_the_command_line_sweeps_a_script(tmp_path, capsys):
    out = tmp_path / "cli"
    code = main(["sweep", str(script(tmp_path)), "--grid", "restitution=0.25,0.75", "--grid", "seed=3",
                 "--seconds", "1.2", "--fps", "300", "--substeps", "2", "--workers", "2", "--out", str(out),
                 "--no-progress"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "2 of 2 variants done" in printed and "restitution" in printed
    rows = json.loads((out / "sweep.json").read_text())
    assert [row["params"] for row in rows] == [{"restitution": 0.25, "seed": 3}, {"restitution": 0.75, "seed": 3}]
    assert all(abs(row["measures"]["apex"] - row["params"]["restitution"] ** 2) <= 1e-3 for row in rows)
    assert main(["sweep", str(tmp_path / "none.py"), "--grid", "a=1", "--seconds", "1", "--out", str(out)]) == 2


def test_the_stability_study_on_two_workers_gives_the_same_rows(two_workers):
    """The study's cases spread over workers give the same rows as one process (wall times aside)."""
    options = dict(cases=["spring_1e2", "impact_100"], integrators=["symplectic_euler", "rk4"], quick=True)
    alone = studies.stability(**options)
    spread = studies.stability(**options, client=two_workers)
    assert repr(spread.rows) == repr(alone.rows)          # every value, NaN included, digit for digit


def test_the_accuracy_study_on_two_workers_gives_the_same_errors(two_workers):
    """References and (problem, integrator) points as tasks: every error, step and order as in one process; only
    the measured cost (and how often a point was repeated to fill its time budget) may differ."""
    options = dict(problems=["oscillator", "bouncing_ball"], integrators=["euler", "rk4", "rk45"], quick=True,
                   repeats=1)
    alone = studies.accuracy(**options)
    spread = studies.accuracy(**options, client=two_workers)
    timed = ("seconds_per_simulated_second", "repeats")

    def untimed(rows):
        return repr([{k: v for k, v in row.items() if k not in timed} for row in rows])
    assert untimed(spread.rows) == untimed(alone.rows) and repr(spread.orders) == repr(alone.orders)


def test_local_workers_share_the_cores_between_their_cpu_launches(monkeypatch):
    """connect()'s LocalCluster gives each worker cores / workers CPU threads (WARP_SIM_CPU_THREADS), so that the
    simulations of a sweep do not each take every core; a value the user set is kept."""
    monkeypatch.delenv(VARIABLE, raising=False)
    with cluster.connect(workers=2) as client:
        seen = set(client.run(lambda: os.environ.get(VARIABLE)).values())
    assert seen == {str(max(1, available_cores() // 2))}
    monkeypatch.setenv(VARIABLE, "3")
    with cluster.connect(workers=1) as client:
        assert set(client.run(lambda: os.environ.get(VARIABLE)).values()) == {"3"}

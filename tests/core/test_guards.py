"""Divergence guards: the error names step, time, component and element; USD keeps good frames."""
import numpy as np
import pytest
from helpers import oscillator
from pxr import Usd, UsdGeom

import warp_sim as ws
from warp_sim.stages import validate_stage


def chain_scene(links=6):
    scene = ws.Scene()
    scene.add_ground()
    ids = scene.add_particles([[0.1 * i, 2.0, 0.0] for i in range(links + 1)], pinned=[0])
    scene.add_springs(np.stack([ids[:-1], ids[1:]], 1), stiffness=100.0)
    return scene


def test_injected_nan_names_step_component_and_element(device):
    sim = ws.Simulator(chain_scene(), integrator="rk4", device=device)
    sim.step(0.01)
    x = sim.state.particle_x.numpy()
    x[4, 1] = np.nan
    sim.state.particle_x.assign(x)
    with pytest.raises(ws.SimulationDiverged) as caught:
        sim.step(0.01)
    error = caught.value
    assert (error.step, error.component, error.element) == (2, "particles", 3) or error.element == 4
    assert error.step == 2 and error.time == pytest.approx(0.02)
    assert error.reason.startswith("non-finite")
    assert "step 2" in str(error) and "particles element" in str(error)


def test_speed_bound_is_configurable(device):
    scene = ws.Scene(gravity=(0, 0, 0))
    scene.add_particles([[0, 0, 0], [1, 0, 0]], [[0, 0, 0], [0, 60.0, 0]])
    ws.Simulator(scene, device=device).step(0.01)        # 60 m/s is fine under the default bound
    sim = ws.Simulator(scene, device=device, max_speed=50.0)
    with pytest.raises(ws.SimulationDiverged) as caught:
        sim.step(0.01)
    assert caught.value.element == 1 and "speed above max_speed = 50 m/s" in str(caught.value)


def test_first_bad_step_is_named_even_when_read_a_frame_later(tmp_path):
    """Explicit Euler on ks/m = 1e4 grows; run() reads the guard once per frame (200 steps),
    yet the error names the exact first step over the bound, that of Euler's linear map."""
    k, h, bound = 1.0e4, 1.0 / (10 * 200), 100.0
    sim = ws.Simulator(oscillator(k=k, amplitude=0.01, rest=1000.0), integrator="euler", device="cpu",
                       max_speed=bound)   # a long spring stays linear: the particle never reaches the anchor
    path = tmp_path / "diverged.usda"
    with pytest.raises(ws.SimulationDiverged) as caught:
        sim.run(seconds=10.0, fps=10, substeps=200, usd=path, progress=False)
    x, v, first = 0.01, 0.0, 0
    while abs(v) <= bound:
        x, v, first = x + h * v, v - h * k * x, first + 1
    assert caught.value.step == first
    assert caught.value.time == pytest.approx(first * h, rel=1e-12)
    frames_before = (caught.value.step - 1) // 200 + 1
    stage = Usd.Stage.Open(str(path))
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/group0")).GetPointsAttr()
    assert len(points.GetTimeSamples()) == frames_before
    for t in points.GetTimeSamples():
        assert np.all(np.isfinite(np.array(points.Get(t))))
    assert validate_stage(stage) == []


def test_guard_off_runs_on():
    with pytest.warns(UserWarning, match="grows an undamped oscillator at any step"):
        sim = ws.Simulator(oscillator(k=1.0e6, amplitude=0.01), integrator="euler", device="cpu", guard=False)
    for _ in range(200):
        sim.step(0.01, substeps=1)
    assert not np.all(np.isfinite(sim.state.particle_x.numpy()))


def test_interrupted_run_leaves_no_file(tmp_path, monkeypatch):
    sim = ws.Simulator(chain_scene(), device="cpu")
    calls = {"n": 0}
    original = sim.integrator.step

    def interrupt(*args):
        calls["n"] += 1
        if calls["n"] == 50:
            raise KeyboardInterrupt
        original(*args)

    monkeypatch.setattr(sim.integrator, "step", interrupt)
    path = tmp_path / "run.usdc"
    with pytest.raises(KeyboardInterrupt):
        sim.run(seconds=1.0, fps=30, substeps=4, usd=path, progress=False)
    assert list(tmp_path.iterdir()) == []

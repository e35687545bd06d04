"""Simulator.frames(): the frames run() writes, at the times the USD conventions give them."""
import math

import numpy as np
import pytest

import warp_sim as ws

G = 9.81


def projectile(precision="float64"):
    scene = ws.Scene(precision=precision)
    scene.add_particles([[0.0, 10.0, 0.0]], [[1.0, 2.0, 0.0]])
    return scene


def test_frame_zero_is_the_initial_state_and_frame_k_is_at_k_over_fps():
    """Frames k = 0 .. round(seconds fps) - 1 at times k / fps, each the closed-form projectile (Verlet is exact
    under uniform gravity), to 1e-12 m."""
    sim = ws.Simulator(projectile(), integrator="verlet", device="cpu")
    seen = list(sim.frames(seconds=0.5, fps=24, substeps=4))
    assert [frame for frame, _, _ in seen] == list(range(12))
    for frame, time, arrays in seen:
        assert time == pytest.approx(frame / 24, abs=1e-15)
        t = frame / 24
        expected = [t, 10.0 + 2.0 * t - 0.5 * G * t * t, 0.0]
        np.testing.assert_allclose(arrays["particle_x"][0], expected, rtol=0, atol=1e-12)
    assert sim.time == pytest.approx(11 / 24, abs=1e-15)


def test_frames_continue_from_the_current_time():
    sim = ws.Simulator(projectile(), integrator="verlet", device="cpu")
    sim.step(0.1)
    times = [time for _, time, _ in sim.frames(seconds=0.1, fps=30, substeps=2)]
    assert times == pytest.approx([0.1 + k / 30 for k in range(3)], abs=1e-15)


def test_without_arrays_nothing_is_copied_and_the_motion_is_the_same():
    with_arrays = ws.Simulator(projectile(), integrator="rk4", device="cpu")
    without = ws.Simulator(projectile(), integrator="rk4", device="cpu")
    last = [arrays for _, _, arrays in with_arrays.frames(seconds=0.2, fps=60)][-1]
    assert all(arrays is None for _, _, arrays in without.frames(seconds=0.2, fps=60, arrays=False))
    np.testing.assert_array_equal(last["particle_x"], without.state.particle_x.numpy())


def test_a_divergence_is_raised_before_its_frame_is_yielded():
    """A stiff spring under explicit Euler blows up; the last frame yielded is finite, and the error names a
    step after it."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_particles([[0.0, 0.0, 0.0], [1.1, 0.0, 0.0]], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=1.0e6, rest_length=1.0)
    sim = ws.Simulator(scene, integrator="euler", device="cpu", max_speed=1e3)
    yielded = []
    with pytest.raises(ws.SimulationDiverged) as caught:
        for frame, _, arrays in sim.frames(seconds=1.0, fps=60, substeps=1):
            yielded.append(frame)
            assert np.all(np.isfinite(arrays["particle_x"]))
    assert caught.value.step > yielded[-1]


@pytest.mark.parametrize("kwargs, name", [({"seconds": 0.0}, "seconds"), ({"fps": -1.0}, "fps"),
                                          ({"substeps": 0}, "substeps"), ({"arrays": 1}, "arrays"),
                                          ({"seconds": 1e-4}, "seconds")])
def test_bad_frame_arguments_are_refused_before_any_step(kwargs, name):
    sim = ws.Simulator(projectile(), device="cpu")
    arguments = {"seconds": 1.0, **kwargs}
    with pytest.raises(ValueError, match=f"^{name}="):
        sim.frames(**arguments)
    assert sim.step_count == 0 and not math.isnan(sim.time)

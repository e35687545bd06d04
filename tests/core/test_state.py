"""Model and State: struct-of-arrays on the device, one flat buffer per state, chosen precision."""
import numpy as np
import pytest
import warp as wp

import warp_sim as ws


def two_particle_scene(precision):
    scene = ws.Scene(precision=precision)
    scene.add_particles([[0, 1, 0], [1, 2, 3]], [[4, 5, 6], [7, 8, 9]], mass=[1.0, 2.0], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=10.0)
    return scene


@pytest.mark.parametrize("precision, scalar, vector", [("float32", wp.float32, wp.vec3f),
                                                        ("float64", wp.float64, wp.vec3d)])
def test_precision_applies_to_the_whole_state(precision, scalar, vector, device):
    sim = ws.Simulator(two_particle_scene(precision), device=device)
    state, model = sim.state, sim.model
    assert state.y.dtype == scalar
    assert state.particle_x.dtype == vector and state.particle_v.dtype == vector
    assert model.particle_inv_mass.dtype == scalar and model.spring_stiffness.dtype == scalar
    assert str(state.y.device) == str(sim.device)


def test_fields_are_views_into_the_flat_buffer():
    sim = ws.Simulator(two_particle_scene("float64"), device="cpu")
    y = sim.state.y.numpy()
    # position block first, then the velocity block; the pinned particle's velocity is zeroed
    np.testing.assert_array_equal(y, [0, 1, 0, 1, 2, 3, 0, 0, 0, 7, 8, 9])
    sim.state.particle_v.assign(np.full((2, 3), 0.5))
    np.testing.assert_array_equal(sim.state.velocity.numpy(), np.full(6, 0.5))
    assert sim.state.position.shape == (6,) and sim.state.velocity.shape == (6,)


def test_pinned_particles_have_infinite_mass_and_never_move(device):
    sim = ws.Simulator(two_particle_scene("float64"), integrator="rk4", device=device)
    np.testing.assert_array_equal(sim.model.particle_inv_mass.numpy(), [0.0, 0.5])
    for _ in range(50):
        sim.step(0.01)
    np.testing.assert_array_equal(sim.state.particle_x.numpy()[0], [0, 1, 0])
    np.testing.assert_array_equal(sim.state.particle_v.numpy()[0], [0, 0, 0])


def test_drag_relaxes_towards_the_wind_at_rate_drag_over_mass(device):
    """m v' = -c (v - w): v(t) = w + (v0 - w) exp(-c t / m), no gravity."""
    scene = ws.Scene(gravity=(0, 0, 0), drag=0.5, wind=(2.0, 0.0, -1.0), precision="float64")
    scene.add_particles([[0, 0, 0]], [[0.0, 3.0, 0.0]], mass=2.0)
    sim = ws.Simulator(scene, integrator="rk4", device=device)
    for _ in range(100):
        sim.step(0.01)
    w, v0 = np.array([2.0, 0.0, -1.0]), np.array([0.0, 3.0, 0.0])
    np.testing.assert_allclose(sim.state.particle_v.numpy()[0], w + (v0 - w) * np.exp(-0.25), atol=1e-10)

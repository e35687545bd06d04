"""Captured steps (core.capture): a step recorded once as a Warp graph and replayed gives the uncaptured states bit
for bit, whatever the step sizes and the State parity; scenes whose launches change per step are not captured."""
import warnings

import numpy as np
import pytest

import warp_sim as ws


def _cloth():
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(8, 8), size=(1.0, 1.0), position=(0.0, 1.0, 0.0), mass=1.0, pinned=(0, 7),
                         stiffness=(500.0, 500.0, 50.0))
    scene.add_ground()
    return scene


def _tumbling():
    """Two bodies spinning in free fall, apart (collisions off): no contacts, so the step is the same every time."""
    scene = ws.Scene(angular_drag=0.01)
    scene.add_rigid_body(ws.Box((0.1, 0.2, 0.3)), position=(0.0, 5.0, 0.0), angular_velocity=(1.0, 5.0, 0.5))
    scene.add_rigid_body(ws.Capsule(0.1, 0.4), position=(3.0, 5.0, 0.0), angular_velocity=(-2.0, 0.3, 4.0))
    return scene


def _particles_in_a_vortex():
    scene = ws.Scene(drag=0.1)
    rng = np.random.default_rng(3)
    scene.add_particles(rng.uniform(-1.0, 1.0, (300, 3)) + (0.0, 2.0, 0.0), velocities=rng.normal(0.0, 1.0, (300, 3)))
    scene.add_field(ws.Vortex(position=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0), strength=2.0))
    scene.add_field(ws.Turbulence(strength=1.0, scale=0.5, frequency=0.0))
    scene.add_ground()
    return scene


FRAME_RATES = (240.0, 60.0, 24.0)   # bodies and particles: steps of 1/240, 1/60 and 1/24 s
CLOTH_RATES = (2400.0, 1200.0, 600.0)   # explicit cloth: stable steps of its springs


def _run(sim, rates):
    """Steps of three sizes, each an odd count (both States current at each size), the first size again between."""
    for rate, steps in ((rates[0], 7), (rates[1], 5), (rates[0], 3), (rates[2], 3)):
        sim.step(1.0 / rate, steps=steps)
    return sim


@pytest.mark.parametrize("build, integrator", [(_cloth, "symplectic_euler"), (_cloth, "rk4"),
                                               (_tumbling, "rk4"), (_tumbling, "verlet"),
                                               (_particles_in_a_vortex, "symplectic_euler")])
def test_captured_steps_equal_uncaptured_steps_bit_for_bit(build, integrator):
    rates = CLOTH_RATES if build is _cloth else FRAME_RATES
    plain = _run(ws.Simulator(build(), integrator=integrator, device="cpu", collisions=False), rates)
    captured = _run(ws.Simulator(build(), integrator=integrator, device="cpu", collisions=False,
                                  capture=True), rates)
    assert captured.captured and not plain.captured
    graphs = captured._graphs
    assert graphs.recorded == 6 and graphs.replays == 18 - 6   # 3 sizes x 2 parities recorded, the rest replayed
    assert captured.time == plain.time and captured.step_count == plain.step_count == 18
    for name in ("particle_x", "particle_v", "body_x", "body_q", "body_P", "body_L"):
        if getattr(plain.model, "body_count" if name.startswith("body") else "particle_count"):
            np.testing.assert_array_equal(getattr(captured.state, name).numpy(), getattr(plain.state, name).numpy())
    # free fall of the centre of mass, the closed form: y = 5 - g t^2 / 2 (the uncaptured run agrees, above)
    if build is _tumbling:
        assert abs(captured.state.body_x.numpy()[0][1] - (5.0 - 0.5 * 9.81 * captured.time ** 2)) < 1e-4


def test_an_invalidated_capture_is_recorded_again_and_changes_nothing():
    """Dropping the graphs (what a replaced array calls for) records them afresh on the next steps."""
    plain = ws.Simulator(_cloth(), integrator="symplectic_euler", device="cpu")
    captured = ws.Simulator(_cloth(), integrator="symplectic_euler", device="cpu", capture=True)
    for sim in (plain, captured):
        sim.step(1.0 / 600.0, steps=4)
    captured._graphs.invalidate()
    assert captured._graphs.graphs == {}
    for sim in (plain, captured):
        sim.step(1.0 / 600.0, steps=4)
    assert captured._graphs.recorded == 4
    np.testing.assert_array_equal(captured.state.particle_x.numpy(), plain.state.particle_x.numpy())


def test_the_guard_still_names_the_step_under_capture():
    scene = ws.Scene(precision="float64")
    scene.add_particles([[0.0, 1.0, 0.0], [0.0, 2.0, 0.0]])
    scene.add_ground()
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu", capture=True, max_speed=5.0)
    sim.step(1.0 / 60.0, steps=10)
    sim.state.particle_v.assign(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 50.0]]))
    with pytest.raises(ws.SimulationDiverged, match="step 11.*particle 1"):
        sim.step(1.0 / 60.0, steps=3)


def test_scenes_whose_launches_change_are_not_captured_and_say_why():
    """A pile reads its contact counts back and colours them on the host; a moving turbulence blends at each time."""
    scene = ws.Scene()
    scene.add_ground()
    scene.add_rigid_body(ws.Box(0.1), position=(0.0, 0.5, 0.0))
    with pytest.warns(UserWarning, match="BodyContacts"):
        sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu", capture=True)
    assert not sim.captured
    sim.step(1.0 / 60.0, steps=120)
    assert abs(sim.state.body_x.numpy()[0][1] - 0.1) < 2e-3   # it still simulates: the box rests on the ground
    moving = _particles_in_a_vortex()
    moving.fields[-1] = ws.Turbulence(strength=1.0, scale=0.5, frequency=2.0)
    with pytest.warns(UserWarning, match="FieldForces"):
        assert not ws.Simulator(moving, integrator="symplectic_euler", device="cpu", capture=True).captured
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert ws.Simulator(_cloth(), integrator="symplectic_euler", device="cpu", capture=True).captured
    with pytest.raises(ValueError, match="capture"):
        ws.Simulator(_cloth(), device="cpu", capture=1)

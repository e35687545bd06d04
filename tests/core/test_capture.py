"""Captured steps (core.capture): a step recorded once as a Warp graph and replayed gives the uncaptured states bit
for bit, whatever the step sizes and the State parity; scenes whose launches change per step are not captured."""
import warnings

import numpy as np
import pytest

import warp_sim as ws
from warp_sim.core.capture import StepGraphs


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
    # the first step runs uncaptured (primed), 3 sizes x 2 parities are recorded, the rest replayed
    assert graphs.recorded == 6 and graphs.replays == 18 - 1 - 6 and graphs.missed == 0
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
    """Penalty contacts read their contact counts back; a moving turbulence blends at each time."""
    scene = ws.Scene()
    scene.add_ground()
    scene.add_rigid_body(ws.Box(0.1), position=(0.0, 0.5, 0.0))
    with pytest.warns(UserWarning, match="BodyPenalty"):
        sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu", capture=True, contact="penalty")
    assert not sim.captured
    sim.step(1.0 / 60.0, steps=120)
    assert abs(sim.state.body_x.numpy()[0][1] - 0.1) < 5e-3   # it still simulates: the box rests on the ground
    moving = _particles_in_a_vortex()
    moving.fields[-1] = ws.Turbulence(strength=1.0, scale=0.5, frequency=2.0)
    with pytest.warns(UserWarning, match="FieldForces"):
        assert not ws.Simulator(moving, integrator="symplectic_euler", device="cpu", capture=True).captured
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert ws.Simulator(_cloth(), integrator="symplectic_euler", device="cpu", capture=True).captured
    with pytest.raises(ValueError, match="capture"):
        ws.Simulator(_cloth(), device="cpu", capture=1)


def _pile(count=16, seed=1):
    """Boxes and spheres dropped in a column onto the ground: contacts appear, grow and change colours as they land."""
    scene = ws.Scene()
    scene.add_ground(friction=0.5, restitution=0.2)
    rng = np.random.default_rng(seed)
    for k in range(count):
        shape = ws.Box((0.1, 0.1, 0.1)) if k % 2 == 0 else ws.Sphere(0.06)
        scene.add_rigid_body(shape, position=(rng.uniform(-0.2, 0.2), 0.2 + 0.25 * k, rng.uniform(-0.2, 0.2)))
    return scene


def _assert_same_bodies(a, b):
    for name in ("body_x", "body_q", "body_P", "body_L"):
        np.testing.assert_array_equal(getattr(a.state, name).numpy(), getattr(b.state, name).numpy())


@pytest.mark.slow   # piles twice each
@pytest.mark.parametrize("rates", [(500.0,), (60.0,), (500.0, 240.0)])
def test_a_captured_pile_equals_the_uncaptured_pile_bit_for_bit_through_its_misses(rates):
    """The contact pass is captured: launches over the last uncaptured counts and colours with headroom, gated on
    the device. Where a step outgrows them (a new colour as bodies land), it is done again uncaptured and the
    graphs kept or recorded afresh; every step still equals the uncaptured run. At 1/60 s each step is two pieces;
    (500, 240): the step size alternates every 50 steps, so graphs of one size are recorded while the other's live."""
    plain = ws.Simulator(_pile(), integrator="symplectic_euler", device="cpu")
    captured = ws.Simulator(_pile(), integrator="symplectic_euler", device="cpu", capture=True)
    assert captured.captured
    steps = int(2.5 * max(rates))
    pieces = 0
    for k in range(steps):
        rate = rates[(k // 50) % len(rates)]
        plain.step(1.0 / rate)
        captured.step(1.0 / rate)
        pieces += captured.substeps(1.0 / rate)
        if k % 25 == 0 or k == steps - 1:
            _assert_same_bodies(plain, captured)
    graphs = captured._graphs
    assert graphs.missed > 0 and graphs.replays > 0.5 * pieces   # misses back off: a few hundred pieces uncaptured
    # the bodies landed: no centre nearer the ground than its half size (box 0.1 m, sphere 0.06 m) less 2 mm, and
    # no vertical speed above 5 % of the top body's landing speed sqrt(2 g h) (the spheres may roll, a box tip)
    y = captured.state.body_x.numpy()[:, 1]
    assert np.all(y >= np.where(np.arange(y.size) % 2 == 0, 0.1, 0.06) - 2e-3)
    landing = np.sqrt(2.0 * 9.81 * (0.2 + 0.25 * (y.size - 1)))
    assert np.abs(captured.body_velocities()[0].numpy()[:, 1]).max() < 0.05 * landing


def test_a_buffer_that_grows_during_a_captured_step_makes_a_new_capture():
    """Buffers shrunk to a few entries before the first step: the bodies land during captured steps, the contacts
    outgrow the buffers inside a replay, the gate leaves that step undone, and it is done again uncaptured (which
    grows them) and the next steps recorded afresh, with the uncaptured run's states."""
    sims = [ws.Simulator(_pile(count=6), integrator="symplectic_euler", device="cpu", capture=capture)
            for capture in (False, True)]
    for sim in sims:
        detection = sim.body_contacts.detection
        detection.pairs._allocate(2)
        detection.contacts._allocate(4)
    plain, captured = sims
    captured.step(1.0 / 240.0)   # the first step runs uncaptured, in the air: nothing grows
    plain.step(1.0 / 240.0)
    assert captured.body_contacts.detection.contacts.grows == 0
    recorded = captured._graphs.recorded
    for _ in range(360):
        plain.step(1.0 / 240.0)
        captured.step(1.0 / 240.0)
    detection = captured.body_contacts.detection
    assert detection.contacts.grows > 0 and detection.contacts.capacity > 4 and detection.pairs.capacity > 2
    assert detection.contacts.grows == plain.body_contacts.detection.contacts.grows
    assert captured._graphs.missed >= detection.contacts.grows and captured._graphs.recorded > recorded + 2
    _assert_same_bodies(plain, captured)


def test_misses_keep_the_graphs_until_they_pile_up_then_recording_backs_off():
    """A miss whose redo reallocated nothing keeps the graphs (replayed on); the ``refresh``-th miss since the last
    recording, or one that reallocated a buffer, drops them, and the next recording waits ``backoff`` steps,
    doubled each time (a recording costs as much as a hundred CPU steps; a landing pile misses often)."""
    graphs = StepGraphs(model=None)
    graphs.graphs = {"a": object()}
    graphs.waiting = 0
    for _ in range(graphs.refresh - 1):
        graphs.miss(intact=True)
    assert graphs.graphs and graphs.waiting == 0 and graphs.missed == graphs.refresh - 1
    graphs.miss(intact=True)
    assert not graphs.graphs and graphs.waiting == graphs.first_backoff and graphs.backoff == 2 * graphs.first_backoff
    graphs.graphs = {"a": object()}
    graphs.miss(intact=False)   # a buffer grew: the graphs point at freed arrays
    assert not graphs.graphs and graphs.waiting == 2 * graphs.first_backoff
    for _ in range(20):
        graphs.miss(intact=False)
    assert graphs.backoff == graphs.longest_backoff

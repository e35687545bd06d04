"""Particle emitters against closed forms: live counts, lifetimes, ids, bursts, sampling ranges,
reproducibility, pools that fill up, attributes over life, shapes, kill planes and bounces."""
import math

import numpy as np
import pytest
from helpers import G

import warp_sim as ws


def emitter_sim(integrator="symplectic_euler", device="cpu", gravity=(0.0, -G, 0.0), ground=None, **emitter):
    """A float64 scene with one emitter (and a ground of restitution `ground` if given)."""
    scene = ws.Scene(gravity=gravity, precision="float64")
    if ground is not None:
        scene.add_ground(restitution=ground, friction=0.0)
    scene.add_emitter(**emitter)
    return ws.Simulator(scene, integrator=integrator, device=device)


def live(sim, pool=0):
    """(ids, ages, lifetimes, x, v, colour, opacity, radius) of the live particles of one emitter, in slot order."""
    p = sim.emitters.pools[pool]
    start, n = p.e.start_slot, p.e.capacity
    mask = p.alive.numpy().astype(bool)
    rows = slice(start, start + n)
    return dict(ids=p.ids.numpy()[mask], age=p.age.numpy()[mask], lifetime=p.lifetime.numpy()[mask],
                x=sim.state.particle_x.numpy()[rows][mask], v=sim.state.particle_v.numpy()[rows][mask],
                color=p.color.numpy()[mask], opacity=p.opacity.numpy()[mask],
                radius=sim.model.particle_radius.numpy()[rows][mask], slots=np.flatnonzero(mask))


def test_live_count_follows_rate_and_lifetime_every_frame(device):
    """Rate r, constant lifetime T: r min(t, T) live at every step, within one particle."""
    r, T, h = 100.0, 0.5, 1.0 / 120.0
    sim = emitter_sim(device=device, rate=r, lifetime=T, speed=1.0)
    for _ in range(180):
        sim.step(h)
        count = sim.emitter_stats()[0]["live"]
        assert abs(count - r * min(sim.time, T)) <= 1.0, (sim.time, count)


def test_lifetimes_ids_and_slot_reuse():
    """No particle is older than its lifetime; every id is unique and new ids increase; a pool
    smaller than the number of births reuses dead slots."""
    sim = emitter_sim(rate=200.0, lifetime=(0.1, 0.3), speed=(1.0, 2.0))
    seen, slots_used, newest = set(), set(), -1
    for _ in range(120):
        sim.step(1.0 / 120.0)
        state = live(sim)
        assert np.all(state["age"] < state["lifetime"]) and np.all(state["age"] >= 0.0)
        assert np.all((state["lifetime"] >= 0.1 - 1e-6) & (state["lifetime"] <= 0.3 + 1e-6))
        new = np.setdiff1d(state["ids"], np.fromiter(seen, dtype=np.int64, count=len(seen)))
        assert len(np.unique(state["ids"])) == len(state["ids"])
        if len(new):
            assert new.min() > newest           # ids are handed out in increasing order
            newest = new.max()
        seen.update(state["ids"].tolist())
        slots_used.update(state["slots"].tolist())
    stats = sim.emitter_stats()[0]
    assert stats["born"] > stats["capacity"] >= len(slots_used) and stats["skipped"] == 0


def test_same_seed_reproduces_and_other_seed_differs():
    def run(seed):
        sim = emitter_sim(rate=300.0, lifetime=(0.2, 0.6), spread=40.0, speed=(1.0, 3.0), shape="ball", radius=0.2,
                          seed=seed)
        sim.step(1.0 / 100.0, 50)
        state = live(sim)
        return state["ids"], state["x"]

    ids_a, x_a = run(7)
    ids_b, x_b = run(7)
    ids_c, x_c = run(8)
    assert np.array_equal(ids_a, ids_b) and np.array_equal(x_a, x_b)     # bit for bit
    assert not (np.array_equal(ids_a, ids_c) and np.allclose(x_a, x_c))  # other draws (lifetimes, places)


def test_burst_appears_at_its_frame_and_dies_after_its_lifetime(device):
    sim = emitter_sim(device=device, rate=0.0, bursts=[(0.5, 20)], lifetime=0.3, speed=0.5)
    counts = {}
    for _ in range(100):
        sim.step(0.01)
        counts[round(sim.time, 6)] = sim.emitter_stats()[0]["live"]
    assert counts[0.49] == 0 and counts[0.5] == 20 and counts[0.79] == 20 and counts[0.8] == 0
    assert sim.emitter_stats()[0]["born"] == 20


def test_burst_at_time_zero_is_in_the_initial_state():
    sim = emitter_sim(rate=0.0, bursts=[(0.0, 5)], lifetime=1.0, position=(1.0, 2.0, 3.0), speed=0.0)
    state = live(sim)
    assert len(state["ids"]) == 5 and np.allclose(state["x"], [1.0, 2.0, 3.0])


def test_speeds_and_directions_lie_in_range_and_cone():
    """10^5 births at once: every speed in [2, 4] m/s and direction within 25 degrees of the axis;
    the mean speed is within 1 % of 3 m/s; the directions fill the cone (uniform over the cap)."""
    axis = np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0)
    sim = emitter_sim(gravity=(0.0, 0.0, 0.0), rate=0.0, bursts=[(0.0, 100_000)], lifetime=1.0, direction=axis,
                      spread=25.0, speed=(2.0, 4.0))
    v = live(sim)["v"]
    speed = np.linalg.norm(v, axis=1)
    assert len(v) == 100_000
    assert speed.min() >= 2.0 - 1e-6 and speed.max() <= 4.0 + 1e-6
    assert abs(speed.mean() - 3.0) < 0.01 * 3.0
    cos_angle = (v @ axis) / speed
    assert cos_angle.min() >= math.cos(math.radians(25.0)) - 1e-6
    # uniform over the cap: cos(angle) is uniform on [cos 25 deg, 1], so its mean is the midpoint
    assert abs(cos_angle.mean() - 0.5 * (1.0 + math.cos(math.radians(25.0)))) < 1e-3


@pytest.mark.parametrize("shape, extra, on_shape", [
    ("disc", dict(radius=0.5), lambda p: (abs(p[:, 1]) < 1e-9) & (np.hypot(p[:, 0], p[:, 2]) <= 0.5 + 1e-9)),
    ("sphere", dict(radius=0.5), lambda p: abs(np.linalg.norm(p, axis=1) - 0.5) < 1e-6),
    ("ball", dict(radius=0.5), lambda p: np.linalg.norm(p, axis=1) <= 0.5 + 1e-6),
    ("box", dict(half_extents=(0.1, 0.2, 0.3)), lambda p: np.all(np.abs(p) <= [0.1 + 1e-7, 0.2 + 1e-7, 0.3 + 1e-7], 1)),
])
def test_emitter_shapes_place_births_on_the_shape(shape, extra, on_shape):
    centre = np.array([1.0, 2.0, 3.0])
    sim = emitter_sim(gravity=(0.0, 0.0, 0.0), rate=0.0, bursts=[(0.0, 2000)], lifetime=1.0, position=centre,
                      speed=0.0, shape=shape, **extra)
    p = live(sim)["x"] - centre
    assert np.all(on_shape(p))
    assert np.ptp(p, axis=0).max() > 0.1          # spread over the shape, not at one point


def test_mesh_surface_and_normal_direction():
    """Births on a box mesh's surface, moving along the outward face normal."""
    trimesh = pytest.importorskip("trimesh")
    sim = emitter_sim(gravity=(0.0, 0.0, 0.0), rate=0.0, bursts=[(0.0, 3000)], lifetime=1.0, speed=1.0,
                      shape="mesh", mesh=trimesh.creation.box(extents=(2.0, 4.0, 6.0)), direction="normal",
                      spread=0.0)
    state = live(sim)
    p, v = state["x"], state["v"]
    scaled = np.abs(p) / [1.0, 2.0, 3.0]
    assert np.allclose(scaled.max(axis=1), 1.0, atol=1e-6)              # on a face
    face = np.argmax(scaled, axis=1)
    assert np.allclose(np.abs(v[np.arange(len(v)), face]), 1.0, atol=1e-6)   # along that face's normal
    assert np.all(v[np.arange(len(v)), face] * p[np.arange(len(p)), face] > 0)  # outwards
    # by area: the two 4 x 6 faces (normal x) hold 48 / 88 of the births
    assert abs(np.mean(face == 0) - 48.0 / 88.0) < 0.03


def test_full_pool_skips_and_counts_births_without_overwriting():
    sim = emitter_sim(rate=100.0, lifetime=1.0, capacity=5, speed=0.0)
    with pytest.warns(UserWarning, match="5 was full"):
        sim.run(seconds=0.5, fps=100, substeps=1, progress=False)
    stats = sim.emitter_stats()[0]
    wanted = math.floor(100.0 * sim.time + 0.5)        # births due by now (49 steps: frame 0 is the start)
    assert stats["live"] == 5 and stats["born"] == 5 and stats["skipped"] == wanted - 5
    assert sorted(live(sim)["ids"].tolist()) == [0, 1, 2, 3, 4]       # the first five, never overwritten


def test_colour_opacity_and_size_ramps_follow_normalised_age():
    color = ws.Ramp([0.0, 1.0], [(1.0, 0.0, 0.0), (0.0, 0.0, 1.0)])
    opacity = ws.Ramp([0.0, 0.5, 1.0], [1.0, 1.0, 0.0])
    size = ws.Ramp([0.0, 1.0], [0.01, 0.05])
    sim = emitter_sim(rate=50.0, lifetime=2.0, speed=1.0, color=color, opacity=opacity, size=size)
    sim.step(0.01, 150)
    state = live(sim)
    s = state["age"] / 2.0
    assert len(s) > 50
    assert np.allclose(state["color"], np.stack([1.0 - s, 0 * s, s], axis=1), atol=2e-5)
    assert np.allclose(state["opacity"], np.where(s <= 0.5, 1.0, 2.0 * (1.0 - s)), atol=2e-5)
    assert np.allclose(state["radius"], 0.01 + 0.04 * s, atol=2e-6)


def test_colour_and_opacity_ranges_are_drawn_at_birth():
    sim = emitter_sim(rate=0.0, bursts=[(0.0, 1000)], lifetime=1.0, color=((0.0, 0.5, 1.0), (1.0, 0.5, 1.0)),
                      opacity=(0.2, 0.4), speed=0.0)
    state = live(sim)
    assert np.all((state["color"][:, 0] >= 0.0) & (state["color"][:, 0] <= 1.0)) and np.ptp(state["color"][:, 0]) > 0.9
    assert np.allclose(state["color"][:, 1:], [0.5, 1.0])
    assert np.all((state["opacity"] >= 0.2 - 1e-7) & (state["opacity"] <= 0.4 + 1e-7))


def test_particles_emitted_onto_the_ground_bounce_with_restitution():
    """A particle dropped from 1 m by an emitter bounces to e^2 m (e = 0.8), within 1e-3 relative."""
    sim = emitter_sim(integrator="rk4", ground=0.8, rate=0.0, bursts=[(0.0, 1)], lifetime=10.0,
                      position=(0.0, 1.0, 0.0), speed=0.0, size=0.0)
    heights, speeds = [], []
    for _ in range(300):
        sim.step(1.0 / 240.0)
        heights.append(live(sim)["x"][0, 1])
        speeds.append(live(sim)["v"][0, 1])
    heights, speeds = np.array(heights), np.array(speeds)
    first_bounce = np.flatnonzero(speeds > 0)[0]          # the first step ending on the way up
    assert heights.min() >= 0.0
    assert heights[first_bounce:].max() == pytest.approx(0.64, rel=1e-3)


def test_kill_plane_and_kill_on_contact():
    sim = emitter_sim(rate=100.0, lifetime=5.0, speed=0.0, position=(0.0, 1.0, 0.0),
                      kill_planes=[((0.0, 1.0, 0.0), 0.5)])
    sim.step(0.01, 100)
    assert live(sim)["x"][:, 1].min() >= 0.5 - 1e-12          # nothing lives below y = 0.5
    fall = math.sqrt(2 * 0.5 / G)                               # time to fall 0.5 m
    assert abs(sim.emitter_stats()[0]["live"] - 100.0 * fall) <= 2.0
    sim = emitter_sim(ground=0.5, rate=100.0, lifetime=5.0, speed=0.0, position=(0.0, 0.3, 0.0),
                      kill_on_contact=True)
    sim.step(0.01, 100)
    assert abs(sim.emitter_stats()[0]["live"] - 100.0 * math.sqrt(2 * 0.3 / G)) <= 2.0


def test_fixed_particles_and_emitters_share_the_simulation():
    scene = ws.Scene(precision="float64")
    fixed = scene.add_particles([[0.0, 5.0, 0.0]], name="ball")
    scene.add_emitter(rate=10.0, lifetime=1.0, speed=1.0)
    sim = ws.Simulator(scene, integrator="verlet", device="cpu")
    sim.step(0.01, 100)
    y = sim.state.particle_x.numpy()[fixed[0], 1]
    assert y == pytest.approx(5.0 - 0.5 * G * sim.time**2, abs=1e-9)
    assert sim.emitter_stats()[0]["live"] == 10


@pytest.mark.parametrize("kwargs, argument", [
    (dict(rate=-1.0), "rate"),
    (dict(rate=float("nan")), "rate"),
    (dict(lifetime=(2.0, 1.0)), "lifetime"),
    (dict(lifetime=0.0), "lifetime"),
    (dict(capacity=0), "capacity"),
    (dict(spread=-1.0), "spread"),
    (dict(spread=181.0), "spread"),
    (dict(position=(0.0, float("nan"), 0.0)), "position"),
    (dict(direction=(0.0, 0.0, 0.0)), "direction"),
    (dict(speed=(3.0, float("nan"))), "speed"),
    (dict(mass=0.0), "mass"),
    (dict(color=(1.0, 2.0, 0.0)), "color"),
    (dict(opacity=1.5), "opacity"),
    (dict(shape="cone"), "shape"),
    (dict(shape="disc"), "radius"),
    (dict(shape="box", half_extents=(1.0, -1.0, 1.0)), "half_extents"),
    (dict(direction="normal"), "direction"),
    (dict(bursts=[(1.0, 0)]), "bursts"),
    (dict(rate=0.0), "rate"),
    (dict(seed=-1), "seed"),
    (dict(seed=1.5), "seed"),
])
def test_bad_emitter_input_names_the_argument(kwargs, argument):
    with pytest.raises(ValueError, match=rf"^{argument}="):
        ws.Scene().add_emitter(**kwargs)


def test_bad_ramp_and_a_step_longer_than_a_lifetime():
    with pytest.raises(ValueError, match="^keys="):
        ws.Ramp([0.5, 0.2], [1.0, 0.0])
    with pytest.raises(ValueError, match="^values="):
        ws.Ramp([0.0, 1.0], [1.0])
    sim = emitter_sim(rate=10.0, lifetime=(0.05, 0.1))
    with pytest.raises(ValueError, match="^dt="):
        sim.step(0.06)


def test_usd_points_per_emitter_change_count_with_matching_arrays(tmp_path):
    """Per frame: points, ids, widths, velocities, colours and opacities have one length, the
    live count (r min(t, T) within one particle); ids are unique int64; the stage validates."""
    from pxr import Usd, UsdGeom

    from warp_sim.stages import validate_stage

    sim = emitter_sim(rate=120.0, lifetime=0.25, speed=(1.0, 2.0), name="fountain",
                      opacity=ws.Ramp([0.0, 1.0], [1.0, 0.0]))
    path = sim.run(seconds=0.5, fps=60, substeps=2, usd=tmp_path / "fountain.usdc", progress=False)
    stage = Usd.Stage.Open(str(path))
    assert validate_stage(stage) == []
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/fountain"))
    opacity = UsdGeom.PrimvarsAPI(points).GetPrimvar("displayOpacity")
    for frame in range(30):
        x = points.GetPointsAttr().Get(frame)
        arrays = [points.GetIdsAttr().Get(frame), points.GetWidthsAttr().Get(frame),
                  points.GetVelocitiesAttr().Get(frame), points.GetDisplayColorAttr().Get(frame), opacity.Get(frame)]
        assert all(len(a) == len(x) for a in arrays), frame
        assert abs(len(x) - 120.0 * min(frame / 60.0, 0.25)) <= 1.0
        ids = np.array(arrays[0])
        assert len(np.unique(ids)) == len(ids)
        assert np.all((np.array(arrays[4]) >= 0.0) & (np.array(arrays[4]) <= 1.0))

"""Stable substeps by default: sim.step(dt) and run() split a step into the pieces the scene's stiffest mode and
the solver's stability interval need (substeps="auto"); explicit counts are honoured and warn when too few."""
import math
import warnings

import numpy as np
import pytest

import warp_sim as ws
from warp_sim.demo import JOINT_STEP, demo_scene
from warp_sim.solvers.stability import SAFETY
from warp_sim.studies.frame_rate import FRAME_SCENES, frame_rate_row, holds


def in_the_scene(sim, start_low, start_high, reach=10.0, max_speed=200.0) -> bool:
    """Finite, within ``reach`` [m] of the starting bounding box and slower than ``max_speed`` [m/s]."""
    x, v = sim.state.particle_x.numpy(), sim.state.particle_v.numpy()
    return bool(np.isfinite(x).all() and (x >= start_low - reach).all() and (x <= start_high + reach).all()
                and (np.linalg.norm(v, axis=1) <= max_speed).all())


@pytest.mark.parametrize("dt", [1 / 60, 1 / 24])
@pytest.mark.parametrize("integrator", [None, "rk4", "symplectic_euler", "verlet"])
def test_the_demo_holds_at_the_step_everyone_writes(integrator, dt):
    """sim.step(1/60) and sim.step(1/24) for 2 s with the defaults: before, every explicit solver diverged at step 5
    (two pieces of 1/120 s are past rk4's 2.83 / omega for the chain's omega = 400 rad/s). Every particle stays
    finite, within 10 m of the scene and below 200 m/s; every body above the ground's margin."""
    scene = demo_scene()
    start = scene.particle_array("position")
    sim = ws.Simulator(scene, **({} if integrator is None else {"integrator": integrator}))
    assert sim.substeps(dt) >= math.ceil(dt * sim.step_limit.omega * SAFETY / 2.83)
    for _ in range(round(2.0 / dt)):
        sim.step(dt)
    assert in_the_scene(sim, start.min(axis=0), start.max(axis=0))
    assert sim.state.body_x.numpy()[:, 1].min() > 0.0


def test_a_stiff_cloth_holds_at_frame_rate_and_takes_the_substeps_theory_gives():
    """A 32^2 cloth of stiffness 1e5 N/m in every family, 1 kg, hanging from two corners, at sim.step(1/60) under
    rk4: omega^2 -> 10.1 k/m of its lightest (corner) vertices; auto takes ceil(dt omega / (0.95 * 2.83)) pieces and
    the cloth hangs still."""
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(32, 32), size=(1.0, 1.0), position=(0.0, 1.0, 0.0), mass=1.0,
                         stiffness=(1e5, 1e5, 1e5), damping=(0.1, 0.1, 0.01), pinned=["top_corners"])
    start = scene.particle_array("position")
    sim = ws.Simulator(scene)
    omega = sim.step_limit.omega
    assert 28000.0 < omega < 45000.0
    assert sim.substeps(1 / 60) == math.ceil((1 / 60) / sim.step_limit.step)
    assert sim.step_limit.step == pytest.approx(SAFETY * sim.step_limit.longest)
    assert sim.step_limit.longest * omega == pytest.approx(2.83, rel=0.02)
    for _ in range(60):
        sim.step(1 / 60)
    assert in_the_scene(sim, start.min(axis=0), start.max(axis=0), reach=1.5, max_speed=20.0)


def test_an_explicit_count_is_honoured_and_warns_once_when_too_few():
    """substeps=2 on the demo under rk4 takes exactly 2 pieces (the contact step's) and warns once, naming the
    limit and the stable count; substeps=4 takes 4 and does not warn. (The demo's joint_step, as `warp-sim demo`
    runs it: the default 1/480 s would split every piece into the joints' own.)"""
    sim = ws.Simulator(demo_scene(), integrator="rk4", joint_step=JOINT_STEP)
    stable = sim.substeps(1 / 60)
    with pytest.warns(RuntimeWarning, match=rf"substeps=2 gives steps of 0.008333 s, longer than rk4's stable "
                                            rf"step on this scene, .* {stable} substeps of a 0.01667 s step would be "
                                            "stable"):
        sim.step(1 / 60, substeps=2)
    assert sim._substeps.pieces(1 / 60, 2) == 2
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.step(1 / 60, substeps=2)   # once per Simulator
        sim.step(1 / 60, substeps=4)
    assert sim._substeps.pieces(1 / 60, 4) == 4 and sim.step_count == 3


def test_run_takes_auto_substeps_per_frame_and_counts_one_step_a_frame(tmp_path):
    """run() defaults to substeps="auto": one step(1 / fps) a frame, split as step() splits it; an explicit count
    is that many steps of 1 / (fps n) a frame, as before."""
    scene = ws.Scene()
    ids = scene.add_particles([(0.1 * i, 1.0, 0.0) for i in range(6)], mass=0.01, pinned=[0])
    scene.add_springs(np.stack([ids[:-1], ids[1:]], axis=1), stiffness=1e4)
    sim = ws.Simulator(scene, integrator="symplectic_euler")
    assert sim.substeps(1 / 30) > 1
    sim.run(seconds=0.5, fps=30, usd=tmp_path / "auto.usda", progress=False)
    assert sim.step_count == 14   # 15 frames: frame 0 is the initial state
    explicit = ws.Simulator(scene, integrator="symplectic_euler")
    count = sim.substeps(1 / 30)
    explicit.run(seconds=0.5, fps=30, substeps=count, progress=False)
    assert explicit.step_count == 14 * count
    np.testing.assert_array_equal(explicit.state.particle_x.numpy(), sim.state.particle_x.numpy())


def test_euler_and_midpoint_on_springs_say_they_grow_at_any_step_and_rigid_scenes_keep_the_contact_step():
    scene = ws.Scene()
    scene.add_particles([[0.0, 1.0, 0.0], [0.1, 1.0, 0.0]], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=100.0)
    for name in ("euler", "midpoint"):
        with pytest.warns(UserWarning, match=f"integrator='{name}' grows an undamped oscillator at any step"):
            ws.Simulator(scene, integrator=name)
    rigid = ws.Scene()
    rigid.add_ground()
    rigid.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), position=(0.0, 0.1, 0.0))
    sim = ws.Simulator(rigid)
    assert sim.step_limit.step == math.inf and sim.substeps(1 / 60) == 2 and sim.substeps(1 / 240) == 1


def test_penalty_contacts_limit_the_step_by_the_lightest_particle():
    """contact="penalty" with k = 1e6 N/m on 1 g particles: omega = sqrt(k / m) = 3.16e4 rad/s, critically damped."""
    scene = ws.Scene()
    scene.add_ground()
    scene.add_particles([[0.0, 0.5, 0.0]], mass=1e-3)
    sim = ws.Simulator(scene, integrator="symplectic_euler", contact="penalty", penalty_stiffness=1e6)
    assert sim.step_limit.omega == pytest.approx(math.sqrt(1e9))
    assert sim.step_limit.longest * sim.step_limit.omega == pytest.approx(2.0 * math.sqrt(2.0) - 2.0, rel=1e-5)


@pytest.mark.parametrize("value", [0, -1, 1.5, "many", True])
def test_bad_substeps_are_named(value):
    sim = ws.Simulator(demo_scene())
    with pytest.raises(ValueError, match="substeps.*expected 'auto' or an integer >= 1"):
        sim.step(1 / 60, substeps=value)


def test_the_frame_rate_study_finds_auto_within_a_quarter_of_the_fewest_that_hold():
    """The demo under rk4 at 1/60 s: the bisected fewest substeps that hold, and auto at most 1.25 times it
    (the full study's table has the benchmark cloths too); the count just below the fewest does not hold."""
    row = frame_rate_row("demo", "rk4", "cpu")
    assert row["fewest"] <= row["auto"] <= 1.25 * row["fewest"]
    assert not holds(FRAME_SCENES["demo"], "rk4", row["fewest"] - 1, "cpu")


def test_run_warns_in_the_terms_of_its_own_count(tmp_path):
    """run(substeps=2) on the demo under rk4 warns about 2 substeps of a 1/60 s frame (not the 1 of each step it
    takes inside), with the count that would hold the frame."""
    sim = ws.Simulator(demo_scene(), integrator="rk4", joint_step=JOINT_STEP)
    stable = sim.substeps(1 / 60)
    with pytest.warns(RuntimeWarning, match=rf"substeps=2 gives steps of 0.008333 s, .* {stable} substeps of a "
                                            r"0.01667 s step would be stable"):
        sim.run(seconds=2 / 60, fps=60, substeps=2, progress=False)   # frames 0 and 1: one frame stepped

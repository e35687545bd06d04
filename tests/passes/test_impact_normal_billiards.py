"""Two spheres meeting off-centre respond along the line of centres at their time of impact inside the step
(kernels.contacts.impact_normal), not at the start of the step: a billiards cut shot and a ball glancing off a
static sphere against their closed forms, at the default steps of sim.step(1/60) (two contact steps of 1/120 s).

Before the fix the normal was the narrow phase's at the start of the step, a step's worth of relative motion off,
so the red's path depended on where the step boundaries fell: its final position against the cue's speed was a
sawtooth (jumps of 9 to 12 mm every 0.04 m/s here). Every scene is float64, frictionless, e = 1, gravity off.
"""
import math

import numpy as np
import pytest

import warp_sim as ws

R, MASS = 0.05, 0.17          # the balls: radius [m], mass [kg]
OFFSET = 0.5 * 2.0 * R        # the impact parameter b: the red's centre off the cue's line [m]
RED = np.array([0.3, R, OFFSET])
SECONDS, FPS = 0.5, 60
CUT = math.asin(OFFSET / (2.0 * R))   # the red leaves at this angle from the cue's direction (30 degrees)


def table(speed: float) -> ws.Scene:
    """The cue ball at the origin moving along +x at ``speed`` [m/s], the red at rest at RED, on the plane y = R."""
    scene = ws.Scene(precision="float64", gravity=(0.0, 0.0, 0.0))
    for position, velocity in (((0.0, R, 0.0), (speed, 0.0, 0.0)), (tuple(RED), (0.0, 0.0, 0.0))):
        scene.add_rigid_body(ws.Sphere(R), mass=MASS, position=position, linear_velocity=velocity, restitution=1.0,
                             friction=0.0)
    return scene


def red_after(speed: float) -> tuple[np.ndarray, np.ndarray]:
    """The red's position and velocity after SECONDS of sim.step(1/60) with the default substeps."""
    sim = ws.Simulator(table(speed))
    sim.step(1.0 / FPS, steps=round(SECONDS * FPS))
    return sim.state.body_x.numpy()[1].copy(), sim.body_velocities()[0].numpy()[1].copy()


def red_closed_form(speed: float) -> np.ndarray:
    """Equal masses, e = 1, frictionless: at the impact (the cue's centre 2R from the red's, at x = x_red - 2R cos
    CUT) the red takes the cue's velocity along the line of centres n = (cos CUT, 0, sin CUT), speed u cos CUT, and
    goes straight on."""
    impact = (RED[0] - 2.0 * R * math.cos(CUT)) / speed
    n = np.array([math.cos(CUT), 0.0, math.sin(CUT)])
    return RED + n * speed * math.cos(CUT) * (SECONDS - impact)


def test_the_red_leaves_along_the_line_of_centres_at_the_impact():
    """The red's direction after the hit is asin(b / 2R) = 30 degrees from the cue's within 1e-3 degrees and its
    speed u cos(30 degrees) within 1e-6 relative. Measured (u = 1 m/s): 28.6105 degrees (1.39 off) and 1.2e-2 before
    the fix, 0 degrees (to double rounding) and 2e-14 after."""
    _, v = red_after(1.0)
    angle = math.degrees(math.atan2(v[2], v[0]))
    print(f"angle {angle:.8f} deg, speed {np.linalg.norm(v):.10f} (closed form {math.cos(CUT):.10f})")
    assert abs(v[1]) < 1e-12
    assert angle == pytest.approx(math.degrees(CUT), abs=1e-3)
    assert np.linalg.norm(v) == pytest.approx(math.cos(CUT), rel=1e-6)


def test_the_red_s_final_position_is_smooth_in_the_cue_s_speed():
    """Over 21 cue speeds from 0.9 to 1.1 m/s (impacts at every phase of the steps: the impact time moves by 0.045 s)
    the red's final position matches the closed form within 1 mm and its x has second differences below 1e-6 m (the
    closed form's are 0: x is linear in u). Measured: 12.0 mm off and second differences of 10.2 mm before the fix
    (jumps of 9 to 12 mm every 0.04 m/s), 1.6e-8 m and 1.4e-8 m after (the narrow phase's float32 centres)."""
    speeds = np.linspace(0.9, 1.1, 21)
    final = np.array([red_after(u)[0] for u in speeds])
    off = np.linalg.norm(final - np.array([red_closed_form(u) for u in speeds]), axis=1)
    bends = np.abs(np.diff(final[:, 0], 2))
    print(f"largest miss {off.max():.2e} m, largest second difference {bends.max():.2e} m")
    assert off.max() < 1e-3
    assert bends.max() < 1e-6


def test_a_ball_glancing_off_a_static_sphere_reflects_about_the_normal_at_the_impact():
    """A ball (e = 1) moving along +x past a static sphere of radius 2R whose centre is 0.6 (R + 2R) off its line
    reflects about the line of centres at the impact, n = (-cos a, 0, -sin a) with sin a = 0.6: it leaves with
    v - 2 (v . n) n within 1e-6 m/s (of 1 m/s). Measured: 3.7e-2 before the fix, 3.7e-8 after."""
    reach = 3.0 * R
    scene = ws.Scene(precision="float64", gravity=(0.0, 0.0, 0.0))
    scene.add_rigid_body(ws.Sphere(R), mass=MASS, position=(0.0, R, 0.0), linear_velocity=(1.0, 0.0, 0.0),
                         restitution=1.0, friction=0.0)
    scene.add_collider(ws.Sphere(2.0 * R), position=(0.3, R, 0.6 * reach), restitution=1.0, friction=0.0)
    sim = ws.Simulator(scene)
    sim.step(1.0 / FPS, steps=round(SECONDS * FPS))
    v = sim.body_velocities()[0].numpy()[0]
    n = -np.array([math.sqrt(1.0 - 0.36), 0.0, 0.6])
    expected = np.array([1.0, 0.0, 0.0]) - 2.0 * n[0] * n
    error = np.linalg.norm(v - expected)
    print(f"outgoing velocity {v}, expected {expected}, {error:.1e} apart")
    assert error < 1e-6

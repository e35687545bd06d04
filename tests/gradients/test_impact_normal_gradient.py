"""The gradient of an off-centre billiards hit through the normal at the time of impact (kernels.contacts
impact_normal, taped in kernels.contact_adjoint.taped_rows): the red's final position against the cue's velocity,
now a smooth function of it, against central differences and, along the cue's line, the closed form.

Float64, frictionless, e = 1, gravity off, steps of 1/120 s (ws.gradient at 60 fps, 2 substeps).
"""
import math

import numpy as np
import pytest
import warp as wp
from gradient_scenes import forward_value

import warp_sim as ws

R, MASS = 0.05, 0.17
RED = np.array([0.3, R, 0.5 * 2.0 * R])   # the red 0.5 (2R) off the cue's line
CUT = math.asin(RED[2] / (2.0 * R))        # the red leaves at 30 degrees
SECONDS, FPS, SUBSTEPS = 0.5, 60.0, 2
WEIGHTS = (0.6, 0.0, 0.9)


def table(cue) -> ws.Scene:
    """The cue ball at the origin with velocity (cue[0], 0, cue[1]) [m/s], the red at rest at RED."""
    scene = ws.Scene(precision="float64", gravity=(0.0, 0.0, 0.0))
    for position, velocity in (((0.0, R, 0.0), (cue[0], 0.0, cue[1])), (tuple(RED), (0.0, 0.0, 0.0))):
        scene.add_rigid_body(ws.Sphere(R), mass=MASS, position=position, linear_velocity=velocity, restitution=1.0,
                             friction=0.0)
    return scene


@wp.kernel
def weighted_red(x: wp.array2d(dtype=wp.vec3d), frame: int, w: wp.vec3d, out: wp.array(dtype=wp.float64)):
    out[0] = wp.dot(w, x[frame, 1])


def loss(traj):
    """WEIGHTS . the red's final position."""
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    wp.launch(weighted_red, 1, [traj.body_x, traj.frames, wp.vec3d(*WEIGHTS), out])
    return out


def value(cue) -> float:
    return ws.gradient(table(cue), loss, seconds=SECONDS, fps=FPS, substeps=SUBSTEPS)


def test_the_red_s_final_position_against_the_cue_velocity_matches_central_differences():
    """d(w . red(T)) / d(cue v_x, v_z) matches central differences of the same runs (step 1e-5 m/s) within 1e-5
    relative, and d/dv_x the closed form w . n cos(CUT) T (the red leaves along n at u cos CUT, from an impact at
    t* = x* / u: red(T) = RED + n cos(CUT) (u T - x*)) within 1e-6 relative, as does a central difference over
    +-0.05 m/s (impacts in other steps: the sawtooth jumped every 0.04 m/s). Measured: 4e-12 and 1.8e-9 from
    central differences, 7e-10 from the closed form, 1e-14 over +-0.05 m/s; before the fix (the normal at the start
    of the step) 1e-9 and 4e-10 from central differences (of the sawtooth's piece), but 4.8e-2 from the closed
    form (the piece's slope) and 3.6e-2 over +-0.05 m/s."""
    cue = np.array([1.0, 0.0])
    value0, grads = ws.gradient(table(cue), loss, ["body_v"], seconds=SECONDS, fps=FPS, substeps=SUBSTEPS)
    assert value0 == pytest.approx(forward_value(table(cue), loss, SECONDS, FPS, SUBSTEPS), abs=1e-7)
    analytic = grads["body_v"][0, [0, 2]]
    step = 1e-5
    numeric = np.array([(value(cue + step * e) - value(cue - step * e)) / (2.0 * step) for e in np.eye(2)])
    n = np.array([math.cos(CUT), 0.0, math.sin(CUT)])
    closed = float(np.dot(WEIGHTS, n)) * math.cos(CUT) * SECONDS
    print(f"gradient {analytic}, central differences {numeric}, closed form d/dv_x {closed}; relative "
          f"{np.abs(analytic / numeric - 1.0)}, {abs(analytic[0] / closed - 1.0):.1e}")
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5)
    assert analytic[0] == pytest.approx(closed, rel=1e-6)
    wide = (value(cue + [0.05, 0.0]) - value(cue - [0.05, 0.0])) / 0.1   # across impacts in different steps
    print(f"central difference over +-0.05 m/s: {wide} ({abs(wide / analytic[0] - 1.0):.1e} off)")
    assert wide == pytest.approx(analytic[0], rel=1e-6)   # red(T) is linear in v_x: no jumps in between
    assert abs(numeric[1]) > 0.1   # aiming sideways turns the red's path


def glancing(v) -> ws.Scene:
    """A ball with velocity (v[0], 0, v[1]) [m/s] from the origin past a static sphere of radius 2R, 0.09 m off."""
    scene = ws.Scene(precision="float64", gravity=(0.0, 0.0, 0.0))
    scene.add_rigid_body(ws.Sphere(R), mass=MASS, position=(0.0, R, 0.0), linear_velocity=(v[0], 0.0, v[1]),
                         restitution=1.0, friction=0.0)
    scene.add_collider(ws.Sphere(2.0 * R), position=(0.3, R, 0.09), restitution=1.0, friction=0.0)
    return scene


@wp.kernel
def weighted_ball(x: wp.array2d(dtype=wp.vec3d), frame: int, w: wp.vec3d, out: wp.array(dtype=wp.float64)):
    out[0] = wp.dot(w, x[frame, 0])


def ball_loss(traj):
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    wp.launch(weighted_ball, 1, [traj.body_x, traj.frames, wp.vec3d(*WEIGHTS), out])
    return out


def test_a_ball_glancing_off_a_static_sphere_matches_central_differences():
    """The ball's final position against its velocity, through the static sphere's normal at the impact: within
    1e-5 relative of central differences (step 1e-5 m/s), and d/dv_x within 1e-6 of the closed form: it reflects
    about n = -(0.8, 0, 0.6) at x* = (0.18, R, 0) to u (-0.28, 0, -0.96), so x(T) = x* + (-0.28, 0, -0.96) (u T -
    0.18) and d/du = (-0.28, 0, -0.96) T. Measured: 3e-11 and 1e-9 from central differences, 2e-8 from the closed
    form (the float32 radii); before the fix 1e-9 from central differences but 8.8e-2 from the closed form."""
    v = np.array([1.0, 0.0])
    _, grads = ws.gradient(glancing(v), ball_loss, ["body_v"], seconds=SECONDS, fps=FPS, substeps=SUBSTEPS)
    run = lambda u: ws.gradient(glancing(u), ball_loss, seconds=SECONDS, fps=FPS, substeps=SUBSTEPS)  # noqa: E731
    numeric = np.array([(run(v + 1e-5 * e) - run(v - 1e-5 * e)) / 2e-5 for e in np.eye(2)])
    analytic = grads["body_v"][0, [0, 2]]
    print(f"gradient {analytic}, central differences {numeric}, relative {np.abs(analytic / numeric - 1.0)}")
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5)
    assert analytic[0] == pytest.approx(float(np.dot(WEIGHTS, [-0.28, 0.0, -0.96])) * SECONDS, rel=1e-6)

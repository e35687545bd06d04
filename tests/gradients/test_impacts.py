"""Gradients through particle impacts on planes, the time of impact included (float64).

The ball: a particle of radius r at height h (its centre) with the upward velocity v0, under gravity g, onto the
ground (restitution e, friction irrelevant: the motion is vertical), exactly one bounce before T.

- Fall: h - r + v0 t - g t^2 / 2 = 0 at the impact, so with s = sqrt(v0^2 + 2 g (h - r)) the impact time is
  t1 = (v0 + s) / g and the impact velocity v0 - g t1 = -s.
- Bounce: the velocity leaves as e s, from y = r.
- Then ballistic: y(T) = r + e s (T - t1) - g (T - t1)^2 / 2.
- Differentiating, with ds/dh = g / s, dt1/dh = 1 / s, ds/dv0 = v0 / s, dt1/dv0 = (1 + v0 / s) / g:

      dy/dh  = e (g / s)(T - t1) - e s dt1/dh + g (T - t1) dt1/dh       = (1 + e) g (T - t1) / s - e
      dy/dv0 = e (v0 / s)(T - t1) - e s dt1/dv0 + g (T - t1) dt1/dv0    = e (v0 / s)(T - t1) - e (s + v0) / g
                                                                          + (T - t1)(1 + v0 / s)

rk4 integrates the ballistic path exactly and the plane pass finds the impact at its exact time, so the
simulated y(T) is the closed form's and so must its gradient be. The naive gradient holds the impact time fixed
(``PlaneImpacts.hold_impact_time``): the contact point's height is then the plane's whatever h is, so it gives
dy/dh = 0 and dy/dv0 = -e (T - t1), far from the closed form.
"""
import numpy as np
from gradient_scenes import central_difference, final_position_loss, forward_value

import warp_sim as ws
from warp_sim.passes import PlaneImpacts

G, E, H, V0, R, T = 9.81, 0.5, 1.0, 0.5, 0.05, 0.8
TOLERANCE = 2e-4
HEIGHT = final_position_loss(weights=(0.0, 1.0, 0.0))


def ball(h=H, v0=V0, velocity=None, position=None) -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_particles([position or (0.0, h, 0.0)], velocities=[velocity or (0.0, v0, 0.0)], radius=R)
    scene.add_ground(restitution=E, friction=0.4)
    return scene


def closed_form(h=H, v0=V0, t=T):
    """(y(T), dy/dh, dy/dv0) of the module docstring."""
    s = np.sqrt(v0 * v0 + 2.0 * G * (h - R))
    t1 = (v0 + s) / G
    assert t1 < t < t1 + 2.0 * E * s / G, "exactly one bounce before T"
    y = R + E * s * (t - t1) - 0.5 * G * (t - t1) ** 2
    dy_dh = (1.0 + E) * G * (t - t1) / s - E
    dy_dv0 = E * (v0 / s) * (t - t1) - E * (s + v0) / G + (t - t1) * (1.0 + v0 / s)
    return y, dy_dh, dy_dv0, t1


def ball_gradient(integrator="rk4"):
    value, grads = ws.gradient(ball(), HEIGHT, ["particle_x", "particle_v"], seconds=T, integrator=integrator)
    return value, grads["particle_x"][0, 1], grads["particle_v"][0, 1]


def test_a_dropped_ball_bounces_with_the_closed_forms_gradient():
    value, dy_dh, dy_dv0 = ball_gradient()
    y, exact_dh, exact_dv0, t1 = closed_form()
    errors = abs(dy_dh - exact_dh), abs(dy_dv0 - exact_dv0)
    print(f"rk4, impact at t1 = {t1:.4f} s, T = {T} s: y(T) {value:.12f} (closed form {y:.12f}); dy/dh {dy_dh:.12f} "
          f"({exact_dh:.12f}), dy/dv0 {dy_dv0:.12f} ({exact_dv0:.12f}): errors {errors[0]:.1e}, {errors[1]:.1e}")
    assert abs(value - y) < 1e-10
    assert max(errors) < TOLERANCE


def test_the_naive_gradient_with_the_impact_time_held_differs(monkeypatch):
    monkeypatch.setattr(PlaneImpacts, "hold_impact_time", True)
    value, dy_dh, dy_dv0 = ball_gradient()
    y, exact_dh, exact_dv0, t1 = closed_form()
    print(f"naive (impact time held): dy/dh {dy_dh:.6f} against {exact_dh:.6f}, dy/dv0 {dy_dv0:.6f} against "
          f"{exact_dv0:.6f}; its own closed form: 0 and -e (T - t1) = {-E * (T - t1):.6f}")
    assert abs(value - y) < 1e-10   # the same run: only the adjoint differs
    assert abs(dy_dh - exact_dh) > 100 * TOLERANCE and abs(dy_dv0 - exact_dv0) > 100 * TOLERANCE
    assert abs(dy_dh) < 1e-12 and abs(dy_dv0 + E * (T - t1)) < 1e-9


def test_the_bounce_gradient_is_the_discrete_runs_under_symplectic_euler():
    """Symplectic Euler's path is not the parabola, so no closed form: its gradient against central differences of
    its own forward runs (the impact found at the time of impact on its step's quadratic path)."""
    value, dy_dh, dy_dv0 = ball_gradient("symplectic_euler")

    def y_of(p):
        return forward_value(ball(p[0], p[1]), HEIGHT, T, integrator="symplectic_euler")

    differences = central_difference(y_of, np.array([H, V0]), 1e-6)
    errors = np.abs(np.array([dy_dh, dy_dv0]) - differences) / np.abs(differences)
    print(f"symplectic Euler: dy/dh {dy_dh:.10f}, dy/dv0 {dy_dv0:.10f}; relative to central differences "
          f"{errors[0]:.1e}, {errors[1]:.1e}")
    assert errors.max() < 1e-6


def corner(velocity) -> ws.Scene:
    scene = ball(velocity=tuple(velocity), position=(0.0, 0.6, 0.1))
    scene.add_plane((-1.0, 0.0, 0.0), -0.7, restitution=0.8, friction=0.2, name="Wall")
    return scene


def test_a_throw_off_a_wall_and_the_ground_against_central_differences():
    """A particle thrown at a wall (x = 0.7) that then bounces on the ground, both with friction, in 0.6 s: the
    gradient of its final position (a weighting of x, y, z) with respect to its initial velocity."""
    velocity, loss = np.array([3.0, 0.5, 0.4]), final_position_loss()
    final = [arrays for _, _, arrays in ws.Simulator(corner(velocity), "rk4").frames(0.6, 60.0, 8)][-1]
    assert final["particle_v"][0, 0] < 0.0 and final["particle_v"][0, 1] > 0.0   # off the wall, up off the ground
    _, grads = ws.gradient(corner(velocity), loss, ["particle_v"], seconds=0.6)
    differences = central_difference(lambda v: forward_value(corner(v), loss, 0.6), velocity, 1e-6)
    error = np.abs(grads["particle_v"][0] - differences).max() / np.abs(differences).max()
    print(f"wall then ground: d loss / d v0 {grads['particle_v'][0]}, {error:.1e} relative to central differences")
    assert error < 1e-6


def test_newton_lands_a_bounced_throw_on_its_target(integrator="rk4"):
    """A particle thrown from (0, 0.5, 0) with (vx, vy) bounces once on the ground (e = 0.5, friction 0.4, which
    takes from vx at the impact) and must be at a target point at T = 0.9 s: Newton's method on the 2 x 2 system
    p(T; v) = target, its Jacobian from two ws.gradient calls (one per coordinate), from a throw 0.5 m short."""
    seconds = 0.9

    def throw(v):
        return ball(velocity=(v[0], v[1], 0.0), position=(0.0, 0.5, 0.0))

    target = np.array([1.431, 0.229])
    v, history = np.array([1.8, 2.2]), []
    for _ in range(6):
        p, jacobian = np.zeros(2), np.zeros((2, 2))
        for row, weights in enumerate(((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))):
            p[row], grads = ws.gradient(throw(v), final_position_loss(weights=weights), ["particle_v"],
                                        seconds=seconds, integrator=integrator)
            jacobian[row] = grads["particle_v"][0, :2]
        history.append(float(np.linalg.norm(p - target)))
        if history[-1] < 1e-4:
            break
        v = v - np.linalg.solve(jacobian, p - target)
    landed = np.array([forward_value(throw(v), final_position_loss(weights=w), seconds, integrator=integrator)
                       for w in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0))])
    miss = float(np.linalg.norm(landed - target))
    print(f"Newton: misses {', '.join(f'{m:.2e}' for m in history)} m; throw (vx, vy) = ({v[0]:.6f}, {v[1]:.6f}) m/s "
          f"lands {miss * 1000:.3f} mm from the target")
    assert miss < 0.01 and len(history) <= 5


def test_the_differentiable_response_is_the_forward_ones():
    """300 particles thrown about in a box of four planes for 1 s: a differentiable Simulator (its own plane
    kernel, the loops unrolled) ends where the forward-only one does, bit for bit."""
    rng = np.random.default_rng(1)
    scene = ws.Scene(precision="float64")
    scene.add_particles(rng.uniform(-0.4, 0.4, (300, 3)) + [0.0, 0.6, 0.0], velocities=rng.normal(0.0, 3.0, (300, 3)),
                        radius=0.02)
    scene.add_ground(restitution=0.6, friction=0.3)
    for k, normal in enumerate(((-1.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))):
        scene.add_plane(normal, -0.5, name=f"Wall{k}")
    ends = []
    for differentiable in (False, True):
        sim = ws.Simulator(scene, "symplectic_euler", differentiable=differentiable)
        for _ in range(60):
            sim.step(1.0 / 60.0, substeps=4)
        ends.append(sim.state.y.numpy())
    assert np.array_equal(ends[0], ends[1])

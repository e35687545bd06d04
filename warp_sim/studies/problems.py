"""Reference problems of the accuracy study: scenes with a closed form or a trusted reference run.

Every problem is a ``ws.Scene`` run by ``ws.Simulator`` for ``duration`` seconds. ``observe(sim)``
turns the final state into a dimensionless vector (positions over a length scale, velocities
over a speed scale); ``exact()`` gives the same vector from the closed form, or None when the
reference is a run of the same scene with rk4 at a quarter of the finest step (half in quick
runs). The error of a run is the largest entry of |observed - reference| (a relative max-norm
error).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..scene import Attractor, PointMasses, Scene
from ..simulator import Simulator
from ..util.rotations import quat_to_matrix

G = 9.81                   # [m/s^2]
PENDULUM_PERIOD = 4.8935242741   # [s] L = 1 m, g = 9.81, released at 170 degrees (closed form below)
#: a lamina of point masses with I_body = diag(1, 2, 3) kg m^2 (the intermediate-axis problem)
LAMINA = ((math.sqrt(2.0), 0.0, 0.0), (-math.sqrt(2.0), 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0))
OMEGA0 = (0.1, 1.0, 0.1)   # [rad/s] the Dzhanibekov case: spin mostly about the intermediate axis


@dataclass(frozen=True)
class Problem:
    """One accuracy problem. duration [s]; steps and quick_steps: step counts N (h = duration / N),
    coarse to fine; build() -> Scene; observe(sim) -> dimensionless vector; exact() -> the same
    from the closed form, or None (a reference run); error: what the error measures."""
    name: str
    title: str
    duration: float
    steps: tuple
    quick_steps: tuple
    build: Callable[[], Scene]
    observe: Callable
    exact: Callable | None
    error: str
    notes: str = ""


def complete_elliptic_k(m: float) -> float:
    """K(m) = integral over [0, pi/2] of (1 - m sin^2)^(-1/2), by the arithmetic-geometric mean."""
    a, b = 1.0, math.sqrt(1.0 - m)
    while abs(a - b) > 1e-15 * a:
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return math.pi / (2.0 * a)


def pendulum_period(theta0: float, length: float = 1.0, g: float = G) -> float:
    """Period [s] of a rigid pendulum released at rest at theta0 [rad]: 4 sqrt(L/g) K(sin^2(theta0/2))."""
    return 4.0 * math.sqrt(length / g) * complete_elliptic_k(math.sin(0.5 * theta0) ** 2)


def intermediate_axis_period(inertia=(1.0, 2.0, 3.0), omega=OMEGA0) -> float:
    """Period [s] of omega's torque-free polhode (body frame) when L^2 > 2 E I2: 4 K(k^2) / rate."""
    I1, I2, I3 = inertia
    w = np.asarray(omega, dtype=float)
    L2 = float(np.sum((np.asarray(inertia) * w) ** 2))
    E2 = float(np.sum(np.asarray(inertia) * w * w))
    k2 = (I2 - I1) * (E2 * I3 - L2) / ((I3 - I2) * (L2 - E2 * I1))
    return 4.0 * complete_elliptic_k(k2) / math.sqrt((I3 - I2) * (L2 - E2 * I1) / (I1 * I2 * I3))


def particles(sim, length: float, speed: float, first: int = 0) -> np.ndarray:
    """Positions / length and velocities / speed of particles first.. as one flat float64 vector."""
    x = sim.state.particle_x.numpy()[first:].astype(np.float64)
    v = sim.state.particle_v.numpy()[first:].astype(np.float64)
    return np.concatenate([x.ravel() / length, v.ravel() / speed])


def body_frame_omega(sim) -> np.ndarray:
    """omega [rad/s] of body 0 in its own frame: I_body^-1 R^T L."""
    q = sim.state.body_q.numpy()[0].astype(np.float64)
    L = sim.state.body_L.numpy()[0].astype(np.float64)
    return np.linalg.solve(sim.scene.bodies[0].mass.inertia, quat_to_matrix(q).T @ L)


# projectile -----------------------------------------------------------------------------------------
X0, V0 = np.array([0.0, 1.0, 0.0]), np.array([3.0, 10.0, -1.0])


def _projectile() -> Scene:
    scene = Scene(precision="float64")
    scene.add_particles([X0], [V0])
    return scene


def _projectile_exact(T=2.0) -> np.ndarray:
    g = np.array([0.0, -G, 0.0])
    return np.concatenate([(X0 + V0 * T + 0.5 * g * T * T) / 10.0, (V0 + g * T) / 10.0])


# oscillators: a particle on a spring to a pinned particle, along x, no gravity -----------------------
K, M, A, KD = 4.0, 1.0, 0.1, 0.4   # [N/m], [kg], amplitude [m], damping [N s/m]
OMEGA = math.sqrt(K / M)


def _oscillator(damping: float = 0.0) -> Scene:
    scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_particles([[0.0, 0.0, 0.0], [1.0 + A, 0.0, 0.0]], mass=[1.0, M], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=K, damping=damping, rest_length=1.0)
    return scene


def _oscillator_observe(sim) -> np.ndarray:
    x, v = sim.state.particle_x.numpy()[1], sim.state.particle_v.numpy()[1]
    return np.array([(float(x[0]) - 1.0) / A, float(v[0]) / (A * OMEGA)])


def _oscillator_exact(T: float, damping: float = 0.0) -> np.ndarray:
    gamma = damping / (2.0 * M)
    wd = math.sqrt(OMEGA**2 - gamma**2)
    decay = math.exp(-gamma * T)
    x = A * decay * (math.cos(wd * T) + gamma / wd * math.sin(wd * T))
    v = -A * decay * OMEGA**2 / wd * math.sin(wd * T)
    return np.array([x / A, v / (A * OMEGA)])


# pendulum: a bob on a stiff spring rod to a pinned pivot --------------------------------------------
THETA0, ROD_K = math.radians(170.0), 1.0e4   # release angle, rod stiffness [N/m] for a 1 kg bob


def _pendulum(stiffness: float = ROD_K) -> Scene:
    scene = Scene(precision="float64")
    bob = (math.sin(THETA0), -math.cos(THETA0), 0.0)
    scene.add_particles([[0.0, 0.0, 0.0], bob], mass=[1.0, 1.0], pinned=[0])
    # rest length chosen so that the rod starts in radial equilibrium (compressed by the weight above it)
    scene.add_springs([[0, 1]], stiffness=stiffness, rest_length=1.0 - G * math.cos(THETA0) / stiffness)
    return scene


# Kepler orbits around ws.Attractor: GM = 1 m^3/s^2, a = 1 m (period 2 pi s), from apoapsis -----------
def _kepler(e: float) -> Callable[[], Scene]:
    def build() -> Scene:
        scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
        scene.add_particles([[1.0 + e, 0.0, 0.0]], [[0.0, math.sqrt((1.0 - e) / (1.0 + e)), 0.0]])
        scene.add_field(Attractor(position=(0.0, 0.0, 0.0), strength=1.0))
        return scene
    return build


def _kepler_exact(e: float) -> Callable[[], np.ndarray]:
    return lambda: np.array([1.0 + e, 0.0, 0.0, 0.0, math.sqrt((1.0 - e) / (1.0 + e)), 0.0])


# torque-free body spinning near its intermediate axis -----------------------------------------------
def _tumbling_body() -> Scene:
    scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_rigid_body(PointMasses(LAMINA, 0.5), angular_velocity=OMEGA0)
    return scene


def flip_period(integrator: str = "rk4", h: float = 1e-3, device: str = "cpu", every: int = 10) -> float:
    """The tumbling body's flip period [s] as simulated: omega_2 (body frame) crosses zero at each flip,
    and successive crossings are half a period apart; twice the time from the first downward crossing
    to the next upward one, each interpolated linearly between samples ``every`` steps apart."""
    sim = Simulator(_tumbling_body(), integrator=integrator, device=device)
    times, values, crossings = [0.0], [body_frame_omega(sim)[1]], []
    while len(crossings) < 2 and sim.time < 1.5 * intermediate_axis_period():
        sim.step(h, every, substeps=1)
        times.append(sim.time)
        values.append(body_frame_omega(sim)[1])
        (t0, t1), (w0, w1) = times[-2:], values[-2:]
        if (w0 > 0.0 >= w1) if not crossings else (w0 < 0.0 <= w1):
            crossings.append(t0 - w0 * (t1 - t0) / (w1 - w0))
    if len(crossings) < 2:
        raise RuntimeError(f"omega_2 did not flip twice within {sim.time:.3g} s ({integrator}, h = {h:g} s)")
    return 2.0 * (crossings[1] - crossings[0])


def swing_period(stiffness: float = ROD_K, integrator: str = "rk4", h: float = 1e-3, device: str = "cpu") -> float:
    """The spring-rod pendulum's period [s] as simulated, rod stiffness [N/m]: its angular velocity about
    the pivot changes sign at each turning point, half a period apart; the time of the second change,
    interpolated linearly."""
    sim = Simulator(_pendulum(stiffness), integrator=integrator, device=device)

    def spin() -> float:
        x, v = sim.state.particle_x.numpy()[1], sim.state.particle_v.numpy()[1]
        return float(x[0] * v[1] - x[1] * v[0])

    turns = []
    sim.step(h, substeps=1)                              # released at rest: spin() is 0 at t = 0
    previous = (sim.time, spin())
    while len(turns) < 2 and sim.time < 2.0 * PENDULUM_PERIOD:
        sim.step(h, substeps=1)
        (t0, w0), (t1, w1) = previous, (sim.time, spin())
        if w0 * w1 < 0.0:
            turns.append(t0 - w0 * (t1 - t0) / (w1 - w0))
        previous = (t1, w1)
    if len(turns) < 2:
        raise RuntimeError(f"the pendulum did not turn twice within {sim.time:.3g} s ({integrator}, h = {h:g} s)")
    return turns[1]


# bouncing ball: a particle dropped on the ground, restitution 0.8 ----------------------------------
BALL_Y0, BALL_R, BALL_E = 1.0, 0.05, 0.8


def _ball() -> Scene:
    scene = Scene(precision="float64")
    scene.add_ground(restitution=BALL_E, friction=0.0)
    scene.add_particles([[0.0, BALL_Y0, 0.0]], radius=BALL_R)
    return scene


def ball_exact(T: float) -> tuple[float, float]:
    """Height [m] and vertical velocity [m/s] of the ball's centre at T: parabolas between impacts."""
    t, v = math.sqrt(2.0 * (BALL_Y0 - BALL_R) / G), 0.0
    if T < t:
        return BALL_Y0 - 0.5 * G * T * T, -G * T
    v = BALL_E * G * t                     # speed leaving the first impact
    while t + 2.0 * v / G <= T:
        t, v = t + 2.0 * v / G, BALL_E * v
    s = T - t
    return BALL_R + v * s - 0.5 * G * s * s, v - G * s


def _ball_observe(sim) -> np.ndarray:
    x, v = sim.state.particle_x.numpy()[0], sim.state.particle_v.numpy()[0]
    return np.array([float(x[1]), float(v[1]) / math.sqrt(2.0 * G)])


def _ball_exact(T=2.0) -> np.ndarray:
    y, vy = ball_exact(T)
    return np.array([y, vy / math.sqrt(2.0 * G)])


# a chain of 10 springs pinned at one end, released horizontal --------------------------------------
def _chain() -> Scene:
    scene = Scene(precision="float64")
    ids = scene.add_particles([[0.1 * i, 1.0, 0.0] for i in range(11)], mass=0.01, pinned=[0])
    scene.add_springs(np.stack([ids[:-1], ids[1:]], axis=1), stiffness=100.0)
    return scene


# a small cloth, all spring families, pinned at two corners, released flat ----------------------------
def _cloth() -> Scene:
    scene = Scene(precision="float64")
    flat = (-math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))
    scene.add_cloth_grid(resolution=(6, 6), size=(0.5, 0.5), position=(0.0, 1.0, 0.0), orientation=flat,
                         mass=0.1, stiffness=(50.0, 50.0, 5.0), damping=(0.01, 0.01, 0.001), pinned=["top_corners"])
    return scene


SE_NOTE = ("Symplectic Euler's first-order error is a velocity offset of h a / 2 (its velocities are Verlet's, "
           "half a kick early); at apoapsis that kick is radial, changes neither energy nor period, and cancels "
           "after a whole orbit, so it converges at order 2 here (as implicit Euler, explicit in the field)")


def _halving(first: int, count: int) -> tuple:
    return tuple(first * 2**k for k in range(count))


def _problems() -> dict:
    sqrt_gl = math.sqrt(G)
    unit = "max |x - x_ref| / {l} and |v - v_ref| / {v}"
    items = [
        Problem("projectile", "particle under gravity", 2.0, _halving(8, 6), _halving(8, 4), _projectile,
                lambda sim: particles(sim, 10.0, 10.0), _projectile_exact, unit.format(l="10 m", v="10 m/s"),
                "closed form; second-order and higher solvers are exact (a quadratic in t)"),
        Problem("oscillator", "undamped spring to a pinned particle, k/m = 4 /s^2, for 2 s", 2.0,
                _halving(32, 6), _halving(64, 4), _oscillator, _oscillator_observe,
                lambda: _oscillator_exact(2.0), "|x - x_exact| / A and |v - v_exact| / (A omega)",
                "closed form; 2 s is 0.64 of a period (at a whole period symplectic Euler's first-order "
                "error, a shear of the orbit, vanishes)"),
        Problem("damped_oscillator", "the oscillator with a damper, zeta = 0.1, for 2 s", 2.0,
                _halving(32, 6), _halving(64, 4), lambda: _oscillator(KD), _oscillator_observe,
                lambda: _oscillator_exact(2.0, KD), "|x - x_exact| / A and |v - v_exact| / (A omega)",
                "closed form, x = A exp(-gamma t)(cos wd t + gamma / wd sin wd t). Verlet takes velocity-dependent "
                "forces at the half-step velocity (warp_sim.solvers.partitioned), which makes it first order with a "
                "damper"),
        Problem("pendulum_170", "pendulum released at 170 deg: 1 kg bob on a rod of k = 1e4 N/m, L = 1 m",
                PENDULUM_PERIOD, _halving(500, 6), _halving(300, 4), _pendulum,
                lambda sim: particles(sim, 1.0, sqrt_gl, first=1), None, unit.format(l="L", v="sqrt(g L)"),
                "run for the rigid pendulum's period 4 sqrt(L/g) K(sin^2(85 deg)) = 4.8935242741 s; reference: "
                "the same spring rod with rk4 at a quarter of the finest step (the rod stretches, so the spring "
                "pendulum itself is not back at its start). Explicit Euler is unstable on the rod's radial "
                "mode at every step tried. Ending a whole swing from rest, midpoint's h^2 term cancels (observed 3)"),
        Problem("kepler_e0.5", "Kepler orbit e = 0.5 around ws.Attractor (GM = 1, a = 1), one period",
                2.0 * math.pi, _halving(100, 6), _halving(100, 4), _kepler(0.5), lambda sim: particles(sim, 1.0, 1.0),
                _kepler_exact(0.5), unit.format(l="a", v="sqrt(GM / a)"), "closed form: back at apoapsis. " + SE_NOTE),
        Problem("kepler_e0.9", "Kepler orbit e = 0.9 (periapsis 0.1 a), one period", 2.0 * math.pi,
                _halving(400, 6), _halving(400, 4), _kepler(0.9), lambda sim: particles(sim, 1.0, 1.0),
                _kepler_exact(0.9), unit.format(l="a", v="sqrt(GM / a)"), "closed form: back at apoapsis. " + SE_NOTE),
        Problem("kepler_e0.99", "Kepler orbit e = 0.99 (periapsis 0.01 a), one period: the stiff extreme where "
                "adaptive stepping pays", 2.0 * math.pi, _halving(2000, 6), _halving(1000, 2), _kepler(0.99),
                lambda sim: particles(sim, 1.0, 1.0), _kepler_exact(0.99), unit.format(l="a", v="sqrt(GM / a)"),
                "closed form: back at apoapsis. The periapsis pass takes 1e-3 of the period at 14 times the "
                "apoapsis speed, so a fixed step must resolve it everywhere; rk45 shrinks its step there only. "
                + SE_NOTE),
        Problem("intermediate_axis", "torque-free body, I = diag(1, 2, 3), omega0 = (0.1, 1, 0.1), one flip period",
                intermediate_axis_period(), _halving(100, 7), _halving(100, 4), _tumbling_body,
                lambda sim: body_frame_omega(sim) / np.linalg.norm(OMEGA0), lambda: np.array(OMEGA0) / np.linalg.norm(
                    OMEGA0), "|omega_body - omega0| / |omega0|", "closed form: the polhode closes after "
                "4 K(k^2) / rate = 22.99626 s. Midpoint, symplectic Euler, Verlet and implicit Euler take one and the "
                "same step here (no torque: the kicks do nothing, the drift is a midpoint step); their error terms "
                "cancel near h = 0.02 s, so the local slopes only approach 2 (and rk4's 4) at the finest steps"),
        Problem("bouncing_ball", "ball dropped from 1 m on the ground, restitution 0.8, three impacts", 2.0,
                _halving(20, 7), _halving(20, 4), _ball, _ball_observe, _ball_exact,
                "|y - y_exact| / 1 m and |v - v_exact| / sqrt(2 g 1 m)", "closed form: parabolas between impacts. "
                "The time-of-impact pass assumes a parabola over the step, exact for the second-order solvers; "
                "with the first-order ones it misjudges the impact speed, and at coarse steps a bounce is lost"),
        Problem("hanging_chain", "10 springs (k/m = 1e4 /s^2) pinned at one end, released horizontal", 1.0,
                _halving(100, 6), _halving(100, 4), _chain, lambda sim: particles(sim, 1.0, sqrt_gl), None,
                unit.format(l="1 m", v="sqrt(g 1 m)"), "reference: rk4 at a quarter of the finest step"),
        Problem("cloth", "6 x 6 cloth, all spring families, pinned at two corners, released flat", 0.5,
                _halving(200, 6), _halving(200, 4), _cloth, lambda sim: particles(sim, 0.5, math.sqrt(0.5 * G)),
                None, unit.format(l="0.5 m", v="sqrt(g 0.5 m)"), "reference: rk4 at a quarter of the finest step"),
    ]
    return {p.name: p for p in items}


#: the accuracy problems by name
PROBLEMS = _problems()

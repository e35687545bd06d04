"""Cases of the stability study: stiff springs and extreme scenes, each with the size whose growth
means instability, and (where there is one) the fastest frequency of its linearisation.

A case runs either a fixed number of steps (``duration`` None: linear cases, where stability is
growth per step) or a fixed simulated time (nonlinear ones). ``size(sim)`` is an energy measured
from the case's ground state [J], or, for the orbit, the distance from the attractor [m].
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..scene import Attractor, Scene
from . import contact_scenes
from .problems import G, pendulum_period

STRETCH = 1e-6          # [m] initial perturbations: far inside the linear range, so growth cannot saturate early
SPRING_RATIOS = (1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8)   # ks/m [1/s^2] of the single-spring sweep
QUICK_SPRING_RATIOS = (1e2, 1e8)


@dataclass(frozen=True)
class Case:
    """One stability case. build() -> Scene; size(sim) -> float; omega [rad/s]: the fastest frequency of
    the linearised springs (theory), or None; duration [s] or None (a fixed number of steps);
    h0 [s]: where the search starts (default 1 / omega); h_max [s]: the largest step tried;
    options: extra Simulator arguments; group: "spring" (the ks/m sweep) or "extreme"."""
    name: str
    title: str
    build: Callable[[], Scene]
    size: Callable
    omega: float | None
    group: str
    duration: float | None = None
    h0: float | None = None
    h_max: float | None = None
    options: dict = field(default_factory=dict)
    notes: str = ""
    unit: tuple | None = None      # (size [s], name): a unit the report also gives the limits in
    bound: float | None = None     # a size past it is unstable, whatever its growth (a stack that moved 5 mm)


def linear_omega(scene: Scene) -> float:
    """Largest angular frequency [rad/s] of the scene's springs linearised about the initial positions:
    sqrt of the top eigenvalue of M^-1/2 K M^-1/2, K the stiffness (axial k d d^T plus the geometric
    k (1 - L0/L)(I - d d^T) of a stretched or compressed spring), pinned particles fixed."""
    x, mass = scene.particle_array("position"), scene.particle_array("mass")
    free = ~scene.particle_array("pinned").astype(bool)
    n = len(x)
    K = np.zeros((3 * n, 3 * n))
    for (i, j), k, rest in zip(scene.spring_array("pairs"), scene.spring_array("stiffness"),
                               scene.spring_array("rest_length")):
        delta = x[j] - x[i]
        length = float(np.linalg.norm(delta))
        d = delta / length
        block = k * (np.outer(d, d) + (1.0 - rest / length) * (np.eye(3) - np.outer(d, d)))
        for a, b, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
            K[3 * a:3 * a + 3, 3 * b:3 * b + 3] += sign * block
    keep = np.repeat(free, 3)
    scale = 1.0 / np.sqrt(np.repeat(mass, 3)[keep])
    return float(math.sqrt(max(np.linalg.eigvalsh(K[np.ix_(keep, keep)] * np.outer(scale, scale)).max(), 0.0)))


def energy(scene: Scene, height: float = 0.0, strain_only: bool = False) -> Callable:
    """size(sim) = kinetic + spring + gravity energy above ``height`` [J] of the free particles
    (strain_only: the springs' energy alone)."""
    mass = scene.particle_array("mass")
    mass = np.where(scene.particle_array("pinned").astype(bool), 0.0, mass)
    pairs = scene.spring_array("pairs")
    k, rest = scene.spring_array("stiffness"), scene.spring_array("rest_length")
    g = scene.gravity

    def size(sim) -> float:
        x = sim.state.particle_x.numpy().astype(np.float64)
        v = sim.state.particle_v.numpy().astype(np.float64)
        total = 0.0
        if not strain_only:
            total = 0.5 * float(np.sum(mass * np.sum(v * v, axis=1))) - float(np.sum(mass * ((x - [0, height, 0]) @ g)))
        if len(pairs):
            length = np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1)
            total += 0.5 * float(np.sum(k * (length - rest) ** 2))
        return total
    return size


def spring_name(ratio: float) -> str:
    """The case name of the single spring with ks/m = ratio, e.g. "spring_1e4"."""
    return f"spring_{ratio:.0e}".replace("+0", "").replace("+", "")


def _measured(build: Callable[[], Scene], height: float = 0.0, strain_only: bool = False):
    """(build, size) where size is built from the scene once."""
    return build, energy(build(), height, strain_only)


def _spring(ratio: float) -> Callable[[], Scene]:
    """A 1 kg particle on a spring of k = ratio N/m to a pinned particle, stretched by 1e-6 m, no gravity."""
    def build() -> Scene:
        scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
        scene.add_particles([[0.0, 0.0, 0.0], [1.0 + STRETCH, 0.0, 0.0]], mass=1.0, pinned=[0])
        scene.add_springs([[0, 1]], stiffness=ratio, rest_length=1.0)
        return scene
    return build


def lattice_cloth(n: int = 12, spacing: float = 0.05, mass: float = 0.01, stiffness: float = 100.0,
                  kick: float = STRETCH, seed: int = 0) -> Scene:
    """An n x n cloth lattice in the x-y plane, every particle ``mass`` [kg], structural, shear and bend
    springs all of ``stiffness`` [N/m], no gravity, each particle displaced by N(0, kick) [m]. Its
    fastest in-plane mode has omega^2 -> 10.125 k/m as n grows: symplectic Euler's limit 0.6285 sqrt(m/k)."""
    i, j = np.divmod(np.arange(n * n), n)
    grid = np.stack([i, j], axis=1)
    rest = np.stack([i * spacing, j * spacing, np.zeros(n * n)], axis=1)
    pairs = []
    for offset in ((1, 0), (0, 1), (1, 1), (1, -1), (2, 0), (0, 2)):     # structural, shear, bend
        other = grid + offset
        inside = np.all((other >= 0) & (other < n), axis=1)
        pairs.append(np.stack([np.flatnonzero(inside), other[inside] @ [n, 1]], axis=1))
    scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    moved = rest + np.random.default_rng(seed).normal(0.0, kick, size=rest.shape)
    scene.add_particles(moved, mass=mass)
    pairs = np.concatenate(pairs)
    scene.add_springs(pairs, stiffness=stiffness, rest_length=np.linalg.norm(rest[pairs[:, 1]] - rest[pairs[:, 0]],
                                                                              axis=1))
    return scene


def _mass_ratio() -> Scene:
    """1 kg and 1e-6 kg joined by a 1 N/m spring of rest length 1 m, stretched by 1e-6 m, free, no gravity."""
    scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_particles([[0.0, 0.0, 0.0], [1.0 + STRETCH, 0.0, 0.0]], mass=[1.0, 1e-6])
    scene.add_springs([[0, 1]], stiffness=1.0, rest_length=1.0)
    return scene


ORBIT_GM = 4.0 * math.pi**2      # a = 1 m: period 1 s


def _orbit() -> Scene:
    """e = 0.99 around ws.Attractor (GM = 4 pi^2, a = 1 m, period 1 s, periapsis 0.01 m), from apoapsis."""
    scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    e = 0.99
    scene.add_particles([[1.0 + e, 0.0, 0.0]], [[0.0, math.sqrt(ORBIT_GM * (1.0 - e) / (1.0 + e)), 0.0]])
    scene.add_field(Attractor(position=(0.0, 0.0, 0.0), strength=ORBIT_GM))
    return scene


def _distance(sim) -> float:
    return float(np.linalg.norm(sim.state.particle_x.numpy()[0]))


THETA_179 = math.radians(179.0)


def _pendulum() -> Scene:
    """A 1 kg bob on a 1 m rod of k = 1e4 N/m released at rest 179 degrees from hanging, in radial equilibrium."""
    scene = Scene(precision="float64")
    scene.add_particles([[0.0, 0.0, 0.0], [math.sin(THETA_179), -math.cos(THETA_179), 0.0]], mass=1.0,
                        pinned=[0])
    scene.add_springs([[0, 1]], stiffness=1e4, rest_length=1.0 - G * math.cos(THETA_179) / 1e4)
    return scene


def _impact() -> Scene:
    """A 1 kg particle bouncing at 100 m/s between the ground and a ceiling 1 m above it, restitution 1."""
    scene = Scene(precision="float64")
    scene.add_ground(restitution=1.0, friction=0.0)
    scene.add_plane((0.0, -1.0, 0.0), -1.0, restitution=1.0, friction=0.0, name="Ceiling")
    scene.add_particles([[0.0, 0.5, 0.0]], [[0.0, -100.0, 0.0]], radius=0.0)
    return scene


def _zero_rest() -> Scene:
    """A 1 kg particle on a zero-rest-length spring (k = 1e4 N/m) to a pinned one, on an ellipse, no gravity."""
    scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_particles([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]], [[0.0, 0.0, 0.0], [0.0, 5.0, 0.0]], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=1e4, rest_length=0.0)
    return scene


def _light_chain() -> Scene:
    """Eight 1e-6 kg particles in a chain of 1e3 N/m springs (0.01 m), pinned at one end, kicked, no gravity."""
    scene = Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    x = np.array([[0.01 * i, 0.0, 0.0] for i in range(8)])
    moved = x + np.random.default_rng(1).normal(0.0, 1e-2 * STRETCH, size=x.shape)
    ids = scene.add_particles(moved, mass=1e-6, pinned=[0])
    scene.add_springs(np.stack([ids[:-1], ids[1:]], axis=1), stiffness=1e3, rest_length=0.01)
    return scene


def _cases() -> dict:
    items = []
    for ratio in SPRING_RATIOS:
        build, size = _measured(_spring(ratio))
        items.append(Case(spring_name(ratio), f"single spring, ks/m = {ratio:.0e} /s^2", build,
                          size, math.sqrt(ratio), "spring"))
    build, size = _measured(lattice_cloth)
    items.append(Case("cloth", "12 x 12 cloth lattice, structural = shear = bend = 100 N/m, 0.01 kg", build, size,
                      linear_omega(build()), "extreme", unit=(0.01, "sqrt(m/k)"),
                      notes="theory from this lattice's fastest mode, omega^2 = 9.752 k/m (symplectic Euler "
                      "0.6404 sqrt(m/k)); the infinite lattice has 10.125 k/m (0.6285 sqrt(m/k))"))
    build, size = _measured(_mass_ratio)
    items.append(Case("mass_ratio_1e6", "1 kg and 1e-6 kg across a 1 N/m spring, free", build, size,
                      linear_omega(build()), "extreme"))
    items.append(Case("orbit_e0.99", "Kepler orbit e = 0.99 (period 1 s, periapsis 0.01 m), one period",
                      _orbit, _distance, None, "extreme", duration=1.0, h0=1e-3, h_max=0.05,
                      notes="size: distance from the attractor; no linear theory (periapsis time scale 1.6e-4 s)"))
    build, size = _measured(_pendulum, strain_only=True)
    items.append(Case("pendulum_179", "pendulum released at 179 deg, rod k = 1e4 N/m, two periods", build, size,
                      linear_omega(build()), "extreme", duration=2.0 * pendulum_period(THETA_179),
                      notes="size: the rod's strain energy; theory from the rod's radial mode at release"))
    build, size = _measured(_impact)
    items.append(Case("impact_100", "100 m/s impacts between the ground and a ceiling 1 m above, restitution 1 "
                      "(time-of-impact contacts)", build, size, None, "extreme", duration=0.2, h0=1e-4, h_max=4e-3,
                      notes="no linear theory: the impulse pass resolves each impact exactly at any step"))
    items.append(Case("impact_100_penalty", "the same 100 m/s impacts with penalty contacts of 1e8 N/m", build, size,
                      1e4, "extreme", duration=0.2, h0=1e-4, h_max=4e-3,
                      options={"contact": "penalty", "penalty_stiffness": 1e8},
                      notes="theory: the contact spring, omega = sqrt(k/m) = 1e4 rad/s (undamped at restitution 1)"))
    build, size = _measured(_zero_rest)
    items.append(Case("zero_rest_length", "zero-rest-length spring, k/m = 1e4 /s^2, elliptic orbit", build, size,
                      linear_omega(build()), "extreme"))
    build, size = _measured(_light_chain)
    items.append(Case("light_particles", "eight 1e-6 kg particles on 1e3 N/m springs", build, size,
                      linear_omega(build()), "extreme"))
    return {case.name: case for case in items}


def _moved(sim) -> float:
    """The largest distance [m] any body has moved from where the scene put it."""
    start = np.array([body.position for body in sim.scene.bodies], dtype=np.float64)
    return contact_scenes.displacement(sim, start)


STANDS = 5e-3      # [m] a contact case still stands while no body has moved this far
CONTACT_CASES = (
    ("stack_10", "a stack of ten 0.5 m boxes of 1 kg, 10 s", lambda: contact_scenes.stack(10)),
    ("pyramid_15", "a 5-4-3-2-1 pyramid of 0.5 m boxes, 1 cm gaps, 10 s", lambda: contact_scenes.pyramid(5)),
    ("heavy_on_light_100", "a 100 kg box on four 1 kg boxes, 10 s", lambda: contact_scenes.heavy_on_light(100.0)),
)


def _contact_cases() -> list:
    """The frame-rate contact scenes: stable while no box moves 5 mm over 10 s. Run without the simulator's
    sub-steps (contact_step=None), so the limit is the contact solver's own largest step."""
    return [Case(name, title, build, _moved, None, "contact", duration=10.0, h0=1.0 / 60.0, h_max=0.25,
                 options={"contact_step": None}, bound=STANDS,
                 notes="stands: no box moves 5 mm over 10 s; the solver's own step (the Simulator splits steps "
                       "above contact_step = 1/120 s by default)")
            for name, title, build in CONTACT_CASES]


#: the stability cases by name
CASES = {**_cases(), **{case.name: case for case in _contact_cases()}}

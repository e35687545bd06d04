"""The demo scene: particles bouncing on the ground, a spring chain hanging from a pinned particle,
rigid bodies thrown tumbling into the air, a pile of boxes and spheres, a chain of capsules on ball
joints swinging from a pivot, a particle fountain, a flag in the wind and a cloth draped over a sphere."""
from __future__ import annotations

import numpy as np
import trimesh

from . import scene as shapes  # the shape classes: shapes.Box, shapes.Sphere, ...
from .scene import Ramp, Scene

WIND = (3.0, 0.0, 1.0)   # [m/s]: blows the flag (and drags everything a little)
PILE_ORIGIN = (-2.0, 0.0, 2.5)   # [m]: where the pile of boxes and spheres falls
SWING_PIVOT, SWING_LINK, SWING_SPIN = (3.0, 2.6, -2.0), 0.15, 1.5   # [m], [m], [rad/s]: the ball-jointed chain
# The Simulator's joint_step for the demo (`warp-sim demo`, the frame-rate study): None solves the swinging chain at
# the substeps the rest of the demo takes (3 a frame under rk4, 5 under symplectic Euler; its worst anchor gap over
# 4 s is then 0.7 mm and 0.3 mm), where the default 1/480 s would take 8 a frame for the whole scene, 1.7 times
# the run time for a gap of 0.12 mm.
JOINT_STEP = None
DRAPE_SPHERE = ((0.5, 0.35, 3.0), 0.35)   # centre [m] and radius [m] of the static sphere the cloth falls on

# Thrown high (19 m/s, a 3.9 s flight), they tumble in the air for most of the default 4 s demo and
# land at its end. The slab spins about its intermediate axis and flips.
THROWN_BODIES = (
    ("slab", shapes.Box((0.05, 0.15, 0.3)), (-3.0, 0.5, -1.0), (0.4, 19.0, 0.2), (0.05, 12.0, 0.05)),
    ("ball", shapes.Sphere(0.15), (-3.0, 0.5, 0.0), (0.6, 19.2, 0.0), (4.0, 0.0, 2.0)),
    ("capsule", shapes.Capsule(0.08, 0.2), (-3.0, 0.5, 1.0), (0.5, 18.8, -0.2), (6.0, 1.0, 3.0)),
    ("drum", shapes.Cylinder(0.2, 0.08), (-4.0, 0.5, -0.5), (0.9, 19.1, 0.1), (1.0, 8.0, 5.0)),
)


def demo_scene(particles: int = 200, chain_links: int = 20, seed: int = 0, fountain_rate: float = 400.0) -> Scene:
    """A ground plane, `particles` balls thrown up from a box, a chain of `chain_links` springs
    hanging from a pinned particle at (2.5, 3, 0), kicked sideways, five rigid bodies (a slab,
    a ball, a capsule, a drum and a torus mesh) thrown spinning into the air, a pile of boxes
    and spheres falling onto the ground and each other, eight capsules on ball joints released
    straight out from a pivot at SWING_PIVOT and swinging down and sideways, a fountain emitting `fountain_rate`
    droplets per second that fade as they age, a flag pinned at two corners blowing in the
    wind, and a cloth falling onto a sphere and draping over it."""
    rng = np.random.default_rng(seed)
    scene = Scene(gravity=(0.0, -9.81, 0.0), drag=0.001, wind=WIND)
    scene.add_ground(restitution=0.7, friction=0.3)
    start = rng.uniform((-1.5, 0.5, -1.5), (1.5, 2.5, 1.5), size=(particles, 3))
    throw = rng.uniform((-1.0, 0.0, -1.0), (1.0, 4.0, 1.0), size=(particles, 3))
    scene.add_particles(start, throw, mass=0.05, radius=0.03, name="balls", color=(0.9, 0.4, 0.1))
    link = 0.1
    chain = np.array([(2.5 + i * link, 3.0, 0.0) for i in range(chain_links + 1)])
    kick = np.zeros_like(chain)
    kick[1:, 2] = np.linspace(0.0, 2.0, chain_links)
    ids = scene.add_particles(chain, kick, mass=0.05, radius=0.02, pinned=[0], name="chain",
                              color=(0.2, 0.5, 0.9))
    scene.add_springs(np.stack([ids[:-1], ids[1:]], axis=1), stiffness=2000.0, damping=0.5)
    for name, shape, position, velocity, spin in THROWN_BODIES:
        scene.add_rigid_body(shape, density=500.0, position=position, linear_velocity=velocity,
                             angular_velocity=spin, name=name, color=(0.3, 0.7, 0.4))
    scene.add_rigid_body(shapes.MeshShape(trimesh.creation.torus(0.2, 0.06)), density=500.0,
                         position=(-4.0, 0.5, 0.5), linear_velocity=(0.8, 18.9, -0.1),
                         angular_velocity=(5.0, 2.0, 0.5), name="torus", color=(0.8, 0.7, 0.2))
    scene.add_emitter(rate=fountain_rate, lifetime=(1.2, 1.8), position=(0.0, 0.05, -3.0), direction=(0.0, 1.0, 0.0),
                      spread=8.0, speed=(5.0, 6.0), shape="disc", radius=0.05, size=0.015, mass=0.001,
                      color=Ramp([0.0, 1.0], [(0.6, 0.8, 1.0), (1.0, 1.0, 1.0)]),
                      opacity=Ramp([0.0, 0.7, 1.0], [1.0, 0.8, 0.0]), restitution=0.3, friction=0.2, seed=seed,
                      name="fountain")
    add_pile(scene, rng)
    add_swing_chain(scene)
    # a cloth dropped flat onto a static sphere, draping over it
    centre, radius = DRAPE_SPHERE
    scene.add_collider(shapes.Sphere(radius), position=centre, restitution=0.0, friction=0.6, name="drape_sphere",
                       color=(0.4, 0.4, 0.5))
    scene.add_cloth_grid(resolution=(16, 16), size=(1.2, 1.2), position=(centre[0], 0.9, centre[2]), density=0.2,
                         orientation=(-0.7071067811865476, 0.0, 0.0, 0.7071067811865476),   # lying flat
                         stiffness=(30.0, 15.0, 1.5), damping=(0.02, 0.01, 0.002), max_stretch=0.1,
                         radius=0.01, friction=0.6, name="drape", color=(0.3, 0.4, 0.85))
    # a flag pinned at its two top corners, blowing in the wind: soft springs held to 10 % stretch
    scene.add_cloth_grid(resolution=(16, 12), size=(1.5, 1.0), position=(2.5, 1.2, 2.0), density=0.2,
                         orientation=(0.0, 0.7071067811865476, 0.0, 0.7071067811865476),   # facing the wind
                         stiffness=(40.0, 20.0, 2.0), damping=(0.02, 0.01, 0.002), pinned=["top_corners"],
                         drag=1.2, lift=0.4, max_stretch=0.1, name="flag", color=(0.85, 0.2, 0.2))
    return scene


def add_swing_chain(scene: Scene, links: int = 8) -> list[int]:
    """Add a chain of ``links`` capsules on ball joints, hung from a world pivot at SWING_PIVOT and released
    straight out along +x, swinging sideways too; returns their body indices."""
    pivot, link = np.asarray(SWING_PIVOT, float), SWING_LINK
    along = (0.0, 0.0, np.sin(np.pi / 4.0), np.cos(np.pi / 4.0))   # a capsule's y axis onto +x
    bodies, parent = [], None
    for k in range(links):
        centre = pivot + ((k + 0.5) * link, 0.0, 0.0)
        body = scene.add_rigid_body(shapes.Capsule(0.025, link / 2.0 - 0.025), density=500.0, position=centre,
                                    orientation=along, linear_velocity=(0.0, 0.0, -SWING_SPIN * (centre[0] - pivot[0])),
                                    angular_velocity=(0.0, SWING_SPIN, 0.0), name=f"swing{k}", color=(0.6, 0.3, 0.7))
        scene.add_joint("ball", parent, body, anchor=pivot + (k * link, 0.0, 0.0), name=f"swing_joint{k}")
        bodies.append(body)
        parent = body
    return bodies


def add_pile(scene: Scene, rng: np.random.Generator, layers: int = 3) -> list[int]:
    """Add a loose pile over PILE_ORIGIN: ``layers`` layers of 2 x 2 boxes and spheres (alternating), each
    a little turned and offset, falling from just above the ground; returns their body indices."""
    bodies = []
    ox, _, oz = PILE_ORIGIN
    for layer in range(layers):
        for k, (dx, dz) in enumerate(((-0.2, -0.2), (0.2, -0.2), (-0.2, 0.2), (0.2, 0.2))):
            position = (ox + dx + rng.uniform(-0.04, 0.04), 0.2 + 0.3 * layer, oz + dz + rng.uniform(-0.04, 0.04))
            if (k + layer) % 2 == 0:
                angle = rng.uniform(0.0, np.pi)
                shape = shapes.Box((0.12, 0.08, 0.1))
                turn = (0.0, np.sin(angle / 2.0), 0.0, np.cos(angle / 2.0))
                color = (0.75, 0.45, 0.3)
            else:
                shape, turn, color = shapes.Sphere(0.1), (0.0, 0.0, 0.0, 1.0), (0.3, 0.55, 0.8)
            bodies.append(scene.add_rigid_body(shape, density=400.0, position=position, orientation=turn,
                                               restitution=0.3, friction=0.6, name=f"pile{len(bodies)}",
                                               color=color))
    return bodies

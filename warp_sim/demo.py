"""The demo scene: particles bouncing on the ground and a spring chain hanging from a pinned particle."""
from __future__ import annotations

import numpy as np

from .scene import Scene


def demo_scene(particles: int = 200, chain_links: int = 20, seed: int = 0) -> Scene:
    """A ground plane, `particles` balls thrown up from a box, and a chain of `chain_links`
    springs hanging from a pinned particle at (0, 3, 0), kicked sideways."""
    rng = np.random.default_rng(seed)
    scene = Scene(gravity=(0.0, -9.81, 0.0), drag=0.001)
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
    return scene

"""Small scene builders shared by the tests."""
import numpy as np

import warp_sim as ws

G = 9.81


def oscillator(k=4.0, m=1.0, amplitude=0.1, rest=1.0, precision="float64", damping=0.0):
    """A particle on a spring to a pinned particle at the origin, along x, no gravity.
    Returns the scene; the free particle is index 1, displaced by `amplitude` from rest."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision=precision)
    scene.add_particles([[0.0, 0.0, 0.0], [rest + amplitude, 0.0, 0.0]], mass=[1.0, m], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=k, damping=damping, rest_length=rest)
    return scene


def run_steps(sim, steps, h):
    for _ in range(steps):
        sim.step(h)


def particle(sim, i=0):
    """(position, velocity) of particle i as float64 numpy vectors."""
    return (sim.state.particle_x.numpy()[i].astype(np.float64),
            sim.state.particle_v.numpy()[i].astype(np.float64))

"""Penalty contacts: one damping model for particles and bodies, so both rebound with the requested restitution."""
import pytest

import warp_sim as ws

SPEED = 4.43            # entry speed [m/s]
RADIUS = 0.1            # [m]
STIFFNESS = 1.0e5       # [N/m]
H = 1.0e-4              # [s]
STEPS = 1000            # 0.1 s: the approach (0.1 m at 4.43 m/s), the 10-20 ms contact, and the departure


def exit_speed(kind: str, e: float) -> float:
    """The upward speed [m/s] after a penalty contact with the ground, thrown down at SPEED with no gravity."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_ground(restitution=e, friction=0.0)
    if kind == "body":
        scene.add_rigid_body(ws.Sphere(RADIUS), density=1000.0, position=(0.0, 2.0 * RADIUS, 0.0),
                             linear_velocity=(0.0, -SPEED, 0.0), restitution=e, friction=0.0)
    else:
        scene.add_particles([(0.0, 2.0 * RADIUS, 0.0)], [(0.0, -SPEED, 0.0)], mass=4.19, radius=RADIUS)
    sim = ws.Simulator(scene, integrator="rk4", device="cpu", contact="penalty", penalty_stiffness=STIFFNESS)
    sim.step(H, steps=STEPS)
    if kind == "body":
        v, _ = sim.body_velocities()
        height, speed = sim.state.body_x.numpy()[0, 1], v.numpy()[0, 1]
    else:
        height, speed = sim.state.particle_x.numpy()[0, 1], sim.state.particle_v.numpy()[0, 1]
    assert height > RADIUS, "still in contact at the end of the run"
    return float(speed)


@pytest.mark.parametrize("kind", ["body", "particle"])
@pytest.mark.parametrize("e", [0.3, 0.5, 0.8])
def test_penalty_contact_rebounds_with_the_requested_restitution(kind, e):
    """Exit over entry speed equals e within 2 % for a sphere body and a particle (the no-tension
    spring-dashpot closed form of Schwager and Poeschel, inverted per contact)."""
    ratio = exit_speed(kind, e) / SPEED
    assert ratio == pytest.approx(e, rel=0.02)

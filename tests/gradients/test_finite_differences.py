"""Gradients against central differences (float64, steps of 1e-5 relative, forward-only Simulators for the
differences): a hanging spring chain's loss, read at every frame, against stiffness and mass within 1e-4 relative
under symplectic Euler and rk4 (and implicit Euler: 1e-2 with CG's default tolerance, 1e-6 with CG to 1e-10), and
against gravity, rest lengths and damping; a spinning box's final orientation
against its initial angular velocity; a pushed box's final position against its mass, under a constant force."""
import numpy as np
import pytest
from gradient_scenes import (
    CHAIN_DAMPING,
    CHAIN_MASS,
    CHAIN_REST,
    CHAIN_STIFFNESS,
    WEIGHTS,
    axis_loss,
    central_difference,
    chain,
    chain_loss,
    final_position_loss,
    forward_value,
    spinning_box,
)

import warp_sim as ws

SECONDS, SUBSTEPS, STEP = 0.5, 8, 1.0e-5
TOLERANCE = 1.0e-4


def relative_error(gradient: np.ndarray, differences: np.ndarray) -> float:
    return float(np.max(np.abs(gradient - differences) / np.maximum(np.abs(differences), 1e-8)))


@pytest.fixture(scope="module", params=["symplectic_euler", "rk4"])
def chain_gradients(request):
    integrator = request.param
    value, grads = ws.gradient(chain(), chain_loss, ["spring_stiffness", "particle_mass", "gravity",
                                                     "spring_rest_length", "spring_damping", "particle_v"],
                               seconds=SECONDS, substeps=SUBSTEPS, integrator=integrator)
    return integrator, value, grads


def chain_value(integrator, **changes) -> float:
    return forward_value(chain(**changes), chain_loss, SECONDS, substeps=SUBSTEPS, integrator=integrator)


def test_the_differentiable_run_gives_the_forward_runs_loss(chain_gradients):
    integrator, value, _ = chain_gradients
    assert value == chain_value(integrator)


def test_chain_stiffness_and_mass(chain_gradients):
    integrator, _, grads = chain_gradients
    stiffness = central_difference(lambda k: chain_value(integrator, stiffness=k), CHAIN_STIFFNESS, STEP)
    free = CHAIN_MASS[1:]
    mass = central_difference(lambda m: chain_value(integrator, mass=np.r_[CHAIN_MASS[0], m]), free, STEP)
    errors = relative_error(grads["spring_stiffness"], stiffness), relative_error(grads["particle_mass"][1:], mass)
    print(f"{integrator}: stiffness {errors[0]:.1e}, mass {errors[1]:.1e} relative to central differences")
    assert max(errors) < TOLERANCE
    assert grads["particle_mass"][0] == 0.0   # the pinned particle's mass moves nothing


def test_chain_gravity_rest_length_and_damping(chain_gradients):
    integrator, _, grads = chain_gradients
    gravity = central_difference(lambda g: chain_value(integrator, gravity=g), np.array([0.0, -9.81, 0.0]), STEP)
    rest = central_difference(lambda r: chain_value(integrator, rest=r), CHAIN_REST, STEP)
    damping = central_difference(lambda c: chain_value(integrator, damping=c), CHAIN_DAMPING, STEP)
    errors = [relative_error(grads["gravity"], gravity), relative_error(grads["spring_rest_length"], rest),
              relative_error(grads["spring_damping"], damping)]
    print(f"{integrator}: gravity {errors[0]:.1e}, rest length {errors[1]:.1e}, damping {errors[2]:.1e}")
    assert max(errors) < TOLERANCE


def test_chain_initial_velocity_along_a_direction(chain_gradients):
    """d loss / d v0 along one direction of every particle's initial velocity at once (the pinned one's is 0)."""
    integrator, _, grads = chain_gradients
    direction = np.random.default_rng(3).normal(size=(5, 3))
    direction[0] = 0.0

    def value(e):
        return forward_value(moving_chain(e[0] * direction), chain_loss, SECONDS, substeps=SUBSTEPS,
                             integrator=integrator)

    along = central_difference(value, np.zeros(1), STEP)[0]
    assert abs(np.sum(grads["particle_v"] * direction) - along) < TOLERANCE * abs(along)


def moving_chain(velocities) -> ws.Scene:
    scene = ws.Scene(precision="float64")
    positions = [(0.05 * i, -0.3 * i, 0.0) for i in range(5)]
    scene.add_particles(positions, velocities=velocities, mass=CHAIN_MASS, pinned=[0])
    scene.add_springs([(i, i + 1) for i in range(4)], stiffness=CHAIN_STIFFNESS, damping=CHAIN_DAMPING,
                      rest_length=CHAIN_REST)
    return scene


@pytest.mark.parametrize("integrator", ["rk4", "symplectic_euler"])
def test_box_angular_velocity(integrator):
    omega = np.array([1.0, 2.0, 0.5])
    _, grads = ws.gradient(spinning_box(omega), axis_loss, ["body_w", "body_mass"], seconds=SECONDS,
                           substeps=SUBSTEPS, integrator=integrator)
    differences = central_difference(lambda w: forward_value(spinning_box(w), axis_loss, SECONDS, substeps=SUBSTEPS,
                                                             integrator=integrator), omega, STEP)
    error = relative_error(grads["body_w"][0], differences)
    print(f"{integrator}: d axis / d omega0 {error:.1e} relative to central differences")
    assert error < TOLERANCE
    assert abs(grads["body_mass"][0]) < 1e-12   # inertia and angular momentum scale together: the spin is the same


def test_box_mass_under_a_constant_force():
    frames, loss = int(round(SECONDS * 60)), final_position_loss("body_x")
    force = np.tile([1.0, 2.0, -1.0], (frames, 1, 1))
    _, grads = ws.gradient(spinning_box(mass=2.0), loss, ["body_mass"], seconds=SECONDS, substeps=SUBSTEPS,
                           controls={"body_force": force})

    def value(m):   # the force held by set_body_force: the same over every frame
        sim = ws.Simulator(spinning_box(mass=m[0]))
        sim.set_body_force(0, force[0, 0])
        x = [arrays["body_x"] for _, _, arrays in sim.frames(SECONDS + 1.0 / 60.0, 60.0, SUBSTEPS)][-1]
        return float(np.dot(WEIGHTS, x[0]))

    differences = central_difference(value, np.array([2.0]), STEP)
    assert relative_error(grads["body_mass"], differences) < TOLERANCE


@pytest.mark.parametrize("tolerance, bound", [(1.0e-3, 1.0e-2), (1.0e-10, 1.0e-6)])
def test_chain_stiffness_and_mass_under_implicit_euler(tolerance, bound):
    """Implicit Euler's step solves its linear system by CG, off the tape; the tape's adjoint of the solve is the
    same CG on the same (symmetric) matrix. With CG's default tolerance (1e-3 relative) the forward runs the
    differences come from carry errors of that size, the gradient too; to 1e-10 both are near exact."""
    def integrator():
        return ws.ImplicitEuler(tolerance=tolerance)

    value, grads = ws.gradient(chain(), chain_loss, ["spring_stiffness", "particle_mass"], seconds=SECONDS,
                               substeps=SUBSTEPS, integrator=integrator())

    def chain_value(**changes) -> float:
        return forward_value(chain(**changes), chain_loss, SECONDS, substeps=SUBSTEPS, integrator=integrator())

    assert value == chain_value()
    stiffness = central_difference(lambda k: chain_value(stiffness=k), CHAIN_STIFFNESS, STEP)
    mass = central_difference(lambda m: chain_value(mass=np.r_[CHAIN_MASS[0], m]), CHAIN_MASS[1:], STEP)
    errors = relative_error(grads["spring_stiffness"], stiffness), relative_error(grads["particle_mass"][1:], mass)
    print(f"implicit Euler, CG to {tolerance:g}: stiffness {errors[0]:.1e}, mass {errors[1]:.1e} relative to central "
          f"differences")
    assert max(errors) < bound

"""Simulator(differentiable=True) under a tape of one's own: the same states as a forward-only Simulator bit for bit,
every launch recorded (the guard's aside), nothing read by an adjoint overwritten after it (Warp's own audit,
wp.config.verify_autograd_array_access), the in-place renormalisation of orientations taken back exactly, the
taped launcher's prepared launches, and the modules it launches compiled with their adjoints."""
import numpy as np
import pytest
import warp as wp
from gradient_scenes import CHAIN_STIFFNESS, WEIGHTS, weighted_final

import warp_sim as ws
from warp_sim.core import compiling
from warp_sim.core.tape import TapedLauncher

EXPLICIT = ["euler", "midpoint", "rk4", "symplectic_euler", "verlet"]
H = 1.0 / 240.0
pytestmark = pytest.mark.filterwarnings("ignore:integrator=.* grows an undamped oscillator")


def mixed() -> ws.Scene:
    """A chain of springs and a spinning box: every covered part at once (collisions off: the box would hit)."""
    scene = ws.Scene(precision="float64", drag=0.05)
    scene.add_particles([(0.05 * i, 1.0 - 0.3 * i, 0.0) for i in range(5)], mass=0.1, pinned=[0])
    scene.add_springs([(i, i + 1) for i in range(4)], stiffness=CHAIN_STIFFNESS, damping=0.2, rest_length=0.25)
    scene.add_rigid_body(ws.Box((0.2, 0.1, 0.05)), mass=2.0, position=(1.0, 1.0, 0.0),
                         linear_velocity=(0.5, 1.0, 0.0), angular_velocity=(1.0, 2.0, 0.5))
    return scene


@pytest.mark.parametrize("integrator", EXPLICIT)
def test_the_same_states_as_a_forward_only_simulator(integrator):
    forward = ws.Simulator(mixed(), integrator, collisions=False)
    taped = ws.Simulator(mixed(), integrator, collisions=False, differentiable=True)
    forward.set_body_force(0, (1.0, 0.0, 0.5), torque=(0.0, 0.1, 0.0))
    taped.set_body_force(0, (1.0, 0.0, 0.5), torque=(0.0, 0.1, 0.0))
    forward.step(H, steps=20)
    taped.step(H, steps=20)
    assert np.array_equal(forward.state.y.numpy(), taped.state.y.numpy())


@wp.kernel
def mixed_loss(y: wp.array(dtype=wp.float64), weights: wp.array(dtype=wp.float64), out: wp.array(dtype=wp.float64)):
    """out += weights[i] y[i] + y[i]^2 / 2 over the flat state: every field, nonlinearly."""
    i = wp.tid()
    wp.atomic_add(out, 0, weights[i] * y[i] + wp.float64(0.5) * y[i] * y[i])


def loss_after(sim, steps: int, weights) -> wp.array:
    sim.step(H, steps=steps)
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    wp.launch(mixed_loss, sim.state.y.shape[0], [sim.state.y, weights, out])
    return out


@pytest.mark.parametrize("integrator", EXPLICIT)
def test_a_tape_over_every_covered_part_matches_central_differences(integrator):
    """Along one direction of the whole initial state (particles, springs' ends, the box's x, q, P, L) and one of the
    stiffnesses at once: what a reused scratch state or accumulator would get wrong (it reads zeros, or later
    values), and the renormalisation's Jacobian."""
    rng = np.random.default_rng(7)
    sim = ws.Simulator(mixed(), integrator, collisions=False, differentiable=True)
    start, size = sim.state, sim.state.y.shape[0]
    weights = wp.array(rng.normal(size=size), dtype=wp.float64)
    direction, stiffness_direction = rng.normal(size=size), rng.normal(size=4)
    with wp.Tape() as tape:
        loss = loss_after(sim, 12, weights)
    tape.backward(loss)
    along = start.y.grad.numpy() @ direction + sim.model.spring_stiffness.grad.numpy() @ stiffness_direction

    def value(e):
        forward = ws.Simulator(mixed(), integrator, collisions=False)
        forward.state.y.assign(start.y.numpy() + e * direction)
        forward.model.spring_stiffness.assign(CHAIN_STIFFNESS + e * stiffness_direction)
        return float(loss_after(forward, 12, weights).numpy()[0])

    h = 1e-6
    differences = (value(h) - value(-h)) / (2 * h)
    assert abs(along - differences) < 1e-6 * abs(differences), (along, differences)


def test_the_guard_stays_off_the_tape():
    sim = ws.Simulator(mixed(), collisions=False, differentiable=True)
    with wp.Tape() as tape:
        sim.step(H, steps=2)
    recorded = {launch[0].key for launch in tape.launches if not callable(launch)}
    assert {"rk4_combine", "spring_forces_unpacked", "body_momentum_rates"} <= recorded
    assert not recorded & {"check_finite_and_bounded", "check_bodies"}
    assert sim.guard is not None


def test_a_hand_held_tape_gives_the_projectile_gradient():
    scene = ws.Scene(precision="float64")
    scene.add_particles([(0.0, 1.0, 0.0)], velocities=[(1.0, 2.0, 0.5)])
    sim = ws.Simulator(scene, "rk4", differentiable=True)
    start = sim.state
    with wp.Tape() as tape:
        sim.step(1.0 / 60.0, steps=30)
        loss = wp.zeros(1, dtype=wp.float64, requires_grad=True)
        wp.launch(weighted_final, 1, [sim.state.particle_x.reshape((1, 1)), 0, wp.vec3d(*WEIGHTS), loss])
    tape.backward(loss)
    assert np.abs(start.particle_v.grad.numpy() - 0.5 * np.array(WEIGHTS)).max() < 1e-12
    assert np.abs(start.particle_x.grad.numpy() - np.array(WEIGHTS)).max() < 1e-12


def test_the_renormalisation_is_taken_back_at_the_values_it_read():
    """The orientations are normalised in place after each step; the tape puts back what that launch read before
    its adjoint runs (so the Jacobian is the one at the unnormalised quaternion) and what it wrote after."""
    scene = ws.Scene(precision="float64")
    scene.add_rigid_body(ws.Box((0.2, 0.1, 0.05)), mass=2.0, angular_velocity=(3.0, 5.0, 1.0))
    sim = ws.Simulator(scene, "symplectic_euler", differentiable=True)   # a norm drift of ~1e-4 a step
    start = sim.state
    with wp.Tape() as tape:
        sim.step(1.0 / 30.0, steps=4)
    end = sim.state
    q = end.body_q.numpy().copy()
    assert abs(np.linalg.norm(q) - 1.0) < 1e-14
    tape.backward(grads={end.body_q: wp.array([[0.3, -0.2, 0.5, 0.1]], dtype=wp.float64).view(wp.quatd)})
    assert np.array_equal(end.body_q.numpy(), q)   # put back as it was written
    gradient = start.body_L.grad.numpy().copy()

    def orientation(L0):
        s = ws.Simulator(scene, "symplectic_euler")
        s.state.body_L.assign(wp.array([L0], dtype=wp.vec3d))
        s.step(1.0 / 30.0, steps=4)
        return float(np.dot(s.state.body_q.numpy()[0], [0.3, -0.2, 0.5, 0.1]))

    L0, h = start.body_L.numpy()[0].astype(np.float64), 1e-6
    differences = [(orientation(L0 + h * e) - orientation(L0 - h * e)) / (2 * h) for e in np.eye(3)]
    assert np.abs(gradient[0] - differences).max() < 1e-7 * np.abs(differences).max()


@wp.kernel
def squares(x: wp.array(dtype=wp.float64), scale: wp.float64, base: int, out: wp.array(dtype=wp.float64)):
    """out[i] = scale x[i]^2 for i = base + tid (a kernel launched in pieces, each from its base)."""
    i = base + wp.tid()
    out[i] = scale * x[i] * x[i]


def test_prepared_launches_of_the_taped_launcher_are_recorded():
    launcher = TapedLauncher(wp.get_device("cpu"))
    x = wp.array([1.0, 2.0, 3.0, 4.0], dtype=wp.float64, requires_grad=True)
    out = wp.zeros(4, dtype=wp.float64, requires_grad=True)
    with wp.Tape() as tape:
        prepared = launcher.prepare(squares, 4, [x, wp.float64(1.0), 5, out])
        prepared.set(1, wp.float64(3.0))
        prepared.run_pieces(4, 2, 2)   # one launch from base 0 on a tape
    assert out.numpy().tolist() == [3.0, 12.0, 27.0, 48.0] and len(tape.launches) == 1 and launcher.launches == 1
    tape.backward(grads={out: wp.ones(4, dtype=wp.float64)})
    assert x.grad.numpy().tolist() == [6.0, 12.0, 18.0, 24.0]


def test_its_modules_compile_with_their_adjoints():
    sim = ws.Simulator(mixed(), collisions=False, differentiable=True)
    modules = set(sim.kernel_modules())
    assert {"integrate", "particles", "springs", "rigid", "guards"} <= modules
    cpu = (wp.get_device("cpu").context, 1)
    for name in modules:
        module = wp.get_module(f"warp_sim.kernels.{name}")
        hooks = [module.execs[cpu].get_kernel_hooks(overload) for kernel in module._get_live_kernels()
                 for overload in kernel.overloads.values()]
        assert hooks and all(bool(h.backward) == (name != "guards") for h in hooks), name
        assert compiling.adjoints_enabled(name) == (name != "guards")

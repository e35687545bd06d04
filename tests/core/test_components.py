"""Rigid bodies against closed forms: torque-free motion, the intermediate-axis flip, the symmetric
top, projectile flight, impulses, held forces, drag, and the divergence guard."""
import math

import numpy as np
import pytest
from helpers import G

import warp_sim as ws
from warp_sim.util.rotations import quat_to_matrix

# A flat body of point masses in the xy-plane with I_body = diag(1, 2, 3) kg m^2
# (I_zz = I_xx + I_yy for a lamina): 0.5 kg at (+-sqrt 2, 0, 0) and at (0, +-1, 0).
LAMINA = ws.PointMasses([[math.sqrt(2.0), 0, 0], [-math.sqrt(2.0), 0, 0], [0, 1, 0], [0, -1, 0]], 0.5)
OMEGA0 = (0.1, 1.0, 0.1)   # [rad/s], the intermediate-axis (Dzhanibekov) case


def free_body(shape, integrator="rk4", device="cpu", **body):
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_rigid_body(shape, **body)
    return ws.Simulator(scene, integrator=integrator, device=device)


def body_state(sim, i=0):
    """(x, q, P, L) of body i as float64 numpy arrays."""
    return tuple(getattr(sim.state, name).numpy()[i].astype(np.float64)
                 for name in ("body_x", "body_q", "body_P", "body_L"))


def body_frame_omega(sim, i=0):
    """omega in the body frame: I_body^-1 R^T L [rad/s]."""
    _, q, _, L = body_state(sim, i)
    inertia = sim.scene.bodies[i].mass.inertia
    return np.linalg.solve(inertia, quat_to_matrix(q).T @ L)


def kinetic_energy(sim, i=0):
    """1/2 omega . L + 1/2 P . v [J]."""
    v, omega = (a.numpy()[i].astype(np.float64) for a in sim.body_velocities())
    _, _, P, L = body_state(sim, i)
    return 0.5 * (omega @ L + P @ v)


def complete_elliptic_k(m):
    """K(m) = integral_0^pi/2 (1 - m sin^2)^-1/2, by the arithmetic-geometric mean."""
    a, b = 1.0, math.sqrt(1.0 - m)
    while abs(a - b) > 1e-15:
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return math.pi / (2.0 * a)


def test_intermediate_axis_period_formula():
    """The issue's T = 4 K(k^2) / sqrt((I3 - I2)(L^2 - 2 E I1) / (I1 I2 I3)) gives 22.99626 s."""
    I1, I2, I3 = 1.0, 2.0, 3.0
    w = np.array(OMEGA0)
    L2 = float(np.sum((np.array([I1, I2, I3]) * w) ** 2))
    E2 = float(np.sum(np.array([I1, I2, I3]) * w * w))   # 2E
    assert L2 > E2 * I2                                   # polhode around the I3 axis
    k2 = (I2 - I1) * (E2 * I3 - L2) / ((I3 - I2) * (L2 - E2 * I1))
    T = 4.0 * complete_elliptic_k(k2) / math.sqrt((I3 - I2) * (L2 - E2 * I1) / (I1 * I2 * I3))
    assert T == pytest.approx(22.99626, abs=5e-6)


@pytest.mark.parametrize("integrator", sorted(ws.INTEGRATORS))
def test_torque_free_body_keeps_L_and_reports_energy_drift(integrator, capsys):
    """No torque: L is constant to 1e-12 relative with every integrator. The kinetic-energy drift
    over 20 s at h = 1e-3 is printed per integrator; rk4's must be below 1e-8."""
    sim = free_body(LAMINA, integrator, angular_velocity=OMEGA0)
    L0 = body_state(sim)[3]
    E0 = kinetic_energy(sim)
    for _ in range(20):
        sim.step(1e-3, 1000)
        L = body_state(sim)[3]
        assert np.linalg.norm(L - L0) <= 1e-12 * np.linalg.norm(L0)
    drift = abs(kinetic_energy(sim) - E0) / E0
    with capsys.disabled():
        print(f"\n  torque-free body, 20 s at h = 1e-3: {integrator:>16} relative energy drift {drift:.3e}")
    assert np.isfinite(drift)
    if integrator == "rk4":
        assert drift < 1e-8
    q = body_state(sim)[1]
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12       # renormalised after every step


ORDERS = {"euler": 1, "midpoint": 2, "rk4": 4, "symplectic_euler": 2, "verlet": 2}


@pytest.mark.parametrize("integrator", sorted(ORDERS))
def test_tumbling_orientation_converges_at_the_solver_order(integrator):
    """Observed order of q(2 s) for a tumbling box, from h = 0.02 and 0.01 against rk4 at h = 0.0025.
    Without torque the kicks do nothing, so symplectic Euler is its (midpoint) drift: second order."""
    def final_orientation(name, h):
        sim = free_body(ws.Box((0.1, 0.2, 0.3)), name, angular_velocity=(1.0, 2.0, 0.5))
        sim.step(h, int(round(2.0 / h)))
        return body_state(sim)[1]

    reference = final_orientation("rk4", 0.0025)
    errors = [np.linalg.norm(final_orientation(integrator, h) - reference) for h in (0.02, 0.01)]
    assert math.log2(errors[0] / errors[1]) == pytest.approx(ORDERS[integrator], abs=0.15)


def test_intermediate_axis_flip_period(device):
    """omega_2 (body frame) flips with the full period 22.99626 s within 0.5 % (rk4, h = 1e-3)."""
    sim = free_body(LAMINA, "rk4", device, angular_velocity=OMEGA0)
    h, every = 1e-3, 20
    times, omega2 = [0.0], [body_frame_omega(sim)[1]]
    while sim.time < 31.0:            # the second downward crossing comes at about 5T/4 = 28.7 s
        sim.step(h, every)
        times.append(sim.time)
        omega2.append(body_frame_omega(sim)[1])
    t, w = np.array(times), np.array(omega2)
    down = np.flatnonzero((w[:-1] > 0.0) & (w[1:] <= 0.0))
    crossings = t[down] - w[down] * (t[down + 1] - t[down]) / (w[down + 1] - w[down])
    assert len(crossings) >= 2
    assert np.diff(crossings)[0] == pytest.approx(22.99626, rel=5e-3)
    assert w.min() < -0.9 and w.max() > 0.9       # it really flips


def test_symmetric_top_precesses_at_closed_form_rate(device):
    """A cylinder (symmetry axis y) spinning about an off-symmetric axis: in the body frame omega
    turns about the axis at (I3 - I1) omega3 / I1 within 0.5 %."""
    shape = ws.Cylinder(radius=0.5, half_height=0.1)
    sim = free_body(shape, "rk4", device, mass=1.0, angular_velocity=(0.3, 2.0, 0.0))
    inertia = np.diag(shape.mass_properties(mass=1.0).inertia)
    I1, I3 = inertia[0], inertia[1]
    rate = (I3 - I1) * 2.0 / I1
    times, angles = [], []
    for _ in range(200):
        sim.step(1e-3, 10)
        w = body_frame_omega(sim)
        times.append(sim.time)
        angles.append(math.atan2(w[2], w[0]))
        assert w[1] == pytest.approx(2.0, rel=1e-9)     # the spin about the symmetry axis is constant
    slope = np.polyfit(times, np.unwrap(angles), 1)[0]
    assert abs(slope) == pytest.approx(rate, rel=5e-3)


@pytest.mark.parametrize("integrator", ["rk4", "midpoint", "verlet"])
def test_thrown_spinning_box_follows_the_projectile(integrator, device):
    """The centre of mass of a spinning box flies x0 + v0 t + g t^2 / 2 to 1e-9 m (float64)."""
    scene = ws.Scene(precision="float64")
    x0, v0 = np.array([0.0, 1.0, 0.0]), np.array([1.5, 6.0, -0.5])
    scene.add_rigid_body(ws.Box((0.1, 0.2, 0.3)), position=x0, linear_velocity=v0,
                         angular_velocity=(3.0, -5.0, 7.0), orientation=(0.2, 0.3, 0.1, 0.927362))
    sim = ws.Simulator(scene, integrator=integrator, device=device)
    sim.step(1.0 / 240.0, 240)
    g = np.array([0.0, -G, 0.0])
    expected = x0 + v0 * sim.time + 0.5 * g * sim.time**2
    assert np.linalg.norm(body_state(sim)[0] - expected) < 1e-9
    v = sim.body_velocities()[0].numpy()[0]
    assert np.linalg.norm(v - (v0 + g * sim.time)) < 1e-9


def test_impulse_changes_momentum_and_spin_exactly(device):
    """J at offset r: delta P = J and delta omega = I(t)^-1 (r x J), with I(t) of a rotated box."""
    q = np.array([0.3, -0.5, 0.2, 0.78])
    q /= np.linalg.norm(q)
    sim = free_body(ws.Box((0.1, 0.25, 0.4)), "rk4", device, density=700.0, position=(1.0, 2.0, 3.0),
                    orientation=q, linear_velocity=(0.5, 0.0, 0.0), angular_velocity=(0.0, 1.0, 0.0))
    x, _, P0, _ = body_state(sim)
    omega0 = sim.body_velocities()[1].numpy()[0]
    J, r = np.array([0.3, -1.2, 2.0]), np.array([0.05, 0.2, -0.3])
    sim.apply_impulse(0, J, point=x + r)
    R = quat_to_matrix(q)
    inertia_world = R @ sim.scene.bodies[0].mass.inertia @ R.T
    assert np.allclose(body_state(sim)[2] - P0, J, rtol=0, atol=1e-14)
    expected = np.linalg.solve(inertia_world, np.cross(r, J))
    assert np.allclose(sim.body_velocities()[1].numpy()[0] - omega0, expected, rtol=1e-12, atol=1e-12)


def test_force_at_a_point_gives_force_and_torque(device):
    """A held force F at world point p: P grows as F t and L as ((p - x) x F) t (no gravity)."""
    sim = free_body(ws.Sphere(0.2), "rk4", device, position=(0.0, 1.0, 0.0))
    F, p = np.array([0.0, 0.0, 2.0]), np.array([0.2, 1.0, 0.0])
    sim.set_body_force(0, F, point=p)
    sim.step(1e-2, 50)
    _, _, P, L = body_state(sim)
    assert np.allclose(P, F * sim.time, rtol=1e-12, atol=1e-14)
    assert np.allclose(L, np.cross(p - np.array([0.0, 1.0, 0.0]), F) * sim.time, rtol=1e-12, atol=1e-14)
    sim.set_body_force(0)                           # cleared: momentum now constant
    P1 = body_state(sim)[2]
    sim.step(1e-2, 10)
    assert np.allclose(body_state(sim)[2], P1, rtol=0, atol=1e-14)


def test_linear_and_angular_drag_decay_exponentially(device):
    """A sphere (isotropic, so omega stays along L): v = v0 exp(-c t / M), omega = w0 exp(-k t / I),
    and with wind the velocity relaxes towards the wind (rk4 at h = 1e-3: 1e-9 relative)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64", wind=(1.0, 0.0, 0.0))
    shape = ws.Sphere(0.1)
    props = shape.mass_properties(mass=2.0)
    scene.add_rigid_body(shape, mass=2.0, linear_velocity=(0.0, 3.0, 0.0), angular_velocity=(0.0, 0.0, 5.0),
                         drag=0.8, angular_drag=0.01)
    sim = ws.Simulator(scene, integrator="rk4", device=device)
    sim.step(1e-3, 1000)
    t = sim.time
    v, omega = (a.numpy()[0] for a in sim.body_velocities())
    decay = math.exp(-0.8 * t / 2.0)
    assert np.allclose(v, [1.0 - decay, 3.0 * decay, 0.0], rtol=1e-9, atol=1e-12)
    assert omega[2] == pytest.approx(5.0 * math.exp(-0.01 * t / props.inertia[0, 0]), rel=1e-9)


def test_rotation_matrix_is_available(device):
    q = np.array([0.1, 0.7, -0.2, 0.5])
    sim = free_body(ws.Sphere(0.1), "rk4", device, orientation=q / np.linalg.norm(q))
    assert np.allclose(sim.body_rotations().numpy()[0], quat_to_matrix(q / np.linalg.norm(q)), atol=1e-12)


def test_mesh_body_sits_at_its_mesh_placement():
    """A mesh with its centre of mass off its origin: the body's x is position + R com."""
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    box.apply_translation((0.5, 0.0, 0.0))
    scene = ws.Scene(precision="float64")
    q = np.array([0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4)])   # 90 degrees about y
    scene.add_rigid_body(ws.MeshShape(box), position=(1.0, 2.0, 3.0), orientation=q)
    assert np.allclose(scene.bodies[0].position, [1.0, 2.0, 2.5], atol=1e-12)


def test_nan_user_force_stops_with_the_body_named():
    scene = ws.Scene(precision="float64")
    scene.add_rigid_body(ws.Sphere(0.1), position=(0, 1, 0))
    scene.add_rigid_body(ws.Sphere(0.1), position=(1, 1, 0))
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.step(0.01, 3)
    sim.control.body_force.assign(np.array([[0, 0, 0], [np.inf, 0, 0]]))
    with pytest.raises(ws.SimulationDiverged) as error:
        sim.step(0.01, 5)
    assert (error.value.step, error.value.component, error.value.element) == (4, "bodies", 1)
    assert "non-finite" in str(error.value) and "P = [" in str(error.value)


def test_runaway_body_speed_is_caught():
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_rigid_body(ws.Box(0.1), linear_velocity=(5.0, 0.0, 0.0))
    sim = ws.Simulator(scene, device="cpu", max_speed=10.0)
    sim.set_body_force(0, (sim.scene.bodies[0].mass.mass * 100.0, 0.0, 0.0))   # 100 m/s^2
    with pytest.raises(ws.SimulationDiverged, match="speed above max_speed") as error:
        sim.step(0.01, 20)
    assert error.value.step == 6     # 5 + 100 * 0.06 = 11 m/s > 10 first after step 6


@pytest.mark.parametrize("kwargs, argument", [
    (dict(orientation=(0, 0, 0, 0)), "orientation"),
    (dict(orientation=(0, 0, np.nan, 1)), "orientation"),
    (dict(position=(0, np.nan, 0)), "position"),
    (dict(linear_velocity=(0, 1)), "linear_velocity"),
    (dict(angular_velocity=(np.inf, 0, 0)), "angular_velocity"),
    (dict(mass=0.0), "mass"),
    (dict(mass=-1.0), "mass"),
    (dict(density=-5.0), "density"),
    (dict(restitution=1.5), "restitution"),
    (dict(friction=-0.1), "friction"),
    (dict(drag=-1.0), "drag"),
])
def test_bad_body_input_names_the_argument(kwargs, argument):
    scene = ws.Scene()
    with pytest.raises(ValueError, match=rf"^{argument}="):
        scene.add_rigid_body(ws.Sphere(0.1), **kwargs)


def test_non_unit_quaternion_is_normalised_with_a_warning():
    scene = ws.Scene()
    with pytest.warns(UserWarning, match="orientation"):
        scene.add_rigid_body(ws.Sphere(0.1), orientation=(0.0, 0.0, 0.0, 2.0))
    assert np.allclose(scene.bodies[0].orientation, [0, 0, 0, 1])


def test_bad_shape_and_body_index():
    scene = ws.Scene()
    with pytest.raises(ValueError, match="^shape="):
        scene.add_rigid_body("sphere")
    scene.add_rigid_body(ws.Sphere(0.1), name="ball")
    with pytest.raises(ValueError, match="^name="):
        scene.add_rigid_body(ws.Sphere(0.1), name="ball")
    sim = ws.Simulator(scene, device="cpu")
    for bad in (1, -1, 0.5, True):
        with pytest.raises(ValueError, match="^body="):
            sim.apply_impulse(bad, (1, 0, 0))
    with pytest.raises(ValueError, match="^impulse="):
        sim.apply_impulse(0, (1, np.nan, 0))
    with pytest.raises(ValueError, match="^steps="):
        sim.step(0.01, 0)

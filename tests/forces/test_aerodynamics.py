"""Cloth aerodynamics (drag and lift per triangle) against closed forms."""
import math

import numpy as np
import pytest
from helpers import RHO, add_grid, add_mesh, host

import warp_sim as ws
from warp_sim.core import Forces
from warp_sim.forces import AeroForces

G = 9.81


def aero_term(sim):
    return next(term for term in sim.dynamics.force_terms if isinstance(term, AeroForces))


def aero_forces(sim, state=None):
    """The aerodynamic force on every particle at ``state`` (default: the current one), float64 (N, 3)."""
    forces = sim.dynamics.forces
    forces.clear()
    aero_term(sim).apply(state or sim.state, sim.time, forces)
    return host(forces.particle_f)


def rotation(seed):
    """A random proper rotation matrix."""
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


# aerodynamics -------------------------------------------------------------------------------------------------
def test_falling_triangle_reaches_the_terminal_velocity(device):
    """Face-on fall with drag: v(t) = v_t tanh(g t / v_t), v_t = sqrt(2 m g / (rho C_D A))."""
    mass, c_drag, area = 0.01, 1.0, 0.5
    scene = ws.Scene(precision="float64")
    ids = scene.add_particles([[0.0, 10.0, 0.0], [1.0, 10.0, 0.0], [0.0, 10.0, 1.0]], mass=mass / 3)
    add_mesh(scene, [ids], ids[0], 3, drag=c_drag)
    sim = ws.Simulator(scene, integrator="rk4", device=device)
    v_t = math.sqrt(2.0 * mass * G / (RHO * c_drag * area))
    h = 1.0e-3
    sim.step(h, steps=100)
    v = host(sim.state.particle_v)
    assert np.allclose(v, v[0], rtol=0.0, atol=1e-15)            # the three vertices move as one
    assert -v[0, 1] == pytest.approx(v_t * math.tanh(G * 0.1 / v_t), rel=1e-8)
    sim.step(h, steps=400)                                         # t = 0.5 s = 8.6 v_t / g
    x, v = host(sim.state.particle_x), host(sim.state.particle_v)
    assert abs(-v[0, 1] - v_t) <= 0.005 * v_t
    assert np.all(x[:, 1] == x[0, 1])                              # still horizontal
    assert np.abs(v[:, [0, 2]]).max() < 1e-15


def test_triangle_moving_in_its_own_plane_feels_no_force(device):
    R = rotation(1)
    corners = np.array([[0.0, 0.0, 0.0], [0.7, 0.0, 0.1], [0.2, 0.0, 0.5]]) @ R.T + [0.3, 1.0, -0.2]
    along = np.array([[1.0, 0.0, 0.3], [-0.4, 0.0, 2.0]]) @ R.T          # in the triangle's plane
    for velocity, wind in ((along[0], np.zeros(3)), (np.zeros(3), along[1]), (along[0], along[1])):
        scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64", wind=wind)
        ids = scene.add_particles(corners, velocities=np.tile(velocity, (3, 1)), mass=0.1)
        add_mesh(scene, [ids], ids[0], 3, drag=1.3, lift=0.8)
        sim = ws.Simulator(scene, integrator="euler", device=device)
        assert np.abs(aero_forces(sim)).max() <= 1e-12
        sim.step(1e-3, steps=10)
        assert np.abs(host(sim.state.particle_v) - velocity).max() <= 1e-12


@pytest.mark.parametrize("kind", ["drag", "lift"])
def test_force_on_a_stationary_triangle_in_a_wind_matches_the_formula(kind, device):
    """A plate at angle of attack alpha to a wind of speed W, in its own frame (plate in xz, normal y,
    wind W (cos alpha, sin alpha, 0)): drag 1/2 rho C_D A W^2 sin(alpha) along y, lift
    1/2 rho C_L A W^2 sin(alpha) cos(alpha) along (-sin alpha, cos alpha, 0); rotated at random."""
    coefficient, W, mass, h = 0.9, 6.0, 0.2, 1.0e-3
    R = rotation(7)
    local = np.array([[0.0, 0.0, 0.0], [0.8, 0.0, 0.0], [0.3, 0.0, 0.6]])
    area = 0.5 * 0.8 * 0.6
    for winding in ([0, 1, 2], [0, 2, 1]):                        # either normal: the same force
        for alpha in np.radians([0.0, 10.0, 30.0, 45.0, 60.0, 90.0]):
            wind_local = W * np.array([math.cos(alpha), math.sin(alpha), 0.0])
            scale = 0.5 * RHO * coefficient * area * W**2
            if kind == "drag":
                expected = scale * math.sin(alpha) * np.array([0.0, 1.0, 0.0])
            else:
                expected = scale * math.sin(alpha) * math.cos(alpha) * np.array([-math.sin(alpha), math.cos(alpha),
                                                                                0.0])
            scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64", wind=R @ wind_local)
            ids = scene.add_particles(local @ R.T + [1.0, 2.0, 3.0], mass=mass)
            add_mesh(scene, [ids[winding]], ids[0], 3, **{kind: coefficient})
            sim = ws.Simulator(scene, integrator="euler", device=device)
            force = aero_forces(sim)
            assert np.abs(force - (R @ expected) / 3).max() <= 1e-9 * scale / 3
            sim.step(h)                                           # from rest: v1 = h F / m per vertex
            v1 = host(sim.state.particle_v)
            assert np.abs(v1 * mass / h - (R @ expected) / 3).max() <= 1e-9 * scale / 3


def test_pinned_vertices_do_not_move_in_the_wind(device):
    scene = ws.Scene(precision="float64", wind=(1.0, 0.5, 6.0))
    ids, _ = add_grid(scene, n=6, drag=1.2, lift=0.6, stiffness=20.0)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
    x0 = host(sim.state.particle_x)
    top = np.arange(6)
    for _ in range(10):
        sim.step(2e-3, steps=10)
        x, v = host(sim.state.particle_x), host(sim.state.particle_v)
        assert np.array_equal(x[top], x0[top]) and not np.any(v[top])
    assert np.abs(x[6:, 2] - x0[6:, 2]).max() > 1e-3             # the free part is blown along +z
    assert np.abs(aero_forces(sim)[top]).max() > 0.0              # pinned vertices get their share, ignore it


def test_momentum_change_of_a_free_cloth_equals_the_aerodynamic_impulse(device):
    """No gravity, free cloth: springs are internal, so d(sum m v) = sum over steps of h F_aero(x_n, v_n)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64", wind=(2.0, 3.0, -1.0))
    ids, _ = add_grid(scene, n=6, hanging=False, pin_top=False, mass=0.02, stiffness=30.0, drag=1.1, lift=0.7)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
    rng = np.random.default_rng(3)
    x = host(sim.state.particle_x)
    x[:, 1] += 0.03 * rng.normal(size=len(x))                     # crumpled: triangles at many angles
    sim.state.particle_x.assign(x)
    mass, h = 0.02, 2e-3
    p0 = mass * host(sim.state.particle_v).sum(axis=0)
    impulse = np.zeros(3)
    for _ in range(100):
        impulse += h * aero_forces(sim).sum(axis=0)
        sim.step(h)
    p1 = mass * host(sim.state.particle_v).sum(axis=0)
    assert np.linalg.norm(impulse) > 1e-3
    assert np.abs((p1 - p0) - impulse).max() <= 1e-10 * np.linalg.norm(impulse)


# strain limiting ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("options, argument", [
    ({"drag": -1.0}, "drag=-1.0"), ({"drag": 1.0, "lift": -0.5}, "lift=-0.5"),
    ({"drag": 1.0, "air_density": 0.0}, "air_density=0.0"), ({"lift": 1.0, "air_density": -1.2}, "air_density=-1.2"),
    ({"max_stretch": 0.0}, "max_stretch=0.0"), ({"max_stretch": -0.1}, "max_stretch=-0.1"),
    ({"max_stretch": float("nan")}, "max_stretch=nan"),
])
def test_bad_mesh_coefficients_are_rejected(options, argument):
    scene = ws.Scene()
    add_grid(scene, n=3, **options)
    with pytest.raises(ValueError, match=argument) as caught:
        ws.Simulator(scene, device="cpu")
    assert "mesh0" in str(caught.value)


def test_forces_accumulator_is_shared_with_other_terms():
    """AeroForces adds into particle_f like any force term: springs and air together."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64", wind=(0.0, 5.0, 0.0))
    add_grid(scene, n=3, hanging=False, pin_top=False, drag=1.0)
    sim = ws.Simulator(scene, integrator="euler", device="cpu")
    assert isinstance(sim.dynamics.forces, Forces) and sim.dynamics.forces.particle_f.shape[0] == 9
    force = aero_forces(sim)
    total = 0.5 * RHO * 1.0 * (0.2 * 0.2) * 25.0                  # flat 0.2 m square face-on to 5 m/s
    assert force.sum(axis=0) == pytest.approx([0.0, total, 0.0], abs=1e-12)

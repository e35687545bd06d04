"""Cloth aerodynamics (drag and lift per triangle) and Provot strain limiting, against closed forms."""
import math

import numpy as np
import pytest

import warp_sim as ws
from warp_sim.aerodynamics import AeroForces
from warp_sim.dynamics import Forces
from warp_sim.scene import SurfaceMesh
from warp_sim.strain import StrainLimiter, colour_springs

G = 9.81
RHO = 1.2


def add_mesh(scene, triangles, start, count, springs=None, drag=0.0, lift=0.0, air_density=RHO, max_stretch=None):
    """Append a SurfaceMesh record by hand (what Scene.add_cloth_grid will make)."""
    triangles = np.asarray(triangles, dtype=np.int64)
    scene.meshes.append(SurfaceMesh(
        name=f"mesh{len(scene.meshes)}", start=start, count=count, face_counts=np.full(len(triangles), 3),
        face_indices=(triangles - start).ravel(), triangles=triangles,
        springs=springs or {"structural": np.zeros(0, dtype=np.int64), "shear": np.zeros(0, dtype=np.int64),
                            "bend": np.zeros(0, dtype=np.int64)},
        color=(0.8, 0.8, 0.8), drag=drag, lift=lift, air_density=air_density, max_stretch=max_stretch))


def add_grid(scene, n=8, spacing=0.1, mass=0.01, stiffness=10.0, damping=0.01, hanging=True, pin_top=True,
             **mesh_options):
    """An n x n cloth of structural and shear springs: hanging in the xy plane from y = 2 (row 0 on top,
    pinned with pin_top) or lying in the xz plane at y = 1. Returns (particle ids, spring families)."""
    rows, cols = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a, b = cols * spacing, rows * spacing
    zero = np.zeros_like(a, dtype=float)
    positions = np.stack([a, 2.0 - b, zero] if hanging else [a, zero + 1.0, b], -1).reshape(-1, 3)
    grid = np.arange(n * n).reshape(n, n)
    ids = scene.add_particles(positions, mass=mass, pinned=grid[0] if pin_top else None,
                              name=f"cloth{len(scene.meshes)}")
    grid = grid + ids[0]
    structural = np.concatenate([np.stack([grid[:, :-1].ravel(), grid[:, 1:].ravel()], 1),
                                 np.stack([grid[:-1].ravel(), grid[1:].ravel()], 1)])
    shear = np.concatenate([np.stack([grid[:-1, :-1].ravel(), grid[1:, 1:].ravel()], 1),
                            np.stack([grid[:-1, 1:].ravel(), grid[1:, :-1].ravel()], 1)])
    springs = {"structural": scene.add_springs(structural, stiffness, damping),
               "shear": scene.add_springs(shear, stiffness, damping), "bend": np.zeros(0, dtype=np.int64)}
    quads = np.stack([grid[:-1, :-1].ravel(), grid[:-1, 1:].ravel(), grid[1:, 1:].ravel(), grid[1:, :-1].ravel()], 1)
    add_mesh(scene, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]), ids[0], n * n, springs,
             **mesh_options)
    return ids, springs


def host(array):
    """A float64 copy of a device array (on the CPU, .numpy() shares the array's memory)."""
    return np.array(array.numpy(), dtype=np.float64)


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
def spring_strains(sim, springs, families=("structural", "shear")):
    scene = sim.model.scene
    ids = np.concatenate([springs[f] for f in families])
    pairs, rest = scene.spring_array("pairs")[ids], scene.spring_array("rest_length")[ids]
    x = host(sim.state.particle_x).astype(np.float64)
    return np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1) / rest - 1.0


@pytest.mark.parametrize("precision, tolerance, rounding", [("float64", 1e-6, 1e-12), ("float32", 1e-4, 1e-5)])
def test_strain_limiting_keeps_every_structural_spring_under_the_configured_elongation(precision, tolerance, rounding,
                                                                                         device):
    """A soft 8 x 8 cloth hanging from its pinned top row stretches to 78 % without limiting; with
    max_stretch 0.1 no structural or shear spring ever exceeds 1.1 (1 + tolerance) L0 (the limiter's
    default tolerance; rounding: a float32 length 2 m from the origin is good to about 4e-6 of 0.11 m)."""
    bound = (1.0 + 0.1) * (1.0 + tolerance) - 1.0 + rounding
    strains = {}
    for max_stretch in (None, 0.1):
        scene = ws.Scene(precision=precision)
        _, springs = add_grid(scene, max_stretch=max_stretch)
        sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
        x0 = host(sim.state.particle_x)
        worst, iterations = -1.0, []
        for _ in range(300):
            sim.step(5e-3)
            strain = spring_strains(sim, springs)
            worst = max(worst, strain.max())
            if max_stretch is not None:
                limiter = sim.strain_limiter
                iterations.append(limiter.last_iterations)
                assert limiter.converged
                assert strain.max() <= bound
                assert limiter.max_strain == pytest.approx(strain.max(), abs=rounding)
                x, v = host(sim.state.particle_x), host(sim.state.particle_v)
                assert np.array_equal(x[:8], x0[:8]) and not np.any(v[:8])      # the pinned row
        strains[max_stretch] = worst
        if max_stretch is not None:
            print(f"{precision}: sweeps per step max {max(iterations)}, mean {np.mean(iterations):.2f}")
            assert max(iterations) < limiter.max_iterations
    assert strains[None] > 0.5                                     # the test can fail: unlimited, it stretches
    assert strains[0.1] <= bound


def free_cloth(device, scale=1.0, max_stretch=0.1, seed=0, noise=0.0, velocity_noise=0.0):
    """A free 6 x 6 cloth (no gravity, no pins, equal masses) with its positions scaled about the
    first particle and jittered: its springs stretched (scale > 1) or compressed (scale < 1)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    _, springs = add_grid(scene, n=6, hanging=False, pin_top=False, max_stretch=max_stretch)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
    rng = np.random.default_rng(seed)
    x = host(sim.state.particle_x)
    x = x[0] + scale * (x - x[0]) + noise * rng.normal(size=x.shape)
    sim.state.particle_x.assign(x)
    sim.state.particle_v.assign(velocity_noise * rng.normal(size=x.shape))
    return sim, springs


@pytest.mark.parametrize("scale", [0.8, 1.0, 1.05])
def test_springs_within_the_limit_and_compressed_ones_are_untouched(scale, device):
    sim, springs = free_cloth(device, scale=scale, velocity_noise=0.3)
    x, v = host(sim.state.particle_x), host(sim.state.particle_v)
    sim.strain_limiter.apply(sim.state, sim.state, 1e-3)
    assert np.array_equal(host(sim.state.particle_x), x) and np.array_equal(host(sim.state.particle_v), v)
    assert sim.strain_limiter.last_iterations == 0 and sim.strain_limiter.converged
    assert sim.strain_limiter.max_strain == pytest.approx(spring_strains(sim, springs).max(), abs=1e-12)


def test_limiter_conserves_the_linear_momentum_of_a_free_cloth(device):
    sim, springs = free_cloth(device, scale=1.25, noise=0.01, velocity_noise=0.5, seed=4)
    mass, h = 0.01, 1e-2
    x, v = host(sim.state.particle_x), host(sim.state.particle_v)
    before = spring_strains(sim, springs)
    assert before.max() > 0.2
    sim.strain_limiter.apply(sim.state, sim.state, h)
    x1, v1 = host(sim.state.particle_x), host(sim.state.particle_v)
    assert sim.strain_limiter.converged
    assert spring_strains(sim, springs).max() <= 1.1 * (1.0 + 1e-6) - 1.0
    assert np.abs(v1 - v).max() > 1.0                              # it did move things (dx / h)
    assert np.allclose(v1 - v, (x1 - x) / h, rtol=0.0, atol=1e-10)  # v += dx / h
    assert np.abs(mass * (v1.sum(axis=0) - v.sum(axis=0))).max() <= 1e-12
    assert np.abs(mass * (x1.sum(axis=0) - x.sum(axis=0))).max() <= 1e-12
    assert (before > 0.1).sum() > 100                              # most springs started over their limit


def test_limiter_in_the_simulator_conserves_momentum(device):
    sim, springs = free_cloth(device, scale=1.0, velocity_noise=2.0, seed=5)
    p0 = host(sim.state.particle_v).sum(axis=0)
    for _ in range(50):
        sim.step(5e-3)
        assert spring_strains(sim, springs).max() <= 1.1 * (1.0 + 1e-6) - 1.0
    assert np.abs(host(sim.state.particle_v).sum(axis=0) - p0).max() <= 1e-11


def test_spring_between_two_pinned_particles_is_left_alone():
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    ids = scene.add_particles([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], pinned=[0, 1])
    pinned_spring = scene.add_springs([[0, 1]], 1.0, rest_length=0.5)
    free_spring = scene.add_springs([[1, 2]], 1.0, rest_length=0.5)
    add_mesh(scene, [ids], 0, 3, {"structural": np.concatenate([pinned_spring, free_spring])}, max_stretch=0.1)
    sim = ws.Simulator(scene, integrator="euler", device="cpu")
    assert sim.strain_limiter.constraint_count == 1
    sim.step(1e-2)
    x = host(sim.state.particle_x)
    assert np.array_equal(x[:2], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    assert x[2, 0] == pytest.approx(1.55, abs=1e-12)             # the free end comes to 1.1 L0
    assert sim.strain_limiter.last_iterations == 1


def test_colouring_never_gives_one_colour_two_springs_at_a_particle():
    rows = np.arange(64).reshape(8, 8)
    grid = np.concatenate([np.stack([rows[:, :-1].ravel(), rows[:, 1:].ravel()], 1),
                           np.stack([rows[:-1].ravel(), rows[1:].ravel()], 1),
                           np.stack([rows[:-1, :-1].ravel(), rows[1:, 1:].ravel()], 1),
                           np.stack([rows[:-1, 1:].ravel(), rows[1:, :-1].ravel()], 1)])
    rng = np.random.default_rng(0)
    random = rng.integers(0, 40, size=(400, 2))
    random = random[random[:, 0] != random[:, 1]]
    for pairs, count in ((grid, 64), (random, 40)):
        colours = colour_springs(pairs, count)
        for c in np.unique(colours):
            ends = pairs[colours == c].ravel()
            assert len(np.unique(ends)) == len(ends)
        degree = np.bincount(pairs.ravel(), minlength=count).max()
        assert colours.max() + 1 <= 2 * degree - 1
    assert colour_springs(grid, 64).max() + 1 == 8


# validation ---------------------------------------------------------------------------------------------------
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


@pytest.mark.parametrize("options, argument", [
    ({"max_iterations": 0}, "max_iterations=0"), ({"max_iterations": 2.5}, "max_iterations=2.5"),
    ({"max_iterations": True}, "max_iterations=True"), ({"tolerance": -1e-6}, "tolerance=-1e-06"),
    ({"relaxation": 2.0}, "relaxation=2.0"), ({"relaxation": 0.5}, "relaxation=0.5"),
])
def test_bad_limiter_options_are_rejected(options, argument):
    scene = ws.Scene()
    add_grid(scene, n=3, max_stretch=0.1)
    with pytest.raises(ValueError, match=argument):
        StrainLimiter(ws.Model(scene, "cpu"), **options)


def test_forces_accumulator_is_shared_with_other_terms():
    """AeroForces adds into particle_f like any force term: springs and air together."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64", wind=(0.0, 5.0, 0.0))
    add_grid(scene, n=3, hanging=False, pin_top=False, drag=1.0)
    sim = ws.Simulator(scene, integrator="euler", device="cpu")
    assert isinstance(sim.dynamics.forces, Forces) and sim.dynamics.forces.particle_f.shape[0] == 9
    force = aero_forces(sim)
    total = 0.5 * RHO * 1.0 * (0.2 * 0.2) * 25.0                  # flat 0.2 m square face-on to 5 m/s
    assert force.sum(axis=0) == pytest.approx([0.0, total, 0.0], abs=1e-12)

"""Particles and cloth against static colliders over the step (continuous collision, passes/particle_shapes.py):
no tunnelling through thin boxes, spheres, capsules, cylinders, closed meshes and open surfaces (from both sides)
at any speed, cloth on a table at 1/60 s, the bounce at the time of impact, sliding across a mesh's inner edges.

Tolerances: positions are float32 geometry (a collider's pose and a mesh's points are float32, like a body's
contacts), so "on the near side" means within 1e-6 m of the radius off the surface (the gaps land within 3e-8)."""
import math

import numpy as np
import pytest
import trimesh
from helpers import G

import warp_sim as ws

H = 1.0 / 480.0   # 8 substeps of a 60 fps frame
R = 0.01          # particle radius [m]
SLACK = 1.0e-6    # [m] float32 geometry
FLAT = (-math.sin(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4))   # lays a cloth grid flat, facing +Y


def square(n=2, half=0.5):
    """An open surface: the square |x|, |z| <= half at y = 0 in (n - 1)^2 cells of two triangles."""
    ticks = np.linspace(-half, half, n)
    vertices = np.array([(x, 0.0, z) for z in ticks for x in ticks])
    faces = [[j * n + i, (j + 1) * n + i, j * n + i + 1] for j in range(n - 1) for i in range(n - 1)]
    faces += [[j * n + i + 1, (j + 1) * n + i, (j + 1) * n + i + 1] for j in range(n - 1) for i in range(n - 1)]
    return trimesh.Trimesh(vertices, np.array(faces), process=False)


#: each thin shape at y = 0.5, crossed along Y through its middle: (shape, orientation, its half thickness [m])
THIN = {
    "box": (ws.Box((0.5, 0.005, 0.5)), (0.0, 0.0, 0.0, 1.0), 0.005),
    "sphere": (ws.Sphere(0.005), (0.0, 0.0, 0.0, 1.0), 0.005),
    "capsule": (ws.Capsule(0.005, 0.3), (0.0, 0.0, math.sin(math.pi / 4), math.sin(math.pi / 4)), 0.005),  # along X
    "cylinder": (ws.Cylinder(0.5, 0.005), (0.0, 0.0, 0.0, 1.0), 0.005),   # a disc
    "closed mesh": (ws.MeshShape(trimesh.creation.box(extents=(1.0, 0.01, 1.0))), (0.0, 0.0, 0.0, 1.0), 0.005),
    "open mesh": (ws.MeshShape(square(), solid=False), (0.0, 0.0, 0.0, 1.0), 0.0),
}


def shot(shape, orientation, speed, side=1, precision="float64", restitution=0.0, continuous=True, distance=0.5):
    """A particle of radius R fired at ``speed`` [m/s] along -side Y from ``distance`` [m] on the ``side`` of a
    collider at y = 0.5, no gravity; the simulator."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision=precision)
    scene.add_collider(shape, position=(0.0, 0.5, 0.0), orientation=orientation, restitution=restitution,
                       friction=0.0)
    scene.add_particles([[0.0, 0.5 + distance * side, 0.0]], [[0.0, -side * speed, 0.0]], radius=R)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.particle_shapes.continuous = continuous
    return sim


def gaps(sim, side, half, steps):
    """The particle's gap to the collider's near face less R [m] after each of ``steps`` steps of H."""
    out = []
    for _ in range(steps):
        sim.step(H, substeps=1)
        out.append(side * (sim.state.particle_x.numpy()[0, 1] - 0.5) - half - R)
    return np.array(out)


@pytest.mark.parametrize("speed", [10.0, 100.0, 1.0e6])
@pytest.mark.parametrize("name", sorted(THIN))
def test_fast_particle_stops_on_the_near_side(name, speed):
    """At 10, 100 and 1e6 m/s (2 cm to 2 km a step of 1/480 s) against 1 cm thin shapes, restitution 0: it stops
    at R from the near side and stays there; the closest it ever comes is R within float32 geometry."""
    shape, orientation, half = THIN[name]
    sim = shot(shape, orientation, speed)
    gap = gaps(sim, 1, half, 30)
    assert gap.min() >= -SLACK, gap.min()
    assert abs(gap[-1]) <= SLACK
    assert abs(sim.state.particle_v.numpy()[0, 1]) < 1e-9 * speed


def gap_to(name, x, side):
    """Particle x's gap to THIN[name] at y = 0.5 less R [m], on the ``side`` it came from (over the faces of the
    slab-like shapes, where their top face is the nearest part; 1 m elsewhere)."""
    _, _, half = THIN[name]
    if name == "sphere":
        return np.linalg.norm(x - (0.0, 0.5, 0.0)) - half - R
    if name == "capsule":
        return np.linalg.norm(x - (np.clip(x[0], -0.3, 0.3), 0.5, 0.0)) - half - R
    return side * (x[1] - 0.5) - half - R if abs(x[0]) < 0.5 else 1.0


@pytest.mark.parametrize("degrees", [10.0, 45.0])
@pytest.mark.parametrize("name", sorted(THIN))
def test_oblique_particle_bounces_off_the_near_side(name, degrees):
    """At 10 m/s and 10 or 45 degrees to the surface, e = 0.5, mu = 0.3, aimed at the top (or, for the open surface,
    at either side; its path crossing the surface): never closer than R over 40 steps; at 1000 m/s it leaves on the
    side it came from. (A path that grazes within R / 2 of R is left to the end-of-step projection.)"""
    shape, orientation, half = THIN[name]
    a = math.radians(degrees)
    for side in ((1, -1) if name == "open mesh" else (1,)):
        for speed in (10.0, 1000.0):
            direction = np.array([math.cos(a), -side * math.sin(a), 0.0])
            scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
            scene.add_collider(shape, position=(0.0, 0.5, 0.0), orientation=orientation, restitution=0.5,
                               friction=0.3)
            aim = np.array([0.0, 0.5 + side * half, 0.0])   # its path through the surface: a hit (R deep)
            scene.add_particles([aim - 0.3 * direction], [speed * direction], radius=R)
            sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
            worst = np.inf
            for _ in range(40):
                sim.step(H, substeps=1)
                x = sim.state.particle_x.numpy()[0]
                worst = min(worst, gap_to(name, x, side) if speed == 10.0 else np.inf)
            assert worst >= -SLACK, (side, speed, worst)
            assert side * (x[1] - 0.5) > 0.0, (side, speed, x)
            assert side * sim.state.particle_v.numpy()[0, 1] > 0.0


@pytest.mark.parametrize("speed", [10.0, 1.0e6])
def test_open_surface_holds_particles_on_both_sides(speed):
    """An open (double-sided) surface: a particle from above stops above it, one from below stops below it."""
    shape, orientation, half = THIN["open mesh"]
    for side in (1, -1):
        sim = shot(shape, orientation, speed, side=side)
        gap = gaps(sim, side, half, 30)
        assert gap.min() >= -SLACK and abs(gap[-1]) <= SLACK, (side, gap.min(), gap[-1])


def test_float32_particle_at_a_million_metres_a_second_stops_too():
    """float32 state: a 2 km step onto a 1 cm box ends R above it."""
    shape, orientation, half = THIN["box"]
    gap = gaps(shot(shape, orientation, 1.0e6, precision="float32"), 1, half, 5)
    assert gap.min() >= -SLACK and abs(gap[-1]) <= SLACK


def test_projection_alone_lets_it_through():
    """Before the sweep (the end-of-step projection alone, continuous=False), the 10 m/s particle of the
    report passes the 1 cm box at h = 1/480 s: a step of 2.1 cm takes its centre past the box's middle (from
    0.4972 m away the 23rd step ends 3 mm clear of it, the 24th 3 mm below the box's middle), and the projection
    pushes it out of the far side."""
    shape, orientation, half = THIN["box"]
    gap = gaps(shot(shape, orientation, 10.0, continuous=False, distance=0.4972), 1, half, 60)
    assert gap[-1] < -0.5


def test_fast_particle_bounces_back_with_its_restitution():
    """At 100 m/s with e = 0.5 (no gravity): it leaves at 50 m/s from R above the box, having travelled the rest of
    the step after the impact (time of impact: 0.49 - R m at 100 m/s)."""
    shape, orientation, half = THIN["box"]
    sim = shot(shape, orientation, 100.0, restitution=0.5)
    impact = (0.5 - half - R) / 100.0
    steps = math.ceil(impact / H)
    for _ in range(steps):
        sim.step(H, substeps=1)
    y, vy = sim.state.particle_x.numpy()[0, 1], sim.state.particle_v.numpy()[0, 1]
    assert vy == pytest.approx(50.0, rel=1e-9)
    assert y == pytest.approx(0.5 + half + R + 50.0 * (steps * H - impact), abs=SLACK)


@pytest.mark.parametrize("integrator, h, rtol", [("rk4", 1.0 / 60.0, 1e-3), ("verlet", 1.0 / 60.0, 1e-3),
                                                 ("symplectic_euler", H, 2e-3)])
@pytest.mark.parametrize("restitution", [0.8, 0.5])
def test_dropped_particle_rebounds_to_restitution_squared(integrator, h, rtol, restitution, device):
    """Dropped from 0.985 m above its contact height onto a static box: the apex after the first bounce is e^2 of
    the drop within rtol (rk4 and Verlet at 1/60 s land within 1.5e-4: the impact found on the step's chord, the
    velocity there interpolated; symplectic Euler at 1/480 s within 1e-3, its own energy drift g h^2 / 2 a step
    most of it). It never comes below its contact height."""
    scene = ws.Scene(precision="float64")
    scene.add_collider(ws.Box((0.5, 0.005, 0.5)), position=(0.0, 0.5, 0.0), restitution=restitution, friction=0.0)
    scene.add_particles([[0.0, 1.5, 0.0]], radius=R)
    sim = ws.Simulator(scene, integrator=integrator, device=device)
    contact = 0.505 + R
    apex, lowest = None, np.inf
    while apex is None:
        sim.step(h, substeps=1)
        y, vy = sim.state.particle_x.numpy()[0, 1], sim.state.particle_v.numpy()[0, 1]
        lowest = min(lowest, y)
        if vy > 0.0:
            apex = y + vy * vy / (2.0 * G)
    assert (apex - contact) / (1.5 - contact) == pytest.approx(restitution**2, rel=rtol)
    assert lowest >= contact - SLACK


@pytest.mark.parametrize("integrator, h", [("rk4", 1.0 / 60.0), ("implicit_euler", 1.0 / 60.0),
                                           ("symplectic_euler", H)])
def test_dropped_particle_without_restitution_stays_on_top(integrator, h):
    """e = 0: it lands at its contact height and stays there, at rest, for a second."""
    scene = ws.Scene(precision="float64")
    scene.add_collider(ws.Box((0.5, 0.005, 0.5)), position=(0.0, 0.5, 0.0), restitution=0.0, friction=0.5)
    scene.add_particles([[0.0, 1.5, 0.0]], radius=R)
    sim = ws.Simulator(scene, integrator=integrator, device="cpu")
    contact, heights = 0.505 + R, []
    for _ in range(round(1.5 / h)):
        sim.step(h, substeps=1)
        heights.append(sim.state.particle_x.numpy()[0, 1])
    heights = np.array(heights)
    assert heights.min() >= contact - SLACK
    assert np.all(np.abs(heights[-round(1.0 / (h * 2)):] - contact) <= SLACK)
    assert np.linalg.norm(sim.state.particle_v.numpy()[0]) < 1e-9


@pytest.mark.parametrize("integrator, h", [("rk4", 1.0 / 60.0), ("implicit_euler", 1.0 / 60.0),
                                           ("symplectic_euler", 1.0 / 60.0), ("symplectic_euler", H)])
def test_bouncing_particle_comes_to_rest(integrator, h):
    """e = 0.5: it bounces lower and lower and then rests at its contact height with no velocity (an approach no
    faster than twice the step's own change of velocity, g h, is resting contact: no jitter of e g h a step)."""
    scene = ws.Scene(precision="float64")
    scene.add_collider(ws.Box((0.5, 0.005, 0.5)), position=(0.0, 0.5, 0.0), restitution=0.5, friction=0.5)
    scene.add_particles([[0.0, 1.5, 0.0]], radius=R)
    sim = ws.Simulator(scene, integrator=integrator, device="cpu")
    heights = []
    for _ in range(round(4.0 / h)):
        sim.step(h, substeps=1)
        heights.append(sim.state.particle_x.numpy()[0, 1] - 0.505 - R)
    assert min(heights) >= -SLACK
    assert np.abs(heights[-round(1.0 / h):]).max() <= SLACK
    assert np.linalg.norm(sim.state.particle_v.numpy()[0]) == 0.0


@pytest.mark.parametrize("name", ["box", "open mesh", "closed mesh"])
def test_sliding_across_a_mesh_keeps_its_speed(name):
    """A particle sliding at 3 m/s (friction 0, e = 0.5, gravity) over a box, a divided open surface of 128
    triangles and a divided closed mesh: no hop at the triangles' inner edges, no stall, no sinking; after 0.5 s it
    is 1.5 m on, still on the surface."""
    shape = {"box": ws.Box((1.0, 0.005, 1.0)), "open mesh": ws.MeshShape(square(9, 1.0), solid=False),
             "closed mesh": ws.MeshShape(trimesh.creation.box(extents=(2.0, 0.01, 2.0)).subdivide().subdivide())}[name]
    top = 0.0 if name == "open mesh" else 0.005
    scene = ws.Scene(precision="float64")
    scene.add_collider(shape, restitution=0.5, friction=0.0)
    scene.add_particles([[-0.9, top + R, -0.33]], [[3.0, 0.0, 1.0]], radius=R)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    heights = []
    for _ in range(30):
        sim.step(1.0 / 60.0, substeps=1)
        heights.append(sim.state.particle_x.numpy()[0, 1] - top - R)
    assert np.abs(heights).max() <= SLACK
    np.testing.assert_allclose(sim.state.particle_x.numpy()[0, [0, 2]], [0.6, 0.17], atol=1e-4)


def test_particle_thrown_into_a_corner_of_two_thin_boxes_stays_in_front_of_both():
    """A 1 cm floor and a 1 cm wall (two box colliders meeting at a corner), a particle thrown at 30 m/s into the
    corner (1/60 s: half a metre a step) with e = 0.3, mu = 0.5, gravity: at every step it is R clear of both,
    on their near sides, and it ends at rest on the floor."""
    scene = ws.Scene(precision="float64")
    scene.add_collider(ws.Box((5.0, 0.005, 5.0)), position=(4.0, 0.0, 0.0), restitution=0.3, friction=0.5)
    scene.add_collider(ws.Box((0.005, 1.0, 5.0)), position=(-1.0, 1.0, 0.0), restitution=0.3, friction=0.5)
    scene.add_particles([[0.5, 0.5, 0.0]], [[-30.0, -20.0, 1.0]], radius=R)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    for _ in range(240):
        sim.step(1.0 / 60.0, substeps=1)
        x = sim.state.particle_x.numpy()[0]
        assert x[1] >= 0.005 + R - SLACK and x[0] >= -0.995 + R - SLACK, x
    assert np.linalg.norm(sim.state.particle_v.numpy()[0]) < 1e-9


def test_kill_on_contact_particles_die_at_a_thin_box():
    """An emitter's kill-on-contact particles shot down at 50 m/s onto a 1 cm box: they die there (the sweep
    flags the hit) and none lives below the box. (Kill-on-contact flags exist where the scene has a plane: the
    ground, 10 m below, here.)"""
    scene = ws.Scene(gravity=(0.0, -G, 0.0), precision="float64")
    scene.add_plane(normal=(0.0, 1.0, 0.0), offset=-10.0)
    scene.add_collider(ws.Box((1.0, 0.005, 1.0)), position=(0.0, 0.5, 0.0))
    scene.add_emitter(rate=200.0, lifetime=2.0, position=(0.0, 1.0, 0.0), direction=(0.0, -1.0, 0.0), spread=5.0,
                      speed=50.0, size=0.005, kill_on_contact=True)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    for _ in range(60):
        sim.step(1.0 / 120.0, substeps=1)
        arrays = sim.frame_arrays()
        alive = arrays["particle_alive"].astype(bool)
        assert np.all(arrays["particle_x"][alive, 1] > 0.5)
    stats = sim.emitter_stats()[0]
    assert stats["born"] > 50 and stats["live"] <= 2


def table_cloth(resolution, speed=0.0, thickness=0.02):
    """A cloth of 1 m x 1 m laid flat 1 m above a 2 m x 2 m table (a box collider ``thickness`` thick, top at
    0.76 m), falling, optionally at ``speed`` [m/s]; float32, implicit Euler as README's cloth."""
    scene = ws.Scene(precision="float32")
    scene.add_collider(ws.Box((1.0, thickness / 2, 1.0)), position=(0.0, 0.76 - thickness / 2, 0.0), friction=0.5)
    scene.add_cloth_grid(resolution=resolution, size=(1.0, 1.0), position=(0.0, 1.76, 0.0), orientation=FLAT,
                         mass=0.2, velocity=(0.0, -speed, 0.0))
    return scene


@pytest.mark.parametrize("substeps", [1, 8])
def test_cloth_dropped_on_a_table_stays_on_it(substeps):
    """The report: a 16 x 16 cloth dropped 1 m onto a 2 cm table under implicit Euler at 1/60 s passed through it
    with one step a frame (frame 26 at y 0.79, frame 27 at 0.72; the top at 0.76). Now, with 1 and with 8 steps
    a frame, at every frame of 1.5 s no vertex is below the table's top plus the cloth's radius (2 mm) by more
    than 1e-5 m (float32 state near 0.76 m), let alone below its underside, and it ends lying on the table."""
    scene = table_cloth((16, 16))
    sim = ws.Simulator(scene, integrator="implicit_euler", device="cpu")
    lowest = []
    for _ in range(90):
        sim.step(1.0 / 60.0, substeps=substeps)
        lowest.append(sim.state.particle_x.numpy()[:, 1].min())
    assert min(lowest) > 0.74                      # never below the underside
    assert min(lowest) >= 0.762 - 1e-5             # nor into the table
    y = sim.state.particle_x.numpy()[:, 1]
    assert np.all(y <= 0.762 + 0.01)               # lying on it


def test_cloth_at_fifty_metres_a_second_stops_on_a_thin_table():
    """An 8 x 8 cloth at 50 m/s (0.83 m a step of 1/60 s) onto a 1 cm table: all 64 vertices stay above it."""
    scene = table_cloth((8, 8), speed=50.0, thickness=0.01)
    sim = ws.Simulator(scene, integrator="implicit_euler", device="cpu")
    for _ in range(20):
        sim.step(1.0 / 60.0, substeps=1)
        y = sim.state.particle_x.numpy()[:, 1]
        assert y.min() >= 0.762 - 1e-5, y.min()

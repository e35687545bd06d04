"""Bodies in collision: time of impact, restitution, friction, resting contact, stacking, propagation,
tunnelling, conservation, terrain meshes, growable buffers, penalty response, particles against shapes."""
import math

import numpy as np
import pytest
import trimesh

import warp_sim as ws

G = 9.81
H = 1.0 / 480.0   # 8 substeps of a 60 fps frame


def speeds(sim):
    v, w = sim.body_velocities()
    return v.numpy(), w.numpy()


def ground_scene(restitution=0.5, friction=0.4, gravity=(0.0, -G, 0.0)):
    scene = ws.Scene(gravity=gravity, precision="float64")
    scene.add_ground(restitution=restitution, friction=friction)
    return scene


def test_bounce_apex_heights_follow_restitution_squared(device):
    """Dropped from 1 m (lowest point) with e = 0.8: apex n is 0.8^(2n) m, within 1e-3 relative, for 5 bounces."""
    e, r = 0.8, 0.1
    scene = ground_scene(restitution=e, friction=0.0)
    scene.add_rigid_body(ws.Sphere(r), position=(0.0, 1.0 + r, 0.0), restitution=e, friction=0.0)
    sim = ws.Simulator(scene, integrator="rk4", device=device)
    apexes, rising = [], False
    for _ in range(int(3.3 / H)):
        sim.step(H)
        y = sim.state.body_x.numpy()[0, 1] - r
        vy = speeds(sim)[0][0, 1]
        if rising and vy <= 0.0:   # apex within the last step: the ballistic closed form from this state
            apexes.append(y + vy * vy / (2.0 * G))
        rising = vy > 0.0
    assert len(apexes) >= 5
    expected = e ** (2 * np.arange(1, 6))
    error = np.abs(np.array(apexes[:5]) / expected - 1.0)
    print("apex relative errors", error)
    assert np.all(error < 1e-3)


def test_zero_restitution_leaves_no_bounce(device):
    r = 0.1
    scene = ground_scene(restitution=0.0, friction=0.5)
    scene.add_rigid_body(ws.Sphere(r), position=(0.0, 1.0 + r, 0.0), restitution=0.0, friction=0.5)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
    sim.step(H, steps=int(0.44 / H))   # just before the impact at 0.4515 s
    top = 0.0
    for _ in range(int(0.5 / H)):
        sim.step(H)
        top = max(top, speeds(sim)[0][0, 1])
    assert top < 1e-3
    assert sim.state.body_x.numpy()[0, 1] == pytest.approx(r, abs=2e-4)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "rk4"])
def test_sliding_box_stops_after_coulomb_distance(device, integrator):
    """v0 = 5 m/s, mu = 0.5: it stops after v0^2 / (2 mu g) = 2.548 m, within 2 %, without tipping."""
    mu, v0 = 0.5, 5.0
    scene = ground_scene(restitution=0.0, friction=mu)
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), position=(0.0, 0.1, 0.0), linear_velocity=(v0, 0.0, 0.0),
                         restitution=0.0, friction=mu)
    sim = ws.Simulator(scene, integrator=integrator, device=device)
    sim.step(H, steps=int(1.3 / H))
    x = sim.state.body_x.numpy()[0]
    expected = v0 ** 2 / (2.0 * mu * G)
    print("stopped after", x[0], "m, expected", expected)
    assert x[0] == pytest.approx(expected, rel=0.02)
    assert np.linalg.norm(speeds(sim)[0][0]) < 1e-6
    q = sim.state.body_q.numpy()[0]
    assert abs(q[3]) > math.cos(math.radians(0.5) / 2)   # turned by less than half a degree


def test_box_at_rest_stays_at_rest(device):
    scene = ground_scene()
    scene.add_rigid_body(ws.Box((0.2, 0.1, 0.15)), position=(0.0, 0.1, 0.0))
    sim = ws.Simulator(scene, integrator="rk4", device=device)
    x0 = sim.state.body_x.numpy()[0].copy()
    sim.step(1.0 / 240.0, steps=2400)
    v, w = speeds(sim)
    assert np.linalg.norm(sim.state.body_x.numpy()[0] - x0) < 1e-3
    assert np.linalg.norm(v[0]) < 1e-3 and np.linalg.norm(w[0]) < 1e-3


@pytest.mark.parametrize("integrator", ["symplectic_euler", "verlet"])
def test_stack_of_five_boxes_stands(device, integrator):
    scene = ground_scene()
    for k in range(5):
        scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), position=(0.0, 0.1 + 0.2 * k, 0.0))
    sim = ws.Simulator(scene, integrator=integrator, device=device)
    x0 = sim.state.body_x.numpy().copy()
    sim.step(1.0 / 240.0, steps=2400)
    drift = np.linalg.norm(sim.state.body_x.numpy() - x0, axis=1)
    print("drift per box [m]", drift)
    assert drift.max() < 5e-3


def test_box_turned_on_box_rests():
    """A box turned 45 degrees on an equal box touches it in an octagon, none of whose corners is a box corner."""
    scene = ground_scene()
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), position=(0.0, 0.1, 0.0))
    s = math.sin(math.pi / 8)
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), position=(0.0, 0.3, 0.0), orientation=(0.0, s, 0.0, math.cos(
        math.pi / 8)))
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    x0 = sim.state.body_x.numpy().copy()
    sim.step(1.0 / 240.0, steps=480)
    assert np.abs(sim.state.body_x.numpy() - x0).max() < 1e-3
    assert sim.body_contacts.count == 4 + 8


def _convex_box_mesh():
    return ws.MeshShape(trimesh.creation.box(extents=(0.2, 0.2, 0.2)))


@pytest.mark.parametrize("shape, rest_height", [
    (ws.Sphere(0.1), 0.1),
    (ws.Capsule(0.05, 0.1), 0.15),          # standing on one end
    (ws.Cylinder(0.1, 0.05), 0.05),
    (ws.PointMasses([[0, 0, 0], [0.1, 0, 0], [0, 0, 0.1]], [1.0, 1.0, 1.0], radius=0.02), 0.02),
    ("mesh", 0.1),
], ids=["sphere", "capsule", "cylinder", "points", "mesh"])
def test_every_shape_rests_on_the_ground(shape, rest_height):
    shape = _convex_box_mesh() if shape == "mesh" else shape
    scene = ground_scene()
    body = scene.add_rigid_body(shape, position=(0.0, rest_height + 0.05, 0.0))
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.step(1.0 / 240.0, steps=480)
    v, w = speeds(sim)
    low = scene.bodies[body].position[1] - 0.05   # the centre of mass at rest
    assert sim.state.body_x.numpy()[0, 1] == pytest.approx(low, abs=2e-4)
    assert np.linalg.norm(v[0]) < 1e-3 and np.linalg.norm(w[0]) < 1e-2


def test_newtons_cradle_passes_the_impulse_on(device):
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    for k in range(5):
        scene.add_rigid_body(ws.Sphere(0.1), position=(0.2 * k, 0.0, 0.0), restitution=1.0, friction=0.0,
                             linear_velocity=(1.0 if k == 0 else 0.0, 0.0, 0.0))
    sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
    sim.step(H, steps=60)
    vx = speeds(sim)[0][:, 0]
    print("cradle velocities", vx)
    assert vx[4] >= 0.95
    assert np.all(np.abs(vx[:4]) < 0.05)


@pytest.mark.parametrize("integrator", ["symplectic_euler", "rk4"])
def test_fast_sphere_does_not_tunnel_through_thin_wall(device, integrator):
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float32")
    scene.add_collider(ws.Box((0.005, 1.0, 1.0)), position=(1.0, 0.0, 0.0))
    scene.add_rigid_body(ws.Sphere(0.05), position=(0.0, 0.0, 0.0), linear_velocity=(100.0, 0.0, 0.0),
                         restitution=0.0)
    sim = ws.Simulator(scene, integrator=integrator, device=device)
    for _ in range(30):
        sim.step(1.0 / 60.0)
        assert sim.state.body_x.numpy()[0, 0] <= 1.0 - 0.005 - 0.05 + 1e-3


def _free_pair(restitution, friction):
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_rigid_body(ws.Box((0.2, 0.1, 0.15)), linear_velocity=(2.0, 0.3, 0.0), angular_velocity=(0.0, 1.0, 2.0),
                         restitution=restitution, friction=friction)
    scene.add_rigid_body(ws.Sphere(0.15), mass=3.0, position=(0.8, 0.05, 0.02), linear_velocity=(-1.0, 0.0, 0.0),
                         restitution=restitution, friction=friction)
    return scene


def _totals(sim, scene):
    x, P, L = (getattr(sim.state, k).numpy() for k in ("body_x", "body_P", "body_L"))
    v, w = speeds(sim)
    masses = np.array([b.mass.mass for b in scene.bodies])
    energy = 0.5 * np.sum(masses * np.sum(v * v, axis=1)) + 0.5 * np.sum(w * L)
    return P.sum(axis=0), (L + np.cross(x, P)).sum(axis=0), energy


@pytest.mark.parametrize("restitution, friction", [(1.0, 0.0), (0.5, 0.6)])
def test_two_body_collision_conserves_momentum(device, restitution, friction):
    scene = _free_pair(restitution, friction)
    sim = ws.Simulator(scene, integrator="rk4", device=device)
    P0, L0, E0 = _totals(sim, scene)
    sim.step(H, steps=480)
    P1, L1, E1 = _totals(sim, scene)
    assert sim.state.body_x.numpy()[1, 0] > 1.0   # they did collide: the sphere bounced back
    assert np.linalg.norm(P1 - P0) < 1e-6 * np.linalg.norm(P0)
    assert np.linalg.norm(L1 - L0) < 1e-6 * np.linalg.norm(L0)
    if restitution == 1.0:
        assert E1 == pytest.approx(E0, rel=1e-6)
    else:
        assert E1 < E0


def _terrain_file(tmp_path):
    """A bumpy height field y = 0.15 sin(1.3 x) cos(1.1 z), 6 m square, written as OBJ (an open surface)."""
    n = 25
    xs = np.linspace(-3.0, 3.0, n)
    X, Z = np.meshgrid(xs, xs)
    vertices = np.c_[X.ravel(), (0.15 * np.sin(1.3 * X) * np.cos(1.1 * Z)).ravel(), Z.ravel()]
    faces = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            faces += [[a, a + n, a + 1], [a + 1, a + n, a + n + 1]]
    path = tmp_path / "terrain.obj"
    trimesh.Trimesh(vertices, np.array(faces), process=False).export(path)
    return path


def test_body_comes_to_rest_on_trimesh_terrain(tmp_path):
    terrain = ws.MeshShape.from_file(_terrain_file(tmp_path), solid=False)
    scene = ws.Scene(precision="float32")
    scene.add_collider(terrain, restitution=0.2, friction=0.9)
    half = 0.1
    scene.add_rigid_body(ws.Box((half, half, half)), position=(0.3, 0.8, 0.2), angular_velocity=(1.0, 2.0, 0.0),
                         restitution=0.2, friction=0.9)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.step(1.0 / 240.0, steps=720)
    v, w = speeds(sim)
    assert np.linalg.norm(v[0]) < 1e-2 and np.linalg.norm(w[0]) < 1e-1
    # no corner below the surface beyond the slop, and lying on it (some corner within 2 mm)
    x, q = sim.state.body_x.numpy()[0], sim.state.body_q.numpy()[0]
    from warp_sim.util.rotations import quat_to_matrix

    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    world = corners @ quat_to_matrix(q).T + x
    height = world[:, 1] - 0.15 * np.sin(1.3 * world[:, 0]) * np.cos(1.1 * world[:, 2])
    # the OBJ is piecewise linear: its surface lies below the smooth one by at most curvature * cell^2 / 8
    assert height.min() > -0.01 and height.min() < 0.01


def test_contact_buffer_grows_instead_of_dropping():
    """A mesh block with a finely divided bottom lies on the ground: more contacts than the first buffer holds."""
    block = trimesh.creation.box(extents=(0.4, 0.1, 0.4))
    for _ in range(4):
        block = block.subdivide()
    scene = ground_scene()
    scene.add_rigid_body(ws.MeshShape(block), position=(0.0, 0.05, 0.0))
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.step(1.0 / 240.0)
    bottom = int(np.sum(np.isclose(np.asarray(block.vertices)[:, 1], -0.05)))
    stats = sim.body_contacts.stats()
    assert bottom > 256 and stats["grows"] >= 1
    assert stats["contacts"] == bottom
    sim.step(1.0 / 240.0, steps=240)
    assert sim.state.body_x.numpy()[0, 1] == pytest.approx(0.05, abs=2e-4)


def test_penalty_sphere_sinks_by_weight_over_stiffness(device):
    k, mass, r = 2.0e4, 1.0, 0.1
    scene = ground_scene(restitution=0.0)
    scene.add_rigid_body(ws.Sphere(r), mass=mass, position=(0.0, r + 0.01, 0.0), restitution=0.0)
    sim = ws.Simulator(scene, integrator="rk4", contact="penalty", penalty_stiffness=k, device=device)
    assert sim.body_contacts is None
    sim.step(1.0e-3, steps=2000)
    depth = r - sim.state.body_x.numpy()[0, 1]
    assert depth == pytest.approx(mass * G / k, rel=1e-3)


def test_particle_rests_on_static_shape():
    scene = ws.Scene(precision="float64")
    scene.add_collider(ws.Box((0.5, 0.1, 0.5)), position=(0.0, 0.5, 0.0), restitution=0.0, friction=0.5)
    scene.add_particles([[0.1, 1.0, 0.0]], radius=0.01, restitution=0.0)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.step(H, steps=480)
    assert sim.state.particle_x.numpy()[0, 1] == pytest.approx(0.6 + 0.01, abs=1e-6)   # float32 geometry
    assert np.linalg.norm(sim.state.particle_v.numpy()[0]) < 1e-9


def test_moving_body_pushes_particles():
    """A box sliding at 1 m/s through resting particles carries them in front of it (one-way contact)."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64")
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), linear_velocity=(1.0, 0.0, 0.0), restitution=0.0)
    scene.add_particles([[0.3, 0.0, 0.0], [0.3, 0.05, 0.02]], radius=0.01, restitution=0.0, friction=0.0)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.step(H, steps=240)
    x = sim.state.particle_x.numpy()
    box = sim.state.body_x.numpy()[0, 0]
    assert box == pytest.approx(0.5, abs=1e-9)   # one way: the particles do not slow the box
    assert np.all(x[:, 0] >= box + 0.1 + 0.01 - 1e-9)
    assert np.allclose(sim.state.particle_v.numpy()[:, 0], 1.0)


def test_cloth_dropped_on_sphere_ends_with_no_vertex_inside():
    """A 24 x 24 cloth falls on a sphere and drapes over it; at the end no vertex lies inside the sphere (it keeps
    its collision radius off the surface), the middle rests on the top and the edges hang below the centre."""
    scene = ws.Scene(precision="float32")
    scene.add_ground(friction=0.5)
    radius, centre = 0.3, np.array([0.0, 0.5, 0.0])
    scene.add_collider(ws.Sphere(radius), position=centre, friction=0.5, restitution=0.0)
    a = math.sin(math.pi / 4)
    ids = scene.add_cloth_grid(resolution=(24, 24), size=(1.2, 1.2), position=(0.05, 0.9, 0.03),
                               orientation=(-a, 0.0, 0.0, a), mass=0.3, stiffness=(500.0, 500.0, 5.0),
                               damping=(0.05, 0.05, 0.005), radius=0.005, friction=0.5)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.step(1.0 / 2400.0, steps=2400)
    x = sim.state.particle_x.numpy()
    distance = np.linalg.norm(x - centre, axis=1) - radius
    assert distance.min() >= 0.005 - 1e-5
    middle = x[ids[12, 12]]
    assert np.linalg.norm(middle - centre) == pytest.approx(radius + 0.005, abs=0.01)
    assert x[ids[0, 0], 1] < centre[1]


@pytest.mark.parametrize("kwargs, name", [
    (dict(restitution=-0.1), "restitution"),
    (dict(restitution=1.1), "restitution"),
    (dict(friction=-0.5), "friction"),
])
def test_bad_material_is_rejected(kwargs, name):
    scene = ws.Scene()
    with pytest.raises(ValueError, match=name):
        scene.add_rigid_body(ws.Sphere(0.1), **kwargs)
    with pytest.raises(ValueError, match=name):
        scene.add_collider(ws.Sphere(0.1), **kwargs)


def test_open_mesh_as_dynamic_body_is_rejected():
    open_box = trimesh.creation.box()
    open_box = trimesh.Trimesh(open_box.vertices, open_box.faces[:-2], process=False)
    with pytest.raises(ValueError, match="open"):
        ws.Scene().add_rigid_body(ws.MeshShape(open_box))
    surface = ws.MeshShape(open_box, solid=False)
    with pytest.raises(ValueError, match="static collider"):
        ws.Scene().add_rigid_body(surface)


@pytest.mark.parametrize("make", [lambda: ws.Sphere(float("nan")), lambda: ws.Box((0.1, float("nan"), 0.1)),
                                  lambda: ws.Capsule(0.1, float("inf"))], ids=["sphere", "box", "capsule"])
def test_shape_with_nan_is_rejected(make):
    with pytest.raises(ValueError):
        make()


def test_box_dropped_flat_bounces_straight():
    """Four corners hit at once: solved together, they share the impulse, so the box bounces up without turning
    (one corner at a time would spin it: here it turns by under half a degree) and rises to e^2 of its drop."""
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=0.5, friction=0.5)
    scene.add_rigid_body(ws.Box((0.12, 0.08, 0.1)), position=(0.0, 0.4, 0.0), restitution=0.5, friction=0.5)
    sim = ws.Simulator(scene, integrator="rk4", device="cpu")
    top, rising = 0.0, False
    for _ in range(int(0.6 / H)):
        sim.step(H)
        y, vy = sim.state.body_x.numpy()[0, 1], speeds(sim)[0][0, 1]
        if rising and vy <= 0.0 and top == 0.0:
            top = y + vy * vy / (2.0 * G)
        rising = vy > 0.0
    assert top - 0.08 == pytest.approx(0.25 * 0.32, rel=5e-3)
    assert abs(sim.state.body_q.numpy()[0, 3]) > math.cos(math.radians(0.5) / 2)
    assert np.linalg.norm(sim.state.body_x.numpy()[0, [0, 2]]) < 1e-3   # [m] sideways


def test_particle_squeezed_under_a_body_stays_on_the_ground():
    scene = ws.Scene(precision="float32")
    scene.add_ground()
    scene.add_particles([[0.05, 0.03, 0.0]], radius=0.03)
    scene.add_rigid_body(ws.Box((0.12, 0.08, 0.1)), position=(0.0, 0.4, 0.0))
    sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")
    sim.step(1.0 / 240.0, steps=240)
    assert sim.state.particle_x.numpy()[0, 1] >= 0.03 - 1e-6


def test_collisions_off_leaves_contacts_out():
    """collisions=False: a free-body scene (a throughput benchmark, ghosts) runs no contact pass at all."""
    scene = ground_scene()
    scene.add_rigid_body(ws.Sphere(0.1), position=(0.0, 0.5, 0.0))
    scene.add_rigid_body(ws.Sphere(0.1), position=(0.0, 0.5, 0.0))
    sim = ws.Simulator(scene, integrator="verlet", device="cpu", collisions=False)
    assert sim.body_contacts is None and sim.particle_shapes is None
    sim.step(H, steps=240)   # 0.5 s: free fall through the ground
    assert sim.state.body_x.numpy()[:, 1] == pytest.approx(0.5 - 0.5 * G * 0.25, abs=1e-9)
    with pytest.raises(ValueError, match="collisions"):
        ws.Simulator(scene, device="cpu", collisions="no")


def test_contact_margin_is_checked():
    scene = ground_scene()
    scene.add_rigid_body(ws.Sphere(0.1), position=(0.0, 1.0, 0.0))
    with pytest.raises(ValueError, match="contact_margin"):
        ws.Simulator(scene, device="cpu", contact_margin=-1.0)


def _tumbling_pile():
    """Boxes and spheres, a little turned, dropped onto the ground and each other: many colours of manifolds,
    body-body ones and ground ones."""
    scene = ground_scene(restitution=0.3, friction=0.5)
    rng = np.random.default_rng(3)
    for k in range(24):
        x, z = 0.25 * (k % 4) - 0.4, 0.25 * ((k // 4) % 3) - 0.25
        position = (x + rng.uniform(-0.03, 0.03), 0.12 + 0.22 * (k // 12), z + rng.uniform(-0.03, 0.03))
        axis, angle = rng.normal(size=3), rng.uniform(0.0, 0.4)
        turn = (*(np.sin(angle / 2) * axis / np.linalg.norm(axis)), np.cos(angle / 2))   # (x, y, z, w)
        shape = ws.Box((0.1, 0.08, 0.09)) if k % 2 == 0 else ws.Sphere(0.1)
        scene.add_rigid_body(shape, position=position, orientation=turn)
    return scene


@pytest.mark.parametrize("h", [1.0 / 60.0, 1.0 / 24.0])
def test_one_launch_per_run_of_colours_on_the_cpu_equals_one_per_colour_bit_for_bit(monkeypatch, h):
    """On the CPU, uncaptured, a sweep launches a whole run of colours as one (a CPU launch runs its threads in
    order): the same states as one launch per colour, bit for bit, with fewer launches, at frame-rate steps."""
    results = {}
    for merge in (True, False):
        monkeypatch.setattr(ws.passes.body_contacts.BodyContacts, "merge_cpu_colours", merge)
        sim = ws.Simulator(_tumbling_pile(), integrator="symplectic_euler", device="cpu")
        sim.step(h, steps=int(1.5 / h))
        launches = sim.model.launcher.launches
        sim.step(h, steps=6)
        colours = len(sim.body_contacts.manifolds.colours)
        results[merge] = (sim.state.body_x.numpy(), sim.state.body_q.numpy(), sim.model.launcher.launches - launches)
    (x1, q1, merged), (x2, q2, per_colour) = results[True], results[False]
    assert colours >= 3 and np.isfinite(x1).all() and x1[:, 1].min() > 0.05   # resting, not through the ground
    np.testing.assert_array_equal(x1, x2)
    np.testing.assert_array_equal(q1, q2)
    assert merged < per_colour

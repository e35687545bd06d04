"""Rigid bodies as third-party stages author them (issue 31): CollisionAPI on the body's own prim (Isaac-style), physics
materials bound without MaterialBindingAPI, other solvers' schemas in the raw apiSchemas, bodies without a collider
(MassAPI alone, or nothing), and a mass that cannot be had named by its prim. Each stage is authored here with pxr
and checked by the motion it gives (scene/usd_bodies.py, usd_reader.py)."""
import math
import warnings

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdPhysics, UsdShade

import warp_sim as ws
from warp_sim import preview
from warp_sim.scene import usd_bodies
from warp_sim.scene.usd_bodies import NO_MASS_NOTE, UNBOUND_NOTE
from warp_sim.util.rotations import quat_to_matrix


def new_stage():
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    UsdPhysics.Scene.Define(stage, "/World/physicsScene")
    return stage


def cube(stage, path, size, at, collider=True):
    geom = UsdGeom.Cube.Define(stage, path)
    geom.CreateSizeAttr(size)
    geom.AddTranslateOp().Set(Gf.Vec3d(*at))
    if collider:
        UsdPhysics.CollisionAPI.Apply(geom.GetPrim())
    return geom.GetPrim()


def sphere(stage, path, radius, at, body=True):
    geom = UsdGeom.Sphere.Define(stage, path)
    geom.CreateRadiusAttr(radius)
    geom.AddTranslateOp().Set(Gf.Vec3d(*at))
    UsdPhysics.CollisionAPI.Apply(geom.GetPrim())
    if body:
        UsdPhysics.RigidBodyAPI.Apply(geom.GetPrim())
    return geom.GetPrim()


def physics_material(stage, path, restitution=0.0, density=None):
    shade = UsdShade.Material.Define(stage, path)
    api = UsdPhysics.MaterialAPI.Apply(shade.GetPrim())
    api.CreateRestitutionAttr(restitution)
    api.CreateDynamicFrictionAttr(0.5)
    api.CreateStaticFrictionAttr(0.5)
    if density is not None:
        api.CreateDensityAttr(density)
    return shade


def bind_without_api(prim, shade):
    """``material:binding:physics`` as OpenUSD's sphere example and DCC tools author it: the relationship alone."""
    prim.CreateRelationship("material:binding:physics", False).SetTargets([shade.GetPath()])


def read(stage, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = ws.Scene.from_usd(stage, precision="float64", **options)
    return scene, [str(w.message) for w in caught if issubclass(w.category, UserWarning)]


def heights(scene, steps, h=1e-3):
    sim = ws.Simulator(scene, contact_step=None)
    out = []
    for _ in range(steps):
        sim.step(h)
        out.append(sim.state.body_x.numpy()[:, 1].copy())
    return np.array(out), sim


# ---- CollisionAPI on the body's own prim -----------------------------------------------------------------------------
def isaac_body(stage, style):
    """A 0.2 m crate at 0.5 m of density 500 kg/m^3 (its MassAPI), the body prim carrying CollisionAPI itself: an
    Xform with RigidBodyAPI and CollisionAPI over a Cube collider, or a Cube that is both body and collider."""
    if style == "xform":
        body = UsdGeom.Xform.Define(stage, "/World/crate")
        body.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.5, 0.0))
        cube(stage, "/World/crate/box", 0.2, (0.0, 0.0, 0.0))
        prim = body.GetPrim()
    else:
        prim = cube(stage, "/World/crate", 0.2, (0.0, 0.5, 0.0))
    UsdPhysics.RigidBodyAPI.Apply(prim)
    UsdPhysics.CollisionAPI.Apply(prim)
    UsdPhysics.MassAPI.Apply(prim).CreateDensityAttr(500.0)
    ground = UsdGeom.Plane.Define(stage, "/World/ground")
    ground.CreateAxisAttr("Y")
    UsdPhysics.CollisionAPI.Apply(ground.GetPrim())
    return prim


def test_usd_core_gives_nan_for_collision_api_on_the_body_xform_when_told_no_volume():
    """The issue's NaN, reproduced with pxr: usd-core calls the mass callback with the body's own Xform (it has
    CollisionAPI); answering "no information" (volume < 0), as warp_sim did, makes it add a unit mass at an
    uninitialised pose: a NaN centre of mass and an infinite or NaN inertia."""
    stage = new_stage()
    body = isaac_body(stage, "xform")
    asked = []

    def answer(prim):
        asked.append(str(prim.GetPath()))
        info = UsdPhysics.RigidBodyAPI.MassInformation()
        info.volume = -1.0
        if prim.IsA(UsdGeom.Cube):
            info.volume = 0.008
            info.inertia = Gf.Matrix3f(*(np.eye(3) * 0.008 * 0.04 / 6.0).ravel().tolist())
            info.centerOfMass = info.localPos = Gf.Vec3f(0.0)
            info.localRot = Gf.Quatf(1.0)
        return info
    mass, diagonal, com, _ = UsdPhysics.RigidBodyAPI(body).ComputeMassProperties(answer)
    assert asked == ["/World/crate", "/World/crate/box"]
    assert not (np.all(np.isfinite(list(com))) and np.all(np.isfinite(list(diagonal))))


@pytest.mark.parametrize("style", ["xform", "cube"])
def test_collision_api_on_the_body_prim_gives_density_times_volume_and_the_crate_rests(style):
    """Mass = 500 kg/m^3 x 0.008 m^3 = 4 kg to 1e-6 (usd-core computes in float32), a cube's inertia m s^2 / 6, and
    the crate falls as 1/2 g t^2 (2e-4 m) and comes to rest on the ground with its centre 0.1 m up (1 mm)."""
    stage = new_stage()
    isaac_body(stage, style)
    scene, _ = read(stage)
    body = scene.bodies[0]
    assert scene.usd_paths["/World/crate"] == ("body", 0) and body.shape.kind == "box"
    assert body.mass.mass == pytest.approx(4.0, rel=1e-6)
    np.testing.assert_allclose(body.mass.inertia, np.eye(3) * 4.0 * 0.04 / 6.0, rtol=1e-6)
    y, _ = heights(scene, 1500)
    t = np.arange(1, 201) * 1e-3
    np.testing.assert_allclose(y[:200, 0], 0.5 + 0.5 * scene.gravity[1] * t ** 2, atol=2e-4)
    assert abs(y[-1, 0] - 0.1) < 1e-3 and abs(y[-1, 0] - y[-100, 0]) < 1e-5


# ---- materials bound without MaterialBindingAPI ----------------------------------------------------------------------
def test_materials_bound_without_the_api_bounce_as_e_squared_and_are_warned_once():
    """Two spheres dropped 1 m, each onto a pad of its own material (0.8 and 0.1, bound by the relationship alone,
    so a contact's mean of its two sides is 0.8 and 0.1): the first rebounds rise to e^2 of the drop, their ratio
    within 10 % of 0.8^2 / 0.1^2 = 64; one warning names every binding prim and MaterialBindingAPI."""
    stage = new_stage()
    for name, e, x in (("bouncy", 0.8, -1.0), ("dull", 0.1, 1.0)):
        shade = physics_material(stage, f"/World/Looks/{name}", restitution=e)
        ball = sphere(stage, f"/World/{name}", 0.1, (x, 1.1, 0.0))
        pad = cube(stage, f"/World/{name}_pad", 1.0, (x, -0.5, 0.0))
        bind_without_api(ball, shade)
        bind_without_api(pad, shade)
    scene, messages = read(stage)
    assert [b.restitution for b in scene.bodies] == pytest.approx([0.8, 0.1])
    assert [c.restitution for c in scene.colliders] == pytest.approx([0.8, 0.1])
    unbound = [m for m in messages if UNBOUND_NOTE in m]
    assert len(unbound) == 1 and "MaterialBindingAPI" in unbound[0]
    assert all(p in unbound[0] for p in ("/World/bouncy", "/World/dull", "/World/bouncy_pad", "/World/dull_pad"))
    y, _ = heights(scene, 1600)
    rises = []
    for k in range(2):
        h = y[:, k] - 0.1
        v = np.diff(h)
        up = int(np.argmax(v > 0.0))                  # the first step up: the first impact is behind
        top = up + int(np.argmax(v[up:] <= 0.0))      # the apex of the first rebound
        rises.append((h[top] - h[up]) / (1.0 - h[up]))
    print(f"rebound / drop: {rises[0]:.4f} (0.64), {rises[1]:.5f} (0.01); ratio {rises[0] / rises[1]:.2f} (64)")
    assert rises[0] == pytest.approx(0.64, rel=0.05)
    assert rises[0] / rises[1] == pytest.approx(64.0, rel=0.10)


def test_a_material_density_bound_without_the_api_gives_the_mass_and_the_momentum():
    """A sphere under an Xform bound (without MaterialBindingAPI; the sphere inherits it) to a material of density
    200 kg/m^3 weighs 200 V; hit head-on at 1 m/s by a sphere of the default 1000 kg/m^3 with restitution 0 and no
    gravity, the two move on together at 1000 / (1000 + 200) m/s (0.5 m/s, were the density dropped), 1e-3."""
    stage = new_stage()
    UsdPhysics.Scene.Get(stage, "/World/physicsScene").CreateGravityMagnitudeAttr(0.0)
    light = physics_material(stage, "/World/Looks/light", density=200.0)
    props = UsdGeom.Xform.Define(stage, "/World/props").GetPrim()
    sphere(stage, "/World/props/target", 0.1, (0.0, 0.0, 0.0))
    bind_without_api(props, light)
    bullet = sphere(stage, "/World/bullet", 0.1, (-0.5, 0.0, 0.0))
    UsdPhysics.RigidBodyAPI(bullet).CreateVelocityAttr(Gf.Vec3f(1.0, 0.0, 0.0))
    scene, messages = read(stage)
    assert sum(UNBOUND_NOTE in m and "/World/props" in m for m in messages) == 1
    volume = 4.0 / 3.0 * math.pi * 0.1 ** 3
    masses = {b.name: b.mass.mass for b in scene.bodies}
    assert masses["target"] == pytest.approx(200.0 * volume, rel=1e-6)
    assert masses["bullet"] == pytest.approx(1000.0 * volume, rel=1e-6)
    _, sim = heights(scene, 800)
    velocity = sim.state.body_P.numpy()[:, 0] / scene.body_array("mass")
    np.testing.assert_allclose(velocity, [1000.0 / 1200.0] * 2, atol=1e-3)


# ---- other solvers' schemas ------------------------------------------------------------------------------------------
def test_other_solvers_schemas_in_the_raw_api_schemas_are_one_warning_naming_the_prims():
    """PhysxRigidBodyAPI on a body, a NewtonXxxAPI on the physics scene and a MujocoXxxAPI on a collider are not
    registered with usd-core (GetAppliedSchemas hides them); the apiSchemas metadata holds them, and one warning
    names each prim with its schemas. The body still falls as 1/2 g t^2, the schemas ignored."""
    stage = new_stage()
    ball = sphere(stage, "/World/ball", 0.1, (0.0, 2.0, 0.0))
    ball.AddAppliedSchema("PhysxRigidBodyAPI")
    stage.GetPrimAtPath("/World/physicsScene").AddAppliedSchema("NewtonSceneAPI")
    cube(stage, "/World/ground", 1.0, (0.0, -0.5, 0.0)).AddAppliedSchema("MujocoCollisionAPI")
    assert "PhysxRigidBodyAPI" not in ball.GetAppliedSchemas()
    scene, messages = read(stage)
    foreign = [m for m in messages if "other solvers' schemas" in m]
    assert len(foreign) == 1, messages
    for shown in ("/World/ball (PhysxRigidBodyAPI)", "/World/physicsScene (NewtonSceneAPI)",
                  "/World/ground (MujocoCollisionAPI)"):
        assert shown in foreign[0]
    y, _ = heights(scene, 300)
    np.testing.assert_allclose(y[-1, 0], 2.0 + 0.5 * scene.gravity[1] * 0.3 ** 2, atol=2e-4)


# ---- bodies without a collider ---------------------------------------------------------------------------------------
def test_a_body_without_a_collider_takes_its_mass_api_and_swings_on_a_joint():
    """A 1 m, 1.6 kg box rod hinged to the world at its top, and at its bottom a collider-less body of MassAPI
    mass 2 kg (an Xform: no shape) on a second hinge about the same axis (its spin decouples): small swings of 5
    degrees have the compound pendulum's period 2 pi sqrt((I_rod + m L^2) / (g (m_rod L / 2 + m L))) to 0.5 %
    (1.909 s, measured 1.908 s; the rod alone would swing at 1.64 s), and the bob stays at the rod's end (1 mm)."""
    stage = new_stage()
    tilt = math.radians(5.0)
    turn = Gf.Rotation(Gf.Vec3d(0, 0, 1), math.degrees(tilt))
    rod = UsdGeom.Cube.Define(stage, "/World/rod")
    rod.CreateSizeAttr(1.0)
    middle = Gf.Vec3d(0.0, 2.0, 0.0) + turn.TransformDir(Gf.Vec3d(0.0, -0.5, 0.0))
    rod.AddTranslateOp().Set(middle)
    rod.AddOrientOp().Set(Gf.Quatf(turn.GetQuat()))
    rod.AddScaleOp().Set(Gf.Vec3f(0.04, 1.0, 0.04))
    UsdPhysics.RigidBodyAPI.Apply(rod.GetPrim())
    UsdPhysics.CollisionAPI.Apply(rod.GetPrim())
    end = Gf.Vec3d(0.0, 2.0, 0.0) + turn.TransformDir(Gf.Vec3d(0.0, -1.0, 0.0))
    bob = UsdGeom.Xform.Define(stage, "/World/bob")
    bob.AddTranslateOp().Set(end)
    UsdPhysics.RigidBodyAPI.Apply(bob.GetPrim())
    mass_api = UsdPhysics.MassAPI.Apply(bob.GetPrim())
    mass_api.CreateMassAttr(2.0)
    mass_api.CreateDiagonalInertiaAttr(Gf.Vec3f(1e-3, 1e-3, 1e-3))
    for path, body0, body1, pos0, pos1 in (("/World/top", None, "/World/rod", (0, 2, 0), (0, 0.5, 0)),
                                           ("/World/end", "/World/rod", "/World/bob", (0, -0.5, 0), (0, 0, 0))):
        hinge = UsdPhysics.RevoluteJoint.Define(stage, path)
        hinge.CreateAxisAttr("Z")
        if body0:
            hinge.CreateBody0Rel().SetTargets([body0])
        hinge.CreateBody1Rel().SetTargets([body1])
        hinge.CreateLocalPos0Attr(Gf.Vec3f(*pos0))
        hinge.CreateLocalPos1Attr(Gf.Vec3f(*pos1))
    scene, messages = read(stage)
    index = scene.usd_paths["/World/bob"][1]
    bob_body = scene.bodies[index]
    assert scene.usd_paths["/World/bob"][0] == "body" and bob_body.shape.kind == "none"
    assert bob_body.mass.mass == 2.0 and np.allclose(bob_body.mass.inertia, np.eye(3) * 1e-3)
    assert len(scene.joints) == 2 and not any("/World/bob" in m for m in messages)
    rod_mass = scene.bodies[scene.usd_paths["/World/rod"][1]].mass.mass
    assert rod_mass == pytest.approx(1000.0 * 0.04 * 0.04, rel=1e-6)
    sim = ws.Simulator(scene)
    angles, gaps = [], []
    rod_index = scene.usd_paths["/World/rod"][1]
    for _ in range(int(5.0 / (1.0 / 240.0))):
        sim.step(1.0 / 240.0)
        x = sim.state.body_x.numpy()
        angles.append(math.atan2(x[index, 0], 2.0 - x[index, 1]))
        q = sim.state.body_q.numpy()[rod_index]
        tip = x[rod_index] + quat_to_matrix(q) @ np.array([0.0, -0.5, 0.0])
        gaps.append(float(np.linalg.norm(tip - x[index])))
    angles = np.array(angles)
    crossings = np.flatnonzero((angles[:-1] > 0.0) & (angles[1:] <= 0.0))
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1) / 240.0
    L, m, mr, w = 1.0, 2.0, rod_mass, 0.04
    rod_inertia = mr * (L ** 2 + w ** 2) / 12.0 + mr * (L / 2) ** 2
    expected = 2.0 * math.pi * math.sqrt((rod_inertia + m * L ** 2) / (-scene.gravity[1] * (mr * L / 2 + m * L)))
    expected *= 1.0 + tilt ** 2 / 16.0
    print(f"period {period:.4f} s against {expected:.4f} s; largest gap {max(gaps) * 1e6:.2f} um")
    assert period == pytest.approx(expected, rel=5e-3)
    assert max(gaps) < 1e-3


def test_a_body_without_a_collider_or_mass_gets_the_defaults_and_a_warning_and_falls_through_the_ground():
    """An Xform with RigidBodyAPI alone: usd-core answers mass -1, inertia (1, 1, 1) ("possibly invalid"); the body
    gets mass 1 kg and inertia (1, 1, 1) kg m^2 (PhysX's defaults), one warning names it, and having no shape it
    falls through the ground as 1/2 g t^2 (2e-4 m)."""
    stage = new_stage()
    ghost = UsdGeom.Xform.Define(stage, "/World/ghost")
    ghost.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.2, 0.0))
    UsdPhysics.RigidBodyAPI.Apply(ghost.GetPrim())
    cube(stage, "/World/ground", 1.0, (0.0, -0.5, 0.0))
    scene, messages = read(stage)
    body = scene.bodies[0]
    assert body.shape.kind == "none" and body.mass.mass == 1.0 and np.allclose(body.mass.inertia, np.eye(3))
    noted = [m for m in messages if NO_MASS_NOTE in m]
    assert len(noted) == 1 and "/World/ghost" in noted[0]
    y, _ = heights(scene, 500)
    np.testing.assert_allclose(y[-1, 0], 0.2 + 0.5 * scene.gravity[1] * 0.5 ** 2, atol=2e-4)


def test_a_body_without_a_shape_round_trips_through_to_usd_and_is_written_and_drawn(tmp_path):
    """Scene.to_usd writes a shapeless body as its Xform and MassAPI alone, and read back it has the same mass
    properties (float32) and place; a run writes it as an Xform without a Geom child, falling as 1/2 g t^2
    (2e-4 m); the preview renders the scene, drawing nothing for it."""
    scene = ws.Scene(precision="float64")
    properties = ws.MassProperties(3.0, np.array([0.0, 0.1, 0.0]), np.diag([0.1, 0.2, 0.25]))
    scene.add_rigid_body(None, mass_properties=properties, position=(0.0, 1.0, 0.0), name="anchor")
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), position=(1.0, 1.0, 0.0), name="box")
    scene.to_usd(tmp_path / "anchor.usda")
    assert not Usd.Stage.Open(str(tmp_path / "anchor.usda")).GetPrimAtPath("/World/Bodies/anchor").GetChildren()
    back, messages = read(tmp_path / "anchor.usda")
    body = back.bodies[0]
    assert body.shape.kind == "none" and not messages
    assert body.mass.mass == pytest.approx(3.0, rel=1e-7)
    np.testing.assert_allclose(body.mass.inertia, properties.inertia, atol=1e-7)
    np.testing.assert_allclose(body.position, scene.bodies[0].position, atol=1e-7)
    sim = ws.Simulator(back)
    out = sim.run(0.5, fps=10, usd=tmp_path / "run.usda", progress=False)
    stage = Usd.Stage.Open(str(out))
    anchor = stage.GetPrimAtPath("/World/Bodies/anchor")
    assert anchor and not anchor.GetChildren() and stage.GetPrimAtPath("/World/Bodies/box/Geom")
    end = stage.GetEndTimeCode()
    t = (end - stage.GetStartTimeCode()) / stage.GetTimeCodesPerSecond()
    y = UsdGeom.Xformable(anchor).ComputeLocalToWorldTransform(end).ExtractTranslation()[1]
    assert t > 0.3 and y == pytest.approx(1.1 + 0.5 * back.gravity[1] * t ** 2, abs=2e-4)
    image = preview.render(preview.snapshot(sim), width=64, height=48)[0]
    assert image.shape == (48, 64, 3) and len(np.unique(image.reshape(-1, 3), axis=0)) > 1


# ---- a mass that cannot be had ---------------------------------------------------------------------------------------
def test_a_mass_on_a_collision_prim_without_a_shape_is_an_error_naming_it():
    """physics:mass on the Xform body that carries CollisionAPI itself: usd-core's mass computation counts it as a
    shape's mass of no volume (a NaN inertia), so it is a ValueError naming the prim and the attribute and saying
    what to change (the same crate with a density instead loads: the first test)."""
    stage = new_stage()
    body = isaac_body(stage, "xform")
    UsdPhysics.MassAPI(body).CreateMassAttr(3.0)
    with pytest.raises(ValueError, match=r"^/World/crate: physics:mass=3 is invalid: the body's own prim has "
                                         r"PhysicsCollisionAPI but is no collision shape .*Xform.*no volume.* remove "
                                         r"PhysicsCollisionAPI from it, or author the mass on the body's collision "
                                         r"shapes$") as caught:
        ws.Scene.from_usd(stage)
    print(caught.value)


def test_non_finite_computed_mass_properties_are_errors_naming_the_prim():
    """usd_bodies.check, which every body's resolved mass passes: NaN centre of mass, infinite inertia, a
    zero mass and zero axes each name the prim and the MassAPI attribute to author."""
    axes = np.array([1.0, 0.0, 0.0, 0.0])
    cases = [((1.0, (1, 1, 1), (math.nan,) * 3, axes), "physics:centerOfMass"),
             ((1.0, (math.inf,) * 3, (0, 0, 0), axes), "physics:diagonalInertia"),
             ((math.nan, (1, 1, 1), (0, 0, 0), axes), "physics:mass"),
             ((1.0, (1, 1, 1), (0, 0, 0), np.zeros(4)), "physics:principalAxes")]
    for (mass, diagonal, com, q), name in cases:
        with pytest.raises(ValueError, match=rf"^/World/odd: {name}=.* is invalid: .*author"):
            usd_bodies.check("/World/odd", mass, np.array(diagonal, float), np.array(com, float), q,
                             "usd-core's mass computation")


def test_collision_groups_filtered_pairs_and_cones_are_named_and_the_rest_collides():
    """A CollisionGroup, a FilteredPairsAPI between the ball and the ground, and a rigid body whose only shape is
    a Cone: one warning each, naming the prims; the cone body is left out and the ball still lands on the ground
    (warp_sim has neither groups nor filtered pairs), its centre 0.1 m up to 1 mm."""
    stage = new_stage()
    ball = sphere(stage, "/World/ball", 0.1, (0.0, 0.5, 0.0))
    ground = cube(stage, "/World/ground", 1.0, (0.0, -0.5, 0.0))
    UsdPhysics.FilteredPairsAPI.Apply(ball).CreateFilteredPairsRel().SetTargets([ground.GetPath()])
    group = UsdPhysics.CollisionGroup.Define(stage, "/World/group")
    group.GetCollidersCollectionAPI().CreateIncludesRel().SetTargets([ball.GetPath()])
    cone = UsdGeom.Cone.Define(stage, "/World/cone")
    cone.AddTranslateOp().Set(Gf.Vec3d(2.0, 0.5, 0.0))
    UsdPhysics.RigidBodyAPI.Apply(cone.GetPrim())
    UsdPhysics.CollisionAPI.Apply(cone.GetPrim())
    scene, messages = read(stage)
    for what, path in (("collision groups", "/World/group"), ("filtered collision pairs", "/World/ball"),
                       ("cone shapes", "/World/cone"), ("only collision shapes are not simulated", "/World/cone")):
        assert sum(what in m and path in m for m in messages) == 1, (what, messages)
    assert "/World/cone" not in scene.usd_paths and scene.body_count == 1
    y, _ = heights(scene, 1000)
    assert abs(y[-1, 0] - 0.1) < 1e-3

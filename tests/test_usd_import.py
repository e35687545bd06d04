"""Scenes authored as UsdPhysics stages (made here with pxr, as a DCC tool saves them): units and axes, bounces,
the schema's mass rules against usd-core's own ComputeMassProperties, initial velocities, compound bodies, the
round trip through Scene.to_usd, the overlay written back over the artist's prims, and bad stages."""
import math
import pathlib
import re
import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade

import warp_sim as ws
from warp_sim.cli import main
from warp_sim.stages import validate_stage
from warp_sim.util.rotations import quat_to_matrix


def new_stage(path, up="Y", meters=1.0, physics=True, gravity=None, fps=24.0, start=0.0):
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, meters)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(fps)
    stage.SetStartTimeCode(start)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    if physics:
        scene = UsdPhysics.Scene.Define(stage, "/World/physicsScene")
        if gravity is not None:
            scene.CreateGravityDirectionAttr(Gf.Vec3f(*gravity[0]))
            scene.CreateGravityMagnitudeAttr(gravity[1])
    return stage


def up_vector(up, length):
    return Gf.Vec3d(0, 0, length) if up == "Z" else Gf.Vec3d(0, length, 0)


def material(stage, path, restitution=0.0, dynamic=0.5, static=None, density=None):
    shade = UsdShade.Material.Define(stage, path)
    api = UsdPhysics.MaterialAPI.Apply(shade.GetPrim())
    api.CreateRestitutionAttr(restitution)
    api.CreateDynamicFrictionAttr(dynamic)
    api.CreateStaticFrictionAttr(dynamic if static is None else static)
    if density is not None:
        api.CreateDensityAttr(density)
    return shade


def bind(prim, shade):
    UsdShade.MaterialBindingAPI.Apply(prim).Bind(shade, UsdShade.Tokens.weakerThanDescendants, "physics")


def cube(stage, path, size, at, body=True, collide=True):
    geom = UsdGeom.Cube.Define(stage, path)
    geom.CreateSizeAttr(size)
    geom.AddTranslateOp().Set(at)
    if body:
        UsdPhysics.RigidBodyAPI.Apply(geom.GetPrim())
    if collide:
        UsdPhysics.CollisionAPI.Apply(geom.GetPrim())
    return geom.GetPrim()


def drop_stage(path, up, meters):
    """A 10 cm cube dropped from 100 cm onto a static ground cube whose top is at 0, in the given units."""
    unit = 0.01 / meters          # one centimetre in stage units
    stage = new_stage(path, up, meters)
    cube(stage, "/World/box", 10 * unit, up_vector(up, 100 * unit))
    ground = cube(stage, "/World/ground", 200 * unit, up_vector(up, -100 * unit), body=False)
    look = material(stage, "/World/Looks/rubber", restitution=0.0, dynamic=0.6)
    bind(ground, look)
    bind(stage.GetPrimAtPath("/World/box"), look)
    stage.Save()
    return path


def overlay_heights(out, up, frames):
    stage = Usd.Stage.Open(str(out))
    box = UsdGeom.Xformable(stage.GetPrimAtPath("/World/box"))
    start, step = stage.GetStartTimeCode(), 1.0
    axis = 2 if up == "Z" else 1
    return np.array([box.ComputeLocalToWorldTransform(start + k * step).ExtractTranslation()[axis]
                     for k in range(frames)])


@pytest.mark.parametrize("up, meters", [("Z", 0.01), ("Y", 1.0)])
def test_a_cube_comes_to_rest_on_the_ground_in_stage_units(tmp_path, up, meters):
    """Dropped from 100 cm it rests with its centre 5 cm above the ground's top within 0.1 cm, read from the
    overlay in the stage's own units, and the Y-up metre stage moves the same (converted)."""
    source = drop_stage(tmp_path / "drop.usda", up, meters)
    scene = ws.Scene.from_usd(source)
    assert scene.usd_paths == {"/World/box": ("body", 0), "/World/ground": ("collider", 0)}
    np.testing.assert_allclose(scene.gravity, [0.0, -9.81, 0.0], rtol=1e-6)
    out = ws.Simulator(scene).run(3.0, fps=24, substeps=8, usd=tmp_path / "anim.usda", over=source, progress=False)
    heights = overlay_heights(out, up, 72) * meters / 0.01          # centimetres
    assert heights[0] == pytest.approx(100.0)
    assert abs(heights[-1] - 5.0) <= 0.1
    falling = heights[:10]
    t = np.arange(10) / 24.0
    np.testing.assert_allclose(falling, 100.0 - 0.5 * 981.0 * t ** 2, atol=0.05)   # free fall before the hit


def test_a_bound_material_sets_the_bounce(tmp_path):
    """A sphere with restitution 0.5 (on it and on the ground plane) bounces to e^2 of its drop height, 1 %."""
    stage = new_stage(tmp_path / "bounce.usda")
    ball = UsdGeom.Sphere.Define(stage, "/World/ball")
    ball.CreateRadiusAttr(0.1)
    ball.AddTranslateOp().Set(Gf.Vec3d(0, 1.1, 0))
    UsdPhysics.RigidBodyAPI.Apply(ball.GetPrim())
    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    ground = UsdGeom.Plane.Define(stage, "/World/ground")
    ground.CreateAxisAttr("Y")
    UsdPhysics.CollisionAPI.Apply(ground.GetPrim())
    bouncy = material(stage, "/World/Looks/bouncy", restitution=0.5)
    bind(ball.GetPrim(), bouncy)
    bind(ground.GetPrim(), bouncy)
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "bounce.usda", precision="float64")
    assert scene.usd_paths["/World/ground"] == ("plane", 0) and scene.planes[0].restitution == 0.5
    sim = ws.Simulator(scene, contact_step=None)
    heights = []
    for _ in range(1600):
        sim.step(1e-3)
        heights.append(sim.state.body_x.numpy()[0, 1] - 0.1)
    heights = np.array(heights)
    first = int(np.argmin(heights[:600]))                 # the first impact
    apex = heights[first:first + 700].max()
    assert apex == pytest.approx(0.25 * 1.0, rel=0.01)


def mass_case(tmp_path, name, build):
    stage = new_stage(tmp_path / f"{name}.usda")
    body = UsdGeom.Xform.Define(stage, "/World/body").GetPrim()
    UsdPhysics.RigidBodyAPI.Apply(body)
    build(stage, body)
    stage.Save()
    return stage, body


def shape(stage, name, size=1.0, at=(0.0, 0.0, 0.0), enabled=True):
    prim = cube(stage, f"/World/body/{name}", size, Gf.Vec3d(*at), body=False)
    if not enabled:
        UsdPhysics.CollisionAPI(prim).CreateCollisionEnabledAttr(False)
    return prim


MASS_CASES = {   # Newton issue 3591's table and the schema's precedence: name -> (build, expected mass [kg])
    "collider mass": (lambda st, b: UsdPhysics.MassAPI.Apply(shape(st, "c")).CreateMassAttr(2.0), 2.0),
    "collider density": (lambda st, b: UsdPhysics.MassAPI.Apply(shape(st, "c")).CreateDensityAttr(500.0), 500.0),
    "default density": (lambda st, b: shape(st, "c", size=0.5), 1000.0 * 0.125),
    "mass zero means computed": (lambda st, b: (shape(st, "c"), UsdPhysics.MassAPI.Apply(b).CreateMassAttr(0.0)),
                                 1000.0),
    "body mass over the shape's": (lambda st, b: (UsdPhysics.MassAPI.Apply(shape(st, "c")).CreateMassAttr(2.0),
                                                  UsdPhysics.MassAPI.Apply(b).CreateMassAttr(7.0)), 7.0),
    "body density over the default": (lambda st, b: (shape(st, "c"), UsdPhysics.MassAPI.Apply(b).CreateDensityAttr(
        300.0)), 300.0),
    "material density": (lambda st, b: bind(shape(st, "c"), material(st, "/World/Looks/light", density=200.0)),
                         200.0),
    "disabled collider beside an enabled one": (lambda st, b: (shape(st, "on", at=(-1, 0, 0)),
                                                               shape(st, "off", at=(1, 0, 0), enabled=False)), None),
}


@pytest.mark.parametrize("name", list(MASS_CASES))
def test_the_schema_mass_rules_match_usd_core(tmp_path, name):
    """Each case's mass is the schema's (and usd-core's ComputeMassProperties with warp_sim's shapes, which
    warp_sim follows where the two could differ: a collider with collisionEnabled = false has no mass there)."""
    build, expected = MASS_CASES[name]
    stage, body = mass_case(tmp_path, name.replace(" ", "_").replace("'", ""), build)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = ws.Scene.from_usd(stage)

    def info(prim):
        data = UsdPhysics.RigidBodyAPI.MassInformation()
        size = UsdGeom.Cube(prim).GetSizeAttr().Get()
        data.volume = size ** 3
        data.inertia = Gf.Matrix3f(*(np.eye(3) * size ** 5 / 6.0).ravel().tolist())
        data.centerOfMass = Gf.Vec3f(0.0)
        data.localPos = Gf.Vec3f(UsdGeom.Xformable(prim).GetLocalTransformation().ExtractTranslation())
        data.localRot = Gf.Quatf(1.0)
        return data
    reference = UsdPhysics.RigidBodyAPI(body).ComputeMassProperties(info)
    mass = scene.bodies[0].mass.mass
    assert mass == pytest.approx(reference[0], rel=1e-6)
    if expected is not None:
        assert mass == pytest.approx(expected, rel=1e-6)
    else:   # usd-core leaves the disabled collider out of the mass, and warp_sim out of the collisions
        assert mass == pytest.approx(1000.0, rel=1e-6)
        assert scene.bodies[0].shape.kind == "box"


def test_diagonal_inertia_and_principal_axes_give_the_precession_rate(tmp_path):
    """An axisymmetric body (I = 1, 1, 2 kg m^2, its symmetry axis turned onto world Y by principalAxes) spun about
    a tilted axis, without gravity: its angular velocity in the body frame turns about the symmetry axis at
    (I3 - I1) / I1 omega3 (Euler's equations), within 1 %."""
    stage = new_stage(tmp_path / "spin.usda", gravity=((0.0, -1.0, 0.0), 0.0))
    prim = cube(stage, "/World/top", 0.2, Gf.Vec3d(0, 0, 0))
    mass = UsdPhysics.MassAPI.Apply(prim)
    mass.CreateMassAttr(1.0)
    mass.CreateDiagonalInertiaAttr(Gf.Vec3f(1.0, 1.0, 2.0))
    mass.CreatePrincipalAxesAttr(Gf.Quatf(math.cos(math.pi / 4), -math.sin(math.pi / 4), 0.0, 0.0))  # z -> y
    rigid = UsdPhysics.RigidBodyAPI(prim)
    rigid.CreateAngularVelocityAttr(Gf.Vec3f(math.degrees(0.3), math.degrees(2.0), 0.0))
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "spin.usda", precision="float64")
    inertia = scene.bodies[0].mass.inertia
    np.testing.assert_allclose(inertia, np.diag([1.0, 2.0, 1.0]), atol=1e-6)
    sim = ws.Simulator(scene, integrator="rk4")
    angles, h = [], 1e-3
    for _ in range(1000):
        sim.step(h)
        R = quat_to_matrix(sim.state.body_q.numpy()[0])
        omega = np.linalg.solve(R @ inertia @ R.T, sim.state.body_L.numpy()[0])
        body = R.T @ omega
        angles.append(math.atan2(body[2], body[0]))
    rate = np.polyfit(h * np.arange(1, 1001), np.unwrap(angles), 1)[0]
    assert abs(rate) == pytest.approx((2.0 - 1.0) / 1.0 * 2.0, rel=0.01)


def test_an_angular_velocity_in_degrees_turns_once_a_second(tmp_path):
    stage = new_stage(tmp_path / "turn.usda", gravity=((0.0, -1.0, 0.0), 0.0))
    prim = cube(stage, "/World/box", 0.2, Gf.Vec3d(0, 1, 0))
    UsdPhysics.RigidBodyAPI(prim).CreateAngularVelocityAttr(Gf.Vec3f(0.0, 360.0, 0.0))
    stage.Save()
    sim = ws.Simulator(ws.Scene.from_usd(tmp_path / "turn.usda", precision="float64"))
    sim.step(1e-3, steps=250)
    R = quat_to_matrix(sim.state.body_q.numpy()[0])
    np.testing.assert_allclose(R @ [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], atol=1e-6)   # a quarter turn about +Y
    sim.step(1e-3, steps=750)
    np.testing.assert_allclose(quat_to_matrix(sim.state.body_q.numpy()[0]), np.eye(3), atol=1e-6)


def test_a_compound_body_sums_its_parts(tmp_path):
    """A dumbbell: two spheres (r = 0.1 m) at x = +-0.3 m on a capsule (r = 0.03 m, height 0.6 m along X): one
    body whose mass, centre of mass and inertia are the sums of its parts' (parallel axes)."""
    stage = new_stage(tmp_path / "dumbbell.usda")
    body = UsdGeom.Xform.Define(stage, "/World/dumbbell")
    body.AddTranslateOp().Set(Gf.Vec3d(0, 1, 0))
    UsdPhysics.RigidBodyAPI.Apply(body.GetPrim())
    for name, x in (("left", -0.3), ("right", 0.3)):
        ball = UsdGeom.Sphere.Define(stage, f"/World/dumbbell/{name}")
        ball.CreateRadiusAttr(0.1)
        ball.AddTranslateOp().Set(Gf.Vec3d(x, 0, 0))
        UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    bar = UsdGeom.Capsule.Define(stage, "/World/dumbbell/bar")
    bar.CreateAxisAttr("X")
    bar.CreateRadiusAttr(0.03)
    bar.CreateHeightAttr(0.6)
    UsdPhysics.CollisionAPI.Apply(bar.GetPrim())
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "dumbbell.usda", precision="float64")
    (body,) = scene.bodies
    sphere = ws.Sphere(0.1).mass_properties(density=1000.0)
    capsule = ws.Capsule(0.03, 0.3).mass_properties(density=1000.0)
    mass = 2 * sphere.mass + capsule.mass
    ixx = 2 * sphere.inertia[0, 0] + capsule.inertia[1, 1]           # the capsule's axis is X here
    iyy = 2 * (sphere.inertia[1, 1] + sphere.mass * 0.09) + capsule.inertia[0, 0]
    assert body.mass.mass == pytest.approx(mass, rel=1e-5)
    R = quat_to_matrix(body.orientation)
    world = R @ body.mass.inertia @ R.T
    np.testing.assert_allclose(np.diag(world), [ixx, iyy, iyy], rtol=1e-5)
    np.testing.assert_allclose(body.position, [0.0, 1.0, 0.0], atol=1e-9)   # the centre of mass


def python_scene():
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=0.4, friction=0.5)
    scene.add_rigid_body(ws.Box((0.1, 0.05, 0.2)), density=700.0, position=(0.0, 0.6, 0.0),
                         orientation=(0.0, 0.38268343, 0.0, 0.92387953), angular_velocity=(1.0, 2.0, 0.5),
                         restitution=0.3, friction=0.6, name="crate")
    scene.add_rigid_body(ws.Sphere(0.08), mass=0.5, position=(0.5, 0.4, 0.1), linear_velocity=(-1.0, 0.0, 0.0),
                         name="ball")
    scene.add_rigid_body(ws.Capsule(0.05, 0.1), density=900.0, position=(-0.4, 0.5, 0.0), name="pill")
    scene.add_collider(ws.Box((0.3, 0.05, 0.3)), position=(0.0, 0.1, 0.0), name="table")
    scene.add_particles(np.array([[0.2, 1.0, 0.2], [-0.2, 1.2, -0.1]]), mass=0.01, radius=0.02, name="drops")
    return scene


def test_the_round_trip_through_usd_simulates_the_same(tmp_path):
    """A Python scene, written by to_usd and read back by from_usd, gives the same trajectories within 1e-6 m over
    0.4 s of falls, spins and landings. The schema keeps points, masses, inertias and gravity in float32, so the
    stage holds the scene to 1e-7 relative; contacts then amplify that (about 2e-6 m a little later here)."""
    original = python_scene()
    path = original.to_usd(tmp_path / "scene.usda")
    read = ws.Scene.from_usd(path, precision="float64")
    assert read.body_count == 3 and read.particle_count == 2 and len(read.colliders) == 1 and len(read.planes) == 1
    for a, b in zip(original.bodies, read.bodies):
        assert b.mass.mass == pytest.approx(a.mass.mass, rel=1e-6)
    runs = []
    for scene in (original, read):
        sim = ws.Simulator(scene)
        track = []
        for _ in range(48):
            sim.step(1.0 / 120.0)
            track.append(np.concatenate([sim.state.body_x.numpy().ravel(), sim.state.particle_x.numpy().ravel()]))
        runs.append(np.array(track))
    assert np.abs(runs[0] - runs[1]).max() <= 1e-6


def test_the_overlay_composes_over_the_input_and_keeps_the_artists_prims(tmp_path):
    """Opened on its own, the overlay plays the input's prims at their own paths with their material bindings and
    children; frame k lands at start + k timeCodesPerSecond / fps; it sublayers the input and matches its
    metadata; nothing non-finite is in it."""
    source = drop_stage(tmp_path / "drop.usda", "Z", 0.01)
    stage = Usd.Stage.Open(str(source))
    UsdGeom.Sphere.Define(stage, "/World/box/antenna").CreateRadiusAttr(1.0)    # a child the artist added
    stage.SetStartTimeCode(101.0)
    stage.Save()
    scene = ws.Scene.from_usd(source)
    out = ws.Simulator(scene).run(1.0, fps=12, substeps=8, usd=tmp_path / "anim.usdc", over=source, progress=False)
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert list(layer.subLayerPaths) == ["drop.usda"]
    assert layer.rootPrims[0].specifier == Sdf.SpecifierOver
    times = layer.ListTimeSamplesForPath("/World/box.xformOp:translate")
    assert times == [101.0 + 2.0 * k for k in range(12)]      # 24 time codes per second, 12 frames per second
    composed = Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageUpAxis(composed) == "Z" and UsdGeom.GetStageMetersPerUnit(composed) == 0.01
    box = composed.GetPrimAtPath("/World/box")
    assert box.GetTypeName() == "Cube" and composed.GetPrimAtPath("/World/box/antenna")
    bound, _ = UsdShade.MaterialBindingAPI(box).ComputeBoundMaterial("physics")
    assert str(bound.GetPath()) == "/World/Looks/rubber"
    assert list(UsdGeom.Xformable(box).GetXformOpOrderAttr().Get()) == ["xformOp:translate", "xformOp:orient",
                                                                        "xformOp:scale"]
    heights = [UsdGeom.Xformable(box).ComputeLocalToWorldTransform(t).ExtractTranslation()[2] for t in times]
    assert all(np.isfinite(heights)) and heights[0] == pytest.approx(100.0) and heights[-1] < heights[0]
    flat = ws.Simulator(ws.Scene.from_usd(source)).run(1.0, fps=12, substeps=8, usd=tmp_path / "flat.usdc",
                                                       over=source, flatten=True, progress=False)
    flat_layer = Sdf.Layer.FindOrOpen(str(flat))
    assert list(flat_layer.subLayerPaths) == [] and flat_layer.GetPrimAtPath("/World/box/antenna")
    flat_box = UsdGeom.Xformable((flat_stage := Usd.Stage.Open(str(flat))).GetPrimAtPath("/World/box"))
    assert flat_stage.GetStartTimeCode() == 101.0
    np.testing.assert_allclose([flat_box.ComputeLocalToWorldTransform(t).ExtractTranslation()[2] for t in times],
                               heights, atol=1e-9)


def test_a_stage_without_physics_is_a_value_error_naming_the_file(tmp_path):
    stage = new_stage(tmp_path / "plain.usda", physics=False)
    UsdGeom.Cube.Define(stage, "/World/box")
    stage.Save()
    with pytest.warns(UserWarning, match="no UsdPhysics.Scene"):
        with pytest.raises(ValueError, match=r"plain\.usda.*nothing to simulate"):
            ws.Scene.from_usd(tmp_path / "plain.usda")


def test_joints_and_open_dynamic_meshes_are_named_and_the_rest_simulated(tmp_path, capsys):
    """A revolute joint and a dynamic body made of an open mesh are each warned about once, naming the prim; the
    box beside them is simulated; the command line writes its overlay."""
    source = drop_stage(tmp_path / "mixed.usda", "Y", 1.0)
    stage = Usd.Stage.Open(str(source))
    UsdPhysics.RevoluteJoint.Define(stage, "/World/hinge")
    sheet = UsdGeom.Mesh.Define(stage, "/World/sheet")
    sheet.CreatePointsAttr([(0, 1, 0), (1, 1, 0), (0, 1, 1)])
    sheet.CreateFaceVertexCountsAttr([3])
    sheet.CreateFaceVertexIndicesAttr([0, 1, 2])
    UsdPhysics.RigidBodyAPI.Apply(sheet.GetPrim())
    UsdPhysics.CollisionAPI.Apply(sheet.GetPrim())
    stage.Save()
    with pytest.warns(UserWarning) as caught:
        scene = ws.Scene.from_usd(source)
    messages = [str(w.message) for w in caught]
    assert any("joints" in m and "/World/hinge" in m for m in messages)
    assert any("open meshes" in m and "/World/sheet" in m for m in messages)
    assert scene.body_count == 1 and "/World/sheet" not in scene.usd_paths
    out = tmp_path / "mixed_anim.usdc"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["run", str(source), "--out", str(out), "--seconds", "0.5", "--no-progress"]) == 0
    assert Sdf.Layer.FindOrOpen(str(out)).ListTimeSamplesForPath("/World/box.xformOp:translate")[-1] == 11.0
    assert main(["run", str(tmp_path / "missing.usda"), "--out", str(tmp_path / "x.usdc")]) == 2
    assert "missing.usda" in capsys.readouterr().err and not (tmp_path / "x.usdc").exists()


def test_an_animated_kinematic_paddle_sweeps_a_resting_box(tmp_path):
    """A kinematic paddle animated from x = -1 to 1 m over 2 s (two time samples at 24 time codes per second)
    pushes a box resting on the ground ahead of it: the box moves with the paddle, touching it, then slides
    v^2 / (2 mu g) when the paddle stops; the paddle follows its animation exactly (it is never pushed back) and
    the overlay leaves its animation alone."""
    stage = new_stage(tmp_path / "sweep.usda")
    ground = UsdGeom.Plane.Define(stage, "/World/ground")
    ground.CreateAxisAttr("Y")
    UsdPhysics.CollisionAPI.Apply(ground.GetPrim())
    rough = material(stage, "/World/Looks/rough", restitution=0.0, dynamic=0.5)
    bind(ground.GetPrim(), rough)
    box = cube(stage, "/World/box", 0.2, Gf.Vec3d(0, 0.1, 0))
    bind(box, rough)
    paddle = UsdGeom.Cube.Define(stage, "/World/paddle")
    paddle.CreateSizeAttr(1.0)
    move = paddle.AddTranslateOp()
    move.Set(Gf.Vec3d(-1.0, 0.2, 0.0), 0.0)
    move.Set(Gf.Vec3d(1.0, 0.2, 0.0), 48.0)
    paddle.AddScaleOp().Set(Gf.Vec3f(0.1, 0.4, 0.6))
    UsdPhysics.RigidBodyAPI.Apply(paddle.GetPrim()).CreateKinematicEnabledAttr(True)
    UsdPhysics.CollisionAPI.Apply(paddle.GetPrim())
    bind(paddle.GetPrim(), rough)
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "sweep.usda", precision="float64")
    assert scene.bodies[1].track is not None and list(scene.bodies[1].track.times) == [0.0, 2.0]
    sim = ws.Simulator(scene)
    for k in range(1, 181):
        sim.step(1.0 / 60.0)
        x = sim.state.body_x.numpy()
        paddle_x = -1.0 + min(k / 60.0, 2.0)
        assert x[1, 0] == pytest.approx(paddle_x, abs=1e-9)           # exactly its animation, never pushed back
        if 75 <= k <= 120:                                           # pushed along: touching the paddle's face
            assert x[0, 0] == pytest.approx(paddle_x + 0.05 + 0.1, abs=2e-3)
    slide = 1.0 ** 2 / (2 * 0.5 * 9.81)
    assert x[0, 0] == pytest.approx(1.15 + slide, rel=0.05)
    out = ws.Simulator(ws.Scene.from_usd(tmp_path / "sweep.usda")).run(
        0.5, fps=24, usd=tmp_path / "anim.usda", over=tmp_path / "sweep.usda", progress=False)
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert layer.GetPrimAtPath("/World/box") and not layer.GetPrimAtPath("/World/paddle")


def test_warpsim_cloth_particles_and_an_emitter_are_read_and_animated(tmp_path):
    """warp_sim's own attributes: a cloth Mesh pinned at two corners, a Points set and an emitter Xform, in a
    centimetre Z-up stage; each simulates (the pins hold, the points fall freely, the emitter's rate is kept) and
    the overlay samples points and extent on the cloth and the points, and a Points child of the emitter."""
    stage = new_stage(tmp_path / "soft.usda", up="Z", meters=0.01)
    mesh = UsdGeom.Mesh.Define(stage, "/World/flag")
    n = 5
    grid = [(20.0 * i, 0.0, 100.0 + 20.0 * j) for j in range(n) for i in range(n)]
    mesh.CreatePointsAttr(grid)
    mesh.CreateFaceVertexCountsAttr([4] * (n - 1) ** 2)
    mesh.CreateFaceVertexIndicesAttr([c for j in range(n - 1) for i in range(n - 1)
                                      for c in (j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i)])
    prim = mesh.GetPrim()
    prim.CreateAttribute("warpSim:cloth", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    prim.CreateAttribute("warpSim:pinned", Sdf.ValueTypeNames.IntArray, custom=True).Set([20, 24])
    prim.CreateAttribute("warpSim:stiffness", Sdf.ValueTypeNames.Float3, custom=True).Set(Gf.Vec3f(50, 25, 2))
    prim.CreateAttribute("warpSim:damping", Sdf.ValueTypeNames.Float3, custom=True).Set(Gf.Vec3f(0.01, 0.01, 0.001))
    points = UsdGeom.Points.Define(stage, "/World/drops")
    points.CreatePointsAttr([(0.0, 50.0, 200.0), (10.0, 50.0, 200.0)])
    points.CreateWidthsAttr([2.0, 2.0])
    points.GetPrim().CreateAttribute("warpSim:particles", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    fountain = UsdGeom.Xform.Define(stage, "/World/fountain")
    fountain.AddTranslateOp().Set(Gf.Vec3d(0.0, -50.0, 10.0))
    fountain.AddRotateXOp().Set(90.0)            # its +Y (the emission axis) onto the stage's +Z
    f = fountain.GetPrim()
    f.CreateAttribute("warpSim:emitter", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    f.CreateAttribute("warpSim:rate", Sdf.ValueTypeNames.Float, custom=True).Set(50.0)
    f.CreateAttribute("warpSim:lifetime", Sdf.ValueTypeNames.Float2, custom=True).Set(Gf.Vec2f(1.0, 1.0))
    f.CreateAttribute("warpSim:speed", Sdf.ValueTypeNames.Float2, custom=True).Set(Gf.Vec2f(2.0, 2.0))
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "soft.usda")
    kinds = {path: kind for path, (kind, _) in scene.usd_paths.items()}
    assert kinds == {"/World/flag": "cloth", "/World/drops": "particles", "/World/fountain": "particles"}
    np.testing.assert_allclose(scene.emitters[0].direction, [0.0, 1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(scene.emitters[0].position, [0.0, 0.1, 0.5], atol=1e-9)
    out = ws.Simulator(scene, integrator="symplectic_euler").run(
        1.0, fps=24, substeps=16, usd=tmp_path / "anim.usdc", over=tmp_path / "soft.usda", progress=False)
    composed = Usd.Stage.Open(str(out))
    flag = UsdGeom.Mesh(composed.GetPrimAtPath("/World/flag")).GetPointsAttr()
    end = np.array(flag.Get(23.0))
    np.testing.assert_allclose(end[[20, 24]], np.array(grid)[[20, 24]], atol=1e-3)       # the pins, in cm
    sag = np.array(grid)[:, 2] - end[:, 2]
    assert sag.min() >= -1e-3 and sag[22] > 1.0 and sag[0] > 0.5      # hanging from its pins, it sags [cm]
    drops = np.array(UsdGeom.Points(composed.GetPrimAtPath("/World/drops")).GetPointsAttr().Get(23.0))
    steps, h = 23 * 16, 1.0 / (24 * 16)
    fall = 981.0 * h ** 2 * steps * (steps + 1) / 2.0        # symplectic Euler's own free fall, exactly [cm]
    np.testing.assert_allclose(drops[:, 2], 200.0 - fall, atol=1e-2)
    live = UsdGeom.Points(composed.GetPrimAtPath("/World/fountain/warpSimParticles")).GetPointsAttr().Get(23.0)
    assert abs(len(live) - 50.0 * min(23.0 / 24.0, 1.0)) <= 1.0                 # rate x min(t, lifetime)


def test_newton_loads_a_stage_written_by_to_usd(tmp_path):
    """A second, independent client of the same file (optional: skipped without newton): Newton's
    ModelBuilder.add_usd finds the same bodies, masses and inertias (about the centre of mass, body frame)."""
    newton = pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas")
    scene = python_scene()
    path = scene.to_usd(tmp_path / "scene.usda")
    builder = newton.ModelBuilder()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = builder.add_usd(str(path))
    model = builder.finalize(device="cpu")
    assert model.body_count == scene.body_count
    bodies = {path: index for path, index in result["path_body_map"].items()}
    for k, body in enumerate(scene.bodies):
        index = bodies[f"/World/Bodies/{body.name}"]
        assert model.body_mass.numpy()[index] == pytest.approx(body.mass.mass, rel=1e-5)
        np.testing.assert_allclose(model.body_inertia.numpy()[index], body.mass.inertia, rtol=1e-4,
                                   atol=1e-6 * np.abs(body.mass.inertia).max())   # float32 principal axes


def test_blender_imports_the_overlay_and_plays_the_bodies(tmp_path):
    """Blender's own USD importer (optional: skipped where bpy is not installed) reads the overlay composed over
    its input and moves the box between the first and the last frame."""
    bpy = pytest.importorskip("bpy")
    source = drop_stage(tmp_path / "drop.usda", "Y", 1.0)
    out = ws.Simulator(ws.Scene.from_usd(source)).run(1.0, fps=24, usd=tmp_path / "anim.usda", over=source,
                                                      progress=False)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.usd_import(filepath=str(out))
    box = next(obj for obj in bpy.data.objects if obj.name.startswith("box"))
    scene = bpy.context.scene
    scene.frame_set(int(scene.frame_start))
    top = box.matrix_world.translation.copy()
    scene.frame_set(int(scene.frame_end))
    assert (top - box.matrix_world.translation).length > 0.1


def test_the_shipped_example_animates(tmp_path):
    """README's one command on the shipped tabletop_cm.usda (ws.examples; Z up, centimetres, 24 time codes per
    second from 1):
    the crate lands on the table top (z = 72 cm, half size 6 cm) and the kinematic paddle pushes it along; the
    ball ends at rest on the floor (its radius, 5 cm, above it); the towel hangs from its four pins."""
    source = pathlib.Path(ws.examples.path("tabletop_cm.usda"))
    out = tmp_path / "tabletop_anim.usdc"
    assert main(["run", str(source), "--out", str(out), "--seconds", "4", "--no-progress"]) == 0
    stage = Usd.Stage.Open(str(out))
    assert stage.GetStartTimeCode() == 1.0 and stage.GetEndTimeCode() == 96.0

    def at(path, code):
        return np.array(UsdGeom.Xformable(stage.GetPrimAtPath(path)).ComputeLocalToWorldTransform(code)
                        .ExtractTranslation())
    assert at("/World/crate", 25.0)[2] == pytest.approx(78.0, abs=0.2)
    assert at("/World/crate", 73.0)[0] > at("/World/paddle", 73.0)[0] + 1.5 + 6.0 - 0.5   # ahead of the paddle
    assert at("/World/paddle", 73.0)[0] == pytest.approx(40.0, abs=1e-3)
    assert at("/World/ball", 96.0)[2] == pytest.approx(5.0, abs=0.1)
    towel = np.array(UsdGeom.Mesh(stage.GetPrimAtPath("/World/towel")).GetPointsAttr().Get(96.0))
    np.testing.assert_allclose(towel[12:, 2], 120.0, atol=1e-3)
    assert validate_stage(out) == []                    # the overlay composed over the input passes UsdValidation
    assert stage.GetPrimAtPath("/World/crate/label")    # the artist's visual child rides along


USD_DOC = pathlib.Path(__file__).parent.parent / "docs" / "usd.md"


@pytest.mark.parametrize("block", re.findall(r"```usda\n(.*?)```", USD_DOC.read_text(), flags=re.S))
def test_every_usda_example_of_the_docs_reads(tmp_path, block):
    """Each ``warpSim:`` example of docs/usd.md, in a centimetre Z-up stage, reads as the kind it documents."""
    text = ("#usda 1.0\n(\n    metersPerUnit = 0.01\n    upAxis = \"Z\"\n)\n\ndef Xform \"World\"\n{\n"
            "    def PhysicsScene \"physicsScene\"\n    {\n    }\n\n"
            + "\n".join("    " + line for line in block.splitlines()) + "\n}\n")
    (tmp_path / "example.usda").write_text(text)
    scene = ws.Scene.from_usd(tmp_path / "example.usda")
    ((path, (kind, ids)),) = scene.usd_paths.items()
    expected = {"flag": "cloth", "drops": "particles", "fountain": "particles"}[path.rsplit("/", 1)[-1]]
    assert kind == expected and len(ids) > 0


def test_kilograms_per_unit_and_a_two_friction_material_said_once(tmp_path):
    """A stage in grams (kilogramsPerUnit = 0.001): a mass of 500 is 0.5 kg. Two bodies share a material whose
    static friction differs from its dynamic one: the dynamic one is used, and one warning says so."""
    stage = new_stage(tmp_path / "grams.usda")
    UsdPhysics.SetStageKilogramsPerUnit(stage, 0.001)
    sticky = material(stage, "/World/Looks/sticky", dynamic=0.3, static=0.7)
    for k in range(2):
        prim = cube(stage, f"/World/box{k}", 0.1, Gf.Vec3d(k, 1, 0))
        UsdPhysics.MassAPI.Apply(prim).CreateMassAttr(500.0)
        bind(prim, sticky)
    stage.Save()
    with pytest.warns(UserWarning, match="dynamic one") as caught:
        scene = ws.Scene.from_usd(tmp_path / "grams.usda")
    assert sum("staticFriction" in str(w.message) for w in caught) == 1
    assert [body.mass.mass for body in scene.bodies] == pytest.approx([0.5, 0.5])
    assert [body.friction for body in scene.bodies] == pytest.approx([0.3, 0.3])


def test_a_disabled_body_is_static_and_an_open_mesh_is_a_terrain(tmp_path):
    """physics:rigidBodyEnabled = false makes a body's shape a static collider, and an open mesh with no body
    above it is a static surface (a terrain): a ball dropped on the terrain comes to rest on it (its radius
    above), and the disabled box never moves."""
    stage = new_stage(tmp_path / "terrain.usda")
    terrain = UsdGeom.Mesh.Define(stage, "/World/terrain")
    terrain.CreatePointsAttr([(-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2)])
    terrain.CreateFaceVertexCountsAttr([4])
    terrain.CreateFaceVertexIndicesAttr([0, 3, 2, 1])        # its normal up
    UsdPhysics.CollisionAPI.Apply(terrain.GetPrim())
    frozen = cube(stage, "/World/frozen", 0.2, Gf.Vec3d(1, 1, 0))
    UsdPhysics.RigidBodyAPI(frozen).CreateRigidBodyEnabledAttr(False)
    ball = UsdGeom.Sphere.Define(stage, "/World/ball")
    ball.CreateRadiusAttr(0.1)
    ball.AddTranslateOp().Set(Gf.Vec3d(-0.5, 0.6, 0))
    UsdPhysics.RigidBodyAPI.Apply(ball.GetPrim())
    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "terrain.usda")
    assert scene.usd_paths["/World/frozen"][0] == "collider" and scene.usd_paths["/World/terrain"][0] == "collider"
    assert not scene.colliders[scene.usd_paths["/World/terrain"][1]].shape.solid
    sim = ws.Simulator(scene)
    sim.step(1.0 / 60.0, steps=120)
    assert sim.state.body_x.numpy()[0, 1] == pytest.approx(0.1, abs=2e-3)

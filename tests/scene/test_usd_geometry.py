"""Collision meshes as UsdPhysics defines them (scene/usd_geometry.py, docs/usd.md "Collision geometry"): each stage
is authored with pxr as a DCC tool saves it, and each test checks how bodies move on it. Heights are warp_sim's
(Y up, metres); the stages are Z up in centimetres, as the third-party stages of issue 31 were."""
import warnings

import numpy as np
import pytest
import trimesh
from pxr import Gf, Usd, UsdGeom, UsdPhysics

import warp_sim as ws
from warp_sim.scene.usd_geometry import SLAB_MIN
from warp_sim.util.rotations import quat_to_matrix

H = 1.0 / 240.0   # [s]
CM = 0.01         # [m]


def new_stage(up="Z", meters=CM):
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, meters)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    UsdPhysics.Scene.Define(stage, "/World/physicsScene")
    return stage


def mesh(stage, path, points, faces, approximation=None, scale=None, at=None, double=None, normals=None,
         orientation=None, collide=True):
    """A Mesh prim (triangles or polygons), optionally a collider with physics:approximation."""
    geom = UsdGeom.Mesh.Define(stage, path)
    geom.CreatePointsAttr([Gf.Vec3f(*map(float, p)) for p in points])
    geom.CreateFaceVertexCountsAttr([len(f) for f in faces])
    geom.CreateFaceVertexIndicesAttr([int(i) for f in faces for i in f])
    if at is not None:
        geom.AddTranslateOp().Set(Gf.Vec3d(*at))
    if scale is not None:
        geom.AddScaleOp().Set(Gf.Vec3f(*scale))
    if double is not None:
        geom.CreateDoubleSidedAttr(double)
    if normals is not None:
        geom.CreateNormalsAttr([Gf.Vec3f(*normals)] * len(points))
    if orientation is not None:
        geom.CreateOrientationAttr(orientation)
    if collide:
        UsdPhysics.CollisionAPI.Apply(geom.GetPrim())
    if approximation is not None:
        UsdPhysics.MeshCollisionAPI.Apply(geom.GetPrim()).CreateApproximationAttr(approximation)
    return geom.GetPrim()


QUAD = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
UP_FACE, DOWN_FACE = [(0, 1, 2, 3)], [(0, 3, 2, 1)]   # counter-clockwise seen from +z, and from -z


def ground_quad(stage, approximation, winding="down", double=True):
    """The issue's ground: a unit quad scaled x750 (15 m across), doubleSided, authored normals (0, 0, 1)."""
    return mesh(stage, "/World/ground", QUAD, DOWN_FACE if winding == "down" else UP_FACE, approximation,
                scale=(750, 750, 750), double=double, normals=(0, 0, 1))


def body(prim, velocity=None):
    UsdPhysics.RigidBodyAPI.Apply(prim)
    if velocity is not None:
        UsdPhysics.RigidBodyAPI(prim).CreateVelocityAttr(Gf.Vec3f(*velocity))
    if not prim.HasAPI(UsdPhysics.CollisionAPI):
        UsdPhysics.CollisionAPI.Apply(prim)
    return prim


def cube(stage, path, size, at):
    geom = UsdGeom.Cube.Define(stage, path)
    geom.CreateSizeAttr(size)
    geom.AddTranslateOp().Set(Gf.Vec3d(*at))
    return geom.GetPrim()


def ball(stage, path, radius, at):
    geom = UsdGeom.Sphere.Define(stage, path)
    geom.CreateRadiusAttr(radius)
    geom.AddTranslateOp().Set(Gf.Vec3d(*at))
    return geom.GetPrim()


def plane_ground(stage):
    plane = UsdGeom.Plane.Define(stage, "/World/floor")
    plane.CreateAxisAttr("Z")
    UsdPhysics.CollisionAPI.Apply(plane.GetPrim())


def drop_box_and_ball(stage, z=60.0):
    body(cube(stage, "/World/box", 10.0, (-50.0, 0.0, z)))
    body(ball(stage, "/World/ball", 5.0, (50.0, 0.0, z)))


def motion(stage, seconds=1.5, every=4):
    """(scene, body positions (frames, bodies, 3) [m] every ``every`` steps of H)."""
    scene = ws.Scene.from_usd(stage)
    sim = ws.Simulator(scene)
    frames = []
    for _ in range(int(round(seconds / (H * every)))):
        sim.step(H, steps=every)
        frames.append(sim.state.body_x.numpy().copy())
    return scene, np.array(frames)


def index(scene, path):
    kind, i = scene.usd_paths[path]
    assert kind == "body"
    return i


def assert_rests(scene, frames, path, height, tolerance=2e-3):
    """Body ``path`` ends at ``height`` [m] (within ``tolerance``), still, and never went below it by more."""
    y = frames[:, index(scene, path), 1]
    assert abs(y[-1] - height) <= tolerance, (path, y[-1], height)
    assert y.min() >= height - tolerance, (path, y.min(), height)
    assert abs(y[-1] - y[-10]) < 1e-4, (path, y[-10:])


def clean(message: str) -> None:
    for word in ("Trimesh", "array(", "invert()", "trimesh.repair", "\n"):
        assert word not in message, message


# ---- physics:approximation = convexHull: the ground ---------------------------------------------------------
@pytest.mark.parametrize("winding", ["down", "up"])
def test_a_downward_wound_ground_quad_with_convex_hull_holds_a_box_and_a_sphere(winding):
    """The issue's floor (scaled x750, doubleSided, normals up, wound down, convexHull) is a slab whose top face is
    the quad: a dropped 10 cm box and a 5 cm ball come to rest with their centres 5 cm above it, never lower (the
    old reading took everything above the quad for inside and put the box 5.2 m below it in frame 1)."""
    stage = new_stage()
    ground_quad(stage, "convexHull", winding)
    drop_box_and_ball(stage)
    scene, frames = motion(stage)
    slab = scene.colliders[0].shape
    assert slab.solid and len(slab.vertices) == 8
    top = (np.asarray(slab.vertices) @ quat_to_matrix(scene.colliders[0].orientation).T
           + scene.colliders[0].position)[:, 1]
    assert top.max() == pytest.approx(0.0, abs=1e-6)          # the quad's plane
    assert top.max() - top.min() == pytest.approx(0.15)        # 1 % of its 15 m
    assert_rests(scene, frames, "/World/box", 5 * CM)
    assert_rests(scene, frames, "/World/ball", 5 * CM)


def test_an_open_dynamic_mesh_with_convex_hull_is_a_slab_body():
    """A dynamic 10 cm quad with convexHull was left out (an open mesh); now it is a slab SLAB_MIN thick below the
    quad (the stage's up side is its front) and falls flat onto the floor, the quad SLAB_MIN above it."""
    stage = new_stage()
    plane_ground(stage)
    card = mesh(stage, "/World/card", QUAD, UP_FACE, "convexHull", scale=(5, 5, 5), at=(0, 0, 30))
    body(card)
    scene, frames = motion(stage)
    shape = scene.bodies[0].shape
    assert shape.solid and shape.volume == pytest.approx(0.1 * 0.1 * SLAB_MIN, rel=1e-6)
    assert_rests(scene, frames, "/World/card", SLAB_MIN / 2.0, tolerance=1e-3)


# ---- approximation none: two-sided surfaces -----------------------------------------------------------------------
@pytest.mark.parametrize("winding, double", [("down", True), ("up", True), ("up", False)])
def test_a_triangle_ground_collides_from_the_side_each_body_is_on(winding, double):
    """The quad with approximation none (doubleSided, or open anyway) is a surface with two sides: the box and the
    ball dropped on it rest on top whichever way it winds, and a ball thrown up at it from below hits its underside
    and falls back, never above it."""
    stage = new_stage()
    ground_quad(stage, "none", winding, double)
    drop_box_and_ball(stage)
    body(ball(stage, "/World/under", 5.0, (0.0, 0.0, -60.0)), velocity=(0.0, 0.0, 400.0))   # would rise to +22 cm
    scene, frames = motion(stage, seconds=1.0)
    assert not scene.colliders[0].shape.solid
    assert_rests(scene, frames, "/World/box", 5 * CM)
    assert_rests(scene, frames, "/World/ball", 5 * CM)
    under = frames[:, index(scene, "/World/under"), 1]
    assert -5 * CM - 2e-3 <= under.max() <= -5 * CM + 1e-3      # it touched the underside and stayed below
    assert under[-1] < -0.3


def test_a_stack_on_a_two_sided_quad_stays_on_it():
    """Five 10 cm boxes stacked on the two-sided quad, each heavier than the one below, press the bottom one
    0.1 mm into it (the contacts' slop): its corners, behind the surface by less than SIDE_SKIN, still count on
    the stack's side, so the stack stands (with the corners' own side alone, the bottom box fell 76 m in 4 s)."""
    stage = new_stage()
    ground_quad(stage, "none", "down")
    for k in range(5):
        prim = body(cube(stage, f"/World/box{k}", 10.0, (0.0, 0.0, 5.0 + 10.5 * k)))
        UsdPhysics.MassAPI.Apply(prim).CreateDensityAttr(0.01 * (k + 1))   # kg per cm^3: 10 to 50 t/m^3
    scene, frames = motion(stage, seconds=2.0)
    for k in range(5):
        assert_rests(scene, frames, f"/World/box{k}", (5.0 + 10.0 * k) * CM, tolerance=1e-3)


# ---- mirrors and orientation ----------------------------------------------------------------------------------------
BOX = trimesh.creation.box(extents=(1.0, 1.0, 1.0))


def test_a_double_sided_closed_mesh_collider_is_a_shell():
    """A closed static box mesh (1 m, its floor at 0) with doubleSided = true is a surface with two sides: a ball
    dropped inside it rests on its inner floor, one dropped onto it rests on its lid, 1 m up."""
    stage = new_stage()
    mesh(stage, "/World/shell", BOX.vertices, BOX.faces, scale=(100, 100, 100), at=(0, 0, 50), double=True)
    body(ball(stage, "/World/inside", 5.0, (0.0, 0.0, 50.0)))
    body(ball(stage, "/World/on", 5.0, (0.0, 0.0, 130.0)))
    scene, frames = motion(stage)
    assert not scene.colliders[0].shape.solid
    assert_rests(scene, frames, "/World/inside", 5 * CM)
    assert_rests(scene, frames, "/World/on", 105 * CM)


def test_a_mirrored_closed_mesh_collider_and_body_rest_as_solids():
    """A closed box mesh under scale (-1, 1, 1) is a mirror image wound inside out by the mirror: folded into the
    winding, the static block (top at 20 cm) holds a ball, and a mirrored body mesh whose points lie off its
    prim's origin (x in [0.5, 1.5] x 10 cm) is at x in [-1.5, -0.5] and rests on the floor, 5 cm up."""
    stage = new_stage()
    plane_ground(stage)
    mesh(stage, "/World/block", BOX.vertices, BOX.faces, scale=(-40, 40, 20), at=(0, 0, 10))
    body(ball(stage, "/World/ball", 5.0, (0.0, 0.0, 40.0)))
    holder = UsdGeom.Xform.Define(stage, "/World/piece")
    holder.AddTranslateOp().Set(Gf.Vec3d(100, 0, 30))
    UsdPhysics.RigidBodyAPI.Apply(holder.GetPrim())   # the body; its shape is the child mesh
    mesh(stage, "/World/piece/shape", BOX.vertices + (1.0, 0.0, 0.0), BOX.faces, scale=(-10, 10, 10))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)   # no "wound inward" warning: the mirror reverses the winding
        scene, frames = motion(stage)
    assert_rests(scene, frames, "/World/ball", 25 * CM)
    piece = scene.bodies[index(scene, "/World/piece")]
    assert piece.shape.volume == pytest.approx(1e-3, rel=1e-6)
    assert frames[-1, index(scene, "/World/piece"), 0] == pytest.approx(0.9, abs=1e-3)   # 100 cm - 10 cm
    assert_rests(scene, frames, "/World/piece", 5 * CM)


@pytest.mark.parametrize("approximation", ["convexHull", "none"])
def test_a_left_handed_closed_mesh_rests_on_the_ground(approximation):
    """A box mesh authored orientation = leftHanded (its faces wound clockwise seen from outside, as that means)
    loads as a solid, with convexHull and with its triangles, and rests on the floor 10 cm up."""
    stage = new_stage()
    plane_ground(stage)
    body(mesh(stage, "/World/crate", BOX.vertices, BOX.faces[:, ::-1], approximation, scale=(20, 20, 20),
              at=(0, 0, 40), orientation="leftHanded"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        scene, frames = motion(stage)
    assert scene.bodies[0].shape.volume == pytest.approx(8e-3, rel=1e-6)
    assert_rests(scene, frames, "/World/crate", 10 * CM)


def test_a_closed_mesh_wound_inward_is_rewound_with_one_warning_naming_it():
    """A right-handed box mesh whose faces wind inward is read re-wound, said once with its path, and rests."""
    stage = new_stage()
    plane_ground(stage)
    body(mesh(stage, "/World/crate", BOX.vertices, BOX.faces[:, ::-1], scale=(20, 20, 20), at=(0, 0, 40)))
    with pytest.warns(UserWarning, match=r"wound inward.*orientation = \"leftHanded\".*/World/crate") as caught:
        scene, frames = motion(stage)
    assert len([w for w in caught if "wound inward" in str(w.message)]) == 1
    assert_rests(scene, frames, "/World/crate", 10 * CM)


def test_a_mirror_on_a_body_prim_is_refused_naming_it_and_what_to_change():
    stage = new_stage()
    plane_ground(stage)
    body(mesh(stage, "/World/crate", BOX.vertices, BOX.faces, scale=(-20, 20, 20), at=(0, 0, 40)))
    with pytest.raises(ValueError) as caught:
        ws.Scene.from_usd(stage)
    message = str(caught.value)
    assert message.startswith("/World/crate: xformOp:scale=(-20, 20, 20) is invalid: it mirrors the rigid body")
    assert "below the body" in message
    clean(message)


# ---- boundingCube, boundingSphere, convexDecomposition, unknown values ---------------------------------------------
ROCK = trimesh.creation.icosphere(0)   # an icosahedron: 12 points on the unit sphere


@pytest.mark.parametrize("approximation, top", [("boundingCube", None), ("boundingSphere", 1.0)])
def test_bounding_shapes_hold_a_dropped_ball_at_their_top(approximation, top):
    """A static icosahedron (radius 30 cm, centre 40 cm up, its points off its prim's origin by 10 cm) as
    boundingCube is a Box about its bounds, as boundingSphere a Sphere through its farthest point: a ball dropped
    above their centre rests on top, its centre 5 cm above the box's top face or the sphere's top."""
    stage = new_stage()
    points = ROCK.vertices + (1.0 / 3.0, 0.0, 0.0)
    mesh(stage, "/World/rock", points, ROCK.faces, approximation, scale=(30, 30, 30), at=(-10, 0, 40))
    body(ball(stage, "/World/ball", 5.0, (0.0, 0.0, 90.0)))
    scene, frames = motion(stage, seconds=1.2)
    shape = scene.colliders[0].shape
    if approximation == "boundingCube":
        half = (np.ptp(ROCK.vertices, axis=0) / 2.0) * 0.3
        assert isinstance(shape, ws.Box)
        np.testing.assert_allclose(shape.size, half, rtol=1e-6)
        top = half[2] / 0.3
    else:
        assert isinstance(shape, ws.Sphere)
        assert shape.radius == pytest.approx(0.3, rel=1e-6)
    np.testing.assert_allclose(scene.colliders[0].position, (0.0, 0.4, 0.0), atol=1e-6)
    assert_rests(scene, frames, "/World/ball", 0.4 + 0.3 * top + 5 * CM)


def test_a_body_with_a_bounding_sphere_rests_on_it_at_its_centre():
    """A dynamic icosahedron (radius 10 cm) whose points lie 20 cm off its prim's origin, as boundingSphere: the
    body is that sphere at that centre, and it rests on the floor 10 cm up, where it was dropped in x."""
    stage = new_stage()
    plane_ground(stage)
    body(mesh(stage, "/World/pebble", ROCK.vertices + (2.0, 0.0, 0.0), ROCK.faces, "boundingSphere",
              scale=(10, 10, 10), at=(30, 0, 40)))
    scene, frames = motion(stage)
    assert isinstance(scene.bodies[0].shape, ws.Sphere) and scene.bodies[0].shape.radius == pytest.approx(0.1)
    np.testing.assert_allclose(scene.bodies[0].position, (0.5, 0.4, 0.0), atol=1e-6)
    assert frames[-1, 0, 0] == pytest.approx(0.5, abs=1e-4)
    assert_rests(scene, frames, "/World/pebble", 10 * CM)


def test_a_flat_bounding_cube_is_a_slab_under_the_quad():
    """boundingCube of the ground quad is a box 15 cm deep whose top face is the quad: the box rests 5 cm up."""
    stage = new_stage()
    ground_quad(stage, "boundingCube")
    body(cube(stage, "/World/box", 10.0, (0.0, 0.0, 40.0)))
    scene, frames = motion(stage, seconds=1.2)
    shape = scene.colliders[0].shape
    np.testing.assert_allclose(shape.size, (7.5, 7.5, 0.075), rtol=1e-6)   # its own frame: the stage's axes
    assert scene.colliders[0].position[1] == pytest.approx(-0.075)
    assert_rests(scene, frames, "/World/box", 5 * CM)


def test_convex_decomposition_is_the_hull_said_once_naming_the_prims():
    """Two dynamic L-shaped pieces with convexDecomposition are each their convex hull (one warning, both paths)
    and rest on the floor; an unknown approximation is read as the triangles, with a warning naming it."""
    stage = new_stage()
    plane_ground(stage)
    ell = trimesh.util.concatenate([trimesh.creation.box((2, 1, 1)).apply_translation((0.5, 0, 0)),
                                    trimesh.creation.box((1, 1, 1)).apply_translation((0, 0, 1))])
    ell = trimesh.Trimesh(ell.vertices, ell.faces)   # merged: the two boxes share no face, hull 2 x 1 x 2
    for k, path in enumerate(("/World/left", "/World/right")):
        body(mesh(stage, path, ell.vertices, ell.faces, "convexDecomposition", scale=(10, 10, 10),
                  at=(40 * k, 0, 30)))
    body(mesh(stage, "/World/crate", BOX.vertices, BOX.faces, "sdf", scale=(20, 20, 20), at=(-60, 0, 40)))
    with pytest.warns(UserWarning) as caught:
        scene, frames = motion(stage)
    messages = [str(w.message) for w in caught]
    decomposed = [m for m in messages if "convexDecomposition" in m]
    assert len(decomposed) == 1 and "/World/left" in decomposed[0] and "/World/right" in decomposed[0]
    assert any("unknown physics:approximation" in m and "/World/crate ('sdf')" in m for m in messages)
    # the hull's cross-section: the L's 2 x 2 square less the triangle it cuts off, 3.5 in all; its centroid lies
    # (2 * 0.5 - 0.5 * 7/6) / 3.5 above the square's mid-line, so resting on its base the centre is that + 0.5 up
    assert scene.bodies[index(scene, "/World/left")].shape.volume == pytest.approx(3.5e-3, rel=1e-6)
    for path in ("/World/left", "/World/right"):
        assert_rests(scene, frames, path, 0.1 * ((2.0 - 0.5 * 7.0 / 6.0) / 3.5 + 0.5))
    assert_rests(scene, frames, "/World/crate", 10 * CM)


# ---- errors -------------------------------------------------------------------------------------------------------
def inconsistent(stage):
    faces = BOX.faces.copy()
    faces[0] = faces[0][::-1]
    body(mesh(stage, "/World/crate", BOX.vertices, faces, scale=(20, 20, 20), at=(0, 0, 40)))


def collinear(stage):
    body(mesh(stage, "/World/stick", [(0, 0, 0), (1, 0, 0), (2, 0, 0)], [(0, 1, 2)], "convexHull", at=(0, 0, 40)))


@pytest.mark.parametrize("build, start, words", [
    (inconsistent, "/World/crate: faceVertexIndices=", ["wind opposite ways", 'physics:approximation = "convexHull"']),
    (collinear, "/World/stick: points=", ["lie on a line", "extent in two directions"]),
])
def test_errors_name_the_prim_the_attribute_and_what_to_change(build, start, words):
    stage = new_stage()
    plane_ground(stage)
    build(stage)
    with pytest.raises(ValueError) as caught:
        ws.Scene.from_usd(stage)
    message = str(caught.value)
    assert message.startswith(start) and " is invalid: " in message, message
    for word in words:
        assert word in message, message
    clean(message)

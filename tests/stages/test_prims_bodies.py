"""Rigid bodies in StageWriter: Xforms with sampled translate/orient and static shape children, read back with pxr."""

import math
import os

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

from warp_sim.stages import BodySpec, PlaneSpec, PointsGroup, StageLayout, StageWriter, validate_stage

TET_POINTS = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]) * 0.2 - 0.05
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
# One body of each kind; indices out of order and with gaps, so the body arrays hold unused rows.
BODIES = (
    BodySpec("ball", 3, "sphere", (0.1,), color=(1.0, 0.0, 0.0)),
    BodySpec("crate", 0, "box", (0.1, 0.2, 0.3)),
    BodySpec("pill", 7, "capsule", (0.05, 0.2)),
    BodySpec("can", 1, "cylinder", (0.06, 0.15)),
    BodySpec("tet", 5, "mesh", points=TET_POINTS, faces=TET_FACES, color=(0.2, 0.4, 0.8)),
    BodySpec("cloud", 2, "points", points=TET_POINTS * 3, radius=0.03),
)
B = 8
LAYOUT = StageLayout(bodies=BODIES)
GEOM = {"sphere": UsdGeom.Sphere, "box": UsdGeom.Cube, "capsule": UsdGeom.Capsule, "cylinder": UsdGeom.Cylinder,
        "mesh": UsdGeom.Mesh, "points": UsdGeom.Points}


def unit_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def body_frames(count, seed=0, dtype=np.float64):
    rng = np.random.default_rng(seed)
    return [(rng.normal(size=(B, 3)).astype(dtype), unit_quats(rng, B).astype(dtype)) for _ in range(count)]


def write(path, data, layout=LAYOUT, chunk_frames=240):
    with StageWriter(path, 60.0, layout, chunk_frames=chunk_frames) as w:
        for k, (x, q) in enumerate(data):
            w.write_frame(k, body_x=x, body_q=q)
    return data


def rotation(q):
    """Column-vector rotation matrix of the unit quaternion q = (x, y, z, w)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def xyzw(quat: Gf.Quatf) -> np.ndarray:
    return np.array([*quat.GetImaginary(), quat.GetReal()], dtype=np.float32)


def listing(folder):
    return sorted(os.listdir(folder))


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_round_trip_every_frame(tmp_path, dtype):
    path = tmp_path / "bodies.usdc"
    data = write(path, body_frames(30, dtype=dtype), chunk_frames=7)  # chunk saves mid-run
    stage = Usd.Stage.Open(str(path))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 29.0)
    for spec in BODIES:
        prim = stage.GetPrimAtPath(f"/World/Bodies/{spec.name}")
        xform = UsdGeom.Xformable(prim)
        ops = xform.GetOrderedXformOps()
        assert [op.GetOpName() for op in ops] == ["xformOp:translate", "xformOp:orient"]
        translate, orient = ops
        assert translate.GetPrecision() == UsdGeom.XformOp.PrecisionDouble
        assert orient.GetPrecision() == UsdGeom.XformOp.PrecisionFloat
        assert [a.GetName() for a in prim.GetAttributes() if a.GetNumTimeSamples()] == [
            "xformOp:orient", "xformOp:translate"]
        for op in ops:
            assert op.GetTimeSamples() == [float(k) for k in range(30)]
        for k, (x, q) in enumerate(data):
            x, q = x[spec.index].astype(np.float64), q[spec.index].astype(np.float64)
            np.testing.assert_array_equal(np.array(translate.Get(k)), x)  # double: exact
            got, want = xyzw(orient.Get(k)), (q / np.linalg.norm(q)).astype(np.float32)
            assert np.array_equal(got, want) or np.array_equal(got, -want), (spec.name, k, got, want)
            m = np.array(xform.ComputeLocalToWorldTransform(k))  # row-vector convention: [R^T 0; t 1]
            np.testing.assert_array_equal(m[3, :3], x)
            np.testing.assert_allclose(m[:3, :3], rotation(q).T, rtol=0, atol=1e-6)
            np.testing.assert_allclose(m[:, 3], [0, 0, 0, 1], rtol=0, atol=0)
    assert validate_stage(path) == []


def test_shape_children_static(tmp_path):
    path = tmp_path / "bodies.usda"
    write(path, body_frames(3))
    stage = Usd.Stage.Open(str(path))
    for spec in BODIES:
        prim = stage.GetPrimAtPath(f"/World/Bodies/{spec.name}/Geom")
        assert prim.GetTypeName() == GEOM[spec.kind].__name__ and prim.IsA(GEOM[spec.kind]), spec.name
        assert list(stage.GetPrimAtPath(f"/World/Bodies/{spec.name}").GetChildren()) == [prim]
        assert all(a.GetNumTimeSamples() == 0 for a in prim.GetAttributes()), spec.name
        geom = GEOM[spec.kind](prim)
        color = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
        assert color.GetInterpolation() == UsdGeom.Tokens.constant
        np.testing.assert_allclose(np.asarray(color.Get()), [spec.color], rtol=1e-6)
        # The authored extent matches what USD computes from the authored shape attributes.
        computed = UsdGeom.Boundable.ComputeExtentFromPlugins(geom, Usd.TimeCode.Default())
        np.testing.assert_allclose(np.asarray(geom.GetExtentAttr().Get()), np.asarray(computed), rtol=1e-6)
        size = spec.size
        if spec.kind == "sphere":
            assert geom.GetRadiusAttr().Get() == pytest.approx(size[0])
        elif spec.kind == "box":
            assert geom.GetSizeAttr().Get() == 2.0
            (scale,) = geom.GetOrderedXformOps()
            assert scale.GetOpType() == UsdGeom.XformOp.TypeScale
            np.testing.assert_allclose(np.array(scale.Get()), size, rtol=1e-6)
            body = np.array(UsdGeom.Xformable(prim.GetParent()).ComputeLocalToWorldTransform(2))
            world = np.array(geom.ComputeLocalToWorldTransform(2))  # the unit cube scaled in the body frame
            np.testing.assert_allclose(world, np.diag([*size, 1.0]) @ body, rtol=1e-6, atol=1e-7)
        elif spec.kind in ("capsule", "cylinder"):
            assert geom.GetRadiusAttr().Get() == pytest.approx(size[0])
            assert geom.GetHeightAttr().Get() == pytest.approx(2 * size[1])
            assert geom.GetAxisAttr().Get() == UsdGeom.Tokens.y
        elif spec.kind == "mesh":
            np.testing.assert_allclose(np.asarray(geom.GetPointsAttr().Get()), TET_POINTS, rtol=1e-6)
            assert list(geom.GetFaceVertexCountsAttr().Get()) == [3] * len(TET_FACES)
            assert list(geom.GetFaceVertexIndicesAttr().Get()) == TET_FACES.reshape(-1).tolist()
            assert geom.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
        else:
            np.testing.assert_allclose(np.asarray(geom.GetPointsAttr().Get()), TET_POINTS * 3, rtol=1e-6)
            np.testing.assert_allclose(np.asarray(geom.GetWidthsAttr().Get()), np.full(4, 0.06), rtol=1e-6)
    assert validate_stage(path) == []


def test_near_unit_quaternion_is_normalised(tmp_path):
    path = tmp_path / "bodies.usdc"
    x, q = body_frames(1)[0]
    write(path, [(x, q * (1 + 9e-4))])
    stage = Usd.Stage.Open(str(path))
    orient = stage.GetAttributeAtPath("/World/Bodies/crate.xformOp:orient")
    np.testing.assert_allclose(xyzw(orient.Get(0)), q[0], rtol=0, atol=6e-8)  # float32 rounding of the unit q


@pytest.mark.parametrize("array,bad,message", [
    ("body_x", math.nan, "non-finite value at body index 3"),
    ("body_x", -math.inf, "non-finite value at body index 3"),
    ("body_q", math.nan, "non-finite value at body index 3"),
    ("body_q", math.inf, "non-finite value at body index 3"),
    ("body_q", 0.3, "non-unit quaternion at body index 3"),
])
def test_bad_body_values_raise_and_leave_nothing(tmp_path, array, bad, message):
    path = tmp_path / "bodies.usdc"
    data = body_frames(3)
    if array == "body_x":
        data[2][0][3, 1] = bad
    else:
        data[2][1][3, 1] += bad
    with pytest.raises(ValueError, match=rf"frame 2: {array} has a {message}"):
        write(path, data, chunk_frames=1)
    assert not path.exists()
    assert listing(tmp_path) == []


def test_nothing_authored_by_a_rejected_frame(tmp_path):
    (x_bad, q_bad), (x, q) = body_frames(2)
    q_bad[7] *= 2.0  # the last body checked; the bodies before it must not be authored either
    path = tmp_path / "bodies.usdc"
    with StageWriter(path, 60, LAYOUT) as w:
        with pytest.raises(ValueError, match=r"frame 0: body_q .* index 7 \(norm 2;"):
            w.write_frame(0, body_x=x_bad, body_q=q_bad)
        assert w.frames_written == 0
        w.write_frame(0, body_x=x, body_q=q)
    stage = Usd.Stage.Open(str(path))
    for spec in BODIES:
        translate = stage.GetAttributeAtPath(f"/World/Bodies/{spec.name}.xformOp:translate")
        assert translate.GetTimeSamples() == [0.0]
        np.testing.assert_array_equal(np.array(translate.Get(0)), x[spec.index])
    assert validate_stage(path) == []


def test_bad_frame_arrays(tmp_path):
    x, q = body_frames(1)[0]
    with StageWriter(tmp_path / "bodies.usdc", 60, LAYOUT) as w:
        for kwargs, match in [
            ({"body_q": q}, "body_x is required"),
            ({"body_x": x}, "body_q is required"),
            ({"body_x": x[:7], "body_q": q[:7]}, r"body_x must have shape \(N, 3\) with N >= 8, got \(7, 3\)"),
            ({"body_x": x, "body_q": q[:, :3]}, r"body_q must have shape \(N, 4\)"),
            ({"body_x": np.vstack([x, x]), "body_q": q}, "different numbers of bodies"),
            ({"body_x": x, "body_q": q, "particle_x": np.full((2, 3), np.nan)}, "particle_x has a non-finite"),
        ]:
            with pytest.raises(ValueError, match=match):
                w.write_frame(0, **kwargs)
        assert w.frames_written == 0
        w.write_frame(0, body_x=x, body_q=q)


def test_bodies_only_and_particles_only_layouts(tmp_path):
    x, q = body_frames(1)[0]
    write(tmp_path / "bodies.usdc", [(x, q)])  # no particle arrays needed
    particles = StageLayout(points_groups=(PointsGroup("p", 0, 2, np.full(2, 0.02), (1.0, 0.0, 0.0)),))
    with StageWriter(tmp_path / "particles.usdc", 60, particles) as w:
        with pytest.raises(ValueError, match="particle_x is required"):
            w.write_frame(0, body_x=x, body_q=q)
        w.write_frame(0, np.zeros((2, 3)), np.zeros((2, 3)))  # no body arrays needed; positional still works
        w.write_frame(1, particle_x=np.ones((2, 3)), particle_v=np.zeros((2, 3)))
    for name in ("bodies.usdc", "particles.usdc"):
        assert validate_stage(tmp_path / name) == []


def test_mixed_layout(tmp_path):
    path = tmp_path / "mixed.usdc"
    layout = StageLayout(points_groups=(PointsGroup("grains", 0, 5, np.full(5, 0.02), (0.9, 0.8, 0.1)),),
                         springs=np.array([[0, 1], [3, 4]]), planes=(PlaneSpec("ground", (0.0, 1.0, 0.0), 0.0),),
                         bodies=BODIES)
    rng = np.random.default_rng(3)
    data = [(rng.normal(size=(5, 3)), rng.normal(size=(5, 3))) + b for b in body_frames(4)]
    with StageWriter(path, 30, layout) as w:
        for k, (px, pv, bx, bq) in enumerate(data):
            w.write_frame(k, px, pv, bx, bq)
    stage = Usd.Stage.Open(str(path))
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/grains"))
    translate = stage.GetAttributeAtPath("/World/Bodies/pill.xformOp:translate")
    for k, (px, _, bx, _) in enumerate(data):
        np.testing.assert_allclose(np.asarray(points.GetPointsAttr().Get(k)), px, rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(np.array(translate.Get(k)), bx[7])
    assert stage.GetPrimAtPath("/World/Planes/ground") and stage.GetPrimAtPath("/World/Springs")
    assert validate_stage(path) == []


def test_names_made_valid_and_unique(tmp_path):
    layout = StageLayout(bodies=(BodySpec("my body!", 0, "sphere", (0.1,)), BodySpec("2nd", 1, "box", (1, 1, 1))))
    path = tmp_path / "names.usdc"
    with StageWriter(path, 60, layout) as w:
        w.write_frame(0, body_x=np.zeros((2, 3)), body_q=np.tile([0.0, 0.0, 0.0, 1.0], (2, 1)))
    stage = Usd.Stage.Open(str(path))
    assert [p.GetName() for p in stage.GetPrimAtPath("/World/Bodies").GetChildren()] == ["my_body_", "_nd"]
    assert validate_stage(path) == []
    dupes = StageLayout(bodies=(BodySpec("a b", 0, "sphere", (0.1,)), BodySpec("a_b", 1, "sphere", (0.1,))))
    with pytest.raises(ValueError, match=r"unique.*/World/Bodies/a_b"):
        StageWriter(tmp_path / "dupes.usdc", 60, dupes)
    assert listing(tmp_path) == ["names.usdc"]


def rock(**kw):
    return BodySpec(**({"name": "rock", "index": 0, "kind": "sphere", "size": (0.1,)} | kw))


def mesh(**kw):
    return rock(**({"kind": "mesh", "size": (), "points": TET_POINTS, "faces": TET_FACES} | kw))


def cloud(**kw):
    return rock(**({"kind": "points", "size": (), "points": TET_POINTS} | kw))


@pytest.mark.parametrize("spec,message", [
    (rock(kind="cone"), "kind must be one of sphere, box, capsule, cylinder, mesh, points, none, got 'cone'"),
    (rock(index=-1), "index must be an integer >= 0"),
    (rock(index=1.0), "index must be an integer >= 0"),
    (rock(size=()), r"size of a sphere must be \(radius,\)"),
    (rock(size=(0.1, 0.2)), r"size of a sphere must be \(radius,\)"),
    (rock(size=(0.0,)), "finite values > 0"),
    (rock(size=(math.nan,)), "finite values > 0"),
    (rock(kind="box", size=(0.1, 0.2)), r"size of a box must be half extents \(hx, hy, hz\)"),
    (rock(kind="box", size=(0.1, -0.2, 0.3)), "finite values > 0"),
    (rock(kind="capsule", size=(0.1,)), r"size of a capsule must be \(radius, half_height\)"),
    (rock(kind="cylinder", size=(0.1, math.inf)), "finite values > 0"),
    (rock(points=TET_POINTS), "points are not used for a sphere body"),
    (rock(color=(1.0, 0.0)), "color must be 3 finite floats"),
    (mesh(points=None), "points are required for a mesh body"),
    (mesh(faces=None), "faces are required for a mesh body"),
    (mesh(size=(0.1,)), r"size of a mesh must be \(\)"),
    (mesh(points=TET_POINTS[:, :2]), r"points must be a finite \(N, 3\)"),
    (mesh(faces=TET_FACES[:, :2]), r"faces must be an integer \(F, 3\)"),
    (mesh(faces=TET_FACES * 1.0), r"faces must be an integer \(F, 3\)"),
    (mesh(faces=TET_FACES + 1), r"faces must index the 4 points .* 1 \.\. 4"),
    (mesh(faces=TET_FACES - 1), r"faces must index the 4 points .* -1 \.\. 2"),
    (cloud(points=None), "points are required for a points body"),
    (cloud(points=np.zeros((0, 3))), r"points must be a finite \(N, 3\) array with N >= 1"),
    (cloud(points=np.full((2, 3), np.nan)), "points must be a finite"),
    (cloud(radius=0.0), "radius must be finite and > 0"),
    (cloud(faces=TET_FACES), "faces are not used for a points body"),
])
def test_bad_body_specs(tmp_path, spec, message):
    with pytest.raises(ValueError, match=message) as info:
        StageWriter(tmp_path / "bad.usdc", 60, StageLayout(bodies=(spec,)))
    assert str(info.value).startswith("BodySpec 'rock': ")
    assert listing(tmp_path) == []


def test_body_samples_in_chunk_saves(tmp_path):
    path = tmp_path / "bodies.usdc"
    with StageWriter(path, 60, LAYOUT, chunk_frames=2) as w:
        for k, (x, q) in enumerate(body_frames(3)):
            w.write_frame(k, body_x=x, body_q=q)
            if k == 1:  # the first chunk is on disk in the run's folder, readable on its own
                (folder,) = listing(tmp_path)
                layer = Sdf.Layer.OpenAsAnonymous(str(tmp_path / folder / "chunk-000000.usdc"))
                assert layer.ListTimeSamplesForPath("/World/Bodies/ball.xformOp:translate") == [0.0, 1.0]
                assert layer.ListTimeSamplesForPath("/World/Bodies/ball.xformOp:orient") == [0.0, 1.0]
    stage = Usd.Stage.Open(str(path))
    assert stage.GetAttributeAtPath("/World/Bodies/ball.xformOp:orient").GetTimeSamples() == [0.0, 1.0, 2.0]

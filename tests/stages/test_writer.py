"""StageWriter / validate_stage: read the written stages back with pxr and check real properties."""

import math
import os

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdPhysics

from warp_sim.stages import PlaneSpec, PointsGroup, StageLayout, StageWriter, validate_stage

N = 7
SPRINGS = np.array([[0, 1], [1, 2], [4, 6]])
PLANES = (PlaneSpec("ground", (0.0, 1.0, 0.0), 0.0), PlaneSpec("wall", (1.0, 0.0, 1.0), -2.0, size=4.0))


def make_layout(**kw):
    groups = (PointsGroup("balls", 0, 4, np.full(4, 0.1), (1.0, 0.2, 0.0)),
              PointsGroup("cloth 2", 4, 3, np.array([0.02, 0.03, 0.04]), (0.0, 0.5, 1.0)))
    return StageLayout(points_groups=groups, springs=SPRINGS, spring_width=0.01, planes=PLANES, **kw)


def frames(count, seed=0):
    rng = np.random.default_rng(seed)
    return [(rng.normal(size=(N, 3)), rng.normal(size=(N, 3)).astype(np.float32)) for _ in range(count)]


def write(path, count=30, fps=100.0, chunk_frames=240):
    data = frames(count)
    with StageWriter(path, fps, make_layout(), chunk_frames=chunk_frames) as w:
        for k, (x, v) in enumerate(data):
            w.write_frame(k, x, v)
        assert w.frames_written == count
    return data


def animated_attrs(stage):
    prims = [p for p in stage.Traverse() if p.IsA(UsdGeom.Points)] + [stage.GetPrimAtPath("/World/Springs")]
    return [a for p in prims for a in p.GetAttributes() if a.GetNumTimeSamples()]


def listing(folder):
    return sorted(os.listdir(folder))


@pytest.mark.parametrize("fps", [100.0, 24.0, 29.97])
def test_metadata_and_exact_time_samples(tmp_path, fps):
    path = tmp_path / "run.usdc"
    write(path, count=30, fps=fps)
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdPhysics.GetStageKilogramsPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == pytest.approx(fps)
    assert stage.GetFramesPerSecond() == pytest.approx(fps)
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 29.0)
    assert stage.GetDefaultPrim().GetPath() == Sdf.Path("/World")
    assert stage.GetDefaultPrim().IsA(UsdGeom.Xform)
    attrs = animated_attrs(stage)
    names = {a.GetName() for a in attrs}
    assert {"points", "ids", "widths", "velocities", "primvars:displayColor", "extent"} <= names
    for attr in attrs:
        assert attr.GetTimeSamples() == [float(k) for k in range(30)], attr.GetPath()


def test_points_round_trip(tmp_path):
    path = tmp_path / "run.usdc"
    data = write(path, count=5)
    stage = Usd.Stage.Open(str(path))
    groups = make_layout().points_groups
    for g in groups:
        pts = UsdGeom.Points(stage.GetPrimAtPath(f"/World/Particles/{g.name.replace(' ', '_')}"))
        assert pts, g.name
        color = UsdGeom.PrimvarsAPI(pts).GetPrimvar("displayColor")
        assert color.GetInterpolation() == UsdGeom.Tokens.vertex
        sl = slice(g.start, g.start + g.count)
        for k, (x, v) in enumerate(data):
            p = np.asarray(pts.GetPointsAttr().Get(k))
            assert p.dtype == np.float32
            np.testing.assert_allclose(p, x[sl], rtol=1e-6, atol=1e-6)
            np.testing.assert_allclose(np.asarray(pts.GetVelocitiesAttr().Get(k)), v[sl])
            ids = np.asarray(pts.GetIdsAttr().Get(k))
            np.testing.assert_array_equal(ids, np.arange(g.start, g.start + g.count))
            np.testing.assert_allclose(np.asarray(pts.GetWidthsAttr().Get(k)), g.widths, rtol=1e-6)
            np.testing.assert_allclose(np.asarray(color.Get(k)), np.tile(g.color, (g.count, 1)), rtol=1e-6)
            lo, hi = np.asarray(pts.GetExtentAttr().Get(k))
            r = g.widths[:, None] / 2
            np.testing.assert_allclose(lo, (x[sl] - r).min(0), rtol=1e-5, atol=1e-6)
            np.testing.assert_allclose(hi, (x[sl] + r).max(0), rtol=1e-5, atol=1e-6)


def test_springs_topology_once_points_per_frame(tmp_path):
    path = tmp_path / "run.usdc"
    data = write(path, count=4)
    stage = Usd.Stage.Open(str(path))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Springs"))
    assert curves.GetTypeAttr().Get() == UsdGeom.Tokens.linear
    assert list(curves.GetCurveVertexCountsAttr().Get()) == [2] * len(SPRINGS)
    assert curves.GetCurveVertexCountsAttr().GetNumTimeSamples() == 0
    assert curves.GetWidthsAttr().GetNumTimeSamples() == 0
    assert list(curves.GetWidthsAttr().Get()) == [pytest.approx(0.01)]
    assert curves.GetWidthsInterpolation() == UsdGeom.Tokens.constant
    assert curves.GetPointsAttr().GetTimeSamples() == [0.0, 1.0, 2.0, 3.0]
    assert curves.GetExtentAttr().GetNumTimeSamples() == 4
    for k, (x, _) in enumerate(data):
        np.testing.assert_allclose(np.asarray(curves.GetPointsAttr().Get(k)), x[SPRINGS.reshape(-1)],
                                   rtol=1e-6, atol=1e-6)


def test_planes_static_quads(tmp_path):
    path = tmp_path / "run.usdc"
    write(path, count=3)
    stage = Usd.Stage.Open(str(path))
    for spec in PLANES:
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/World/Planes/{spec.name}"))
        assert mesh
        assert all(a.GetNumTimeSamples() == 0 for a in mesh.GetPrim().GetAttributes())
        assert mesh.GetDoubleSidedAttr().Get() is True
        assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
        assert list(mesh.GetFaceVertexCountsAttr().Get()) == [4]
        p = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
        n = np.asarray(spec.normal) / np.linalg.norm(spec.normal)
        np.testing.assert_allclose(p.mean(0), n * spec.offset, atol=1e-5)
        np.testing.assert_allclose(p @ n, spec.offset, atol=1e-5)  # all corners on the plane
        np.testing.assert_allclose(np.linalg.norm(p[1] - p[0]), spec.size, rtol=1e-6)
        face_n = np.cross(p[1] - p[0], p[2] - p[1])
        np.testing.assert_allclose(face_n / np.linalg.norm(face_n), n, atol=1e-6)  # winds around +n


@pytest.mark.parametrize("ext,header", [(".usdc", b"PXR-USDC"), (".usd", b"PXR-USDC"), (".usda", b"#usda")])
def test_format_follows_extension(tmp_path, ext, header):
    path = tmp_path / f"run{ext}"
    write(path, count=2)
    assert path.read_bytes().startswith(header)
    assert listing(tmp_path) == [path.name]
    assert Usd.Stage.Open(str(path)).GetEndTimeCode() == 1.0


def test_close_returns_path_and_creates_parents(tmp_path):
    path = tmp_path / "a" / "b" / "run.usdc"
    w = StageWriter(path, 30, make_layout())
    w.write_frame(0, *frames(1)[0])
    assert not path.exists()  # nothing at the final path until close()
    assert w.close() == path
    assert path.exists() and listing(path.parent) == ["run.usdc"]


@pytest.mark.parametrize("array", ["particle_x", "particle_v"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, 1e39, -3.5e38])
def test_non_finite_raises_and_leaves_nothing(tmp_path, array, bad):
    """NaN, an infinity, and a float64 value beyond float32's largest (3.4028e38), which a stage's float32 points
    and velocities would hold as an infinity, are all refused before anything is written."""
    path = tmp_path / "run.usdc"
    data = [(x.astype(np.float64), v.astype(np.float64)) for x, v in frames(3)]
    with pytest.raises(ValueError, match=rf"frame 2: {array} .* index 5"):
        with StageWriter(path, 100, make_layout(), chunk_frames=1) as w:
            for k, (x, v) in enumerate(data):
                if k == 2:
                    (x if array == "particle_x" else v)[5, 1] = bad
                w.write_frame(k, x, v)
    assert not path.exists()
    assert listing(tmp_path) == []


def test_abort_removes_temp_file(tmp_path):
    w = StageWriter(tmp_path / "run.usda", 100, make_layout(), chunk_frames=1)
    w.write_frame(0, *frames(1)[0])
    assert len(listing(tmp_path)) == 1 and listing(tmp_path)[0].startswith(".run.usda.run-")   # the run's folder
    w.abort()
    assert listing(tmp_path) == []


def test_exception_in_with_keeps_existing_file(tmp_path):
    path = tmp_path / "run.usdc"
    path.write_bytes(b"previous result")
    with pytest.raises(RuntimeError, match="boom"):
        with StageWriter(path, 100, make_layout(), chunk_frames=1) as w:
            for k, (x, v) in enumerate(frames(3)):
                w.write_frame(k, x, v)
            raise RuntimeError("boom")
    assert path.read_bytes() == b"previous result"
    assert listing(tmp_path) == ["run.usdc"]


def test_chunked_saves_give_complete_stage(tmp_path):
    path = tmp_path / "run.usdc"
    data = frames(5)
    with StageWriter(path, 100, make_layout(), chunk_frames=2) as w:
        for k, (x, v) in enumerate(data):
            w.write_frame(k, x, v)
            if k == 1:  # the first chunk is on disk in the run's folder, readable on its own
                (folder,) = listing(tmp_path)
                layer = Sdf.Layer.OpenAsAnonymous(str(tmp_path / folder / "chunk-000000.usdc"))
                assert layer.ListTimeSamplesForPath("/World/Particles/balls.points") == [0.0, 1.0]
    stage = Usd.Stage.Open(str(path))
    assert stage.GetEndTimeCode() == 4.0
    for attr in animated_attrs(stage):
        assert attr.GetTimeSamples() == [0.0, 1.0, 2.0, 3.0, 4.0]
    pts = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/balls"))
    np.testing.assert_allclose(np.asarray(pts.GetPointsAttr().Get(4)), data[4][0][:4], rtol=1e-6, atol=1e-6)
    assert validate_stage(path) == []


@pytest.mark.parametrize("name,value,shown", [
    ("path", "run.abc", "'.abc'"), ("fps", 0, "0"), ("fps", -24.0, "-24.0"),
    ("fps", math.nan, "nan"), ("fps", math.inf, "inf"), ("chunk_frames", 0, "0"), ("chunk_frames", 2.5, "2.5"),
])
def test_bad_arguments(tmp_path, name, value, shown):
    valid = {"path": ".usd, .usdc, .usda", "fps": "> 0", "chunk_frames": ">= 1"}[name]
    args = dict(path="run.usdc", fps=100.0, layout=make_layout(), chunk_frames=240) | {name: value}
    args["path"] = tmp_path / args["path"]
    with pytest.raises(ValueError, match=name) as info:
        StageWriter(**args)
    message = str(info.value)
    assert valid in message and (f"got {shown}" in message or f"(extension {shown})" in message), message
    assert listing(tmp_path) == []


def test_bad_frames_and_shapes(tmp_path):
    x, v = frames(1)[0]
    with StageWriter(tmp_path / "run.usdc", 100, make_layout()) as w:
        with pytest.raises(ValueError, match="frame"):
            w.write_frame(1, x, v)  # frames start at 0
        with pytest.raises(ValueError, match="particle_x"):
            w.write_frame(0, x[:5], v)  # groups/springs need 7 particles
        with pytest.raises(ValueError, match="particle_v"):
            w.write_frame(0, x, v[:, :2])
        assert w.frames_written == 0
        w.write_frame(0, x, v)
        with pytest.raises(ValueError, match="frame"):
            w.write_frame(0, x, v)  # no rewriting
    assert validate_stage(tmp_path / "run.usdc") == []


def test_close_without_frames_raises(tmp_path):
    with pytest.raises(ValueError, match="no frames"):
        with StageWriter(tmp_path / "run.usdc", 100, make_layout()):
            pass
    assert listing(tmp_path) == []


def test_layout_validation(tmp_path):
    with pytest.raises(ValueError, match="widths"):
        bad = PointsGroup("a", 0, 3, np.ones(2), (1, 1, 1))
        StageWriter(tmp_path / "x.usdc", 24, StageLayout(points_groups=(bad,)))
    with pytest.raises(ValueError, match="unique"):
        groups = tuple(PointsGroup(name, i, 1, np.ones(1), (1, 1, 1)) for i, name in enumerate(["a b", "a_b"]))
        StageWriter(tmp_path / "x.usdc", 24, StageLayout(points_groups=groups))


def test_validate_stage(tmp_path):
    path = tmp_path / "run.usdc"
    write(path, count=3)
    assert validate_stage(path) == []
    assert validate_stage(Usd.Stage.Open(str(path))) == []
    bare = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(bare, "/World")
    errors = validate_stage(bare)  # no upAxis, metersPerUnit, defaultPrim
    assert any("upAxis" in e for e in errors) and any("defaultPrim" in e for e in errors)


def test_path_without_extension_gets_usdc(tmp_path):
    layout = StageLayout(points_groups=(PointsGroup("p", 0, 1, np.array([0.02]), (1.0, 0.0, 0.0)),))
    with StageWriter(tmp_path / "scene", 24.0, layout) as writer:
        writer.write_frame(0, np.zeros((1, 3)), np.zeros((1, 3)))
    assert writer.path == tmp_path / "scene.usdc"
    assert (tmp_path / "scene.usdc").read_bytes()[:8] == b"PXR-USDC"

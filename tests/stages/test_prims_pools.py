"""Pooled particle groups in StageWriter: Points whose count follows the live slots, read back with pxr."""

import math
import os

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from warp_sim.stages import BodySpec, PlaneSpec, PointsGroup, StageLayout, StageWriter, validate_stage

FIXED = PointsGroup("grains", 0, 3, np.full(3, 0.04), (0.9, 0.8, 0.1))
POOL = PointsGroup("sparks", 3, 12, pooled=True)   # slots 3 .. 14
POOL_ONLY = StageLayout(points_groups=(POOL,))
N = 16                                             # one trailing row used by no prim
COUNTS = (0, 3, 10, 7, 0, 5)                       # live slots per frame
POOL_ARRAYS = ("particle_alive", "particle_id", "particle_radius", "particle_color", "particle_opacity")
ATTRS = ("points", "ids", "widths", "velocities", "primvars:displayColor", "primvars:displayOpacity")
BODIES = (BodySpec("ball", 1, "sphere", (0.1,)), BodySpec("crate", 0, "box", (0.1, 0.2, 0.3)))


def pool_frame(rng, count, pool=POOL, n=N, int_alive=False):
    """Keyword arrays of one frame with ``count`` random live slots; dead slots hold NaN, inf and out-of-range junk."""
    slots = np.arange(pool.start, pool.start + pool.count)
    live = np.sort(rng.choice(slots, count, replace=False))
    alive = np.zeros(n, dtype=np.int32 if int_alive else bool)
    alive[live] = 7 if int_alive else True  # any nonzero int is alive
    dead = np.setdiff1d(slots, live)
    arrays = {"particle_x": rng.normal(size=(n, 3)), "particle_v": rng.normal(size=(n, 3)).astype(np.float32),
              "particle_alive": alive, "particle_id": rng.permutation(n).astype(np.int64) + 2**40,
              "particle_radius": rng.uniform(0.01, 0.05, n), "particle_color": rng.uniform(0, 1, (n, 3)),
              "particle_opacity": rng.uniform(0, 1, n).astype(np.float32)}
    arrays["particle_x"][dead] = np.nan
    arrays["particle_v"][dead] = np.inf
    arrays["particle_id"][dead] = -1  # duplicated, but dead
    arrays["particle_radius"][dead] = -1.0
    arrays["particle_color"][dead] = np.nan
    arrays["particle_opacity"][dead] = 2.0
    return arrays


def pool_frames(counts=COUNTS, seed=0, **kw):
    rng = np.random.default_rng(seed)
    return [pool_frame(rng, c, int_alive=bool(k % 2), **kw) for k, c in enumerate(counts)]


def write(path, data, layout=POOL_ONLY, chunk_frames=240):
    with StageWriter(path, 50.0, layout, chunk_frames=chunk_frames) as w:
        for k, arrays in enumerate(data):
            w.write_frame(k, **arrays)
    return data


def points(stage, name="sparks"):
    return UsdGeom.Points(stage.GetPrimAtPath(f"/World/Particles/{name}"))


def listing(folder):
    return sorted(os.listdir(folder))


def check_pool(stage, data, pool=POOL):
    """Every frame's samples are exactly the live slots, in slot order."""
    pts = points(stage, pool.name)
    primvars = UsdGeom.PrimvarsAPI(pts)
    for name in ("displayColor", "displayOpacity"):
        assert primvars.GetPrimvar(name).GetInterpolation() == UsdGeom.Tokens.vertex
    assert pts.GetIdsAttr().GetTypeName() == Sdf.ValueTypeNames.Int64Array
    attrs = [pts.GetPrim().GetAttribute(a) for a in (*ATTRS, "extent")]
    for attr in attrs:
        assert attr.GetTimeSamples() == [float(k) for k in range(len(data))], attr.GetName()
    for k, a in enumerate(data):
        live = np.flatnonzero(a["particle_alive"][pool.start:pool.start + pool.count]) + pool.start
        got = {name: np.asarray(pts.GetPrim().GetAttribute(name).Get(k)) for name in ATTRS}
        assert {name: len(v) for name, v in got.items()} == dict.fromkeys(ATTRS, len(live)), k
        assert got["ids"].dtype == np.int64
        np.testing.assert_array_equal(got["ids"], a["particle_id"][live])
        np.testing.assert_allclose(got["points"].reshape(-1, 3), a["particle_x"][live], rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(got["velocities"].reshape(-1, 3), a["particle_v"][live])
        np.testing.assert_allclose(got["widths"], 2 * a["particle_radius"][live], rtol=1e-6)
        np.testing.assert_allclose(got["primvars:displayColor"].reshape(-1, 3), a["particle_color"][live], rtol=1e-6)
        np.testing.assert_array_equal(got["primvars:displayOpacity"], a["particle_opacity"][live])
        extent = pts.GetExtentAttr().Get(k)
        bound = UsdGeom.BBoxCache(k, [UsdGeom.Tokens.default_]).ComputeLocalBound(pts.GetPrim()).GetRange()
        if live.size:
            x, r = a["particle_x"][live], a["particle_radius"][live, None]
            np.testing.assert_allclose(np.asarray(extent), [(x - r).min(0), (x + r).max(0)], rtol=1e-5, atol=1e-6)
            np.testing.assert_allclose(np.array(bound.GetMin()), (x - r).min(0), rtol=1e-5, atol=1e-6)
        else:  # blocked, not held from a neighbouring frame: the bounds are computed, and empty
            assert extent is None
            assert bound.IsEmpty()


@pytest.mark.parametrize("ext", [".usdc", ".usda"])
def test_live_count_changes_per_frame(tmp_path, ext):
    path = tmp_path / f"pool{ext}"
    data = write(path, pool_frames(), chunk_frames=4)  # a chunk save mid-run
    stage = Usd.Stage.Open(str(path))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 5.0)
    assert [len(points(stage).GetPointsAttr().Get(k)) for k in range(6)] == list(COUNTS)
    check_pool(stage, data)
    assert validate_stage(path) == []


def test_full_and_single_slot_pools(tmp_path):
    rng = np.random.default_rng(1)
    data = [pool_frame(rng, c) for c in (12, 1, 12)]
    path = tmp_path / "pool.usdc"
    static = PointsGroup(POOL.name, POOL.start, POOL.count, np.full(12, 0.5), (1.0, 0.0, 0.0), pooled=True)
    write(path, data, StageLayout(points_groups=(static,)))  # a pool's widths and color are unused
    check_pool(Usd.Stage.Open(str(path)), data)
    assert validate_stage(path) == []


def test_mixed_layout(tmp_path):
    path = tmp_path / "mixed.usdc"
    layout = StageLayout(points_groups=(FIXED, POOL), springs=np.array([[0, 1], [1, 2]]),
                         planes=(PlaneSpec("ground", (0.0, 1.0, 0.0), 0.0),), bodies=BODIES)
    rng = np.random.default_rng(2)
    data = pool_frames()
    bodies = [(rng.normal(size=(2, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))) for _ in data]
    with StageWriter(path, 30, layout, chunk_frames=2) as w:
        for k, (a, (bx, bq)) in enumerate(zip(data, bodies)):
            pool = {name: a[name] for name in POOL_ARRAYS}
            w.write_frame(k, a["particle_x"], a["particle_v"], bx, bq, **pool)  # positional still works
    stage = Usd.Stage.Open(str(path))
    check_pool(stage, data)
    fixed = points(stage, "grains")
    assert not UsdGeom.PrimvarsAPI(fixed).GetPrimvar("displayOpacity").HasAuthoredValue()
    translate = stage.GetAttributeAtPath("/World/Bodies/ball.xformOp:translate")
    for k, a in enumerate(data):
        np.testing.assert_allclose(np.asarray(fixed.GetPointsAttr().Get(k)), a["particle_x"][:3], rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(np.asarray(fixed.GetIdsAttr().Get(k)), [0, 1, 2])
        np.testing.assert_allclose(np.asarray(fixed.GetWidthsAttr().Get(k)), FIXED.widths, rtol=1e-6)
        np.testing.assert_array_equal(np.array(translate.Get(k)), bodies[k][0][1])
    assert validate_stage(path) == []


@pytest.mark.parametrize("name", POOL_ARRAYS)
def test_missing_pool_array_raises(tmp_path, name):
    arrays = pool_frames()[1]
    del arrays[name]
    with StageWriter(tmp_path / "pool.usdc", 50, POOL_ONLY) as w:
        with pytest.raises(ValueError, match=rf"^frame 0: {name} is required: the layout has pooled PointsGroup"):
            w.write_frame(0, **arrays)
        assert w.frames_written == 0
        w.write_frame(0, **pool_frames()[1])


def test_layout_without_pools_needs_no_pool_arrays(tmp_path):
    path = tmp_path / "fixed.usdc"
    a = {name: np.nan_to_num(v, posinf=0.5) for name, v in pool_frames()[2].items()}  # no slot is dead here
    with StageWriter(path, 50, StageLayout(points_groups=(FIXED,))) as w:
        w.write_frame(0, a["particle_x"], a["particle_v"])
        w.write_frame(1, **a)  # given anyway: checked, not needed
    assert validate_stage(path) == []


@pytest.mark.parametrize("name,value,message", [
    ("particle_x", math.nan, "non-finite value"), ("particle_v", -math.inf, "non-finite value"),
    ("particle_radius", math.nan, "non-finite value"), ("particle_color", math.nan, "non-finite value"),
    ("particle_opacity", math.inf, "non-finite value"),
    ("particle_radius", -0.01, r"value outside \[0, inf\]"), ("particle_color", 1.5, r"value outside \[0, 1\]"),
    ("particle_color", -1e-3, r"value outside \[0, 1\]"), ("particle_opacity", 1.01, r"value outside \[0, 1\]"),
])
def test_bad_live_value_raises_and_leaves_nothing(tmp_path, name, value, message):
    """Dead slots hold NaN, inf and out-of-range values on every frame; one bad live value rejects the run."""
    path = tmp_path / "pool.usdc"
    data = pool_frames()
    bad = int(np.flatnonzero(data[2]["particle_alive"])[4])  # a live slot
    a = data[2][name]
    if a.ndim == 2:
        a[bad, 1] = value
    else:
        a[bad] = value
    with pytest.raises(ValueError, match=rf"^frame 2: {name} has a {message} at particle index {bad}\b"):
        write(path, data, chunk_frames=1)
    assert not path.exists()
    assert listing(tmp_path) == []


def test_non_finite_in_unused_row_still_raises(tmp_path):
    a = pool_frames()[1]
    a["particle_x"][N - 1] = np.nan  # a row of no prim: checked as before
    with StageWriter(tmp_path / "pool.usdc", 50, POOL_ONLY) as w:
        with pytest.raises(ValueError, match=rf"frame 0: particle_x has a non-finite value at particle index {N - 1}"):
            w.write_frame(0, **a)
        w.write_frame(0, **pool_frames()[1])


def test_nothing_authored_by_a_rejected_frame(tmp_path):
    path = tmp_path / "pool.usdc"
    layout = StageLayout(points_groups=(FIXED, POOL), bodies=BODIES)
    good, bad = pool_frames(counts=(5, 5))
    bad["particle_opacity"][np.flatnonzero(bad["particle_alive"])[-1]] = 1.5  # the last value checked
    bodies = {"body_x": np.zeros((2, 3)), "body_q": np.tile([0.0, 0.0, 0.0, 1.0], (2, 1))}
    with StageWriter(path, 50, layout) as w:
        with pytest.raises(ValueError, match="particle_opacity"):
            w.write_frame(0, **bad, **bodies)
        w.write_frame(0, **good, **bodies)
    stage = Usd.Stage.Open(str(path))
    check_pool(stage, [good])
    assert points(stage, "grains").GetPointsAttr().GetTimeSamples() == [0.0]


def test_bad_pool_arrays(tmp_path):
    base = pool_frames()[2]
    live = np.flatnonzero(base["particle_alive"])
    dup_id = base["particle_id"].copy()
    dup_id[live[3]] = dup_id[live[1]]
    cases = [
        ({"particle_alive": base["particle_alive"].astype(np.float32)}, "particle_alive must hold bools or integers"),
        ({"particle_alive": base["particle_alive"][:, None]}, r"particle_alive must have shape \(N,\)"),
        ({"particle_alive": base["particle_alive"][:10]}, r"particle_alive must have shape \(N,\) with N >= 15"),
        ({"particle_alive": np.ones(N + 1, bool)}, f"particle_x has {N} rows but particle_alive has {N + 1}"),
        ({"particle_id": base["particle_id"].astype(np.float64)}, "particle_id must hold integers, got dtype float64"),
        ({"particle_id": dup_id}, (rf"particle_id {dup_id[live[1]]} is used by more than one live particle, "
                                   rf"at particle indices {live[1]} and {live[3]}")),
        ({"particle_radius": base["particle_radius"][:-1]}, f"particle_radius has {N - 1} rows but particle_alive"),
        ({"particle_color": base["particle_color"][:, :2]}, r"particle_color must have shape \(N, 3\)"),
        ({"particle_opacity": base["particle_opacity"][:, None]}, r"particle_opacity must have shape \(N,\)"),
    ]
    with StageWriter(tmp_path / "pool.usdc", 50, POOL_ONLY) as w:
        for change, match in cases:
            with pytest.raises(ValueError, match=rf"^frame 0: {match}"):
                w.write_frame(0, **(base | change))
        assert w.frames_written == 0
        w.write_frame(0, **base)


@pytest.mark.parametrize("layout,message", [
    (StageLayout(points_groups=(PointsGroup("p", 0, 4),)),
     "PointsGroup 'p': widths and color are required for a fixed"),
    (StageLayout(points_groups=(PointsGroup("p", 0, 0, pooled=True),)), "count >= 1"),
    (StageLayout(points_groups=(POOL, PointsGroup("p", 14, 2, np.ones(2), (1, 1, 1)))),
     (r"pooled group '/World/Particles/sparks': its slots 3 \.\. 14 must not be read by other prims, "
      r"got /World/Particles/p$")),
    (StageLayout(points_groups=(FIXED, POOL), springs=np.array([[0, 1], [2, 3]])),
     r"its slots 3 \.\. 14 must not be read by other prims, got /World/Springs$"),
])
def test_bad_pool_layouts(tmp_path, layout, message):
    with pytest.raises(ValueError, match=message):
        StageWriter(tmp_path / "bad.usdc", 50, layout)
    assert listing(tmp_path) == []

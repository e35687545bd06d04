"""Cloth and soft-body meshes on the USD stage: MeshSpec, the mesh prim writer, and stage_layout's meshes."""

import numpy as np
import pytest
import trimesh
from pxr import Usd, UsdGeom

import warp_sim as ws
from warp_sim.stages import MeshSpec, PointsGroup, StageLayout, StageWriter, stage_layout, validate_stage

N = 9
# a 3 x 2 quad sheet on particles 2 .. 7, and a triangle + quad on particles 5 .. 8 (meshes may share particles)
SHEET = MeshSpec("cloth sheet", 2, 6, np.array([4, 4]), np.array([0, 1, 4, 3, 1, 2, 5, 4]), (0.9, 0.1, 0.2))
MIXED = MeshSpec("mixed", 5, 4, np.array([3, 4]), np.array([0, 1, 2, 0, 2, 3, 1]), (0.0, 0.5, 1.0))


def layout(meshes=(SHEET, MIXED), groups=None):
    groups = (PointsGroup("balls", 0, 2, np.full(2, 0.1), (1.0, 1.0, 1.0)),) if groups is None else groups
    return StageLayout(points_groups=groups, meshes=meshes)


def frames(count, seed=0):
    rng = np.random.default_rng(seed)
    return [(rng.normal(size=(N, 3)), rng.normal(size=(N, 3))) for _ in range(count)]


def write(path, count=4, meshes=(SHEET, MIXED)):
    data = frames(count)
    with StageWriter(path, 24.0, layout(meshes)) as w:
        for k, (x, v) in enumerate(data):
            w.write_frame(k, x, v)
    return data


def mesh_prim(stage, name):
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/World/Meshes/{name}"))
    assert mesh, name
    return mesh


def test_topology_once_points_per_frame(tmp_path):
    path = tmp_path / "cloth.usdc"
    data = write(path, count=4)
    stage = Usd.Stage.Open(str(path))
    for spec, name in ((SHEET, "cloth_sheet"), (MIXED, "mixed")):
        mesh = mesh_prim(stage, name)
        for attr in (mesh.GetFaceVertexCountsAttr(), mesh.GetFaceVertexIndicesAttr(),
                     mesh.GetSubdivisionSchemeAttr(), mesh.GetDoubleSidedAttr()):
            assert attr.GetNumTimeSamples() == 0 and attr.HasAuthoredValue(), attr.GetName()
        np.testing.assert_array_equal(np.asarray(mesh.GetFaceVertexCountsAttr().Get()), spec.face_counts)
        np.testing.assert_array_equal(np.asarray(mesh.GetFaceVertexIndicesAttr().Get()), spec.face_indices)
        assert mesh.GetSubdivisionSchemeAttr().Get() == UsdGeom.Tokens.none
        assert mesh.GetDoubleSidedAttr().Get() is True
        color = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor")
        assert color.GetInterpolation() == UsdGeom.Tokens.constant and color.GetAttr().GetNumTimeSamples() == 0
        np.testing.assert_allclose(np.asarray(color.Get()), [spec.color], rtol=1e-6)
        rows = slice(spec.start, spec.start + spec.count)
        for attr in (mesh.GetPointsAttr(), mesh.GetVelocitiesAttr(), mesh.GetExtentAttr()):
            assert attr.GetTimeSamples() == [0.0, 1.0, 2.0, 3.0], attr.GetName()
        for k, (x, v) in enumerate(data):
            points = np.asarray(mesh.GetPointsAttr().Get(k))
            assert points.dtype == np.float32 and points.shape == (spec.count, 3)
            np.testing.assert_allclose(points, x[rows], rtol=1e-6, atol=1e-6)
            np.testing.assert_allclose(np.asarray(mesh.GetVelocitiesAttr().Get(k)), v[rows], rtol=1e-6, atol=1e-6)
            lo, hi = np.asarray(mesh.GetExtentAttr().Get(k))
            np.testing.assert_allclose(lo, x[rows].min(axis=0), rtol=1e-6, atol=1e-6)
            np.testing.assert_allclose(hi, x[rows].max(axis=0), rtol=1e-6, atol=1e-6)
            bound = UsdGeom.Boundable(mesh).ComputeExtent(k)          # extent agrees with USD's own bound
            np.testing.assert_allclose(np.asarray(bound), [lo, hi], rtol=1e-6, atol=1e-6)
    assert validate_stage(path) == []


def test_meshes_default_empty_and_exported():
    assert StageLayout().meshes == ()
    assert "MeshSpec" in __import__("warp_sim.stages", fromlist=["__all__"]).__all__


@pytest.mark.parametrize("spec,words", [
    (MeshSpec("m", 0, 4, np.array([3, 2]), np.arange(5) % 4), "face_counts"),
    (MeshSpec("m", 0, 4, np.array([3.0]), np.arange(3)), "face_counts"),
    (MeshSpec("m", 0, 4, np.array([], dtype=int), np.array([], dtype=int)), "face_counts"),
    (MeshSpec("m", 0, 4, np.array([4]), np.arange(3)), "face_indices"),
    (MeshSpec("m", 0, 4, np.array([4]), np.array([0, 1, 2, 4])), "face_indices must index its 4 vertices"),
    (MeshSpec("m", 0, 4, np.array([4]), np.array([0, 1, 2, -1])), "face_indices must index"),
    (MeshSpec("m", 0, 4, np.array([4]), np.array([0.0, 1.0, 2.0, 3.0])), "face_indices"),
    (MeshSpec("m", -1, 4, np.array([4]), np.arange(4)), "start"),
    (MeshSpec("m", 0, 2, np.array([3]), np.array([0, 1, 1])), "count"),
    (MeshSpec("m", 0, 4.0, np.array([4]), np.arange(4)), "count"),
    (MeshSpec("m", 0, 4, np.array([4]), np.arange(4), (1.0, 0.0)), "color"),
])
def test_bad_mesh_specs_rejected(tmp_path, spec, words):
    with pytest.raises(ValueError, match=f"MeshSpec 'm'.*{words}"):
        StageWriter(tmp_path / "bad.usdc", 24.0, StageLayout(meshes=(spec,)))
    assert list(tmp_path.iterdir()) == []


def test_mesh_names_unique_and_pools_not_shared(tmp_path):
    twin = MeshSpec("cloth_sheet", 0, 3, np.array([3]), np.arange(3))
    with pytest.raises(ValueError, match="duplicated prim paths"):
        StageWriter(tmp_path / "a.usdc", 24.0, layout(meshes=(SHEET, twin)))
    pool = PointsGroup("sparks", 0, 4, pooled=True)
    with pytest.raises(ValueError, match="sparks.*must not be read.*Meshes/cloth_sheet"):
        StageWriter(tmp_path / "b.usdc", 24.0, layout(meshes=(SHEET,), groups=(pool,)))


def test_mesh_needs_its_particles(tmp_path):
    with StageWriter(tmp_path / "short.usdc", 24.0, layout()) as w:
        with pytest.raises(ValueError, match=r"particle_x must have shape \(N, 3\) with N >= 9"):
            w.write_frame(0, np.zeros((8, 3)), np.zeros((8, 3)))
        w.write_frame(0, np.zeros((N, 3)), np.zeros((N, 3)))


def cloth_scene():
    scene = ws.Scene(precision="float64")
    scene.add_particles([[0.0, 2.0, 0.0], [0.5, 2.0, 0.0]], name="balls")
    scene.add_cloth_grid(resolution=(4, 3), size=(1.0, 0.5), position=(0.0, 1.0, 0.0), pinned="top_corners",
                         stiffness=(200.0, 200.0, 20.0), damping=(0.5, 0.5, 0.05), mass=0.1, name="flag",
                         color=(0.2, 0.4, 0.6))
    scene.add_soft_mesh(trimesh.creation.box(extents=(0.2, 0.2, 0.2)), mass=0.5, stiffness=500.0,
                        position=(1.0, 0.5, 0.0), name="jelly")
    return scene


def test_stage_layout_draws_meshes_not_their_points():
    """A cloth's or soft body's particles are drawn as its mesh only: stage_layout leaves their groups out
    of the Points (the writer would draw them twice)."""
    scene = cloth_scene()
    result = stage_layout(scene)
    assert [g.name for g in result.points_groups] == ["balls"]
    assert [m.name for m in result.meshes] == ["flag", "jelly"]
    for spec, mesh in zip(result.meshes, scene.meshes):
        assert (spec.start, spec.count, spec.color) == (mesh.start, mesh.count, mesh.color)
        np.testing.assert_array_equal(spec.face_counts, mesh.face_counts)
        np.testing.assert_array_equal(spec.face_indices, mesh.face_indices)
    assert result.meshes[0].start == 2 and result.meshes[1].start == 14
    plain = ws.Scene()
    plain.add_particles([[0.0, 0.0, 0.0]])
    assert stage_layout(plain).meshes == () and len(stage_layout(plain).points_groups) == 1


def test_simulated_cloth_stage(tmp_path):
    scene = cloth_scene()
    x0 = scene.particle_array("position")
    sim = ws.Simulator(scene, integrator="rk4", device="cpu")
    path = sim.run(0.1, fps=30.0, substeps=10, usd=tmp_path / "flag.usdc", progress=False)
    stage = Usd.Stage.Open(str(path))
    assert not stage.GetPrimAtPath("/World/Particles/flag") and not stage.GetPrimAtPath("/World/Particles/jelly")
    assert stage.GetPrimAtPath("/World/Particles/balls")
    x = sim.state.particle_x.numpy()
    for mesh in scene.meshes:
        prim = mesh_prim(stage, mesh.name)
        rows = slice(mesh.start, mesh.start + mesh.count)
        assert prim.GetPointsAttr().GetTimeSamples() == [0.0, 1.0, 2.0]
        assert prim.GetFaceVertexIndicesAttr().GetNumTimeSamples() == 0
        np.testing.assert_allclose(np.asarray(prim.GetPointsAttr().Get(0)), x0[rows], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(np.asarray(prim.GetPointsAttr().Get(2)), x[rows], rtol=1e-6, atol=1e-6)
    flag = mesh_prim(stage, "flag")
    assert not np.allclose(np.asarray(flag.GetPointsAttr().Get(2)), x0[2:14], atol=1e-3)   # the free cloth fell
    assert validate_stage(path) == []

"""The `warp-sim demo` command's stage and the stages Simulator.run writes (the command line itself: test_cli.py)."""
import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdPhysics

import warp_sim as ws
from warp_sim.cli import main
from warp_sim.stages import validate_stage


@pytest.fixture(scope="module")
def demo_stage(tmp_path_factory):
    path = tmp_path_factory.mktemp("demo") / "demo.usdc"
    assert main(["demo", "--seconds", "0.5", "--fps", "60", "--substeps", "4", "--out", str(path),
                 "--no-progress", "--device", "cpu"]) == 0
    return Usd.Stage.Open(str(path)), path


def test_demo_stage_validates_with_design_metadata(demo_stage):
    stage, path = demo_stage
    assert path.read_bytes()[:8] == b"PXR-USDC"
    assert validate_stage(stage) == []
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdPhysics.GetStageKilogramsPerUnit(stage) == 1.0
    assert stage.GetTimeCodesPerSecond() == stage.GetFramesPerSecond() == 60.0
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 29.0)
    assert stage.GetDefaultPrim().GetPath() == "/World"


def test_demo_has_one_sample_per_frame_and_static_ground(demo_stage):
    stage, _ = demo_stage
    for name in ("balls", "chain"):
        points = UsdGeom.Points(stage.GetPrimAtPath(f"/World/Particles/{name}"))
        assert points.GetPointsAttr().GetTimeSamples() == list(range(30))
        assert len(points.GetVelocitiesAttr().GetTimeSamples()) == 30
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Springs"))
    assert len(curves.GetPointsAttr().GetTimeSamples()) == 30
    assert list(curves.GetCurveVertexCountsAttr().Get()) == [2] * 20
    ground = stage.GetPrimAtPath("/World/Planes/Ground")
    assert ground.IsValid()
    assert all(attr.GetNumTimeSamples() == 0 for attr in ground.GetAttributes())


def test_demo_balls_stay_above_ground_and_chain_anchor_stays_put(demo_stage):
    stage, _ = demo_stage
    balls = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/balls")).GetPointsAttr()
    chain = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/chain")).GetPointsAttr()
    for t in range(30):
        assert np.array(balls.Get(t))[:, 1].min() >= 0.03 - 1e-5     # radius 3 cm on y = 0
        np.testing.assert_allclose(np.array(chain.Get(t))[0], (2.5, 3.0, 0.0), atol=1e-6)


def test_demo_bodies_fly_the_projectile_and_tumble(demo_stage):
    """Each thrown body is an Xform whose translate follows the projectile with linear drag c in
    a wind w, x0 + (v0 - u)(1 - exp(-k t))/k + u t with k = c / M and u = w + g / k (float32, rk4),
    and whose orient changes; its shape is a child gprim with no time samples."""
    from warp_sim.demo import THROWN_BODIES, WIND, demo_scene

    stage, _ = demo_stage
    bodies = {body.name: body for body in demo_scene().bodies}
    for name, _, position, velocity, _ in THROWN_BODIES:
        prim = stage.GetPrimAtPath(f"/World/Bodies/{name}")
        assert prim.GetTypeName() == "Xform"
        translate, orient = UsdGeom.Xformable(prim).GetOrderedXformOps()
        assert translate.GetTimeSamples() == list(range(30)) == orient.GetTimeSamples()
        t = 29 / 60.0
        k, g = bodies[name].drag / bodies[name].mass.mass, np.array([0.0, -9.81, 0.0])
        u = np.array(WIND) + g / k
        expected = np.array(position) + (np.array(velocity) - u) * (1 - np.exp(-k * t)) / k + u * t
        np.testing.assert_allclose(np.array(translate.Get(29)), expected, atol=2e-5)
        assert orient.Get(0) != orient.Get(29)
        children = prim.GetChildren()
        assert len(children) == 1 and all(a.GetNumTimeSamples() == 0 for a in children[0].GetAttributes())
    assert stage.GetPrimAtPath("/World/Bodies/torus").GetChildren()[0].GetTypeName() == "Mesh"


@pytest.mark.parametrize("fps, seconds, frames", [(100.0, 0.3, 30), (29.97, 1.0, 30), (24.0, 0.5, 12)])
def test_frame_count_and_time_codes_are_exact(tmp_path, fps, seconds, frames):
    scene = ws.Scene()
    scene.add_particles([[0.0, 1.0, 0.0]])
    sim = ws.Simulator(scene, integrator="verlet", device="cpu")
    path = sim.run(seconds=seconds, fps=fps, substeps=2, usd=tmp_path / "run.usda", progress=False)
    stage = Usd.Stage.Open(str(path))
    points = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/group0")).GetPointsAttr()
    assert points.GetTimeSamples() == list(range(frames))
    assert stage.GetTimeCodesPerSecond() == pytest.approx(fps)
    assert sim.time == pytest.approx((frames - 1) / fps, abs=1e-12)
    # frame k holds the free fall at t = k / fps (verlet is exact for uniform gravity)
    k = frames - 1
    assert np.array(points.Get(k))[0, 1] == pytest.approx(1.0 - 0.5 * 9.81 * (k / fps) ** 2, abs=1e-5)


def test_demo_pile_lands_on_the_ground_and_cloth_stays_off_the_sphere(demo_stage):
    """The pile's spheres never sink into the ground (they rest at their radius, 0.1 m), no box centre falls
    below half its height, and no vertex of the draped cloth gets inside the static sphere it falls on."""
    from warp_sim.demo import DRAPE_SPHERE

    stage, _ = demo_stage
    pile = [prim for prim in stage.GetPrimAtPath("/World/Bodies").GetChildren() if prim.GetName().startswith("pile")]
    assert len(pile) == 12
    for prim in pile:
        translate = UsdGeom.Xformable(prim).GetOrderedXformOps()[0]
        low = 0.1 if prim.GetChildren()[0].GetTypeName() == "Sphere" else 0.06
        assert min(translate.Get(t)[1] for t in range(30)) >= low - 1e-3
    collider = stage.GetPrimAtPath("/World/Colliders/drape_sphere")
    assert collider.IsValid()
    assert all(attr.GetNumTimeSamples() == 0 for attr in collider.GetAttributes())
    centre, radius = DRAPE_SPHERE
    drape = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Meshes/drape")).GetPointsAttr()
    for t in range(30):
        points = np.array(drape.Get(t))
        assert np.linalg.norm(points - centre, axis=1).min() >= radius + 0.01 - 1e-4

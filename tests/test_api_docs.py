"""docs/api.md is what tools/api_docs.py writes now (so CI fails when a public signature or docstring changes
without it), it names every name of warp_sim.__all__, its generation is deterministic (another hash seed gives
the same page) and cheap; and the claims of its units and conventions table hold in the code: quaternion orders
in Python and in USD, the flat cloth's orientation, half and full sizes, degrees in USD."""
import math
import pathlib
import re
import subprocess
import sys
import time

import numpy as np
import pytest
from helpers import load_tool
from pxr import Gf, Usd, UsdGeom, UsdPhysics, Vt

import warp_sim as ws

pytest.importorskip("pdoc", reason="tools/api_docs.py needs pdoc (the test and docs extras)")

ROOT = pathlib.Path(__file__).resolve().parent.parent
FIX = "python tools/api_docs.py"


api_docs = load_tool("api_docs")


@pytest.fixture(scope="module")
def page() -> str:
    start = time.perf_counter()
    text = api_docs.render()
    seconds = time.perf_counter() - start
    assert seconds < 10.0, f"rendering docs/api.md took {seconds:.1f} s"
    return text


def test_api_md_is_up_to_date(page):
    saved = api_docs.DOCS.read_text(encoding="utf-8") if api_docs.DOCS.exists() else ""
    if saved != page:
        diff = "".join(api_docs.check()[:60])
        pytest.fail(f"docs/api.md is out of date: run `{FIX}` and commit it. First lines of the diff:\n{diff}",
                    pytrace=False)


def test_every_public_name_has_a_section_and_an_index_row(page):
    missing = [name for name in ws.__all__ if f"\n## {name}\n" not in page or f"[`{name}`](#" not in page]
    assert not missing, f"docs/api.md lacks {missing}: run `{FIX}`"


def test_public_methods_are_listed_with_their_signatures(page):
    assert "- `add_cloth_grid(resolution=(32, 32), size=(1.0, 1.0)," in page
    assert "- `step(dt: float, steps: int = 1" in page
    assert "\n## Units and conventions\n" in page
    assert not re.search(r"\b0x[0-9a-f]{6,}\b", page)


def test_the_page_is_the_same_under_another_hash_seed():
    start = time.perf_counter()
    done = subprocess.run([sys.executable, str(ROOT / "tools" / "api_docs.py"), "--check"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120, env={**__import__("os").environ,
                                                                               "PYTHONHASHSEED": "12345"})
    seconds = time.perf_counter() - start
    assert done.returncode == 0, f"{done.stdout[-3000:]}\n{done.stderr[-2000:]}\n(run `{FIX}`)"
    assert seconds < 10.0, f"python tools/api_docs.py --check took {seconds:.1f} s"


# -- the conventions table, against the code ---------------------------------------------------------------------

FLAT = (-0.7071067811865476, 0.0, 0.0, 0.7071067811865476)


def test_the_flat_cloth_quaternion_is_the_demos_and_lays_the_grid_flat_facing_up():
    assert str(FLAT) in (ROOT / "warp_sim" / "demo.py").read_text()
    assert any(str(FLAT) in " ".join(row) for row in api_docs.CONVENTIONS)
    scene = ws.Scene()
    upright = scene.add_cloth_grid(resolution=(4, 3), size=(1.5, 1.0), position=(0.0, 1.0, 0.0))
    flat = scene.add_cloth_grid(resolution=(4, 3), size=(1.5, 1.0), position=(0.0, 1.0, 0.0), orientation=FLAT)
    x = scene.particle_array("position")
    assert upright.shape == (3, 4)                                      # (ny, nx): resolution counts vertices
    np.testing.assert_allclose(np.ptp(x[upright][..., 0]), 1.5)        # size is the full width ...
    np.testing.assert_allclose(np.ptp(x[upright][..., 1]), 1.0)        # ... and height
    assert x[upright][0, 0, 0] < x[upright][0, -1, 0] and x[upright][0, 0, 1] < x[upright][-1, 0, 1]
    np.testing.assert_allclose(x[upright][..., 2], 0.0)                # upright: the local x-y plane
    np.testing.assert_allclose(x[flat][..., 1], 1.0, atol=1e-12)       # flat: every vertex at the same height
    assert x[flat][-1, 0, 2] < x[flat][0, 0, 2]                        # the top row towards -Z
    mesh = scene.meshes[-1]
    faces = mesh.start + np.asarray(mesh.face_indices).reshape(-1, 4)           # indices within the mesh
    a, b, c = x[faces[0, 0]], x[faces[0, 1]], x[faces[0, 2]]
    normal = np.cross(b - a, c - a)
    assert normal[1] > 0 and np.allclose(normal[[0, 2]], 0.0, atol=1e-12)   # facing +Y
    assert len(faces) == (4 - 1) * (3 - 1)


def test_box_takes_half_extents():
    box = ws.Box((0.1, 0.2, 0.3))
    assert box.mass_properties(density=1000.0).mass == pytest.approx(1000.0 * 0.2 * 0.4 * 0.6)
    capsule = ws.Capsule(radius=0.1, half_height=0.2)
    assert capsule.bounding_radius == pytest.approx(0.3)              # half_height + radius along Y


def test_usd_quaternions_heights_and_degrees(tmp_path):
    q = np.array([0.1, 0.2, 0.3, 0.9]) / np.linalg.norm([0.1, 0.2, 0.3, 0.9])   # (x, y, z, w)
    omega = (0.0, 2.0, 0.0)                                                     # [rad/s]
    scene = ws.Scene()
    scene.add_ground()
    scene.add_rigid_body(ws.Capsule(radius=0.1, half_height=0.25), position=(0, 1, 0), orientation=q,
                         angular_velocity=omega, name="capsule")
    scene.add_rigid_body(ws.Box((0.1, 0.2, 0.3)), position=(1, 1, 0), name="box")
    scene.add_particles([(0.0, 2.0, 0.0)], radius=0.05, name="drop")
    scene.add_emitter(spread=30.0, name="fountain")
    stage = Usd.Stage.Open(scene.to_usd(str(tmp_path / "scene.usda")))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    body = stage.GetPrimAtPath("/World/Bodies/capsule")
    orient = UsdGeom.Xformable(body).GetOrderedXformOps()[1]
    assert orient.GetOpName() == "xformOp:orient"
    value = orient.Get()                                                        # Gf.Quatf(w, x, y, z)
    assert value.GetReal() == pytest.approx(q[3], abs=1e-6)
    np.testing.assert_allclose(list(value.GetImaginary()), q[:3], atol=1e-6)
    spin = UsdPhysics.RigidBodyAPI(body).GetAngularVelocityAttr().Get()           # [deg/s]
    np.testing.assert_allclose(list(spin), np.degrees(omega), rtol=1e-5, atol=1e-9)
    capsule = UsdGeom.Capsule(stage.GetPrimAtPath("/World/Bodies/capsule/collision"))
    assert capsule.GetAxisAttr().Get() == "Y" and capsule.GetHeightAttr().Get() == pytest.approx(0.5)
    cube = UsdGeom.Cube(stage.GetPrimAtPath("/World/Bodies/box/collision"))
    assert cube.GetSizeAttr().Get() == 2.0
    np.testing.assert_allclose(list(cube.GetOrderedXformOps()[0].Get()), (0.1, 0.2, 0.3), rtol=1e-6)
    widths = UsdGeom.Points(stage.GetPrimAtPath("/World/Particles/drop")).GetWidthsAttr().Get()
    assert list(widths) == pytest.approx([0.1])                                # diameters
    spreads = [p.GetAttribute("warpSim:spread").Get() for p in stage.Traverse() if p.HasAttribute("warpSim:spread")]
    assert spreads == [pytest.approx(30.0)]                                    # degrees, as in Python
    # the memory order Vt.QuatfArray.FromNumpy reads: (x, y, z, w) rows go in unchanged
    row = Vt.QuatfArray.FromNumpy(np.array([q], dtype=np.float32))[0]
    assert row.GetReal() == pytest.approx(q[3], abs=1e-6) and row == Gf.Quatf(*map(float, (q[3], *q[:3])))


def test_the_preview_camera_takes_degrees():
    from warp_sim import preview

    camera = preview.Camera.framing(np.array([-1.0, 0.0, -1.0]), np.array([1.0, 2.0, 1.0]), azimuth=90.0,
                                    elevation=0.0)
    direction = np.subtract(camera.eye, camera.target)
    assert abs(direction[1]) < 1e-9 and math.isclose(abs(direction[0]) + abs(direction[2]),
                                                     np.linalg.norm(direction), rel_tol=1e-9)
    assert min(abs(direction[0]), abs(direction[2])) < 1e-9 * np.linalg.norm(direction)   # 90 degrees: on an axis

"""Bad values in a stage, named where they enter (scene/usd_values.py): each malformed stage, authored with pxr as a
DCC tool saves it, is one ValueError naming the prim (or the stage's metadata key), the attribute and the value, on
one line, and ``warp-sim run`` prints exactly that line, with no traceback and no output written. usd-core alone
would replace most of them quietly (a mass of -1 kg became 8 kg, a cube of size -0.2 one of 0.2) or fail with a
KeyError, TypeError, IndexError or "Singular matrix" that names nothing."""
import math
import os
import shutil
import subprocess
import sys
import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade

import warp_sim as ws
from warp_sim.cli import main


def new_stage(path, meters=1.0):
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, meters)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    UsdPhysics.Scene.Define(stage, "/World/physicsScene")
    return stage


def box(stage, path="/World/box", size=0.2, at=(0.0, 1.0, 0.0)):
    geom = UsdGeom.Cube.Define(stage, path)
    geom.CreateSizeAttr(size)
    geom.AddTranslateOp().Set(Gf.Vec3d(*at))
    UsdPhysics.RigidBodyAPI.Apply(geom.GetPrim())
    UsdPhysics.CollisionAPI.Apply(geom.GetPrim())
    return geom.GetPrim()


def body(stage, kind, path, **attributes):
    geom = kind.Define(stage, path)
    for name, value in attributes.items():
        geom.GetPrim().GetAttribute(name).Set(value)
    UsdPhysics.RigidBodyAPI.Apply(geom.GetPrim())
    UsdPhysics.CollisionAPI.Apply(geom.GetPrim())
    return geom.GetPrim()


def flag(prim, name, type_name=Sdf.ValueTypeNames.Bool, value=True):
    prim.CreateAttribute(name, type_name, custom=True).Set(value)


def cloth(stage, counts=(4,), indices=(0, 1, 3, 2), points=((0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0))):
    mesh = UsdGeom.Mesh.Define(stage, "/World/flag")
    flag(mesh.GetPrim(), "warpSim:cloth")
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in points])
    mesh.CreateFaceVertexCountsAttr(list(counts))
    mesh.CreateFaceVertexIndicesAttr(list(indices))
    return mesh.GetPrim()


def drops(stage, points=((0, 1, 0), (0, 2, 0)), **attributes):
    prim = UsdGeom.Points.Define(stage, "/World/drops").GetPrim()
    flag(prim, "warpSim:particles")
    if points is not None:
        UsdGeom.Points(prim).CreatePointsAttr([Gf.Vec3f(*p) for p in points])
    for name, (type_name, value) in attributes.items():
        prim.CreateAttribute(name, type_name, custom=name.startswith("warpSim:")).Set(value)
    return prim


def scaled(prim, scale):
    UsdGeom.Xformable(prim).AddScaleOp().Set(Gf.Vec3f(*scale))


def look(stage, prim, restitution=0.0, density=None):
    shade = UsdShade.Material.Define(stage, "/World/Looks/look")
    api = UsdPhysics.MaterialAPI.Apply(shade.GetPrim())
    api.CreateRestitutionAttr(restitution)
    api.CreateDynamicFrictionAttr(0.5)
    api.CreateStaticFrictionAttr(0.5)
    if density is not None:
        api.CreateDensityAttr(density)
    UsdShade.MaterialBindingAPI.Apply(prim).Bind(shade, UsdShade.Tokens.weakerThanDescendants, "physics")


def kinematic_nan(stage):
    prim = box(stage)
    UsdPhysics.RigidBodyAPI(prim).CreateKinematicEnabledAttr(True)
    op = UsdGeom.Xformable(prim).GetOrderedXformOps()[0]
    op.Set(Gf.Vec3d(0, 1, 0), 0.0)
    op.Set(Gf.Vec3d(0, math.nan, 0), 10.0)
    box(stage, "/World/other", at=(0, 3, 0))


NAN, INF = math.nan, math.inf
#: name -> (what to author, the prim (or the file, for metadata) named, the attribute or key, the value shown)
CASES = {
    "negative mass": (lambda st: UsdPhysics.MassAPI.Apply(box(st)).CreateMassAttr(-1.0),
                      "/World/box", "physics:mass", "-1"),
    "non-finite mass": (lambda st: UsdPhysics.MassAPI.Apply(box(st)).CreateMassAttr(NAN),
                        "/World/box", "physics:mass", "nan"),
    "negative density": (lambda st: UsdPhysics.MassAPI.Apply(box(st)).CreateDensityAttr(-5.0),
                         "/World/box", "physics:density", "-5"),
    "negative cube size": (lambda st: box(st, size=-0.2), "/World/box", "size", "-0.2"),
    "zero cube size": (lambda st: box(st, size=0.0), "/World/box", "size", "0"),
    "negative radius": (lambda st: body(st, UsdGeom.Sphere, "/World/ball", radius=-0.1), "/World/ball", "radius",
                        "-0.1"),
    "infinite radius": (lambda st: body(st, UsdGeom.Sphere, "/World/ball", radius=INF), "/World/ball", "radius",
                        "inf"),
    "negative capsule height": (lambda st: body(st, UsdGeom.Capsule, "/World/pill", radius=0.1, height=-0.5),
                                "/World/pill", "height", "-0.5"),
    "zero cylinder height": (lambda st: body(st, UsdGeom.Cylinder, "/World/can", radius=0.1, height=0.0),
                             "/World/can", "height", "0"),
    "unknown cylinder axis": (lambda st: body(st, UsdGeom.Cylinder, "/World/can", axis="W"), "/World/can", "axis",
                              "'W'"),
    "zero scale": (lambda st: scaled(box(st), (1, 0, 1)), "/World/box", "xformOp:scale", "(1, 0, 1)"),
    "zero scale of a parent": (lambda st: (scaled(UsdGeom.Xform.Define(st, "/World/group").GetPrim(), (0, 1, 1)),
                                           box(st, "/World/group/box")),
                               "/World/group", "xformOp:scale", "(0, 1, 1)"),
    "non-finite scale": (lambda st: scaled(box(st), (1, NAN, 1)), "/World/box", "xformOp:scale", "(1, nan, 1)"),
    "mirrored scale": (lambda st: scaled(box(st), (1, -1, 1)), "/World/box", "xformOp:scale", "(1, -1, 1)"),
    "NaN translate": (lambda st: box(st, at=(0, NAN, 0)), "/World/box", "xformOp:translate", "(0, nan, 0)"),
    "NaN in a kinematic body's animation": (kinematic_nan, "/World/box", "xformOp:translate", "(0, nan, 0) at time "
                                                                                              "code 10"),
    "metersPerUnit 0": (lambda st: (box(st), UsdGeom.SetStageMetersPerUnit(st, 0.0)), "FILE", "metadata "
                        "metersPerUnit", "0"),
    "negative metersPerUnit": (lambda st: (box(st), UsdGeom.SetStageMetersPerUnit(st, -1.0)), "FILE", "metadata "
                               "metersPerUnit", "-1"),
    "kilogramsPerUnit 0": (lambda st: (box(st), UsdPhysics.SetStageKilogramsPerUnit(st, 0.0)), "FILE", "metadata "
                           "kilogramsPerUnit", "0"),
    "upAxis W": (lambda st: (box(st), st.SetMetadata("upAxis", "W")), "FILE", "metadata upAxis", "'W'"),
    "infinite gravity": (lambda st: (box(st), UsdPhysics.Scene(st.GetPrimAtPath("/World/physicsScene"))
                                     .CreateGravityMagnitudeAttr(1e39)),
                         "/World/physicsScene", "physics:gravityMagnitude", "inf"),
    "negative gravity": (lambda st: (box(st), UsdPhysics.Scene(st.GetPrimAtPath("/World/physicsScene"))
                                     .CreateGravityMagnitudeAttr(-9.81)),
                         "/World/physicsScene", "physics:gravityMagnitude", "-9.81"),
    "diagonal inertia against the triangle inequality": (
        lambda st: UsdPhysics.MassAPI.Apply(box(st)).CreateDiagonalInertiaAttr(Gf.Vec3f(1, 1, 3)),
        "/World/box", "physics:diagonalInertia", "(1, 1, 3)"),
    "negative diagonal inertia": (
        lambda st: UsdPhysics.MassAPI.Apply(box(st)).CreateDiagonalInertiaAttr(Gf.Vec3f(1, -1, 1)),
        "/World/box", "physics:diagonalInertia", "(1, -1, 1)"),
    "NaN centre of mass": (lambda st: UsdPhysics.MassAPI.Apply(box(st)).CreateCenterOfMassAttr(Gf.Vec3f(0, NAN, 0)),
                           "/World/box", "physics:centerOfMass", "(0, nan, 0)"),
    "infinite velocity": (lambda st: UsdPhysics.RigidBodyAPI(box(st)).CreateVelocityAttr(Gf.Vec3f(0, INF, 0)),
                          "/World/box", "physics:velocity", "(0, inf, 0)"),
    "restitution above 1": (lambda st: look(st, box(st), restitution=1.5), "/World/Looks/look", "physics:restitution",
                            "1.5"),
    "negative material density": (lambda st: look(st, box(st), density=-3.0), "/World/Looks/look", "physics:density",
                                  "-3"),
    "faceVertexCounts beyond the indices": (lambda st: cloth(st, counts=(4, 3)), "/World/flag", "faceVertexIndices",
                                            "[0, 1, 3, 2]"),
    "a face index beyond the points": (lambda st: cloth(st, indices=(0, 1, 7, 2)), "/World/flag",
                                       "faceVertexIndices", "[0, 1, 7, 2]"),
    "a NaN cloth point": (lambda st: cloth(st, points=((0, 0, 0), (1, 0, 0), (0, NAN, 0), (1, 1, 0))), "/World/flag",
                          "points", "[(0, 0, 0), (1, 0, 0), (0, nan, 0), (1, 1, 0)]"),
    "a negative cloth mass": (lambda st: flag(cloth(st), "warpSim:mass", Sdf.ValueTypeNames.Float, -2.0),
                              "/World/flag", "warpSim:mass", "-2"),
    "particles without points": (lambda st: drops(st, points=None), "/World/drops", "points", "None"),
    "a negative particle mass": (lambda st: drops(st, **{"warpSim:mass": (Sdf.ValueTypeNames.FloatArray, [-1.0])}),
                                 "/World/drops", "warpSim:mass", "-1"),
    "widths for three of two points": (lambda st: drops(st, widths=(Sdf.ValueTypeNames.FloatArray, [1, 2, 3])),
                                       "/World/drops", "widths", "[1, 2, 3]"),
    "a negative emitter rate": (lambda st: (lambda prim: (flag(prim, "warpSim:emitter"), flag(
        prim, "warpSim:rate", Sdf.ValueTypeNames.Float, -5.0)))(UsdGeom.Xform.Define(st, "/World/fountain").GetPrim()),
        "/World/fountain", "warpSim:rate", "-5"),
}


def author(tmp_path, name):
    build, where, attribute, value = CASES[name]
    path = tmp_path / (name.replace(" ", "_").replace("'", "") + ".usda")
    stage = new_stage(path)
    build(stage)
    stage.Save()
    named = f"{str(path)!r}:" if where == "FILE" else f"{where}:"
    return path, f"{named} {attribute}={value}"


@pytest.mark.parametrize("name", list(CASES))
def test_from_usd_names_the_prim_the_attribute_and_the_value(tmp_path, name):
    path, expected = author(tmp_path, name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ValueError) as caught:
            ws.Scene.from_usd(path)
    message = str(caught.value)
    assert message.startswith(expected) and " is invalid: " in message, message
    assert "\n" not in message


@pytest.mark.parametrize("name", list(CASES))
def test_warp_sim_run_prints_one_line(tmp_path, capsys, name):
    path, expected = author(tmp_path, name)
    out = tmp_path / "anim.usdc"
    assert main(["run", str(path), "--out", str(out), "--no-progress"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"warp-sim: error: {expected}"), lines
    assert not out.exists()


EXE = shutil.which("warp-sim", path=os.path.dirname(sys.executable))


@pytest.mark.parametrize("name", ["upAxis W", "particles without points", "faceVertexCounts beyond the indices",
                                  "zero scale of a parent"])   # were KeyError, TypeError, IndexError, Singular matrix
def test_the_console_script_prints_one_line_without_a_traceback(tmp_path, name):
    path, expected = author(tmp_path, name)
    command = [sys.executable, "-m", "warp_sim"] if EXE is None else [EXE]
    done = subprocess.run(command + ["run", str(path), "--out", str(tmp_path / "x.usdc")], capture_output=True,
                          text=True, timeout=600)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert lines[0] == lines[0].strip() and lines[0].startswith(f"warp-sim: error: {expected}")


def test_two_negative_scales_are_a_turn_and_read(tmp_path):
    """(-1, -2, 1) is a turn by 180 degrees about z with scale (1, 2, 1): no mirror, so the box is read with half
    extents (0.1, 0.2, 0.1) m and its orientation turned."""
    stage = new_stage(tmp_path / "turned.usda")
    scaled(box(stage), (-1, -2, 1))
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "turned.usda")
    np.testing.assert_allclose(scene.bodies[0].shape.size, (0.1, 0.2, 0.1), rtol=1e-6)
    np.testing.assert_allclose(np.abs(scene.bodies[0].orientation), (0, 0, 1, 0), atol=1e-6)


def test_a_mirrored_cloth_is_read_through_its_transform(tmp_path):
    """Cloth takes its points through the transform, so a mirror is allowed there: x becomes -x."""
    stage = new_stage(tmp_path / "mirrored.usda")
    scaled(cloth(stage), (-1, 1, 1))
    stage.Save()
    scene = ws.Scene.from_usd(tmp_path / "mirrored.usda")
    np.testing.assert_allclose(np.sort(scene.particle_array("position")[:, 0]), [-1, -1, 0, 0], atol=1e-7)

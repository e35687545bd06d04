"""Static colliders, host side: surface meshes, Scene.add_collider, and colliders on the USD stage."""

import math

import numpy as np
import pytest
import trimesh
from pxr import Gf, Usd, UsdGeom

import warp_sim as ws
from warp_sim.scene import Collider
from warp_sim.stages import ColliderSpec, StageLayout, StageWriter, stage_layout, validate_stage


def terrain(n=4, size=2.0):
    """An open height field: n x n vertices over [-size/2, size/2]^2 in x-z, 2 (n-1)^2 triangles facing +y."""
    u = np.linspace(-size / 2, size / 2, n)
    x, z = np.meshgrid(u, u)
    vertices = np.column_stack([x.ravel(), 0.1 * np.sin(x.ravel()) * np.cos(z.ravel()), z.ravel()])
    faces = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i, (j + 1) * n + i + 1
            faces += [[a, c, b], [b, c, d]]
    return trimesh.Trimesh(vertices, np.array(faces), process=False)


def open_box():
    box = trimesh.creation.box()
    return trimesh.Trimesh(box.vertices, box.faces[1:], process=False)


# --------------------------------------------------------------------------- surface meshes


def test_surface_mesh_accepted():
    mesh = terrain()
    shape = ws.MeshShape(mesh, solid=False)
    assert shape.solid is False and ws.MeshShape(trimesh.creation.box()).solid is True
    np.testing.assert_array_equal(shape.vertices, mesh.vertices)
    np.testing.assert_array_equal(shape.faces, mesh.faces)
    assert shape.bounding_radius == pytest.approx(np.max(np.linalg.norm(mesh.vertices, axis=1)), rel=1e-12)
    assert repr(shape) == "MeshShape(vertices=16, faces=18, solid=False)"
    for attribute in ("volume", "mass_properties"):
        with pytest.raises(ValueError) as caught:
            value = getattr(shape, attribute)
            value()
        text = str(caught.value)
        assert text.startswith("shape=MeshShape(") and "bounds no volume" in text, text
        assert "static collider" in text and "scene.add_collider" in text, text


def test_surface_mesh_from_file(tmp_path):
    path = tmp_path / "terrain.obj"
    terrain().export(path)
    shape = ws.MeshShape.from_file(path, solid=False)
    assert not shape.solid and shape.faces.shape == (18, 3)
    with pytest.raises(ValueError, match=r"path=.*terrain\.obj.*mesh is open"):
        ws.MeshShape.from_file(path)


def test_surface_mesh_rejected_as_dynamic_body():
    scene = ws.Scene()
    with pytest.raises(ValueError) as caught:
        scene.add_rigid_body(ws.MeshShape(terrain(), solid=False), mass=1.0)
    text = str(caught.value)
    assert "bounds no volume" in text and "cannot be a dynamic rigid body" in text and "add_collider" in text, text
    assert scene.bodies == []


def test_open_solid_mesh_message_points_to_surface_colliders():
    with pytest.raises(ValueError) as caught:
        ws.MeshShape(open_box())
    text = str(caught.value)
    assert "mesh is open" in text and "MeshShape(mesh, solid=False)" in text and "scene.add_collider" in text, text


def test_closed_mesh_may_be_a_surface():
    """solid=False skips the closed and volume checks but keeps the geometry as given."""
    box = trimesh.creation.box()
    box.invert()  # inside out: no solid, but a fine surface
    assert ws.MeshShape(box, solid=False).faces.shape == (12, 3)


def degenerate(kind):
    mesh = terrain()
    vertices, faces = mesh.vertices.copy(), mesh.faces.copy()
    if kind == "coincident":
        faces[2] = [faces[2][0], faces[2][0], faces[2][1]]
    else:  # three collinear vertices: vertex 1 moved to the middle of vertices 0 and 2
        vertices[1] = (vertices[0] + vertices[2]) / 2.0
        faces[2] = [0, 1, 2]
    return trimesh.Trimesh(vertices, faces, process=False)


@pytest.mark.parametrize("kind", ["coincident", "collinear"])
def test_degenerate_faces_rejected(kind):
    with pytest.raises(ValueError, match=r"(?s)^mesh=.*1 of 18 faces have zero area.*face 2 .*nondegenerate"):
        ws.MeshShape(degenerate(kind), solid=False)


def with_vertex(value):
    mesh = terrain()
    vertices = mesh.vertices.copy()
    vertices[3, 1] = value
    return trimesh.Trimesh(vertices, mesh.faces, process=False)


@pytest.mark.parametrize("make, match", [
    (lambda: trimesh.Trimesh(), r"^mesh=.*empty"),
    (lambda: with_vertex(np.nan), r"(?s)^mesh\.vertices=.*entry \(3, 1\) is nan"),
    (lambda: with_vertex(np.inf), r"(?s)^mesh\.vertices=.*entry \(3, 1\) is inf"),
    (lambda: np.zeros((4, 3)), r"(?s)^mesh=.*trimesh\.Trimesh"),
])
def test_surface_mesh_keeps_basic_checks(make, match):
    with pytest.raises(ValueError, match=match):
        ws.MeshShape(make(), solid=False)


def test_surface_mesh_face_index_out_of_range():
    mesh = terrain()
    faces = np.array(mesh.faces)
    faces[0, 0] = 16
    with pytest.raises(ValueError, match=r"(?s)^mesh\.faces=.*\[0, 16\).*entry \(0, 0\) is 16"):
        ws.MeshShape(trimesh.Trimesh(mesh.vertices, faces, process=False), solid=False)


def test_solid_flag_checked():
    with pytest.raises(ValueError, match=r"^solid='no'"):
        ws.MeshShape(terrain(), solid="no")


# --------------------------------------------------------------------------- Scene.add_collider


def test_add_collider_records_every_shape_kind():
    scene = ws.Scene()
    shapes = [ws.MeshShape(terrain(), solid=False), ws.Sphere(0.2), ws.Box((0.5, 0.1, 0.5)), ws.Capsule(0.1, 0.3),
              ws.Cylinder(0.2, 0.4), ws.MeshShape(trimesh.creation.box())]
    for k, shape in enumerate(shapes):
        assert scene.add_collider(shape, position=(k, 0.0, 0.0)) == k
    assert [c.name for c in scene.colliders] == [f"collider{k}" for k in range(len(shapes))]
    first = scene.colliders[0]
    assert isinstance(first, Collider) and first.shape is shapes[0]
    np.testing.assert_array_equal(first.orientation, [0.0, 0.0, 0.0, 1.0])
    assert (first.restitution, first.friction, first.color) == (0.5, 0.4, (0.45, 0.45, 0.5))
    assert scene.bodies == [] and scene.body_count == 0
    assert "6 colliders" in repr(scene)


def test_add_collider_values_and_normalised_orientation():
    scene = ws.Scene()
    with pytest.warns(UserWarning, match="orientation"):
        scene.add_collider(ws.Sphere(1.0), position=(1.0, -2.0, 3.0), orientation=(0.0, 0.7071, 0.0, 0.7071),
                           restitution=0.0, friction=0.0, name="rock", color=(0.1, 0.2, 0.3))
    (rock,) = scene.colliders
    np.testing.assert_array_equal(rock.position, [1.0, -2.0, 3.0])
    np.testing.assert_allclose(rock.orientation, [0.0, math.sqrt(0.5), 0.0, math.sqrt(0.5)], rtol=1e-12)
    assert (rock.name, rock.restitution, rock.friction, rock.color) == ("rock", 0.0, 0.0, (0.1, 0.2, 0.3))
    with pytest.raises(ValueError):
        rock.position[0] = 5.0  # read-only: a static collider never moves


@pytest.mark.parametrize("kwargs, name", [
    ({"friction": -0.1}, "friction"),
    ({"restitution": 1.5}, "restitution"),
    ({"restitution": -0.1}, "restitution"),
    ({"restitution": math.nan}, "restitution"),
    ({"position": (math.nan, 0.0, 0.0)}, "position"),
    ({"position": (0.0, 0.0)}, "position"),
    ({"orientation": (0.0, 0.0, 0.0, 0.0)}, "orientation"),
    ({"color": (1.0, 0.0)}, "color"),
    ({"shape": "sphere"}, "shape"),
    ({"shape": trimesh.creation.box()}, "shape"),
    ({"name": "taken"}, "name"),
])
def test_add_collider_bad_inputs(kwargs, name):
    scene = ws.Scene()
    scene.add_collider(ws.Sphere(0.1), name="taken")
    with pytest.raises(ValueError, match=rf"^{name}="):
        scene.add_collider(**({"shape": ws.Box(0.1)} | kwargs))
    assert len(scene.colliders) == 1


# --------------------------------------------------------------------------- USD


def xyzw(quat: Gf.Quatf) -> np.ndarray:
    return np.array([*quat.GetImaginary(), quat.GetReal()])


def collider_scene():
    """A terrain, a shifted solid mesh (its centre of mass off the shape origin) and a box; one particle."""
    scene = ws.Scene()
    scene.add_collider(ws.MeshShape(terrain(), solid=False), position=(0.5, -0.25, 1.5),
                       orientation=(0.0, math.sin(0.3), 0.0, math.cos(0.3)), name="terrain", color=(0.2, 0.6, 0.2))
    block = trimesh.creation.box(extents=(0.4, 0.2, 0.6))
    block.apply_translation((1.0, 2.0, 3.0))
    scene.add_collider(ws.MeshShape(block), position=(-1.0, 0.0, 0.0), name="block")
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    scene.add_collider(ws.Box((0.3, 0.1, 0.2)), position=(2.0, 1.0, -3.0),
                       orientation=(*(math.sin(0.6) * axis), math.cos(0.6)), friction=0.8)
    scene.add_particles([[0.0, 1.0, 0.0]], radius=0.05)
    return scene


def write_scene(path, scene, frames=3):
    with StageWriter(path, 30.0, stage_layout(scene)) as w:
        for k in range(frames):
            w.write_frame(k, particle_x=[[0.0, 1.0 - 0.01 * k, 0.0]], particle_v=np.zeros((1, 3)))
    return path


def test_stage_layout_colliders():
    scene = collider_scene()
    layout = stage_layout(scene)
    assert [c.name for c in layout.colliders] == ["terrain", "block", "collider2"]
    assert layout.bodies == () and StageLayout().colliders == ()
    terrain_spec, block_spec, box_spec = layout.colliders
    assert (terrain_spec.kind, box_spec.kind, box_spec.size) == ("mesh", "box", (0.3, 0.1, 0.2))
    # the mesh in the shape frame: no centre-of-mass offset, unlike a body's
    np.testing.assert_array_equal(block_spec.points, scene.colliders[1].shape.vertices)
    np.testing.assert_array_equal(block_spec.faces, scene.colliders[1].shape.faces)
    np.testing.assert_array_equal(block_spec.position, (-1.0, 0.0, 0.0))
    assert terrain_spec.color == (0.2, 0.6, 0.2)


def test_colliders_written_once(tmp_path):
    scene = collider_scene()
    path = write_scene(tmp_path / "colliders.usdc", scene)
    stage = Usd.Stage.Open(str(path))
    for collider, name in zip(scene.colliders, ("terrain", "block", "collider2")):
        prim = stage.GetPrimAtPath(f"/World/Colliders/{name}")
        assert prim.IsA(UsdGeom.Xform), name
        ops = UsdGeom.Xformable(prim).GetOrderedXformOps()
        assert [op.GetOpName() for op in ops] == ["xformOp:translate", "xformOp:orient"]
        translate, orient = ops
        for op in ops:
            assert op.GetAttr().GetTimeSamples() == [] and op.GetAttr().HasAuthoredValue(), (name, op.GetOpName())
        np.testing.assert_allclose(np.array(translate.Get()), collider.position, rtol=0, atol=1e-6)
        q, want = xyzw(orient.Get()), collider.orientation
        assert np.allclose(q, want, rtol=0, atol=1e-6) or np.allclose(q, -want, rtol=0, atol=1e-6), (name, q, want)
        geom = prim.GetChild("Geom")
        assert list(prim.GetChildren()) == [geom]
        assert all(a.GetNumTimeSamples() == 0 for a in geom.GetAttributes()), name
        if collider.shape.kind == "mesh":  # drawn in the shape frame
            points = np.asarray(UsdGeom.Mesh(geom).GetPointsAttr().Get())
            np.testing.assert_allclose(points, collider.shape.vertices, rtol=0, atol=1e-6)
            indices = list(UsdGeom.Mesh(geom).GetFaceVertexIndicesAttr().Get())
            assert indices == collider.shape.faces.reshape(-1).tolist()
        else:
            assert geom.IsA(UsdGeom.Cube)
        color = UsdGeom.PrimvarsAPI(geom).GetPrimvar("displayColor")
        np.testing.assert_allclose(np.asarray(color.Get()), [collider.color], rtol=1e-6)
    # the world transform puts the shape origin at the position, turned by the orientation
    m = np.array(UsdGeom.Xformable(stage.GetPrimAtPath("/World/Colliders/terrain")).ComputeLocalToWorldTransform(2))
    np.testing.assert_allclose(m[3, :3], (0.5, -0.25, 1.5), rtol=0, atol=1e-6)
    assert validate_stage(path) == []


def test_only_colliders_and_one_particle_validate(tmp_path):
    scene = ws.Scene()
    scene.add_collider(ws.MeshShape(terrain(), solid=False), name="ground mesh")
    scene.add_collider(ws.Sphere(0.5), position=(0.0, 2.0, 0.0))
    scene.add_particles([[0.0, 3.0, 0.0]])
    path = write_scene(tmp_path / "only.usda", scene, frames=1)
    stage = Usd.Stage.Open(str(path))
    names = [p.GetName() for p in stage.GetPrimAtPath("/World/Colliders").GetChildren()]
    assert names == ["ground_mesh", "collider1"]
    assert not stage.GetPrimAtPath("/World/Bodies")
    assert validate_stage(path) == []


@pytest.mark.parametrize("kwargs, message", [
    ({"position": (0.0, math.nan, 0.0)}, "position must be 3 finite floats"),
    ({"position": (0.0, 0.0)}, "position must be 3 finite floats"),
    ({"orientation": (0.0, 0.0, 0.0, 2.0)}, "orientation must be a unit quaternion"),
    ({"orientation": (0.0, 0.0, 1.0)}, "orientation must be a unit quaternion"),
    ({"kind": "mesh", "size": ()}, "points are required for a mesh collider"),
    ({"size": (-1.0,)}, r"size of a sphere must be \(radius,\): 1 finite values > 0"),
])
def test_bad_collider_specs(tmp_path, kwargs, message):
    spec = ColliderSpec(**({"name": "rock", "kind": "sphere", "size": (0.1,)} | kwargs))
    with pytest.raises(ValueError, match=rf"^ColliderSpec 'rock': {message}"):
        StageWriter(tmp_path / "bad.usdc", 60, StageLayout(colliders=(spec,)))
    assert list(tmp_path.iterdir()) == []

"""Shapes: mass, centre of mass and inertia against closed forms; bad input raises ValueError with useful text."""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from warp_sim.scene.shapes import (
    Box,
    Capsule,
    Cylinder,
    MassProperties,
    MeshShape,
    PointMasses,
    Sphere,
)

EXACT = 1e-12  # relative: closed forms evaluated two ways agree to round-off
FACETED = 5e-3  # relative: a fine triangulation of a curved solid against its closed form


def closed_form(shape, m: float) -> np.ndarray:
    """The inertia tensor [kg m^2] of a primitive of mass m, written out independently of warp_sim.shapes."""
    if isinstance(shape, Sphere):
        return np.eye(3) * 0.4 * m * shape.radius**2
    if isinstance(shape, Box):
        a, b, c = shape.size
        return np.diag([m * (b * b + c * c) / 3, m * (a * a + c * c) / 3, m * (a * a + b * b) / 3])
    r, h = shape.size
    if isinstance(shape, Cylinder):
        across = m * (r * r / 4 + h * h / 3)
        return np.diag([across, m * r * r / 2, across])
    # capsule: split m by volume into the cylinder and the two hemispheres
    v_cyl, v_cap = math.pi * r * r * 2 * h, 2 / 3 * math.pi * r**3
    m_c, m_h = m * v_cyl / (v_cyl + 2 * v_cap), m * v_cap / (v_cyl + 2 * v_cap)
    across = m_c * (r * r / 4 + h * h / 3) + 2 * m_h * (2 / 5 * r * r + h * h + 3 / 4 * h * r)
    return np.diag([across, m_c * r * r / 2 + 2 * 2 / 5 * m_h * r * r, across])


PRIMITIVES = [
    (Sphere(0.3), 4 / 3 * math.pi * 0.3**3),
    (Box((0.1, 0.2, 0.35)), 8 * 0.1 * 0.2 * 0.35),
    (Box(0.25), 0.5**3),
    (Cylinder(0.2, 0.7), math.pi * 0.2**2 * 1.4),
    (Capsule(0.2, 0.7), math.pi * 0.2**2 * 1.4 + 4 / 3 * math.pi * 0.2**3),
    (Capsule(0.4, 0.0), 4 / 3 * math.pi * 0.4**3),
]


def assert_tensor(actual, expected, rel):
    """Every entry within rel of the tensor's largest entry (off-diagonal zeros included)."""
    np.testing.assert_allclose(actual, expected, rtol=0, atol=rel * np.max(np.abs(expected)))


@pytest.mark.parametrize("shape, volume", PRIMITIVES, ids=repr)
def test_primitive_mass_is_density_times_volume(shape, volume):
    props = shape.mass_properties(density=780.0)
    assert shape.volume == pytest.approx(volume, rel=EXACT)
    assert props.mass == pytest.approx(780.0 * volume, rel=EXACT)
    assert shape.mass_properties().mass == pytest.approx(1000.0 * volume, rel=EXACT)  # default: water
    np.testing.assert_array_equal(props.com, np.zeros(3))
    assert_tensor(props.inertia, closed_form(shape, props.mass), EXACT)


@pytest.mark.parametrize("shape, volume", PRIMITIVES, ids=repr)
def test_primitive_given_mass(shape, volume):
    props = shape.mass_properties(mass=2.5)
    assert props.mass == 2.5
    assert_tensor(props.inertia, closed_form(shape, 2.5), EXACT)


def test_capsule_with_no_cylinder_is_the_sphere():
    capsule, sphere = Capsule(0.4, 0.0).mass_properties(density=500.0), Sphere(0.4).mass_properties(density=500.0)
    assert capsule.mass == pytest.approx(sphere.mass, rel=EXACT)
    assert_tensor(capsule.inertia, sphere.inertia, EXACT)


def test_capsule_against_a_fine_triangulated_capsule():
    # trimesh's capsule: height is the cylinder's length, axis Z; ours is along Y, so swap Y and Z
    mesh = trimesh.creation.capsule(height=1.4, radius=0.2, count=[128, 128])
    faceted = MeshShape(mesh).mass_properties(density=1.0)
    exact = Capsule(0.2, 0.7).mass_properties(density=1.0)
    assert faceted.mass == pytest.approx(exact.mass, rel=FACETED)
    swap = [0, 2, 1]
    assert_tensor(faceted.inertia[np.ix_(swap, swap)], exact.inertia, FACETED)


def test_mass_properties_are_read_only():
    props = Sphere(1.0).mass_properties()
    assert isinstance(props, MassProperties)
    with pytest.raises(ValueError):
        props.inertia[0, 0] = 1.0
    np.testing.assert_array_equal(props.inertia, props.inertia.T)


@pytest.mark.parametrize("shape, radius", [
    (Sphere(0.3), 0.3), (Box((0.1, 0.2, 0.35)), math.sqrt(0.01 + 0.04 + 0.1225)),
    (Capsule(0.2, 0.7), 0.9), (Cylinder(0.3, 0.4), 0.5),
], ids=repr)
def test_primitive_bounding_radius(shape, radius):
    assert shape.bounding_radius == pytest.approx(radius, rel=EXACT)


def test_repr_reads_as_the_constructor():
    assert repr(Box((0.1, 0.2, 0.3))) == "Box(half_extents=(0.1, 0.2, 0.3))"
    assert repr(Sphere(0.5)) == "Sphere(radius=0.5)"
    assert repr(Capsule(0.1, 0.2)) == "Capsule(radius=0.1, half_height=0.2)"
    assert repr(Cylinder(0.1, 0.2)) == "Cylinder(radius=0.1, half_height=0.2)"


def test_kinds_and_sizes():
    assert (Sphere(1).kind, Sphere(1).size) == ("sphere", (1.0,))
    assert (Box(2).kind, Box(2).size) == ("box", (2.0, 2.0, 2.0))
    assert (Capsule(1, 2).kind, Capsule(1, 2).size) == ("capsule", (1.0, 2.0))
    assert (Cylinder(1, 2).kind, Cylinder(1, 2).size) == ("cylinder", (1.0, 2.0))


# --- meshes


def test_mesh_box_matches_the_box():
    # a closed polyhedron is integrated exactly (trimesh.triangles.mass_properties), so round-off only
    mesh = MeshShape(trimesh.creation.box(extents=(0.2, 0.4, 0.7)))
    props, exact = mesh.mass_properties(density=780.0), Box((0.1, 0.2, 0.35)).mass_properties(density=780.0)
    assert mesh.kind == "mesh" and mesh.size == ()
    assert props.mass == pytest.approx(exact.mass, rel=1e-9)
    np.testing.assert_allclose(props.com, 0.0, atol=1e-12)
    assert_tensor(props.inertia, exact.inertia, 1e-9)
    assert mesh.bounding_radius == pytest.approx(Box((0.1, 0.2, 0.35)).bounding_radius, rel=1e-12)
    assert mesh.vertices.dtype == np.float64 and mesh.vertices.shape == (8, 3)
    assert mesh.faces.dtype == np.int32 and mesh.faces.shape == (12, 3)


def test_icosphere_matches_the_sphere():
    # 5 subdivisions (20480 faces): the inscribed polyhedron has 0.054 % less volume and 0.090 % less
    # inertia than the sphere of the same density; 4 subdivisions would be 0.22 % and 0.36 %
    mesh = MeshShape(trimesh.creation.icosphere(subdivisions=5, radius=0.3))
    props = mesh.mass_properties(density=780.0)
    mass = 780.0 * 4 / 3 * math.pi * 0.3**3
    assert props.mass == pytest.approx(mass, rel=FACETED)
    assert_tensor(props.inertia, np.eye(3) * 0.4 * mass * 0.3**2, FACETED)
    assert 0.9985 < props.inertia[0, 0] / (0.4 * mass * 0.3**2) < 0.9995  # the faceting error as stated


def test_translated_mesh_moves_the_centre_of_mass_only():
    box = trimesh.creation.box(extents=(0.2, 0.4, 0.7))
    moved = box.copy()
    moved.apply_translation((1.0, 2.0, 3.0))
    at_origin, shifted = MeshShape(box).mass_properties(), MeshShape(moved).mass_properties()
    np.testing.assert_allclose(shifted.com, (1.0, 2.0, 3.0), rtol=1e-12)
    assert shifted.mass == pytest.approx(at_origin.mass, rel=1e-9)
    assert_tensor(shifted.inertia, at_origin.inertia, 1e-9)
    assert MeshShape(moved).bounding_radius == pytest.approx(MeshShape(box).bounding_radius, rel=1e-9)


def test_rotated_mesh_gives_rotated_tensor():
    rotation = trimesh.transformations.rotation_matrix(0.7, (1.0, 2.0, -0.5))
    box = trimesh.creation.box(extents=(0.2, 0.4, 0.7))
    box.apply_transform(rotation)
    props = MeshShape(box).mass_properties(density=780.0)
    R = rotation[:3, :3]
    expected = R @ Box((0.1, 0.2, 0.35)).mass_properties(density=780.0).inertia @ R.T
    assert abs(props.inertia[0, 1]) > 0.1 * props.inertia[0, 0]  # the rotation really mixes the axes
    assert_tensor(props.inertia, expected, 1e-9)


def test_mesh_is_copied():
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    shape = MeshShape(box)
    box.apply_scale(2.0)
    assert shape.volume == pytest.approx(1.0, rel=1e-12)
    assert shape.bounding_radius == pytest.approx(math.sqrt(0.75), rel=1e-12)
    assert repr(shape) == "MeshShape(vertices=8, faces=12, volume=1)"


def test_mesh_given_mass():
    props = MeshShape(trimesh.creation.box(extents=(0.2, 0.4, 0.7))).mass_properties(mass=3.0)
    assert props.mass == 3.0
    assert_tensor(props.inertia, Box((0.1, 0.2, 0.35)).mass_properties(mass=3.0).inertia, 1e-9)


def open_box():
    box = trimesh.creation.box()
    return trimesh.Trimesh(box.vertices, box.faces[1:], process=False)


def flipped_face_box():
    box = trimesh.creation.box()
    faces = box.faces.copy()
    faces[0] = faces[0][::-1]
    return trimesh.Trimesh(box.vertices, faces, process=False)


def inverted_box():
    box = trimesh.creation.box()
    box.invert()
    return box


def overlapping_boxes():
    a, b = trimesh.creation.box(), trimesh.creation.box()
    b.apply_translation((0.1, 0.1, 0.1))
    return trimesh.util.concatenate([a, b])


@pytest.mark.parametrize("make, words", [
    (open_box, ["mesh is open", "3 boundary edges", "fill_holes"]),
    (flipped_face_box, ["winding is inconsistent", "fix_winding"]),
    (inverted_box, ["inside out", "invert()", "fix_normals"]),
    (overlapping_boxes, ["self-intersecting", "overlapping shells"]),
    (lambda: trimesh.Trimesh(), ["empty"]),
    (lambda: np.zeros((8, 3)), ["trimesh.Trimesh", "ndarray"]),
    (lambda: trimesh.Scene(trimesh.creation.box()), ["trimesh.Trimesh", "Scene"]),
])
def test_bad_meshes_rejected(make, words):
    with pytest.raises(ValueError) as caught:
        MeshShape(make())
    text = str(caught.value)
    assert text.startswith("mesh")
    for word in words:
        assert word in text, text


def test_non_finite_vertices_rejected():
    box = trimesh.creation.box()
    vertices = box.vertices.copy()
    vertices[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"(?s)mesh\.vertices=.*entry \(3, 1\) is nan"):
        MeshShape(trimesh.Trimesh(vertices, box.faces, process=False))


def test_user_mesh_not_repaired_or_changed():
    mesh = open_box()
    before = mesh.faces.copy()
    with pytest.raises(ValueError):
        MeshShape(mesh)
    np.testing.assert_array_equal(mesh.faces, before)


def test_from_file(tmp_path):
    path = tmp_path / "box.obj"
    trimesh.creation.box(extents=(0.2, 0.4, 0.7)).export(path)
    shape = MeshShape.from_file(path)
    assert shape.volume == pytest.approx(0.2 * 0.4 * 0.7, rel=1e-9)
    assert_tensor(shape.mass_properties().inertia, Box((0.1, 0.2, 0.35)).mass_properties().inertia, 1e-9)
    assert MeshShape.from_file(str(path)).volume == pytest.approx(shape.volume, rel=1e-12)


def test_from_file_missing(tmp_path):
    with pytest.raises(ValueError, match=r"path=.*nothere\.obj.*no such file"):
        MeshShape.from_file(tmp_path / "nothere.obj")


def test_from_file_without_triangles(tmp_path):
    path = tmp_path / "points.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(ValueError, match=r"path=.*no triangles"):
        MeshShape.from_file(path)


def test_from_file_unreadable(tmp_path):
    path = tmp_path / "broken.glb"
    path.write_bytes(b"\x00\x01\x02")
    with pytest.raises(ValueError, match=r"path=.*could not be read"):
        MeshShape.from_file(path)


def test_from_file_open_mesh_names_path_and_problem(tmp_path):
    path = tmp_path / "open.obj"
    open_box().export(path)
    with pytest.raises(ValueError, match=r"path=.*open\.obj.*mesh is open"):
        MeshShape.from_file(path)


# --- point masses

# Hand computation. Masses m = (1, 2, 3, 4) kg at q1 = (1, 0, 0), q2 = (0, 2, 0), q3 = (0, 0, 1), q4 = (1, 2, 1) m
# (not coplanar: the plane x + y/2 + z = 1 through q1..q3 gives 3 at q4).
# M = 10 kg; sum m q = (1 + 4, 4 + 8, 3 + 4) = (5, 12, 7), so com = (0.5, 1.2, 0.7) m.
# r = q - com: r1 = (0.5, -1.2, -0.7), r2 = (-0.5, 0.8, -0.7), r3 = (-0.5, -1.2, 0.3), r4 = (0.5, 0.8, 0.3).
# sum m x^2 = 0.25 (1 + 2 + 3 + 4)                      = 2.5
# sum m y^2 = 1.44 + 2 (0.64) + 3 (1.44) + 4 (0.64)     = 1.44 + 1.28 + 4.32 + 2.56 = 9.6
# sum m z^2 = 0.49 + 2 (0.49) + 3 (0.09) + 4 (0.09)     = 0.49 + 0.98 + 0.27 + 0.36 = 2.1
# sum m x y = -0.6 + 2 (-0.4) + 3 (0.6) + 4 (0.4)       = -0.6 - 0.8 + 1.8 + 1.6   = 2.0
# sum m x z = -0.35 + 2 (0.35) + 3 (-0.15) + 4 (0.15)   = -0.35 + 0.7 - 0.45 + 0.6 = 0.5
# sum m y z = 0.84 + 2 (-0.56) + 3 (-0.36) + 4 (0.24)   = 0.84 - 1.12 - 1.08 + 0.96 = -0.4
# (check about the origin, parallel axis: sum m x y = 8 - M 0.5 * 1.2 = 2; sum m y^2 = 24 - M 1.44 = 9.6.)
# I_xx = 9.6 + 2.1 = 11.7, I_yy = 2.5 + 2.1 = 4.6, I_zz = 2.5 + 9.6 = 12.1,
# I_xy = -2.0, I_xz = -0.5, I_yz = -(-0.4) = 0.4.
POINTS = [(1, 0, 0), (0, 2, 0), (0, 0, 1), (1, 2, 1)]
MASSES = [1.0, 2.0, 3.0, 4.0]
HAND = np.array([[11.7, -2.0, -0.5], [-2.0, 4.6, 0.4], [-0.5, 0.4, 12.1]])


def test_point_masses_against_hand_computation():
    shape = PointMasses(POINTS, MASSES)
    props = shape.mass_properties()
    assert props.mass == pytest.approx(10.0, rel=EXACT)
    np.testing.assert_allclose(props.com, (0.5, 1.2, 0.7), rtol=EXACT)
    assert_tensor(props.inertia, HAND, EXACT)
    np.testing.assert_array_equal(props.inertia, props.inertia.T)
    assert shape.kind == "points" and shape.size == () and shape.volume == 0.0


def test_point_masses_angular_momentum_is_inertia_times_omega():
    # L = sum m r x (omega x r) must equal I omega: this fails if the products of inertia carry a + sign
    omega = np.array([0.3, -1.1, 2.0])
    com = np.array([0.5, 1.2, 0.7])
    r = np.array(POINTS, dtype=float) - com
    momentum = sum(m * np.cross(ri, np.cross(omega, ri)) for m, ri in zip(MASSES, r))
    np.testing.assert_allclose(PointMasses(POINTS, MASSES).mass_properties().inertia @ omega, momentum, rtol=EXACT)


def test_point_masses_scaled_to_given_mass():
    props = PointMasses(POINTS, MASSES).mass_properties(mass=2.5)
    assert props.mass == 2.5
    np.testing.assert_allclose(props.com, (0.5, 1.2, 0.7), rtol=EXACT)
    assert_tensor(props.inertia, HAND * 0.25, EXACT)


def test_point_masses_scalar_mass_and_bounding_radius():
    shape = PointMasses([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, 0, -1)], 0.5, radius=0.1)
    np.testing.assert_array_equal(shape.masses, [0.5] * 4)
    com = np.array([0.0, 0.25, -0.25])  # sum of positions / 4
    np.testing.assert_allclose(shape.mass_properties().com, com, atol=1e-15)
    expected = max(np.linalg.norm(np.array(p) - com) for p in shape.positions) + 0.1
    assert shape.bounding_radius == pytest.approx(expected, rel=EXACT)
    assert repr(shape) == "PointMasses(count=4, total_mass=2, radius=0.1)"


def test_point_masses_reject_density():
    with pytest.raises(ValueError, match="density.*no volume"):
        PointMasses(POINTS, MASSES).mass_properties(density=1000.0)


@pytest.mark.parametrize("positions", [
    [(0, 0, 0)],
    [(0, 0, 0), (1, 1, 1), (2, 2, 2), (-3, -3, -3)],
    [(0, 0, 0), (1, 0, 0)],
])
def test_collinear_point_masses_rejected(positions):
    with pytest.raises(ValueError) as caught:
        PointMasses(positions, 1.0)
    text = str(caught.value)
    assert text.startswith("positions=") and "singular" in text and "could not rotate" in text
    assert "add a point off the line" in text


# --- bad input: each names the argument, shows the value and says what is valid

NAN = math.nan


@pytest.mark.parametrize("call, argument, value", [
    (lambda: Sphere(0.0), "radius", "> 0"),
    (lambda: Sphere(-1.0), "radius", "-1"),
    (lambda: Sphere(NAN), "radius", "finite"),
    (lambda: Sphere("big"), "radius", "real number"),
    (lambda: Box((0.1, 0.0, 0.3)), "half_extents", "entry 1 is 0"),
    (lambda: Box((0.1, -0.2, 0.3)), "half_extents", "-0.2"),
    (lambda: Box((0.1, NAN, 0.3)), "half_extents", "finite"),
    (lambda: Box(0.0), "half_extents", "> 0"),
    (lambda: Box((0.1, 0.2)), "half_extents", "shape"),
    (lambda: Capsule(0.0, 0.1), "radius", "> 0"),
    (lambda: Capsule(0.1, -0.1), "half_height", ">= 0"),
    (lambda: Capsule(0.1, NAN), "half_height", "finite"),
    (lambda: Cylinder(-0.1, 0.1), "radius", "> 0"),
    (lambda: Cylinder(0.1, 0.0), "half_height", "> 0"),
    (lambda: Cylinder(NAN, 0.1), "radius", "finite"),
    (lambda: Sphere(1.0).mass_properties(density=0.0), "density", "> 0"),
    (lambda: Sphere(1.0).mass_properties(density=-5.0), "density", "-5"),
    (lambda: Sphere(1.0).mass_properties(density=NAN), "density", "finite"),
    (lambda: Sphere(1.0).mass_properties(mass=0.0), "mass", "> 0"),
    (lambda: Sphere(1.0).mass_properties(mass=-2.0), "mass", "-2"),
    (lambda: Sphere(1.0).mass_properties(mass=NAN), "mass", "finite"),
    (lambda: Sphere(1.0).mass_properties(density=1000.0, mass=2.0), "density, mass", "not both"),
    (lambda: PointMasses(POINTS, MASSES).mass_properties(mass=-1.0), "mass", "> 0"),
    (lambda: PointMasses(POINTS, [1.0, 2.0, 0.0, 4.0]), "masses", "entry 2 is 0"),
    (lambda: PointMasses(POINTS, [1.0, 2.0]), "masses", "shape"),
    (lambda: PointMasses(POINTS, NAN), "masses", "finite"),
    (lambda: PointMasses([(0, 0, NAN)], 1.0), "positions", "finite"),
    (lambda: PointMasses([(0, 0)], 1.0), "positions", "shape"),
    (lambda: PointMasses(np.zeros((0, 3)), 1.0), "positions", "at least one"),
    (lambda: PointMasses(POINTS, MASSES, radius=-0.1), "radius", ">= 0"),
])
def test_bad_input_rejected(call, argument, value):
    with pytest.raises(ValueError) as caught:
        call()
    text = str(caught.value)
    assert text.startswith(f"{argument}="), text
    assert value in text, text

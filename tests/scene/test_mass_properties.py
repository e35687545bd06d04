"""ws.MassProperties is checked when made: a finite mass > 0 [kg], a finite centre [m], a finite, symmetric,
positive-definite inertia [kg m^2] whose principal moments obey the triangle inequality I1 + I2 >= I3 (within
float32 rounding); a negative mass or a negative-definite inertia is never simulated."""
import numpy as np
import pytest
import trimesh

import warp_sim as ws

TURN = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])   # 90 degrees about z


@pytest.mark.parametrize("mass, com, inertia, name, words", [
    (-1.0, (0, 0, 0), np.eye(3), "mass", "> 0"),
    (0.0, (0, 0, 0), np.eye(3), "mass", "> 0"),
    (np.nan, (0, 0, 0), np.eye(3), "mass", "finite"),
    (np.inf, (0, 0, 0), np.eye(3), "mass", "finite"),
    (1.0, (0, np.nan, 0), np.eye(3), "com", "finite"),
    (1.0, (0, 0), np.eye(3), "com", "shape (3,)"),
    (1.0, (0, 0, 0), -np.eye(3), "inertia", "positive definite"),
    (1.0, (0, 0, 0), np.diag([1.0, 1.0, 0.0]), "inertia", "positive definite"),
    (1.0, (0, 0, 0), np.diag([1.0, 1.0, 3.0]), "inertia", "triangle inequality"),
    (1.0, (0, 0, 0), [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "inertia", "symmetric"),
    (1.0, (0, 0, 0), np.diag([1.0, np.inf, 1.0]), "inertia", "finite"),
    (1.0, (0, 0, 0), np.eye(2), "inertia", "shape (3, 3)"),
])
def test_bad_mass_properties_are_refused_by_name(mass, com, inertia, name, words):
    with pytest.raises(ValueError) as caught:
        ws.MassProperties(mass, com, inertia)
    text = str(caught.value)
    assert text.startswith(f"{name}=") and words in text and "\n" not in text, text


def test_a_turned_triangle_breaker_is_refused_by_its_principal_moments():
    """The check is of the principal moments, not the diagonal: (1, 1, 3) turned about x still breaks it."""
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    with pytest.raises(ValueError, match=r"principal moments \(1, 1, 3\) break the triangle inequality"):
        ws.MassProperties(1.0, (0, 0, 0), R @ np.diag([1.0, 1.0, 3.0]) @ R.T)


def test_a_flat_body_at_float32_rounding_is_accepted_and_kept_symmetric():
    """A thin disc's I3 = I1 + I2, rounded to float32 as a USD stage stores it, is within the tolerance; an
    inertia off symmetric by round-off is made exactly symmetric."""
    moments = np.array([0.25, 0.25, 0.5], dtype=np.float32).astype(np.float64) * (1 + np.array([0, -6e-8, 6e-8]))
    ws.MassProperties(2.0, (0, 0, 0), np.diag(moments))
    inertia = TURN @ np.diag([1.0, 2.0, 2.5]) @ TURN.T
    inertia[0, 1] += 1e-14
    made = ws.MassProperties(1.0, (0, 0, 0), inertia)
    assert np.array_equal(made.inertia, made.inertia.T) and not made.inertia.flags.writeable


def test_add_rigid_body_never_gets_a_bad_one():
    """The check is in MassProperties itself: there is no valid object carrying a negative mass to hand on."""
    scene = ws.Scene()
    with pytest.raises(ValueError, match="mass=-2"):
        scene.add_rigid_body(ws.Box(0.1), mass_properties=ws.MassProperties(-2.0, (0, 0, 0), np.eye(3)))
    assert scene.body_count == 0


def test_every_shape_still_makes_valid_mass_properties():
    shapes = [ws.Sphere(0.1), ws.Box((0.1, 0.2, 0.3)), ws.Capsule(0.1, 0.0), ws.Capsule(0.1, 0.3),
              ws.Cylinder(0.1, 0.3), ws.MeshShape(trimesh.creation.icosphere(2, radius=0.2)),
              ws.PointMasses([[1, 0, 0], [0, 1, 0], [0, 0, 1]], [1.0, 2.0, 3.0]),
              ws.PointMasses([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [1.0, 1.0, 1.0])]   # flat: I3 = I1 + I2
    for shape in shapes:
        properties = shape.mass_properties(mass=2.0) if shape.kind == "points" else shape.mass_properties()
        assert properties.mass > 0 and np.all(np.linalg.eigvalsh(properties.inertia) > 0)


def test_shape_messages_come_first():
    """A shape's own, more helpful, messages still come before MassProperties' (collinear points, inside-out mesh)."""
    with pytest.raises(ValueError, match="^positions=.*singular.*could not rotate"):
        ws.PointMasses([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [1.0, 1.0, 1.0])
    inside_out = trimesh.creation.box(extents=(1, 1, 1))
    inside_out.invert()
    with pytest.raises(ValueError, match="inside out"):
        ws.MeshShape(inside_out)

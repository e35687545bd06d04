"""Cloth and soft-body building: topology, spring families, rest lengths, mass distribution, pins, validation.

Hand computations are exact up to float64 round-off (rel 1e-12) unless said otherwise.
"""
import math
import time

import numpy as np
import pytest
import trimesh

import warp_sim as ws
from warp_sim.scene import cloth
from warp_sim.util.rotations import quat_to_matrix

RTOL = 1e-12


def family_pairs(scene, mesh, family):
    """The mesh's springs of one family as a set of local (low, high) vertex pairs."""
    pairs = np.sort(scene.spring_array("pairs")[mesh.springs[family]] - mesh.start, axis=1)
    return set(map(tuple, pairs.tolist()))


def rest_lengths(scene, mesh, family):
    return scene.spring_array("rest_length")[mesh.springs[family]]


def grid_mesh(nx, ny, dx, dy, alternate=False):
    """A rectangular quad grid as a trimesh (vertex j nx + i at (i dx, j dy, 0)), each quad split in two;
    alternate: flip the split diagonal on every other quad."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    vertices = np.stack([i.ravel() * dx, j.ravel() * dy, np.zeros(nx * ny)], axis=1)
    ids = np.arange(nx * ny).reshape(ny, nx)
    a, b, c, d = (q.ravel() for q in (ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]))
    faces = []
    for k in range(len(a)):
        if alternate and k % 2:
            faces += [[a[k], b[k], d[k]], [b[k], c[k], d[k]]]
        else:
            faces += [[a[k], b[k], c[k]], [a[k], c[k], d[k]]]
    return trimesh.Trimesh(vertices, np.array(faces), process=False)


def hexagon_fan():
    """Six equilateral triangles (side 1) around vertex 0."""
    angles = np.arange(6) * np.pi / 3
    vertices = np.vstack([[0.0, 0.0, 0.0], np.stack([np.cos(angles), np.sin(angles), np.zeros(6)], axis=1)])
    faces = [[0, 1 + k, 1 + (k + 1) % 6] for k in range(6)]
    return trimesh.Trimesh(vertices, faces, process=False)


# --------------------------------------------------------------------------- grid


@pytest.mark.parametrize("nx,ny", [(2, 2), (3, 3), (5, 4), (2, 7), (9, 3)])
def test_grid_family_counts(nx, ny):
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(nx, ny), size=(1.0, 1.0))
    mesh = scene.meshes[0]
    counts = {family: len(mesh.springs[family]) for family in cloth.FAMILIES}
    assert counts == {"structural": (nx - 1) * ny + nx * (ny - 1), "shear": 2 * (nx - 1) * (ny - 1),
                      "bend": (nx - 2) * ny + nx * (ny - 2)}
    assert scene.spring_count == sum(counts.values())
    all_ids = np.concatenate([mesh.springs[f] for f in cloth.FAMILIES])
    np.testing.assert_array_equal(np.sort(all_ids), np.arange(scene.spring_count))


def test_grid_rest_lengths_and_neighbours():
    nx, ny, dx, dy = 5, 4, 0.5, 0.3
    scene = ws.Scene()
    scene.add_particles([[9.0, 9.0, 9.0]])   # the cloth's ids and springs start after other particles
    ids = scene.add_cloth_grid(resolution=(nx, ny), size=((nx - 1) * dx, (ny - 1) * dy))
    mesh = scene.meshes[0]
    assert mesh.start == 1 and ids[0, 0] == 1

    def index(i, j):
        return j * nx + i

    rows = {(index(i, j), index(i + 1, j)) for j in range(ny) for i in range(nx - 1)}
    columns = {(index(i, j), index(i, j + 1)) for j in range(ny - 1) for i in range(nx)}
    assert family_pairs(scene, mesh, "structural") == rows | columns
    diagonals = {(index(i, j), index(i + 1, j + 1)) for j in range(ny - 1) for i in range(nx - 1)}
    anti = {(index(i + 1, j), index(i, j + 1)) for j in range(ny - 1) for i in range(nx - 1)}
    assert family_pairs(scene, mesh, "shear") == diagonals | anti
    second = ({(index(i, j), index(i + 2, j)) for j in range(ny) for i in range(nx - 2)}
              | {(index(i, j), index(i, j + 2)) for j in range(ny - 2) for i in range(nx)})
    assert family_pairs(scene, mesh, "bend") == second
    pairs = scene.spring_array("pairs") - 1
    horizontal = (pairs[:, 1] - pairs[:, 0]) == 1
    length = scene.spring_array("rest_length")
    structural = mesh.springs["structural"]
    np.testing.assert_allclose(length[structural][horizontal[structural]], dx, rtol=1e-12)
    np.testing.assert_allclose(length[structural][~horizontal[structural]], dy, rtol=1e-12)
    np.testing.assert_allclose(rest_lengths(scene, mesh, "shear"), math.hypot(dx, dy), rtol=1e-12)
    bend = mesh.springs["bend"]
    along_rows = (pairs[bend, 1] - pairs[bend, 0]) == 2
    np.testing.assert_allclose(length[bend][along_rows], 2 * dx, rtol=1e-12)
    np.testing.assert_allclose(length[bend][~along_rows], 2 * dy, rtol=1e-12)


def test_grid_families_have_their_own_stiffness_and_damping():
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(4, 4), size=(1.0, 1.0), stiffness=(300.0, 20.0, 1.0), damping=(3.0, 2.0, 0.5))
    mesh = scene.meshes[0]
    for family, ks, kd in zip(cloth.FAMILIES, (300.0, 20.0, 1.0), (3.0, 2.0, 0.5)):
        assert np.all(scene.spring_array("stiffness")[mesh.springs[family]] == ks)
        assert np.all(scene.spring_array("damping")[mesh.springs[family]] == kd)
    scene.add_cloth_grid(resolution=(3, 3), size=(1.0, 1.0), stiffness=50.0, damping=0.0)
    assert np.all(scene.spring_array("stiffness")[scene.meshes[1].springs["bend"]] == 50.0)


def test_grid_ids_row_major_position_and_orientation():
    nx, ny, width, height = 4, 3, 1.2, 0.8
    q = np.array([0.0, math.sin(math.pi / 6), 0.0, math.cos(math.pi / 6)])  # 60 degrees about +y
    position = np.array([1.0, 2.0, -0.5])
    scene = ws.Scene()
    scene.add_particles([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    ids = scene.add_cloth_grid(resolution=(nx, ny), size=(width, height), position=position, orientation=q)
    assert ids.shape == (ny, nx)
    np.testing.assert_array_equal(ids.ravel(), 2 + np.arange(nx * ny))
    x = scene.particle_array("position")
    R = quat_to_matrix(q)
    for j in range(ny):
        for i in range(nx):
            local = np.array([-width / 2 + i * width / (nx - 1), -height / 2 + j * height / (ny - 1), 0.0])
            np.testing.assert_allclose(x[ids[j, i]], position + R @ local, atol=1e-12)
    np.testing.assert_allclose(x[ids].reshape(-1, 3).mean(axis=0), position, atol=1e-12)  # centred on position
    normal = np.cross(x[ids[0, 1]] - x[ids[0, 0]], x[ids[1, 0]] - x[ids[0, 0]])
    np.testing.assert_allclose(normal / np.linalg.norm(normal), R @ [0.0, 0.0, 1.0], atol=1e-12)


def test_grid_faces_and_triangles():
    nx, ny = 3, 2
    scene = ws.Scene()
    scene.add_particles([[0.0, 0.0, 0.0]])
    scene.add_cloth_grid(resolution=(nx, ny), size=(2.0, 1.0))
    mesh = scene.meshes[0]
    assert mesh.count == nx * ny and mesh.start == 1
    np.testing.assert_array_equal(mesh.face_counts, [4, 4])
    np.testing.assert_array_equal(mesh.face_indices, [0, 1, 4, 3, 1, 2, 5, 4])   # local, counter-clockwise
    np.testing.assert_array_equal(mesh.triangles, 1 + np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]]))
    x = scene.particle_array("position")
    t = x[mesh.triangles]
    normals = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    np.testing.assert_allclose(0.5 * np.linalg.norm(normals, axis=1).sum(), 2.0, rtol=RTOL)   # cover the cloth
    assert np.all(normals[:, 2] > 0)                                                          # wound around +z


@pytest.mark.parametrize("nx,ny,width,height", [(3, 3, 2.0, 2.0), (17, 5, 1.3, 0.7), (256, 256, 2.0, 3.0)])
def test_grid_total_mass_conserved(nx, ny, width, height):
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(nx, ny), size=(width, height), mass=0.37, name="by_mass")
    scene.add_cloth_grid(resolution=(nx, ny), size=(width, height), density=0.25, name="by_density")
    scene.add_cloth_grid(resolution=(nx, ny), size=(width, height), name="default")
    m = scene.particle_array("mass").reshape(3, -1)
    assert m[0].sum() == pytest.approx(0.37, rel=RTOL)
    assert m[1].sum() == pytest.approx(0.25 * width * height, rel=RTOL)
    assert m[2].sum() == pytest.approx(cloth.DEFAULT_CLOTH_DENSITY * width * height, rel=RTOL)


def test_grid_area_weighting_by_hand():
    """3 x 3 vertices over 2 m x 2 m: four 1 m^2 cells; a corner touches one cell (1/4 of it), an edge
    vertex two (2 x 1/4), the centre four (4 x 1/4)."""
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(3, 3), size=(2.0, 2.0), density=1.0)
    expected = np.array([[0.25, 0.5, 0.25], [0.5, 1.0, 0.5], [0.25, 0.5, 0.25]])
    np.testing.assert_allclose(scene.particle_array("mass").reshape(3, 3), expected, rtol=RTOL)
    # the same shares of a total mass, and of unequal cells (dx = 1, dy = 0.5)
    scene.add_cloth_grid(resolution=(3, 3), size=(2.0, 2.0), mass=8.0)
    np.testing.assert_allclose(scene.particle_array("mass")[9:18].reshape(3, 3), 2.0 * expected, rtol=RTOL)
    scene.add_cloth_grid(resolution=(3, 2), size=(2.0, 0.5), density=4.0)
    np.testing.assert_allclose(scene.particle_array("mass")[18:], 4.0 * np.array([0.125, 0.25, 0.125] * 2),
                               rtol=RTOL)


@pytest.mark.parametrize("pinned,expected", [
    ("corners", [0, 4, 15, 19]), ("top_corners", [15, 19]), (["top_corners"], [15, 19]),
    ("top", [15, 16, 17, 18, 19]), ("bottom", [0, 1, 2, 3, 4]), ("left", [0, 5, 10, 15]),
    ("right", [4, 9, 14, 19]), ([7], [7]), (np.array([3, 12]), [3, 12]), (11, [11]),
    (["left", 7, "top_corners", 0], [0, 5, 7, 10, 15, 19]), ((), []), (None, []),
])
def test_grid_pinning(pinned, expected):
    scene = ws.Scene()
    scene.add_particles([[0.0, 0.0, 0.0]])
    ids = scene.add_cloth_grid(resolution=(5, 4), size=(1.0, 1.0), pinned=pinned, velocity=(0.0, 0.0, 2.0))
    pins = scene.particle_array("pinned")
    np.testing.assert_array_equal(np.flatnonzero(pins[1:]), expected)
    assert not pins[0]
    v = scene.particle_array("velocity")[ids.ravel()]
    assert np.all(v[pins[1:]] == 0.0) and np.all(v[~pins[1:]] == [0.0, 0.0, 2.0])


def test_grid_records_surface_options():
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(3, 3), size=(1.0, 1.0), drag=1.1, lift=0.4, air_density=1.0, max_stretch=0.1,
                         restitution=0.2, friction=0.7, radius=0.01, name="flag", color=(0.1, 0.2, 0.3))
    mesh = scene.meshes[0]
    assert (mesh.name, mesh.drag, mesh.lift, mesh.air_density, mesh.max_stretch) == ("flag", 1.1, 0.4, 1.0, 0.1)
    assert mesh.color == (0.1, 0.2, 0.3)
    assert scene.particle_groups[0].name == "flag" and scene.particle_groups[0].count == 9
    assert np.all(scene.particle_array("restitution") == 0.2) and np.all(scene.particle_array("friction") == 0.7)
    assert np.all(scene.particle_array("radius") == 0.01)
    scene.add_cloth_grid(resolution=(3, 3), size=(1.0, 1.0))
    scene.add_cloth_grid(resolution=(3, 3), size=(1.0, 1.0))
    assert [m.name for m in scene.meshes] == ["flag", "cloth1", "cloth2"]


def test_grid_256_builds_fast():
    best = math.inf
    for _ in range(3):
        scene = ws.Scene()
        start = time.perf_counter()
        scene.add_cloth_grid(resolution=(256, 256), size=(2.0, 2.0), pinned="top_corners")
        best = min(best, time.perf_counter() - start)
    assert scene.particle_count == 65536
    assert best < 0.5, f"building a 256 x 256 cloth took {best:.3f} s"


# --------------------------------------------------------------------------- cloth from a mesh


@pytest.mark.parametrize("alternate", [False, True])
def test_cloth_mesh_of_quad_grid_matches_grid(alternate):
    nx, ny, dx, dy = 6, 5, 0.2, 0.35
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(nx, ny), size=((nx - 1) * dx, (ny - 1) * dy), name="grid")
    scene.add_cloth_mesh(grid_mesh(nx, ny, dx, dy, alternate), name="mesh")
    grid, mesh = scene.meshes
    for family in cloth.FAMILIES:
        assert family_pairs(scene, mesh, family) == family_pairs(scene, grid, family), family
        np.testing.assert_allclose(np.sort(rest_lengths(scene, mesh, family)),
                                   np.sort(rest_lengths(scene, grid, family)), rtol=1e-12)
    m = scene.particle_array("mass").reshape(2, -1)
    assert m[1].sum() == pytest.approx(m[0].sum(), rel=RTOL)


def test_cloth_mesh_from_obj_quads_keeps_vertex_order(tmp_path):
    """trimesh splits each OBJ quad into two triangles; the families are those of the grid."""
    nx, ny = 4, 3
    positions = np.array([[0.5 * i, 0.0, -0.5 * j] for j in range(ny) for i in range(nx)])
    quads = [[j * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1, (j + 1) * nx + i]
             for j in range(ny - 1) for i in range(nx - 1)]
    path = tmp_path / "sheet.obj"
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in positions)
                    + "".join("f " + " ".join(str(k + 1) for k in q) + "\n" for q in quads))
    scene = ws.Scene()
    ids = scene.add_cloth_mesh(str(path), mass=0.6, pinned=[0, 3], position=(0.0, 1.0, 0.0))
    np.testing.assert_allclose(scene.particle_array("position")[ids], positions + [0.0, 1.0, 0.0])
    mesh = scene.meshes[0]
    counts = {family: len(mesh.springs[family]) for family in cloth.FAMILIES}
    assert counts == {"structural": 17, "shear": 12, "bend": 10}
    assert scene.particle_array("mass").sum() == pytest.approx(0.6, rel=RTOL)
    np.testing.assert_array_equal(np.flatnonzero(scene.particle_array("pinned")), [0, 3])
    np.testing.assert_array_equal(mesh.face_counts, [3] * 12)


def test_cloth_mesh_triangle_lattice_families():
    """A hexagon of six equilateral triangles: no quads (60 degree corners), every edge structural, and the
    three straight lines through the centre give the only bend springs (ring angles are 120 degrees)."""
    scene = ws.Scene()
    scene.add_cloth_mesh(hexagon_fan())
    mesh = scene.meshes[0]
    assert len(family_pairs(scene, mesh, "structural")) == 12
    assert family_pairs(scene, mesh, "shear") == set()
    assert family_pairs(scene, mesh, "bend") == {(1, 4), (2, 5), (3, 6)}
    np.testing.assert_allclose(rest_lengths(scene, mesh, "bend"), 2.0, rtol=1e-12)


def test_cloth_mesh_area_weighting_by_hand():
    """Triangles (0, 1, 2) of area 1 and (1, 3, 2) of area 3/2: each corner gets a third of each triangle.
    Their largest corners (90 and 108.4 degrees) are not both opposite the shared edge: no quad."""
    vertices = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [3.0, 1.0, 0.0]]
    mesh = trimesh.Trimesh(vertices, [[0, 1, 2], [1, 3, 2]], process=False)
    scene = ws.Scene()
    scene.add_cloth_mesh(mesh, density=2.0, name="by_density")
    scene.add_cloth_mesh(mesh, mass=1.0, name="by_mass")
    share = np.array([1.0 / 3.0, (1.0 + 1.5) / 3.0, (1.0 + 1.5) / 3.0, 1.5 / 3.0])
    m = scene.particle_array("mass").reshape(2, 4)
    np.testing.assert_allclose(m[0], 2.0 * share, rtol=RTOL)
    np.testing.assert_allclose(m[1], share / 2.5, rtol=RTOL)
    assert m[1].sum() == pytest.approx(1.0, rel=RTOL)
    first = scene.meshes[0]
    assert len(first.springs["structural"]) == 5 and len(first.springs["shear"]) == 0
    assert len(first.springs["bend"]) == 0


def test_cloth_mesh_pins_by_index_only():
    scene = ws.Scene()
    scene.add_cloth_mesh(hexagon_fan(), pinned=[1, 4])
    np.testing.assert_array_equal(np.flatnonzero(scene.particle_array("pinned")), [1, 4])
    with pytest.raises(ValueError, match="pinned.*add_cloth_grid"):
        scene.add_cloth_mesh(hexagon_fan(), pinned="corners")
    with pytest.raises(ValueError, match=r"pinned.*\[0, 7\)"):
        scene.add_cloth_mesh(hexagon_fan(), pinned=[7])


def test_coincident_unjoined_vertices_warn():
    soup = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 0, 0], [1, 1, 0], [0, 1, 0]],
                           [[0, 1, 2], [3, 4, 5]], process=False)
    scene = ws.Scene()
    with pytest.warns(UserWarning, match="merge_vertices"):
        scene.add_cloth_mesh(soup)


# --------------------------------------------------------------------------- soft bodies


def test_soft_mesh_edges_are_springs_with_rest_lengths():
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    scene = ws.Scene()
    scene.add_soft_mesh(box, stiffness=500.0, damping=2.0, internal=None)
    mesh = scene.meshes[0]
    edges = {tuple(e) for e in np.sort(box.edges_unique, axis=1).tolist()}
    assert family_pairs(scene, mesh, "structural") == edges and len(edges) == 18
    assert len(mesh.springs["shear"]) == 0 and len(mesh.springs["bend"]) == 0
    np.testing.assert_allclose(np.sort(rest_lengths(scene, mesh, "structural")), np.sort(box.edges_unique_length),
                               rtol=1e-12)
    assert np.all(scene.spring_array("stiffness") == 500.0) and np.all(scene.spring_array("damping") == 2.0)
    np.testing.assert_array_equal(mesh.face_counts, [3] * 12)
    np.testing.assert_array_equal(mesh.face_indices, box.faces.ravel())


@pytest.mark.parametrize("distribution", ["uniform", "area", "volume"])
@pytest.mark.parametrize("make", [lambda: trimesh.creation.box(extents=(1.0, 2.0, 0.5)),
                                  lambda: trimesh.creation.icosphere(2, radius=0.3)])
def test_soft_mesh_distributions_conserve_mass(distribution, make):
    scene = ws.Scene()
    scene.add_soft_mesh(make(), mass=2.5, distribution=distribution)
    assert scene.particle_array("mass").sum() == pytest.approx(2.5, rel=RTOL)


def test_soft_mesh_uniform_and_area_by_hand():
    """Corner tetrahedron (0, e_x, e_y, e_z): three right faces of area 1/2 and a slanted one of area sqrt(3)/2."""
    tet = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
                          process=False)
    scene = ws.Scene()
    scene.add_soft_mesh(tet, mass=1.0, distribution="uniform", name="uniform")
    scene.add_soft_mesh(tet, mass=1.0, distribution="area", name="area")
    m = scene.particle_array("mass").reshape(2, 4)
    np.testing.assert_allclose(m[0], 0.25, rtol=RTOL)
    slanted = math.sqrt(3.0) / 2.0
    share = np.array([1.5, 1.0 + slanted, 1.0 + slanted, 1.0 + slanted]) / 3.0
    np.testing.assert_allclose(m[1], share / share.sum(), rtol=RTOL)


def test_soft_mesh_volume_by_hand():
    """A 2 m cube about its centroid: each of its 12 triangles (area 2) spans a tetrahedron of volume
    2 x 1 / 3 = 2/3 m^3 with the centre, a third of it to each corner. In trimesh's box a corner is in
    4 or 5 triangles: 8/9 or 10/9 m^3 of the 8 m^3."""
    box = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    triangles_at = np.bincount(box.faces.ravel(), minlength=8)
    assert set(triangles_at.tolist()) == {4, 5}
    scene = ws.Scene()
    scene.add_soft_mesh(box, mass=16.0, distribution="volume", position=(5.0, 0.0, 0.0))
    np.testing.assert_allclose(scene.particle_array("mass"), 16.0 * triangles_at * (2.0 / 9.0) / 8.0, rtol=RTOL)
    # a tetrahedron's centroid splits it into four equal volumes: every corner gets a quarter
    tet = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
                          process=False)
    scene.add_soft_mesh(tet, mass=1.0, distribution="volume")
    np.testing.assert_allclose(scene.particle_array("mass")[8:], 0.25, rtol=RTOL)


def test_soft_mesh_two_ring_springs():
    """An icosahedron: each vertex has 5 neighbours, 5 vertices two edges away and its antipode three away."""
    ico = trimesh.creation.icosahedron()
    scene = ws.Scene()
    scene.add_soft_mesh(ico, stiffness=100.0, damping=1.0, internal_stiffness=30.0, internal_damping=0.2)
    mesh = scene.meshes[0]
    ring = family_pairs(scene, mesh, "bend")
    assert len(ring) == 30 and len(mesh.springs["structural"]) == 30
    x = np.asarray(ico.vertices)
    distance = {pair: np.linalg.norm(x[pair[0]] - x[pair[1]]) for pair in ring}
    edge = np.linalg.norm(x[ico.edges_unique[0, 0]] - x[ico.edges_unique[0, 1]])
    assert all(abs(d - 2.0) > 0.1 and d > edge * 1.1 for d in distance.values())   # never the antipode (d = 2)
    assert np.all(scene.spring_array("stiffness")[mesh.springs["bend"]] == 30.0)
    assert np.all(scene.spring_array("damping")[mesh.springs["bend"]] == 0.2)
    none = ws.Scene()
    none.add_soft_mesh(ico, internal=None)
    assert none.spring_count == 30


def dented_icosahedron():
    """The icosahedron and a copy with vertex 0 mirrored through the plane of its five neighbours."""
    ico = trimesh.creation.icosahedron()
    x = np.asarray(ico.vertices, dtype=np.float64)
    ring = np.unique(ico.edges_unique[np.any(ico.edges_unique == 0, axis=1)])
    ring = ring[ring != 0]
    centre = x[ring].mean(axis=0)
    normal = x[0] - centre
    normal /= np.linalg.norm(normal)
    assert np.allclose((x[ring] - centre) @ normal, 0.0, atol=1e-12)      # a planar pentagon
    dented = x.copy()
    dented[0] = x[0] - 2.0 * ((x[0] - centre) @ normal) * normal
    return ico, dented, normal


def spring_forces(scene, x):
    """Hooke forces f_i = sum k (L - L0) (x_j - x_i) / L on every particle, and the stored energy."""
    pairs, k, rest = (scene.spring_array(key) for key in ("pairs", "stiffness", "rest_length"))
    d = x[pairs[:, 1]] - x[pairs[:, 0]]
    length = np.linalg.norm(d, axis=1)
    f = (k * (length - rest) / length)[:, None] * d
    forces = np.zeros_like(x)
    np.add.at(forces, pairs[:, 0], f)
    np.add.at(forces, pairs[:, 1], -f)
    return forces, float(np.sum(0.5 * k * (length - rest) ** 2))


def test_two_ring_springs_resist_a_dent():
    """Mirroring a vertex through its neighbours' plane keeps every edge length: edge springs alone
    exert no force there (the dent is an equilibrium of zero energy); two-ring springs push it back out."""
    ico, dented, outward = dented_icosahedron()
    edges_only, two_ring = ws.Scene(), ws.Scene()
    edges_only.add_soft_mesh(ico, stiffness=1.0e3, internal=None)
    two_ring.add_soft_mesh(ico, stiffness=1.0e3)
    forces, energy = spring_forces(edges_only, dented)
    assert np.abs(forces).max() < 1e-9 and energy < 1e-20
    forces, energy = spring_forces(two_ring, dented)
    assert energy > 1.0
    assert forces[0] @ outward > 100.0                      # [N], pushing the dented vertex back out
    np.testing.assert_allclose(forces.sum(axis=0), 0.0, atol=1e-9)      # internal forces only


def test_dented_soft_body_pops_back_only_with_two_ring_springs(device):
    """Simulated (RK4, no gravity, light drag): the dent springs back with two-ring springs, stays without."""
    ico, dented, _ = dented_icosahedron()
    original = np.asarray(ico.vertices, dtype=np.float64)
    for internal, target in (("two_ring", original), (None, dented)):
        scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision="float64", drag=0.05)
        scene.add_soft_mesh(ico, mass=1.0, stiffness=1.0e3, damping=0.2, internal=internal)
        sim = ws.Simulator(scene, integrator="rk4", device=device)
        sim.state.particle_x.assign(dented)
        sim.step(1.0 / 600.0, steps=1200)
        x = sim.state.particle_x.numpy()
        x -= x.mean(axis=0) - target.mean(axis=0)            # the dent moves the centre of mass; compare shapes
        assert np.linalg.norm(x[0] - target[0]) < 0.05, internal
        assert np.linalg.norm(x[0] - (dented[0] if internal else original[0])) > 0.5, internal


# --------------------------------------------------------------------------- validation


def closed_box():
    return trimesh.creation.box(extents=(1.0, 1.0, 1.0))


def open_sheet():
    return grid_mesh(3, 3, 0.5, 0.5)


BAD_GRID = [
    (dict(resolution=(1, 5)), "resolution"), (dict(resolution=(4,)), "resolution"),
    (dict(resolution=(2.5, 3)), "resolution"), (dict(resolution=("a", 3)), "resolution"),
    (dict(size=(0.0, 1.0)), "size"), (dict(size=(1.0, -2.0)), "size"), (dict(size=(1.0,)), "size"),
    (dict(size=(1.0, math.nan)), "size"),
    (dict(mass=1.0, density=0.2), "mass, density"), (dict(mass=0.0), "mass"), (dict(density=-1.0), "density"),
    (dict(stiffness=(1.0, -1.0, 1.0)), "stiffness"), (dict(stiffness=-5.0), "stiffness"),
    (dict(stiffness=(1.0, 1.0)), "stiffness"), (dict(damping=(1.0, 1.0, -0.1)), "damping"),
    (dict(pinned=[9]), "pinned"), (dict(pinned=[-1]), "pinned"), (dict(pinned="middle"), "pinned"),
    (dict(pinned=[True]), "pinned"), (dict(pinned=[1.5]), "pinned"),
    (dict(orientation=(0.0, 0.0, 0.0, 0.0)), "orientation"), (dict(position=(0.0, 1.0)), "position"),
    (dict(velocity=(0.0, math.inf, 0.0)), "velocity"),
    (dict(drag=-1.0), "drag"), (dict(lift=-0.1), "lift"), (dict(air_density=0.0), "air_density"),
    (dict(max_stretch=0.0), "max_stretch"), (dict(restitution=1.5), "restitution"),
    (dict(friction=-0.2), "friction"), (dict(radius=-0.01), "radius"), (dict(color=(1.0, 0.0)), "color"),
]


@pytest.mark.parametrize("kwargs,name", BAD_GRID)
def test_bad_grid_arguments_rejected(kwargs, name):
    scene = ws.Scene()
    args = dict(resolution=(3, 3), size=(1.0, 1.0)) | kwargs
    with pytest.raises(ValueError, match=rf"^{name}="):
        scene.add_cloth_grid(**args)
    assert (scene.particle_count, scene.spring_count, scene.meshes) == (0, 0, [])   # nothing half-added


def test_duplicate_name_rejected():
    scene = ws.Scene()
    scene.add_cloth_grid(resolution=(3, 3), size=(1.0, 1.0), name="sheet")
    with pytest.raises(ValueError, match="^name="):
        scene.add_soft_mesh(closed_box(), name="sheet")
    assert len(scene.meshes) == 1 and scene.particle_count == 9


def bad_meshes(tmp_path):
    v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]
    return [
        (trimesh.Trimesh(v + [[5.0, 5.0, 5.0]], [[0, 1, 2], [1, 3, 2]], process=False), "mesh", "used by no face"),
        (trimesh.Trimesh(v, [[0, 1, 2], [1, 3, 7]], process=False), "mesh.faces", r"\[0, 4\)"),
        (trimesh.Trimesh(v, [[0, 1, 2], [1, 3, 3]], process=False), "mesh", "repeats a vertex"),
        (trimesh.Trimesh(v + [[2.0, 0.0, 0.0]], [[0, 1, 2], [1, 3, 2], [0, 1, 4]], process=False), "mesh",
         "zero area"),
        (trimesh.Trimesh(v + [[1.0, 0.0, 0.0]], [[0, 1, 2], [1, 3, 2], [1, 4, 3]], process=False), "mesh",
         "zero-length edge"),
        (trimesh.Trimesh(np.array(v) * [1.0, 1.0, math.nan], [[0, 1, 2], [1, 3, 2]], process=False), "mesh.vertices",
         "finite"),
        (trimesh.Trimesh(v, np.zeros((0, 3), dtype=int), process=False), "mesh", "no faces"),
        (str(tmp_path / "missing.obj"), "mesh", "no such file"),
        ([[0, 1, 2]], "mesh", "trimesh.Trimesh"),
    ]


@pytest.mark.parametrize("method", ["add_cloth_mesh", "add_soft_mesh"])
def test_bad_meshes_rejected(tmp_path, method):
    for mesh, name, words in bad_meshes(tmp_path):
        scene = ws.Scene()
        with pytest.raises(ValueError, match=rf"(?s)^{name}=.*{words}"):
            getattr(scene, method)(mesh)
        assert (scene.particle_count, scene.spring_count, scene.meshes) == (0, 0, [])


@pytest.mark.parametrize("kwargs,name", [
    (dict(distribution="volume"), "distribution"), (dict(distribution="mass"), "distribution"),
    (dict(internal="three_ring"), "internal"), (dict(stiffness=-1.0), "stiffness"), (dict(damping=-1.0), "damping"),
    (dict(internal_stiffness=-1.0), "internal_stiffness"), (dict(internal_damping=-2.0), "internal_damping"),
    (dict(mass=-1.0), "mass"), (dict(mass=None), "mass"), (dict(pinned=[9]), "pinned"),
])
def test_bad_soft_mesh_arguments_rejected(kwargs, name):
    scene = ws.Scene()
    with pytest.raises(ValueError, match=rf"^{name}="):
        scene.add_soft_mesh(open_sheet(), **kwargs)   # distribution="volume" fails: the sheet is open
    assert (scene.particle_count, scene.spring_count, scene.meshes) == (0, 0, [])


def test_volume_distribution_needs_an_outward_closed_mesh():
    box = closed_box()
    with pytest.raises(ValueError, match="^distribution=.*closed"):
        ws.Scene().add_soft_mesh(trimesh.Trimesh(box.vertices, box.faces[:-1], process=False), distribution="volume")
    with pytest.raises(ValueError, match="^mesh=.*inside out"):
        ws.Scene().add_soft_mesh(trimesh.Trimesh(box.vertices, box.faces[:, ::-1], process=False),
                                 distribution="volume")


@pytest.mark.parametrize("kwargs,name", [(dict(mass=1.0, density=1.0), "mass, density"), (dict(stiffness=(-1, 0, 0)),
                                          "stiffness"), (dict(max_stretch=-0.1), "max_stretch")])
def test_bad_cloth_mesh_arguments_rejected(kwargs, name):
    scene = ws.Scene()
    with pytest.raises(ValueError, match=rf"^{name}="):
        scene.add_cloth_mesh(open_sheet(), **kwargs)
    assert (scene.particle_count, scene.spring_count, scene.meshes) == (0, 0, [])


def test_a_huge_resolution_is_refused_by_its_size_before_allocation():
    """As an emitter's pool is: (100000, 100000) is 1e10 vertices, about 11,921 GiB to build, above the 16 GiB bound
    (cloth.GRID_VERTEX_BYTES a vertex at the peak of add_cloth_grid); nothing is allocated (it returns at once)."""
    scene = ws.Scene()
    with pytest.raises(ValueError, match=r"^resolution=\[100000 100000\] is invalid: the grid would hold "
                                         r"10,000,000,000 particles, about 11,920.9 GiB to build, above the 16 GiB"):
        scene.add_cloth_grid(resolution=(100000, 100000))
    assert scene.particle_count == 0

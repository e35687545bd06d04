"""Cloth and soft-body topology: pure-numpy builders of vertices, faces, spring families and mass weights.

``Scene.add_cloth_grid``, ``add_cloth_mesh`` and ``add_soft_mesh`` are thin wrappers: they place
a ``Topology`` in the world, turn its weights into particle masses and add its springs.
Everything here is vectorised (no Python loop per vertex, edge or face).

The lecture's mass-spring cloth: every vertex a point mass, every spring paired with a damper,
rest length = initial length; three spring families, each with its own stiffness and damping:

- structural springs along the weft and warp (rows and columns of the quad weave),
- shear springs across both diagonals of each quad,
- bend springs to the second neighbours along rows and columns (they resist folding along
  the structural springs).

A triangle mesh (``mesh_cloth``; trimesh splits every quad into two triangles on load)
recovers the same families by rule:

- quads: two triangles sharing an interior edge form a quad when that edge lies opposite the
  largest angle of both, and both those angles are within ``QUAD_ANGLE_TOLERANCE`` of 90
  degrees (a near-rectangular quad split along its diagonal);
- structural: every mesh edge except the recovered quads' diagonals;
- shear: both diagonals of every recovered quad (the shared edge and the pair of opposite
  corners); a triangle left unpaired gets none (its three structural edges already fix its shape);
- bend: along nearly straight lines of structural edges: for every vertex v and structural
  neighbour a, the structural neighbour b of v that makes the straightest path a-v-b, when
  the angle a-v-b is at least ``BEND_MIN_ANGLE``; the spring joins a and b.

A pair of vertices gets at most one spring (structural before shear before bend). On a
triangulated rectangular quad grid these rules give exactly ``grid_cloth``'s families.

A soft body (``soft_mesh``): every edge a spring (family "structural"); ``internal="two_ring"``
adds one spring between every two vertices exactly two edges apart (neighbours of neighbours
not themselves neighbours; family "bend"). Edge springs alone leave a closed surface free to
dent: mirroring a vertex through the plane of its neighbours (a snap-through) keeps every edge
length, so nothing pushes it back; two-ring springs span that dent and resist it, as bend
springs resist folding a cloth. Family "shear" is empty for soft bodies.
"""
from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass

import numpy as np
import trimesh

from ..util import checks
from .emitters import MAX_POOL_BYTES

FAMILIES = ("structural", "shear", "bend")
DEFAULT_CLOTH_DENSITY = 0.1     # [kg/m^2], a light cotton
QUAD_ANGLE_TOLERANCE = 15.0     # [deg] how far from 90 degrees a quad corner split off by its diagonal may be
BEND_MIN_ANGLE = 150.0          # [deg] smallest angle a-v-b of a "nearly straight" line that gets a bend spring
DEGENERATE_AREA = 1e-12         # a face with area <= this x its longest edge squared has zero area
PIN_NAMES = ("corners", "top_corners", "top", "bottom", "left", "right")
DISTRIBUTIONS = ("uniform", "area", "volume")
INTERNAL = ("two_ring", None)
#: host bytes a grid vertex costs at the peak of add_cloth_grid (measured: 1.23 kB at 512 x 512: the topology, its
#: six springs, the duplicate-spring check's sort), against the same 16 GiB bound as an emitter's pool
GRID_VERTEX_BYTES = 1280


@dataclass(frozen=True)
class Topology:
    """A cloth or soft body before placement, indices local to it (0 .. count - 1).

    vertices (N, 3) [m]; weights (N,): each vertex's share of the mass (areas [m^2] for cloth
    and the "area" distribution, volumes [m^3] for "volume", 1 for "uniform"); face_counts
    (F,) and face_indices (sum of face_counts,); triangles (T, 3); springs: family name ->
    (K, 2) vertex pairs, in FAMILIES order.
    """
    vertices: np.ndarray
    weights: np.ndarray
    face_counts: np.ndarray
    face_indices: np.ndarray
    triangles: np.ndarray
    springs: dict

    @property
    def count(self) -> int:
        return len(self.vertices)


def _pairs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.stack([a.ravel(), b.ravel()], axis=1).astype(np.int64)


def _no_pairs() -> np.ndarray:
    return np.zeros((0, 2), dtype=np.int64)


# --------------------------------------------------------------------------- grid


def grid_resolution(resolution) -> tuple[int, int]:
    """(nx, ny): vertices per row and rows, integers >= 2."""
    values = np.asarray(resolution, dtype=object)
    if values.shape != (2,):
        raise checks.fail("resolution", resolution, "expected (nx, ny): vertices per row and number of rows")
    try:
        whole = all(not isinstance(v, (bool, np.bool_)) and float(v) == int(v) for v in values)
    except (TypeError, ValueError, OverflowError):
        whole = False
    if not whole:
        raise checks.fail("resolution", resolution, "expected two integers >= 2")
    nx, ny = (int(v) for v in values)
    if nx < 2 or ny < 2:
        raise checks.fail("resolution", resolution, "a cloth grid needs at least 2 x 2 vertices (one quad)")
    if nx * ny * GRID_VERTEX_BYTES > MAX_POOL_BYTES:
        raise checks.fail("resolution", resolution, f"the grid would hold {nx * ny:,} particles, about "
                                                    f"{nx * ny * GRID_VERTEX_BYTES / 2**30:,.1f} GiB to build, above "
                                                    f"the {MAX_POOL_BYTES // 2**30} GiB bound (at most "
                                                    f"{MAX_POOL_BYTES // GRID_VERTEX_BYTES:,} vertices, e.g. 3600 x "
                                                    "3600); lower the resolution")
    return nx, ny


def grid_cloth(resolution, size) -> Topology:
    """A rectangular weave in its local x-y plane, centred on the origin (normal +z).

    resolution (nx, ny): ny rows of nx vertices, vertex (i, j) (column i, row j) has index
    j nx + i (row-major) and sits at x = -width/2 + i width/(nx - 1), y = -height/2 + j height/(ny - 1).
    Quads (i, j), (i+1, j), (i+1, j+1), (i, j+1) wind counter-clockwise seen from +z; each is
    split into triangles (a, b, c), (a, c, d). Weights: a vertex gets a quarter of the area of
    each quad it belongs to (corners 1/4 cell, edges 1/2, inside 1); they sum to width x height.
    """
    nx, ny = grid_resolution(resolution)
    width, height = checks.per_element("size", size, 2, low=0.0, low_open=True)
    xs = np.linspace(-width / 2.0, width / 2.0, nx)
    ys = np.linspace(-height / 2.0, height / 2.0, ny)
    vertices = np.zeros((ny, nx, 3))
    vertices[:, :, 0] = xs[None, :]
    vertices[:, :, 1] = ys[:, None]
    ids = np.arange(nx * ny, dtype=np.int64).reshape(ny, nx)
    springs = {
        "structural": np.concatenate([_pairs(ids[:, :-1], ids[:, 1:]), _pairs(ids[:-1, :], ids[1:, :])]),
        "shear": np.concatenate([_pairs(ids[:-1, :-1], ids[1:, 1:]), _pairs(ids[:-1, 1:], ids[1:, :-1])]),
        "bend": np.concatenate([_pairs(ids[:, :-2], ids[:, 2:]), _pairs(ids[:-2, :], ids[2:, :])]),
    }
    a, b, c, d = (corner.ravel() for corner in (ids[:-1, :-1], ids[:-1, 1:], ids[1:, 1:], ids[1:, :-1]))
    quads = np.stack([a, b, c, d], axis=1)
    triangles = np.stack([np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)], axis=1).reshape(-1, 3)
    wx = np.full(nx, width / (nx - 1))
    wx[[0, -1]] /= 2.0
    wy = np.full(ny, height / (ny - 1))
    wy[[0, -1]] /= 2.0
    return Topology(vertices.reshape(-1, 3), np.outer(wy, wx).ravel(), np.full(len(quads), 4, dtype=np.int32),
                    quads.ravel().astype(np.int32), triangles, springs)


def grid_pins(pinned, nx: int, ny: int) -> np.ndarray:
    """Local indices (sorted, unique) of the grid vertices named by ``pinned``.

    pinned: an index, a name, or a list mixing both. Names: "corners" (all four),
    "top_corners" (the two corners of the last row), "top" (last row, +y), "bottom"
    (first row), "left" (first column, -x), "right" (last column).
    """
    ids = np.arange(nx * ny, dtype=np.int64).reshape(ny, nx)
    named = {"corners": ids[[0, 0, -1, -1], [0, -1, 0, -1]], "top_corners": ids[-1, [0, -1]],
             "top": ids[-1], "bottom": ids[0], "left": ids[:, 0], "right": ids[:, -1]}
    if pinned is None:
        items = []
    elif isinstance(pinned, str) or np.ndim(pinned) == 0:
        items = [pinned]
    else:
        items = list(pinned)
    chosen, numbers = [], []
    for item in items:
        if isinstance(item, str):
            if item not in named:
                raise checks.fail("pinned", pinned, f"unknown name {item!r}; names are {', '.join(PIN_NAMES)} "
                                                    "(or vertex indices, row-major)")
            chosen.append(named[item])
        elif isinstance(item, (bool, np.bool_)):
            raise checks.fail("pinned", pinned, "expected vertex indices or names, got a bool")
        else:
            numbers.append(item)
    if numbers:
        chosen.append(checks.indices("pinned", numbers, nx * ny, (-1,)))
    return np.unique(np.concatenate(chosen)) if chosen else np.zeros(0, dtype=np.int64)


def vertex_pins(pinned, count: int) -> np.ndarray:
    """Local indices (sorted, unique) of the mesh vertices listed in ``pinned`` (an index or a list)."""
    if pinned is None:
        return np.zeros(0, dtype=np.int64)
    items = [pinned] if np.ndim(pinned) == 0 else pinned
    if any(isinstance(item, str) for item in items):
        raise checks.fail("pinned", pinned, f"pin names ({', '.join(PIN_NAMES)}) only apply to add_cloth_grid; "
                                            "give vertex indices")
    if any(isinstance(item, (bool, np.bool_)) for item in items):
        raise checks.fail("pinned", pinned, "expected vertex indices, got a bool")
    return np.unique(checks.indices("pinned", list(items), count, (-1,)))


# --------------------------------------------------------------------------- meshes


def load_mesh(mesh, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """(vertices (N, 3) float64, faces (F, 3) int64) of a trimesh.Trimesh or a mesh file, checked.

    Files are read with ``trimesh.load(path, force="mesh", process=False)``, and a Trimesh is
    taken as it is: vertices are never merged, dropped or reordered, so vertex i is particle
    start + i (trimesh still triangulates quads and polygons on load). Rejected (ValueError
    naming ``name``): no triangles, non-finite vertices, face indices out of range, a face
    repeating a vertex, vertices used by no face (they would be loose particles), zero-length
    edges and zero-area faces. Vertices at the same position not joined by any face (a seam
    split by the file's UVs, or a triangle soup) give a UserWarning: they move independently.
    """
    if isinstance(mesh, (str, os.PathLike)):
        if not os.path.isfile(mesh):
            raise checks.fail(name, mesh, "no such file")
        try:
            loaded = trimesh.load(mesh, force="mesh", process=False)
        except Exception as error:  # noqa: BLE001 - trimesh's loaders raise ValueError, IndexError, ImportError ...
            raise checks.fail(name, mesh, f"could not be read as a mesh ({type(error).__name__}: {error})") from None
    else:
        loaded = mesh
    if not isinstance(loaded, trimesh.Trimesh):
        raise checks.fail(name, mesh, f"expected a trimesh.Trimesh or a path to a mesh file, got "
                                      f"{type(loaded).__name__}")
    if len(loaded.faces) == 0:
        raise checks.fail(name, mesh, "the mesh has no faces")
    vertices = checks.finite_array(f"{name}.vertices", loaded.vertices, (-1, 3))
    faces = checks.indices(f"{name}.faces", loaded.faces, len(vertices), (-1, 3))
    repeated = np.flatnonzero((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2])
                              | (faces[:, 0] == faces[:, 2]))
    if len(repeated):
        k = repeated[0]
        raise checks.fail(name, mesh, f"face {k} {tuple(faces[k].tolist())} repeats a vertex ({len(repeated)} such "
                                      "faces); remove them (mesh.update_faces(mesh.nondegenerate_faces()))")
    unused = np.flatnonzero(np.bincount(faces.ravel(), minlength=len(vertices)) == 0)
    if len(unused):
        raise checks.fail(name, mesh, f"{len(unused)} vertices are used by no face (first: {unused[:5].tolist()}); "
                                      "they would be loose particles: mesh.remove_unreferenced_vertices()")
    sides = vertices[np.roll(faces, -1, axis=1)] - vertices[faces]     # side k runs from corner k to k + 1
    lengths = np.linalg.norm(sides, axis=2)
    zero = np.argwhere(lengths == 0.0)
    if len(zero):
        f, k = zero[0]
        raise checks.fail(name, mesh, f"face {f} has a zero-length edge: vertices {faces[f, k]} and "
                                      f"{faces[f, (k + 1) % 3]} coincide; merge them (mesh.merge_vertices())")
    area = 0.5 * np.linalg.norm(np.cross(sides[:, 0], -sides[:, 2]), axis=1)
    flat = np.flatnonzero(area <= DEGENERATE_AREA * lengths.max(axis=1) ** 2)
    if len(flat):
        f = flat[0]
        raise checks.fail(name, mesh, f"face {f} {tuple(faces[f].tolist())} has zero area (its corners are in a "
                                      f"line; {len(flat)} such faces); remove or repair degenerate faces")
    _warn_coincident(name, vertices, faces)
    return vertices, faces


def _warn_coincident(name: str, vertices: np.ndarray, faces: np.ndarray) -> None:
    _, first, group = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    group = group.ravel()
    copies = np.flatnonzero(first[group] != np.arange(len(vertices)))
    if len(copies):
        k = copies[0]
        warnings.warn(f"{name}: {len(copies)} vertices lie exactly on another (e.g. vertex {k} on vertex "
                      f"{first[group[k]]}); they are separate particles, not joined, so the surface can split "
                      "there (a seam split by UVs or a triangle soup?); mesh.merge_vertices() joins them",
                      stacklevel=4)


def _edges(faces: np.ndarray, count: int):
    """Unique undirected edges (E, 2) (low, high) of triangles, and each face side's edge id (F, 3)."""
    sides = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    low, high = sides.min(axis=1), sides.max(axis=1)
    keys, side_edge = np.unique(low * count + high, return_inverse=True)
    edges = np.stack([keys // count, keys % count], axis=1)
    return edges, side_edge.reshape(-1, 3)


def _keys(pairs: np.ndarray, count: int) -> np.ndarray:
    return pairs.min(axis=1) * count + pairs.max(axis=1)


def _unique_pairs(pairs: np.ndarray, count: int, exclude=()) -> np.ndarray:
    """Undirected pairs (low, high), unique, without self pairs or those in any ``exclude`` array."""
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    keys = np.unique(_keys(pairs, count))
    for other in exclude:
        keys = keys[~np.isin(keys, _keys(other, count))]
    return np.stack([keys // count, keys % count], axis=1)


def _fans(pairs: np.ndarray, count: int):
    """The half-edges (src, dst) of undirected ``pairs`` sorted by src, and every ordered couple (h, g)
    of different half-edges leaving the same vertex (sum of degree^2 entries)."""
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.argsort(src, kind="stable")
    src, dst = src[order], dst[order]
    degree = np.bincount(src, minlength=count)
    start = np.cumsum(degree) - degree
    reps = degree[src]
    h = np.repeat(np.arange(len(src)), reps)
    g = start[src[h]] + np.arange(len(h)) - np.repeat(np.cumsum(reps) - reps, reps)
    keep = h != g
    return src, dst, h[keep], g[keep]


def straight_pairs(vertices: np.ndarray, pairs: np.ndarray, min_angle: float = BEND_MIN_ANGLE) -> np.ndarray:
    """Bend pairs (a, b): for each vertex v and neighbour a (along ``pairs``), the neighbour b of v making
    the straightest path a-v-b, where the angle a-v-b >= min_angle degrees; unique, undirected."""
    if len(pairs) == 0:
        return _no_pairs()
    src, dst, h, g = _fans(pairs, len(vertices))
    direction = vertices[dst] - vertices[src]
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    cosine = np.einsum("ij,ij->i", direction[h], direction[g])
    order = np.lexsort((cosine, h))                 # by half-edge h, straightest partner first
    h, g, cosine = h[order], g[order], cosine[order]
    first = np.ones(len(h), dtype=bool)
    first[1:] = h[1:] != h[:-1]
    best = first & (cosine <= math.cos(math.radians(min_angle)))
    return _unique_pairs(np.stack([dst[h[best]], dst[g[best]]], axis=1), len(vertices))


def two_ring_pairs(pairs: np.ndarray, count: int) -> np.ndarray:
    """Vertex pairs exactly two steps apart along ``pairs`` (a common neighbour, not neighbours themselves)."""
    if len(pairs) == 0:
        return _no_pairs()
    _, dst, h, g = _fans(pairs, count)
    return _unique_pairs(np.stack([dst[h], dst[g]], axis=1), count, exclude=(pairs,))


def triangle_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    v0, v1, v2 = (vertices[faces[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(np.cross(v1 - v0, v2 - v0), axis=1)


def area_weights(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each vertex's area [m^2]: a third of the area of every triangle it is a corner of."""
    return np.bincount(faces.ravel(), weights=np.repeat(triangle_areas(vertices, faces) / 3.0, 3),
                       minlength=len(vertices))


def mesh_cloth(vertices: np.ndarray, faces: np.ndarray) -> Topology:
    """Cloth families of a checked triangle mesh (see the module docstring for the rules); weights by area."""
    count = len(vertices)
    edges, side_edge = _edges(faces, count)
    # angle at each corner k, opposite side k + 1 (side k joins corners k and k + 1)
    corner = vertices[faces]
    before, after = np.roll(corner, 1, axis=1) - corner, np.roll(corner, -1, axis=1) - corner
    cosine = np.einsum("fki,fki->fk", before, after) / (np.linalg.norm(before, axis=2) * np.linalg.norm(after, axis=2))
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    widest = np.argmax(angle, axis=1)
    right = np.abs(angle[np.arange(len(faces)), widest] - 90.0) <= QUAD_ANGLE_TOLERANCE
    diagonal_side = (widest + 1) % 3                   # the side opposite the widest corner
    # faces on each edge: sort face sides by edge; an edge used by exactly two faces is interior
    side_face = np.repeat(np.arange(len(faces)), 3)
    side_index = np.tile(np.arange(3), len(faces))
    order = np.argsort(side_edge.ravel(), kind="stable")
    uses = np.bincount(side_edge.ravel(), minlength=len(edges))
    first = np.cumsum(uses) - uses
    interior = np.flatnonzero(uses == 2)
    f1, f2 = side_face[order[first[interior]]], side_face[order[first[interior] + 1]]
    s1, s2 = side_index[order[first[interior]]], side_index[order[first[interior] + 1]]
    is_diagonal = right[f1] & right[f2] & (diagonal_side[f1] == s1) & (diagonal_side[f2] == s2)
    diagonals = interior[is_diagonal]
    f1, f2, s1, s2 = f1[is_diagonal], f2[is_diagonal], s1[is_diagonal], s2[is_diagonal]
    opposite = np.stack([faces[f1, (s1 + 2) % 3], faces[f2, (s2 + 2) % 3]], axis=1)
    structural = np.delete(edges, diagonals, axis=0)
    shear = _unique_pairs(np.concatenate([edges[diagonals], opposite]), count, exclude=(structural,))
    bend = straight_pairs(vertices, structural)
    bend = _unique_pairs(bend, count, exclude=(structural, shear)) if len(bend) else bend
    return Topology(vertices, area_weights(vertices, faces), np.full(len(faces), 3, dtype=np.int32),
                    faces.ravel().astype(np.int32), faces, {"structural": structural, "shear": shear, "bend": bend})


def closed_volume(vertices: np.ndarray, faces: np.ndarray) -> float | None:
    """The enclosed volume [m^3] if every edge joins exactly two faces wound consistently (each directed
    edge used once, its reverse once), else None."""
    count = len(vertices)
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    keys = np.sort(directed[:, 0] * count + directed[:, 1])
    if len(keys) > 1 and np.any(keys[1:] == keys[:-1]):
        return None
    reverse = directed[:, 1] * count + directed[:, 0]
    if not np.all(np.isin(reverse, keys)):
        return None
    v0, v1, v2 = (vertices[faces[:, k]] for k in range(3))
    return float(np.sum(np.einsum("ij,ij->i", v0, np.cross(v1, v2))) / 6.0)


def volume_weights(vertices: np.ndarray, faces: np.ndarray, mesh_label="mesh") -> np.ndarray:
    """Each vertex's volume [m^3] of a closed mesh: with c the solid's centroid, the tetrahedron (c, triangle)
    gives a third of its signed volume to each of the triangle's corners; they sum to the enclosed volume."""
    volume = closed_volume(vertices, faces)
    if volume is None:
        raise checks.fail("distribution", "volume", "needs a closed mesh (every edge shared by exactly two "
                                                    "consistently wound faces); this one is open: use 'area' or "
                                                    "'uniform'")
    if not volume > 0.0:
        raise checks.fail(mesh_label, f"closed mesh of volume {volume:.6g} m^3",
                          "the mesh is inside out or flat (signed volume <= 0); fix its winding (mesh.invert())")
    v0, v1, v2 = (vertices[faces[:, k]] for k in range(3))
    six = np.einsum("ij,ij->i", v0, np.cross(v1, v2))        # 6 x signed volume of (origin, triangle)
    centroid = (six[:, None] * (v0 + v1 + v2)).sum(axis=0) / (4.0 * six.sum())
    tets = np.einsum("ij,ij->i", v0 - centroid, np.cross(v1 - centroid, v2 - centroid)) / 6.0
    weights = np.bincount(faces.ravel(), weights=np.repeat(tets / 3.0, 3), minlength=len(vertices))
    bad = np.flatnonzero(weights <= 0.0)
    if len(bad):
        raise checks.fail("distribution", "volume", f"vertex {bad[0]} gets a share <= 0 ({weights[bad[0]]:.3g} "
                                                    "m^3): the solid is not star-shaped about its centroid; use "
                                                    "'area' or 'uniform'")
    return weights


def soft_mesh(vertices: np.ndarray, faces: np.ndarray, distribution: str = "uniform",
              internal: str | None = "two_ring") -> Topology:
    """A soft body of a checked triangle mesh: structural = every edge, bend = two-ring springs (or none),
    shear = none; weights by ``distribution`` ("uniform": 1 each, "area", "volume")."""
    distribution = checks.choice("distribution", distribution, DISTRIBUTIONS)
    internal = checks.choice("internal", internal, INTERNAL)
    count = len(vertices)
    edges, _ = _edges(faces, count)
    if distribution == "uniform":
        weights = np.ones(count)
    elif distribution == "area":
        weights = area_weights(vertices, faces)
    else:
        weights = volume_weights(vertices, faces)
    bend = two_ring_pairs(edges, count) if internal == "two_ring" else _no_pairs()
    return Topology(vertices, weights, np.full(len(faces), 3, dtype=np.int32), faces.ravel().astype(np.int32),
                    faces, {"structural": edges, "shear": _no_pairs(), "bend": bend})


# --------------------------------------------------------------------------- options


def total_masses(weights: np.ndarray, mass, density, default_density: float | None, unit: str) -> np.ndarray:
    """Per-vertex masses [kg] proportional to ``weights``: summing to ``mass`` [kg], or ``density`` x weight
    (``density`` in kg per ``unit``); exactly one of them, or neither with a default density."""
    if mass is not None and density is not None:
        raise checks.fail("mass, density", (mass, density), f"give either the total mass [kg] or the density "
                                                            f"[kg/{unit}], not both")
    if mass is not None:
        total = checks.scalar("mass", mass, low=0.0, low_open=True)
        return total * (weights / weights.sum())
    if density is None and default_density is None:
        raise checks.fail("mass", mass, "give the total mass [kg]")
    rho = checks.scalar("density", default_density if density is None else density, low=0.0, low_open=True)
    return rho * weights


def family_values(name: str, value) -> np.ndarray:
    """One value >= 0 per spring family (structural, shear, bend): a scalar for all, or three."""
    if np.ndim(value) == 0:
        return np.full(3, checks.scalar(name, value, low=0.0))
    return checks.per_element(name, value, 3, low=0.0)

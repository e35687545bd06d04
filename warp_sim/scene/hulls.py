"""Convex hulls of point sets, in numpy (trimesh's own hull needs scipy, which warp_sim does not depend on).

``convex_hull`` is Quickhull in 3D: a tetrahedron of extreme points, then, farthest point first, each point
outside the hull replaces the faces it sees by a fan from the horizon of those faces to it. Points within
``tolerance`` [length] of the hull count as on it and are left out (they would only add slivers), so the hull's
vertices are a subset of the points and every face winds outward (counter-clockwise seen from outside).
``flat_hull`` is the hull of coplanar points, a convex polygon (Andrew's monotone chain), as a thin prism.
"""
from __future__ import annotations

import numpy as np


def convex_hull(points, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3), faces (F, 3), wound outward) of the hull of ``points`` (N, 3), which must span 3D by more
    than ``tolerance`` [length] (else ValueError)."""
    P = np.unique(np.asarray(points, dtype=np.float64), axis=0)
    start = _tetrahedron(P, tolerance)
    hull = _Hull(P, tolerance)
    centre = P[start].mean(axis=0)
    for face in ((0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0)):
        a, b, c = (start[k] for k in face)
        hull.add(*((a, b, c) if np.cross(P[b] - P[a], P[c] - P[a]) @ (P[a] - centre) > 0.0 else (a, c, b)))
    hull.assign(np.setdiff1d(np.arange(len(P)), start), np.arange(4))
    while hull.outside:
        f, points = hull.outside.popitem()
        if hull.alive[f]:
            heights = P[points] @ hull.normals[f] - hull.offsets[f]
            hull.grow(int(points[np.argmax(heights)]), f, points)
    faces = np.array([f for f, alive in zip(hull.faces, hull.alive) if alive], dtype=np.int64)
    used, faces = np.unique(faces, return_inverse=True)
    return P[used], faces.reshape(-1, 3)


def _tetrahedron(P: np.ndarray, tolerance: float) -> list[int]:
    """Four points of P spanning the largest tetrahedron a greedy search finds: the extreme x, the point farthest
    from it, the farthest from their line, the farthest from their plane."""
    i0 = int(np.argmin(P[:, 0]))
    i1 = int(np.argmax(np.linalg.norm(P - P[i0], axis=1)))
    axis = P[i1] - P[i0]
    if np.linalg.norm(axis) <= tolerance:
        raise ValueError("the points coincide")
    axis /= np.linalg.norm(axis)
    i2 = int(np.argmax(np.linalg.norm(np.cross(P - P[i0], axis), axis=1)))
    normal = np.cross(P[i1] - P[i0], P[i2] - P[i0])
    if np.linalg.norm(np.cross(P[i2] - P[i0], axis)) <= tolerance:
        raise ValueError("the points lie on a line")
    heights = (P - P[i0]) @ (normal / np.linalg.norm(normal))
    i3 = int(np.argmax(np.abs(heights)))
    if abs(heights[i3]) <= tolerance:
        raise ValueError("the points lie in a plane")
    return [i0, i1, i2, i3]


class _Hull:
    """Quickhull's state: faces (index triples, alive flags, unit normals and offsets), the directed edge -> face
    map, and per face the points outside it (beyond the tolerance, each point given to one face only)."""

    def __init__(self, P: np.ndarray, tolerance: float):
        self.P, self.tolerance = P, tolerance
        self.faces: list[tuple[int, int, int]] = []
        self.alive: list[bool] = []
        self.normals = np.zeros((16, 3))
        self.offsets = np.zeros(16)
        self.edges: dict[tuple[int, int], int] = {}
        self.outside: dict[int, np.ndarray] = {}

    def add(self, a: int, b: int, c: int) -> int:
        f = len(self.faces)
        if f == len(self.offsets):
            self.normals = np.concatenate([self.normals, np.zeros_like(self.normals)])
            self.offsets = np.concatenate([self.offsets, np.zeros_like(self.offsets)])
        normal = np.cross(self.P[b] - self.P[a], self.P[c] - self.P[a])
        length = np.linalg.norm(normal)
        self.normals[f] = normal / length if length > 0.0 else 0.0   # a sliver faces nothing: never seen
        self.offsets[f] = self.normals[f] @ self.P[a]
        self.faces.append((a, b, c))
        self.alive.append(True)
        for edge in ((a, b), (b, c), (c, a)):
            self.edges[edge] = f
        return f

    def assign(self, points: np.ndarray, faces: np.ndarray) -> None:
        """Give each of ``points`` to the face among ``faces`` it lies farthest outside of, beyond the tolerance."""
        if len(points) == 0 or len(faces) == 0:
            return
        heights = self.P[points] @ self.normals[faces].T - self.offsets[faces]
        best = np.argmax(heights, axis=1)
        out = heights[np.arange(len(points)), best] > self.tolerance
        for f in np.unique(best[out]):
            self.outside[int(faces[f])] = points[out & (best == f)]

    def grow(self, k: int, f0: int, points: np.ndarray) -> None:
        """Add point k, which lies outside face f0 (whose outside ``points`` it is one of): the faces it sees (found
        from f0 across edges, so they stay connected) go, and a fan from their horizon to k takes their place;
        their outside points go to the new faces."""
        p = self.P[k]
        seen, horizon, stack = {f0}, [], [f0]
        while stack:
            f = stack.pop()
            a, b, c = self.faces[f]
            for edge in ((a, b), (b, c), (c, a)):
                g = self.edges[(edge[1], edge[0])]
                if g in seen:
                    continue
                if self.normals[g] @ p - self.offsets[g] > self.tolerance:
                    seen.add(g)
                    stack.append(g)
                else:
                    horizon.append(edge)
        orphans = [points] + [self.outside.pop(f) for f in seen if f in self.outside]
        for f in seen:
            self.alive[f] = False
        new = np.array([self.add(a, b, k) for a, b in horizon], dtype=np.int64)
        orphans = np.concatenate(orphans)
        self.assign(orphans[orphans != k], new)


def flat_hull(points, front, thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces wound outward) of the prism over the convex polygon of coplanar ``points`` (N, 3): its top
    face the polygon, in the points' plane, its bottom ``thickness`` [length] behind it, away from the unit
    ``front`` (the plane's normal on the side that stays free)."""
    P = np.asarray(points, dtype=np.float64)
    front = np.asarray(front, dtype=np.float64)
    u = np.cross(front, np.eye(3)[int(np.argmin(np.abs(front)))])
    u /= np.linalg.norm(u)
    v = np.cross(front, u)                        # (u, v, front) right-handed: counter-clockwise about front
    ring = P[_polygon(P @ u, P @ v)]
    level = float(np.max(P @ front))             # the plane (coplanar points: any of them, the highest exactly)
    top = ring + (level - ring @ front)[:, None] * front
    bottom = top - thickness * front
    m = len(ring)
    faces = [(0, i, i + 1) for i in range(1, m - 1)]                          # top: normal +front
    faces += [(m, m + i + 1, m + i) for i in range(1, m - 1)]                 # bottom: normal -front
    for i in range(m):
        j = (i + 1) % m
        faces += [(i, m + i, m + j), (i, m + j, j)]                           # sides: outward
    return np.concatenate([top, bottom]), np.array(faces, dtype=np.int64)


def _polygon(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Indices of the convex polygon's corners of the points (x, y), counter-clockwise, collinear points left out."""
    order = np.lexsort((y, x))
    span = max(float(np.ptp(x)), float(np.ptp(y)))
    tolerance = 1e-12 * span * span

    def chain(indices):
        kept: list[int] = []
        for i in indices:
            while len(kept) >= 2:
                a, b = kept[-2], kept[-1]
                if (x[b] - x[a]) * (y[i] - y[a]) - (y[b] - y[a]) * (x[i] - x[a]) > tolerance:
                    break
                kept.pop()
            kept.append(int(i))
        return kept

    lower, upper = chain(order), chain(order[::-1])
    corners = np.array(lower[:-1] + upper[:-1], dtype=np.int64)
    if len(corners) < 3:
        raise ValueError("the points lie on a line")
    return corners

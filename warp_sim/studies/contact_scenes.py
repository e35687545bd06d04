"""Rigid contact scenes users build at frame rate: a stack, a pyramid, a heavy box on light ones, a pile.

Shared by the frame-rate tests, the stability study (the largest step at which each still
stands) and the collision benchmark (the pile). Every box is ws.Box with half extents in
metres; every material is restitution 0 and friction 0.7 (the pile: 0.3 and 0.5).
"""
from __future__ import annotations

import math

import numpy as np

from ..scene import Box, Scene, Sphere

FRICTION = 0.7          # stacks, pyramid and mass ratio: every body and the ground; restitution 0
STACK_SIZE = 0.5        # [m] edge of the stacked and pyramid boxes (1 kg each)
PYRAMID_GAP = 0.01      # [m] between neighbours in a pyramid row
PILE_SIZES = (0.05, 0.1)           # [m] box half extents (per axis) and sphere radii, uniform
PILE_DENSITY = 1000.0              # [kg/m^3]
PILE_RESTITUTION, PILE_FRICTION = 0.3, 0.5
PILE_JITTER = 0.05                 # [m] per axis, uniform in [-JITTER, JITTER]
PILE_GAP = 0.01                    # [m] least gap between two bounding spheres at the start
PILE_SPACING = 2.0 * (math.sqrt(3.0) * PILE_SIZES[1] + PILE_JITTER) + PILE_GAP   # [m] lattice pitch: 0.456 m
PILE_LAYERS = 10                   # at most
PILE_BASE = 0.3                    # [m] height of the lowest layer's centres


def _ground(precision: str, restitution: float = 0.0, friction: float = FRICTION) -> Scene:
    scene = Scene(precision=precision)
    scene.add_ground(restitution=restitution, friction=friction)
    return scene


def _box(scene: Scene, half_extents, position, mass: float) -> None:
    scene.add_rigid_body(Box(half_extents), position=position, mass=mass, restitution=0.0, friction=FRICTION)


def stack(count: int = 10, precision: str = "float32") -> Scene:
    """``count`` 0.5 m boxes of 1 kg, each resting on the one below, the lowest on the ground."""
    scene = _ground(precision)
    half = STACK_SIZE / 2.0
    for k in range(count):
        _box(scene, (half, half, half), (0.0, half + STACK_SIZE * k, 0.0), 1.0)
    return scene


def pyramid(rows: int = 5, precision: str = "float32") -> Scene:
    """A pyramid of 0.5 m boxes of 1 kg, ``rows`` at the bottom down to 1 at the top (5-4-3-2-1: 15 boxes),
    PYRAMID_GAP between neighbours in a row, each box above resting on two below."""
    scene = _ground(precision)
    half, pitch = STACK_SIZE / 2.0, STACK_SIZE + PYRAMID_GAP
    for row in range(rows):
        for i in range(rows - row):
            _box(scene, (half, half, half), ((i - (rows - row - 1) / 2.0) * pitch, half + STACK_SIZE * row, 0.0), 1.0)
    return scene


def heavy_on_light(ratio: float = 100.0, precision: str = "float32") -> Scene:
    """A 1 x 0.2 x 1 m box of ``ratio`` kg on four 0.2 m cubes of 1 kg, one under each of its corners."""
    scene = _ground(precision)
    for sx in (-1.0, 1.0):
        for sz in (-1.0, 1.0):
            _box(scene, (0.1, 0.1, 0.1), (0.4 * sx, 0.1, 0.4 * sz), 1.0)
    _box(scene, (0.5, 0.1, 0.5), (0.0, 0.3, 0.0), ratio)
    return scene


def pile_lattice(n: int) -> np.ndarray:
    """n lattice points, layer by layer from the bottom: min(PILE_LAYERS, ceil(cbrt n)) layers over a square
    footprint of side ceil(sqrt(n / layers)) points, PILE_SPACING apart, centred on x = z = 0, the lowest at
    y = PILE_BASE [m]."""
    layers = min(PILE_LAYERS, math.ceil(round(n ** (1.0 / 3.0), 9)))
    side = math.ceil(math.sqrt(n / layers))
    layers = math.ceil(n / side**2)
    j, i, k = np.meshgrid(np.arange(layers), np.arange(side), np.arange(side), indexing="ij")
    points = np.stack([i.ravel(), j.ravel(), k.ravel()], axis=1)[:n].astype(np.float64)
    offset = np.array([(side - 1) / 2.0, -PILE_BASE / PILE_SPACING, (side - 1) / 2.0])
    return PILE_SPACING * (points - offset)


def pile_bodies(n: int, seed: int = 0) -> dict:
    """n bodies' shapes and poses as arrays: kind ("box" or "sphere", half each, shuffled), size (box half
    extents; a sphere's radius in column 0) [m], position (the lattice jittered) [m], orientation (x, y, z, w,
    uniformly random); seeded."""
    rng = np.random.default_rng(seed)
    kinds = np.array(["box"] * (n // 2) + ["sphere"] * (n - n // 2))
    rng.shuffle(kinds)
    sizes = rng.uniform(*PILE_SIZES, size=(n, 3))
    positions = pile_lattice(n) + rng.uniform(-PILE_JITTER, PILE_JITTER, size=(n, 3))
    quaternions = rng.normal(size=(n, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    return {"kind": kinds, "size": sizes, "position": positions, "orientation": quaternions}


def pile(bodies: dict, precision: str = "float32") -> Scene:
    """The ground and one add_rigid_body call per body of ``pile_bodies``, as a user would; the default gravity."""
    scene = _ground(precision, PILE_RESTITUTION, PILE_FRICTION)
    for kind, size, position, orientation in zip(bodies["kind"].tolist(), bodies["size"].tolist(),
                                                 bodies["position"].tolist(), bodies["orientation"].tolist(),
                                                 strict=True):
        shape = Box(size) if kind == "box" else Sphere(size[0])
        scene.add_rigid_body(shape, density=PILE_DENSITY, position=position, orientation=orientation,
                             restitution=PILE_RESTITUTION, friction=PILE_FRICTION)
    return scene


def lowest_points(x: np.ndarray, R: np.ndarray, bodies: dict) -> np.ndarray:
    """Each pile body's lowest point [m] (y), from centres x [m] and rotations R: a sphere's centre less its
    radius, a box's centre less the y-extent of its rotated half extents (its lowest corner)."""
    is_box = bodies["kind"] == "box"
    reach = np.where(is_box, np.sum(np.abs(R[:, 1, :]) * bodies["size"], axis=1), bodies["size"][:, 0])
    return x[:, 1] - reach


def displacement(sim, start: np.ndarray) -> float:
    """The largest distance [m] any body's centre has moved from ``start`` (body_x at the start)."""
    return float(np.linalg.norm(sim.state.body_x.numpy().astype(np.float64) - start, axis=1).max())

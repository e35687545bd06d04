"""Small scene builders and stage readers shared by the tests."""
import importlib.util
import pathlib
import sys

import numpy as np
from pxr import Sdf

import warp_sim as ws
from warp_sim.scene import SurfaceMesh
from warp_sim.util.rotations import quat_to_matrix

G = 9.81


def oscillator(k=4.0, m=1.0, amplitude=0.1, rest=1.0, precision="float64", damping=0.0):
    """A particle on a spring to a pinned particle at the origin, along x, no gravity.
    Returns the scene; the free particle is index 1, displaced by `amplitude` from rest."""
    scene = ws.Scene(gravity=(0.0, 0.0, 0.0), precision=precision)
    scene.add_particles([[0.0, 0.0, 0.0], [rest + amplitude, 0.0, 0.0]], mass=[1.0, m], pinned=[0])
    scene.add_springs([[0, 1]], stiffness=k, damping=damping, rest_length=rest)
    return scene


def run_steps(sim, steps, h):
    """``steps`` steps of exactly h seconds each (substeps=1: no automatic split), one step() call each."""
    for _ in range(steps):
        sim.step(h, substeps=1)


def particle(sim, i=0):
    """(position, velocity) of particle i as float64 numpy vectors."""
    return (sim.state.particle_x.numpy()[i].astype(np.float64),
            sim.state.particle_v.numpy()[i].astype(np.float64))


RHO = 1.2   # air density of the cloth tests [kg/m^3]


def add_mesh(scene, triangles, start, count, springs=None, drag=0.0, lift=0.0, air_density=RHO, max_stretch=None):
    """Append a SurfaceMesh record by hand (what Scene.add_cloth_grid will make)."""
    triangles = np.asarray(triangles, dtype=np.int64)
    scene.meshes.append(SurfaceMesh(
        name=f"mesh{len(scene.meshes)}", start=start, count=count, face_counts=np.full(len(triangles), 3),
        face_indices=(triangles - start).ravel(), triangles=triangles,
        springs=springs or {"structural": np.zeros(0, dtype=np.int64), "shear": np.zeros(0, dtype=np.int64),
                            "bend": np.zeros(0, dtype=np.int64)},
        color=(0.8, 0.8, 0.8), drag=drag, lift=lift, air_density=air_density, max_stretch=max_stretch))


def add_grid(scene, n=8, spacing=0.1, mass=0.01, stiffness=10.0, damping=0.01, hanging=True, pin_top=True,
             **mesh_options):
    """An n x n cloth of structural and shear springs: hanging in the xy plane from y = 2 (row 0 on top,
    pinned with pin_top) or lying in the xz plane at y = 1. Returns (particle ids, spring families)."""
    rows, cols = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a, b = cols * spacing, rows * spacing
    zero = np.zeros_like(a, dtype=float)
    positions = np.stack([a, 2.0 - b, zero] if hanging else [a, zero + 1.0, b], -1).reshape(-1, 3)
    grid = np.arange(n * n).reshape(n, n)
    ids = scene.add_particles(positions, mass=mass, pinned=grid[0] if pin_top else None,
                              name=f"cloth{len(scene.meshes)}")
    grid = grid + ids[0]
    structural = np.concatenate([np.stack([grid[:, :-1].ravel(), grid[:, 1:].ravel()], 1),
                                 np.stack([grid[:-1].ravel(), grid[1:].ravel()], 1)])
    shear = np.concatenate([np.stack([grid[:-1, :-1].ravel(), grid[1:, 1:].ravel()], 1),
                            np.stack([grid[:-1, 1:].ravel(), grid[1:, :-1].ravel()], 1)])
    springs = {"structural": scene.add_springs(structural, stiffness, damping),
               "shear": scene.add_springs(shear, stiffness, damping), "bend": np.zeros(0, dtype=np.int64)}
    quads = np.stack([grid[:-1, :-1].ravel(), grid[:-1, 1:].ravel(), grid[1:, 1:].ravel(), grid[1:, :-1].ravel()], 1)
    add_mesh(scene, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]), ids[0], n * n, springs,
             **mesh_options)
    return ids, springs


def host(array):
    """A float64 copy of a device array (on the CPU, .numpy() shares the array's memory)."""
    return np.array(array.numpy(), dtype=np.float64)


def stage_samples(path) -> dict:
    """Every time sample of a USD file: (attribute path, time) -> the value's bytes (or repr for scalars)."""
    layer = Sdf.Layer.FindOrOpen(str(path))
    found = {}

    def visit(spec_path):
        if spec_path.IsPropertyPath():
            for t in layer.ListTimeSamplesForPath(spec_path):
                value = layer.QueryTimeSample(spec_path, t)
                found[(str(spec_path), t)] = np.asarray(value).tobytes() if hasattr(value, "__len__") else repr(value)
    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return found


TOOLS = pathlib.Path(__file__).resolve().parent.parent / "tools"


def load_tool(name: str):
    """The module tools/<name>.py (the tools are scripts, not a package; their shared modules sit beside them)."""
    if str(TOOLS) not in sys.path:
        sys.path.insert(0, str(TOOLS))
    spec = importlib.util.spec_from_file_location(name, TOOLS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def turn_between(q0, q1) -> tuple[float, np.ndarray]:
    """(angle [rad], unit axis) of the world rotation taking orientation q0 to q1 (quaternions x, y, z, w)."""
    turn = quat_to_matrix(np.asarray(q1, float)) @ quat_to_matrix(np.asarray(q0, float)).T
    angle = float(np.arccos(np.clip((np.trace(turn) - 1.0) / 2.0, -1.0, 1.0)))
    axis = np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0], turn[1, 0] - turn[0, 1]])
    return angle, axis / np.linalg.norm(axis)

"""The kernels compile for CUDA on a machine without a GPU, and every overload the simulator launches was declared.

Warp compiles CUDA ahead of time through NVRTC with no GPU and no driver (``wp.compile_aot_module(module,
device=None, arch=...)``), and only the overloads a module declares (kernels.precisions). So: first, a fresh
process runs scenes that use every component, solver and pass, in both precisions, and checks that no
launch needed an overload that was not declared; then every kernel module is compiled for sm_80 and sm_90.
A kernel that only compiles for the CPU, or an overload declared for neither, cannot land."""
import importlib
import pkgutil
import subprocess
import sys
import textwrap

import pytest
import warp as wp

import warp_sim.kernels as package
from warp_sim.kernels import precisions

pytestmark = pytest.mark.slow   # every module compiled for CUDA by NVRTC: about 2 minutes

SCENES = textwrap.dedent("""
    import numpy as np, warp as wp, warnings
    wp.config.quiet = True
    import warp_sim as ws
    from warp_sim.kernels import precisions
    from warp_sim.studies import contact_scenes
    warnings.simplefilter("ignore")
    declared = None

    def snapshot():
        return {id(k): len(k.overloads) for k, _ in precisions._registered}

    for precision in ("float32", "float64"):
        scenes = []
        s = ws.Scene(precision=precision)
        s.add_ground(restitution=0.5)
        s.add_particles(np.random.default_rng(0).uniform(0, 1, (20, 3)), radius=0.02)
        s.add_cloth_grid(resolution=(4, 4), size=(0.5, 0.5), position=(0, 1, 0), pinned=["top_corners"],
                         drag=0.1, lift=0.1, max_stretch=0.1)
        s.add_field(ws.Attractor((0, 0, 0), strength=0.1))
        s.add_field(ws.Vortex((0, 0, 0), axis=(0, 1, 0), strength=0.1))
        s.add_field(ws.Turbulence(strength=0.1, scale=0.5))
        s.add_field(ws.Turbulence(strength=0.1, scale=0.5, frequency=1.0))
        s.add_emitter(rate=100, lifetime=0.5, position=(0, 1, 0), speed=1.0, kill_planes=[((0.0, 1.0, 0.0), -1.0)])
        s.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), position=(0, 0.3, 0))
        s.add_rigid_body(ws.Sphere(0.1), position=(0.05, 0.6, 0))
        scenes.append(s)
        scenes.append(contact_scenes.pile(contact_scenes.pile_bodies(20), precision))
        for scene in scenes:
            for integrator in ("euler", "midpoint", "rk4", "symplectic_euler", "verlet", "implicit_euler", "rk45"):
                for contact in ("impulse", "penalty"):
                    sim = ws.Simulator(scene, integrator=integrator, device="cpu", contact=contact, guard=False)
                    if declared is None:
                        declared = snapshot()   # the Model declared float32 (float64 follows with its Model)
                    sim.step(1.0 / 240.0, steps=3)
                    sim.apply_impulse(0, (0.1, 0, 0))
                    sim.body_rotations(); sim.body_velocities()
        if precision == "float32":
            declared = None
    grown = [k.key for k, _ in precisions._registered if len(k.overloads) != 2]
    print("REGISTERED", len(precisions._registered), "GROWN", grown)
""")


def test_every_launched_overload_was_declared():
    """Each registered generic kernel ends with exactly its two declared overloads (float32, float64): a launch
    with other argument types would have added one."""
    done = subprocess.run([sys.executable, "-c", SCENES], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    line = [entry for entry in done.stdout.splitlines() if entry.startswith("REGISTERED")][-1]
    print(line)
    count, grown = line.split(" GROWN ")
    assert int(count.split()[1]) > 40
    assert grown == "[]"


def kernel_modules():
    names = []
    for info in pkgutil.iter_modules(package.__path__):
        module = importlib.import_module(f"warp_sim.kernels.{info.name}")
        own = [v for v in vars(module).values() if isinstance(v, wp.Kernel) and v.module.name == module.__name__]
        if own:
            names.append(info.name)
    return names


@pytest.mark.parametrize("name", kernel_modules())
def test_module_compiles_for_cuda_without_a_gpu(name, tmp_path):
    precisions.declare(wp.float32)
    precisions.declare(wp.float64)
    module = importlib.import_module(f"warp_sim.kernels.{name}")
    artifacts = wp.compile_aot_module(module, device=None, arch=[80, 90], module_dir=tmp_path)
    assert {path.suffixes[-2] for path in artifacts} == {".sm80", ".sm90"}
    assert all(path.stat().st_size > 0 for path in artifacts)

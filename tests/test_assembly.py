"""A scene allocates and compiles only what it uses: proven in a fresh process per scene."""
import importlib
import json
import pkgutil
import subprocess
import sys

import pytest
import warp as wp

import warp_sim.kernels as topics

PROBE = r"""
import json, pkgutil, sys
import warp as wp
import warp_sim.demo, warp_sim.kernels
wp.config.log_level = wp.LOG_WARNING
import warp_sim as ws
kind = sys.argv[1]
scene = ws.Scene()
if kind != "no_planes":
    scene.add_ground()
if kind != "bodies_only":
    ids = scene.add_particles([[0.0, 1.0, 0.0], [0.5, 1.0, 0.0]])
if kind == "springs":
    scene.add_springs([[0, 1]], 100.0)
if kind == "emitter":
    scene.add_emitter(rate=50.0, lifetime=0.5)
if kind in ("bodies_only", "mixed"):
    scene.add_rigid_body(ws.Box(0.1), position=(0.0, 2.0, 0.0), angular_velocity=(1.0, 2.0, 3.0))
if kind == "demo":
    scene = warp_sim.demo.demo_scene()
sim = ws.Simulator(scene, integrator="symplectic_euler" if kind != "demo" else "rk4", device="cpu",
                   guard=(kind != "no_guard"), fused=sys.argv[2] == "fused")
declared = sim.kernel_modules()
for _ in range(3 if kind != "demo" else 360):   # the demo at its 8 steps per frame: first contacts by 0.75 s
    sim.step(1.0 / 480.0 if kind == "demo" else 0.01)
topics = [module.name for module in pkgutil.iter_modules(warp_sim.kernels.__path__)]
loaded = [t for t in topics if wp.get_module("warp_sim.kernels." + t).execs]
names = ("spring_pairs", "plane_normal", "particle_inv_mass", "body_inv_mass", "body_inv_inertia")
arrays = {name: getattr(sim.model, name) is not None for name in names}
fields = [field.name for field in sim.dynamics.layout.fields]
forces = sim.dynamics.forces
print(json.dumps({"loaded": loaded, "declared": declared, "arrays": arrays, "force": forces.particle_f.shape[0],
                  "body_force": forces.body_f.shape[0] + forces.body_t.shape[0], "fields": fields,
                  "pools": sim.emitters is not None}))
"""


def probe(kind, path="generic"):
    """What a fresh process compiles for a scene ``kind``, on the generic path or the fused one."""
    out = subprocess.run([sys.executable, "-c", PROBE, kind, path], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def kernels(result):
    """The warp_sim kernel modules (topics) that were compiled or loaded for a device."""
    return set(result["loaded"])


def test_particles_only_scene_never_loads_springs_or_bodies():
    result = probe("particles")
    assert not {"springs", "rigid"} & kernels(result)
    assert {"particles", "integrate", "planes", "guards"} <= kernels(result)
    assert result["arrays"] == {"spring_pairs": False, "plane_normal": True, "particle_inv_mass": True,
                                "body_inv_mass": False, "body_inv_inertia": False}
    assert result["force"] == 0          # no force term: no force accumulator either
    assert result["fields"] == ["particle_x", "particle_v"]


def test_emitter_kernels_and_pools_only_with_emitters():
    plain, emitting = probe("particles"), probe("emitter")
    assert "emitters" not in kernels(plain) and not plain["pools"]
    assert "emitters" in kernels(emitting) and emitting["pools"]


def test_rigid_only_scene_loads_no_particle_spring_or_plane_kernels():
    """A body over the ground runs the rigid, integrate and guard modules and the body contacts' (detection,
    manifolds, contacts), and nothing of particles, springs or particle-plane impulses."""
    result = probe("bodies_only")
    assert {"rigid", "integrate", "guards", "detection", "manifolds", "contacts"} == kernels(result)
    assert result["arrays"]["body_inv_inertia"] and not result["arrays"]["particle_inv_mass"]
    assert result["force"] == 0 and result["body_force"] == 0
    assert result["fields"] == ["body_x", "body_q", "body_P", "body_L"]


def test_mixed_scene_has_both_components():
    result = probe("mixed")
    assert {"rigid", "particles", "integrate", "guards", "planes"} <= kernels(result)
    assert result["fields"] == ["particle_x", "particle_v", "body_x", "body_q", "body_P", "body_L"]


def test_springs_are_loaded_when_present():
    result = probe("springs")
    assert "springs" in kernels(result) and result["arrays"]["spring_pairs"]
    assert result["force"] == 2


@pytest.mark.parametrize("kind, absent", [("no_planes", "planes"), ("no_guard", "guards")])
def test_absent_planes_and_guards_are_not_loaded(kind, absent):
    assert absent not in kernels(probe(kind))


def test_fused_path_compiles_only_the_fused_module_for_particles():
    """Particles on the ground under symplectic_euler: one fused kernel replaces the particle, integrate, plane
    and guard modules; with springs the springs module is compiled too (a force term)."""
    assert kernels(probe("particles", "fused")) == {"fused"}
    assert kernels(probe("springs", "fused")) == {"fused", "springs"}
    assert kernels(probe("emitter", "fused")) == {"fused", "emitters", "guards"}   # the guard after the births


@pytest.mark.parametrize("kind, path", [("particles", "generic"), ("mixed", "generic"), ("bodies_only", "generic"),
                                        ("springs", "fused"), ("emitter", "fused"), ("no_guard", "fused"),
                                        ("demo", "generic")])
@pytest.mark.slow   # seven scenes' modules loaded
def test_the_modules_compiled_up_front_are_the_modules_launched(kind, path):
    """Simulator compiles sim.kernel_modules() together at its start (in parallel): exactly those it launches
    (every kernel module of warp_sim.kernels is watched; the demo launches thirteen of them)."""
    result = probe(kind, path)
    assert set(result["declared"]) == kernels(result)


def test_every_kernel_module_has_a_compile_time_to_order_the_start_by():
    """Simulator compiles the longest modules first by kernels.COMPILE_SECONDS: each module with kernels has a
    positive entry, and no entry names a module that is not there."""
    with_kernels = set()
    for module in pkgutil.iter_modules(topics.__path__):
        loaded = importlib.import_module(f"warp_sim.kernels.{module.name}")
        if any(isinstance(value, wp.Kernel) for value in vars(loaded).values()):
            with_kernels.add(module.name)
    assert set(topics.COMPILE_SECONDS) == with_kernels
    assert min(topics.COMPILE_SECONDS.values()) > 0.0

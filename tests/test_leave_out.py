"""A scene allocates and compiles only what it uses: proven in a fresh process per scene."""
import json
import subprocess
import sys

import pytest

PROBE = r"""
import json, sys
import warp as wp
wp.config.log_level = wp.LOG_WARNING
import warp_sim as ws
kind = sys.argv[1]
scene = ws.Scene()
if kind != "no_planes":
    scene.add_ground()
ids = scene.add_particles([[0.0, 1.0, 0.0], [0.5, 1.0, 0.0]])
if kind == "springs":
    scene.add_springs([[0, 1]], 100.0)
sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu", guard=(kind != "no_guard"))
for _ in range(3):
    sim.step(0.01)
topics = ("springs", "planes", "particles", "integrate", "guards")
loaded = [t for t in topics if wp.get_module("warp_sim.kernels." + t).execs]
arrays = {name: getattr(sim.model, name) is not None for name in ("spring_pairs", "plane_normal", "particle_inv_mass")}
print(json.dumps({"loaded": loaded, "arrays": arrays, "force": sim.dynamics.forces.particle_f.shape[0]}))
"""


def probe(kind):
    out = subprocess.run([sys.executable, "-c", PROBE, kind], capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def kernels(result):
    """The warp_sim kernel modules (topics) that were compiled or loaded for a device."""
    return set(result["loaded"])


def test_particles_only_scene_never_loads_springs():
    result = probe("particles")
    assert "springs" not in kernels(result)
    assert {"particles", "integrate", "planes", "guards"} <= kernels(result)
    assert result["arrays"] == {"spring_pairs": False, "plane_normal": True, "particle_inv_mass": True}
    assert result["force"] == 0          # no force term: no force accumulator either


def test_springs_are_loaded_when_present():
    result = probe("springs")
    assert "springs" in kernels(result) and result["arrays"]["spring_pairs"]
    assert result["force"] == 2


@pytest.mark.parametrize("kind, absent", [("no_planes", "planes"), ("no_guard", "guards")])
def test_absent_planes_and_guards_are_not_loaded(kind, absent):
    assert absent not in kernels(probe(kind))

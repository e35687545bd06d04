"""Forward-only runs keep their speed and cold start: importing warp_sim (and so ws.gradient) turns no adjoint on, a
forward-only Simulator in a fresh process, after a differentiable one ran in another, loads its modules with
their backward kernels off (no adjoint compiled, none loaded), built apart from the differentiable ones (other
module hashes), and its launches are the recorded replays of core.launcher, not the tape's wp.launch."""
import json
import subprocess
import sys
import textwrap

CHAIN = """
    import numpy as np, time, json, warp as wp
    wp.config.quiet = True
    import warp_sim as ws
    import warp_sim.gradients
    from warp_sim.core import compiling
    from warp_sim.core.launcher import Launcher
    scene = ws.Scene(precision="float64")
    scene.add_particles([(0.05 * i, -0.3 * i, 0.0) for i in range(5)], mass=0.1, pinned=[0])
    scene.add_springs([(i, i + 1) for i in range(4)], stiffness=50.0, damping=0.2)
    scene.add_rigid_body(ws.Box((0.2, 0.1, 0.05)), mass=2.0, angular_velocity=(1.0, 2.0, 0.5))
    cpu = (wp.get_device("cpu").context, 1)

    def report(sim, started):
        modules = {}
        for name in sim.kernel_modules():
            module = wp.get_module(f"warp_sim.kernels.{name}")
            hooks = [module.execs[cpu].get_kernel_hooks(o) for k in module._get_live_kernels()
                     for o in k.overloads.values()]
            modules[name] = dict(enabled=compiling.adjoints_enabled(name), kernels=len(hooks),
                                 backward=sum(bool(h.backward) for h in hooks),
                                 hash=module.get_module_hash(1).hex()[:12])
        print("REPORT", json.dumps(dict(modules=modules, seconds=time.perf_counter() - started,
                                        launcher=type(sim.model.launcher).__name__)))
"""

DIFFERENTIABLE = CHAIN + """
    started = time.perf_counter()
    sim = ws.Simulator(scene, collisions=False, differentiable=True)
    sim.step(1.0 / 60.0)
    report(sim, started)
"""

FORWARD = CHAIN + """
    enabled = [name for name in compiling.module_names() if compiling.adjoints_enabled(name)]
    assert not enabled, enabled   # importing warp_sim and its gradients turns nothing on
    started = time.perf_counter()
    sim = ws.Simulator(scene, collisions=False)
    sim.step(1.0 / 60.0)
    report(sim, started)
"""


def run(script: str) -> dict:
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(next(line for line in done.stdout.splitlines() if line.startswith("REPORT"))[7:])


def test_a_forward_only_simulator_after_a_differentiable_one_compiles_no_adjoint():
    taped, forward = run(DIFFERENTIABLE), run(FORWARD)
    print(f"differentiable Simulator and a step: {taped['seconds']:.2f} s; forward-only, in a fresh process "
          f"after it: {forward['seconds']:.2f} s")
    assert taped["launcher"] == "TapedLauncher" and forward["launcher"] == "Launcher"
    assert set(taped["modules"]) == set(forward["modules"]) >= {"integrate", "particles", "springs", "rigid"}
    for name, module in forward["modules"].items():
        assert not module["enabled"] and module["backward"] == 0 and module["kernels"] > 0, name
        other = taped["modules"][name]
        if name == "guards":   # the guard's checks are off the tape: no adjoint there either
            assert not other["enabled"] and other["backward"] == 0 and other["hash"] == module["hash"]
        else:
            assert other["enabled"] and other["backward"] == other["kernels"] and other["hash"] != module["hash"]

"""Checkpointing: a state stored per frame (frames + 1 of them), each frame recomputed on a tape of its own in the
backward pass and dropped with everything it made before the next, the same gradient as one tape over the whole
run, and the peak memory of a 16 x 16 cloth's 2 s gradient (8 substeps), measured and printed."""
import json
import subprocess
import sys
import textwrap
import weakref

import numpy as np
import warp as wp
from gradient_scenes import chain, chain_loss

import warp_sim as ws
from warp_sim.gradients.checkpoints import Checkpoints
from warp_sim.gradients.controls import Controls
from warp_sim.gradients.trajectory import Trajectory

FPS, FRAMES, SUBSTEPS = 60.0, 12, 4


def checkpointed(integrator="rk4"):
    sim = ws.Simulator(chain(), integrator, differentiable=True)
    traj = Trajectory(sim.model, FRAMES, FPS)
    run = Checkpoints(sim, FRAMES, FPS, SUBSTEPS, Controls(sim.model, FRAMES, {}, set()))
    run.forward(traj)
    traj.track(["particle_x", "particle_v"])   # what chain_loss reads
    with wp.Tape() as tape:
        loss = chain_loss(traj)
    tape.backward(loss)
    return sim, traj, run


def test_one_state_is_stored_per_frame_and_each_frames_tape_is_dropped():
    """The trajectory's rows are the stored states (with the bodies' momenta, here none, beside them); going back,
    each frame's tape and the state it starts from are dropped before the next frame, whose steps reuse the same
    pool of scratch states."""
    sim, traj, run = checkpointed()
    assert run.count == FRAMES + 1 and run.rest == {}
    assert run.stored_bytes == (FRAMES + 1) * sim.dynamics.layout.size * 8
    forward = ws.Simulator(chain(), "rk4")
    rows = [arrays for _, _, arrays in forward.frames((FRAMES + 1) / FPS, FPS, SUBSTEPS)]
    assert np.array_equal(traj.particle_x.numpy(), np.stack([row["particle_x"] for row in rows]))
    assert np.array_equal(traj.particle_v.numpy(), np.stack([row["particle_v"] for row in rows]))

    visited, previous = [], []

    def on_frame(frame, tape):
        assert all(ref() is None for ref in previous), "the last frame's tape or its start state is still alive"
        previous.clear()
        previous.append(weakref.ref(tape))
        size = sim.dynamics.layout.size
        states = {id(a): a for launch in tape.launches if not callable(launch) for a in launch[3]
                  if isinstance(a, wp.array) and a.shape == (size,)}
        pooled = {id(state.y) for state in run.pool.states}
        previous.extend(weakref.ref(a) for key, a in states.items() if key not in pooled)
        visited.append((frame, len(tape.launches), len(states), run.pool.size))

    run.backward(traj, on_frame)
    frames, launches, states, pooled = zip(*visited)
    print(f"{FRAMES} frames of {SUBSTEPS} rk4 steps: each frame's tape {launches[1]} launches over "
          f"{states[1]} flat states ({pooled[0]} of them a pool reused frame after frame), dropped before the next")
    assert frames == tuple(range(FRAMES, 0, -1))
    assert len(set(launches[:-1])) == 1 and launches[-1] == launches[0] + 2   # frame 1 also copies the initial state
    assert states[1] >= 8 * SUBSTEPS   # rk4: four slopes, three trial states and the end state a step
    assert len(set(pooled)) == 1 and pooled[0] >= 8 * SUBSTEPS - 1


def test_the_checkpointed_gradient_is_one_tape_over_the_whole_run():
    sim, traj, run = checkpointed()
    start = run.backward(traj)
    whole = ws.Simulator(chain(), "rk4", differentiable=True)
    first, full = whole.state, Trajectory(whole.model, FRAMES, FPS)
    full.track(["particle_x", "particle_v"])
    with wp.Tape() as tape:
        wp.copy(full.particle_x[0], first.particle_x)
        wp.copy(full.particle_v[0], first.particle_v)
        for frame in range(1, FRAMES + 1):
            whole.step(1.0 / (FPS * SUBSTEPS), steps=SUBSTEPS)
            wp.copy(full.particle_x[frame], whole.state.particle_x)
            wp.copy(full.particle_v[frame], whole.state.particle_v)
        loss = chain_loss(full)
    tape.backward(loss)
    for ours, theirs in ((start.y.grad, first.y.grad), (sim.model.spring_stiffness.grad,
                                                         whole.model.spring_stiffness.grad),
                         (sim.model.particle_inv_mass.grad, whole.model.particle_inv_mass.grad)):
        a, b = ours.numpy(), theirs.numpy()
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max()


MEMORY = textwrap.dedent("""
    import json, time, numpy as np, warp as wp
    wp.config.quiet = True
    import warp_sim as ws

    def peak_kb():
        for line in open("/proc/self/status"):
            if line.startswith("VmHWM"):
                return int(line.split()[1])

    def reset():
        try:
            with open("/proc/self/clear_refs", "w") as f:
                f.write("5")
            return True
        except OSError:
            return False

    @wp.kernel
    def heights(x: wp.array2d(dtype=wp.vec3d), out: wp.array(dtype=wp.float64)):
        k, i = wp.tid()
        wp.atomic_add(out, 0, x[k, i][1])

    def loss(traj):
        out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
        wp.launch(heights, traj.particle_x.shape, [traj.particle_x, out])
        return out

    def cloth(n):
        scene = ws.Scene(precision="float64")
        scene.add_cloth_grid(resolution=(n, n), size=(1.0, 1.0), mass=1.0, stiffness=(100.0, 100.0, 10.0),
                             damping=(0.1, 0.1, 0.01), pinned="top_corners")
        return scene

    ws.gradient(cloth(4), loss, ["spring_stiffness"], seconds=1 / 60, substeps=2, integrator="symplectic_euler")
    for _ in ws.Simulator(cloth(4), "symplectic_euler").frames(2 / 60, 60.0, 2, arrays=False):
        pass
    scene, seconds, substeps = cloth(16), 2.0, 8
    out = {}
    resettable = reset()
    base = peak_kb()
    started = time.perf_counter()
    for _ in ws.Simulator(scene, "symplectic_euler").frames(seconds + 1 / 60, 60.0, substeps, arrays=False):
        pass
    out["forward"] = (peak_kb() - base, time.perf_counter() - started)
    reset()
    base = peak_kb()
    started = time.perf_counter()
    value, grads = ws.gradient(scene, loss, ["spring_stiffness", "particle_mass"], seconds=seconds, substeps=substeps,
                               integrator="symplectic_euler")
    out["gradient"] = (peak_kb() - base, time.perf_counter() - started)
    size = 6 * scene.particle_count
    out["stored"] = (int(round(seconds * 60)) + 1) * size * 8 / 1024
    out["trajectory"] = 2 * 2 * (int(round(seconds * 60)) + 1) * scene.particle_count * 24 / 1024
    out["resettable"] = resettable
    steps = int(round(seconds * 60)) * substeps   # a tape over every step: per step the end state and two rate
    out["all_steps"] = steps * 2 * (3 * size * 8 + scene.particle_count * 24) / 1024   # states, the accumulator
    out["finite"] = bool(np.isfinite(grads["spring_stiffness"]).all())
    print("MEMORY", json.dumps(out))
""")


def test_peak_memory_of_a_cloth_gradient(tmp_path):
    script = tmp_path / "memory.py"   # a file: Warp compiles no kernel defined in a -c string
    script.write_text(MEMORY)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(next(line for line in done.stdout.splitlines() if line.startswith("MEMORY"))[7:])
    (forward_kb, forward_s), (gradient_kb, gradient_s) = out["forward"], out["gradient"]
    print(f"16 x 16 cloth, 2 s at 60 fps, 8 substeps (960 steps), symplectic Euler, on the CPU: peak memory growth "
          f"{forward_kb / 1024:.1f} MB forward only ({forward_s:.2f} s), {gradient_kb / 1024:.1f} MB for the gradient "
          f"({gradient_s:.2f} s); of which stored states {out['stored'] / 1024:.2f} MB and the trajectory with its "
          f"gradient {out['trajectory'] / 1024:.2f} MB (peak reset per phase: {out['resettable']})")
    assert out["finite"]
    print(f"(one tape over all 960 steps would hold {out['all_steps'] / 1024:.0f} MB of states and accumulators)")
    assert gradient_kb < 0.5 * out["all_steps"]   # one frame's tape at a time, not every step's

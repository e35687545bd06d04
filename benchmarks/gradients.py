"""Gradient memory and time: ws.gradient over a long cloth run, against the forward run alone.

    python benchmarks/gradients.py [--quick] [--out benchmarks/results/gradients.json]

The scene: a 64 x 64 cloth (1 m square, 2 kg, structural and shear springs of 20 N/m, bend springs of 2 N/m, a
little damping and air drag) hanging from its two top corners, float64, symplectic Euler, collisions off, 20 s at
60 fps with 8 substeps a frame (9600 steps). The loss: its drape, the mean height of its vertices at the last
frame; the gradient: with respect to every spring's stiffness (``wrt=["spring_stiffness"]``). ``--quick``: a
16 x 16 cloth over 1 s (480 steps).

Measured in this one process, after a warm-up that compiles every module both runs use (a 4 x 4 cloth's forward
run and gradient over two frames), on the CPU:

- forward: a plain ``Simulator`` (no adjoint: the fused step) over the same frames, its wall time and its peak
  memory growth;
- gradient: ``ws.gradient`` (a differentiable Simulator's forward run storing each frame, the loss's tape, then
  every frame recomputed on a tape of its own going back), its wall time and peak memory growth;
- what the gradient stores: the states at the frames + 1 (gradients.checkpoints: they are the trajectory the loss
  reads), the gradient of the one trajectory field the loss reads (particle_x), and one frame's pool of scratch
  states.

Peak memory growth: the process's peak resident set size (VmHWM in /proc/self/status) at the end of a run, less
its resident size at its start, the peak reset to the resident size first (writing 5 to /proc/self/clear_refs,
Linux 4.0 on); Warp's CPU arrays are ordinary host memory, so they are in it, and so is Python's. Where the reset
is refused the growth is over the process's peak so far, and the table says so. Nothing is asserted about times.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import warp as wp
from common import cpu_model, markdown

import warp_sim as ws
from warp_sim.gradients.checkpoints import Checkpoints
from warp_sim.gradients.controls import Controls
from warp_sim.gradients.trajectory import Trajectory

FPS, SUBSTEPS = 60.0, 8
FULL = {"resolution": 64, "seconds": 20.0}
QUICK = {"resolution": 16, "seconds": 1.0}

MEGABYTE = 2**20


@wp.kernel
def mean_height(x: wp.array2d(dtype=wp.vec3d), frame: int, weight: wp.float64, out: wp.array(dtype=wp.float64)):
    """out += weight y of every vertex at ``frame`` (weight 1 / count: the mean height) [m]."""
    i = wp.tid()
    wp.atomic_add(out, 0, weight * x[frame, i][1])


def drape(traj):
    """The loss: the mean height of the cloth's vertices at the last frame [m]."""
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    count = traj.particle_x.shape[1]
    wp.launch(mean_height, count, [traj.particle_x, traj.frames, 1.0 / count, out])
    return out


def cloth(resolution: int, drag: float = 5e-4, precision: str = "float64") -> ws.Scene:
    """The hanging cloth: ``resolution`` x ``resolution`` vertices, air drag ``drag`` [N s/m] (float64 unless
    ``precision``)."""
    scene = ws.Scene(precision=precision, drag=drag)
    scene.add_cloth_grid(resolution=(resolution, resolution), size=(1.0, 1.0), mass=2.0, stiffness=(20.0, 20.0, 2.0),
                         damping=(1e-3, 1e-3, 1e-4), pinned="top_corners")
    return scene


def _status_kb(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1])
    raise RuntimeError(f"no {key} in /proc/self/status")


def reset_peak() -> bool:
    """Reset the peak resident size to the resident size now (Linux); False where that is refused."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def measured(run) -> dict:
    """run() timed, with its peak memory growth [MB] (module docstring)."""
    reset = reset_peak()
    before = _status_kb("VmRSS")
    started = time.perf_counter()
    result = run()
    seconds = time.perf_counter() - started
    return {"seconds": seconds, "peak_growth_mb": (_status_kb("VmHWM") - before) / 1024, "peak_reset": reset,
            "result": result}


def step_frames(sim: ws.Simulator, seconds: float) -> ws.Simulator:
    """sim run for round(seconds * fps) frames of SUBSTEPS steps, as ws.gradient runs them; returns it."""
    for _ in sim.frames(seconds + 1.0 / FPS, FPS, SUBSTEPS, arrays=False):   # frames 0 to round(seconds * fps)
        pass
    return sim


def run_frames(scene: ws.Scene, seconds: float, integrator: str = "symplectic_euler", **options) -> ws.Simulator:
    """A plain Simulator (``options``: e.g. collisions=False) made and run by step_frames; returns it."""
    return step_frames(ws.Simulator(scene, integrator, **options), seconds)


def forward(scene: ws.Scene, seconds: float) -> float:
    """A plain Simulator's run of round(seconds * fps) frames; returns the drape at the end [m]."""
    sim = run_frames(scene, seconds, collisions=False)
    return float(sim.state.particle_x.numpy()[:, 1].mean())


def gradient(scene: ws.Scene, seconds: float):
    return ws.gradient(scene, drape, ["spring_stiffness"], seconds=seconds, fps=FPS, substeps=SUBSTEPS,
                       integrator="symplectic_euler", collisions=False)


def stored(scene: ws.Scene, frames: int) -> dict:
    """What ws.gradient keeps [MB]: the frames + 1 stored states, the gradient of the field the loss reads, and
    one frame's pool of scratch states with their gradients (counted on a one-frame run)."""
    sim = ws.Simulator(scene, "symplectic_euler", collisions=False, differentiable=True)
    one = Checkpoints(sim, 1, FPS, SUBSTEPS, Controls(sim.model, 1, {}, set()))
    one.forward(Trajectory(sim.model, 1, FPS))
    state_bytes = sim.dynamics.layout.size * 8
    return {"states_mb": (frames + 1) * state_bytes / MEGABYTE,
            "loss_gradient_mb": (frames + 1) * scene.particle_count * 24 / MEGABYTE,
            "pool_states": one.pool.size, "pool_mb": one.pool.size * 2 * state_bytes / MEGABYTE}


def bench(resolution: int, seconds: float) -> dict:
    warm = cloth(4)
    forward(warm, 2.0 / FPS)
    gradient(warm, 2.0 / FPS)
    scene = cloth(resolution)
    frames = int(round(seconds * FPS))
    plain = measured(lambda: forward(scene, seconds))
    grad = measured(lambda: gradient(scene, seconds))
    value, grads = grad.pop("result")
    stiffness = scene.spring_array("stiffness")
    return {"resolution": resolution, "particles": scene.particle_count, "springs": scene.spring_count,
            "seconds": seconds, "frames": frames, "steps": frames * SUBSTEPS,
            "forward": {**plain, "drape_m": plain.pop("result")},
            "gradient": {**grad, "drape_m": value,
                         "d_drape_d_log_stiffness": float(np.dot(grads["spring_stiffness"], stiffness)),
                         "finite": bool(np.isfinite(grads["spring_stiffness"]).all())},
            "stored": stored(scene, frames)}


def table(result: dict) -> str:
    f, g, s = result["forward"], result["gradient"], result["stored"]
    header = ["cloth", "steps", "forward [s]", "forward peak growth [MB]", "gradient [s]", "gradient / forward",
              "gradient peak growth [MB]", "stored states [MB]", "loss field's gradient [MB]", "frame pool [MB]"]
    row = [f"{result['resolution']}²", f"{result['steps']}", f"{f['seconds']:.2f}", f"{f['peak_growth_mb']:.1f}",
           f"{g['seconds']:.1f}", f"{g['seconds'] / f['seconds']:.0f}x", f"{g['peak_growth_mb']:.1f}",
           f"{s['states_mb']:.1f}", f"{s['loss_gradient_mb']:.1f}", f"{s['pool_mb']:.1f}"]
    return markdown(header, [row], left=("cloth",))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 16 x 16 cloth over 1 s")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/gradients.json"))
    args = parser.parse_args()
    size = QUICK if args.quick else FULL
    result = bench(size["resolution"], size["seconds"])
    result["host"] = cpu_model()
    print(table(result))
    reset = result["forward"]["peak_reset"] and result["gradient"]["peak_reset"]
    print(f"peak memory growth: VmHWM after each run less VmRSS before it, the peak {'reset' if reset else 'NOT reset'}"
          f" first; drape {result['gradient']['drape_m']:.6f} m, d drape / d ln k "
          f"{result['gradient']['d_drape_d_log_stiffness']:.6e} m, on {result['host']}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

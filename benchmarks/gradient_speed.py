"""Gradient speed: ws.gradient (the forward run and the backward pass) against the forward run alone, on four
scenes, and Newton's differentiable cloth beside warp_sim's on the same cloth.

    python benchmarks/gradient_speed.py [--quick] [--repeats R] [--device cpu|cuda]
                                        [--out benchmarks/results/gradient_speed.json]

Every run is 1 s (SIZES) at FPS (60) frames a second, SUBSTEPS (8) steps a frame: 480 steps, float64 (--quick:
0.5 s, the throw 1 s still). The scenes, each with the loss and the ``wrt`` of its gradient:

- cloth 32² and 64²: benchmarks/gradients.py's hanging cloth (1 m square, 2 kg, structural, shear and bend springs
  of 20, 20 and 2 N/m, two pinned corners) without its air drag (Newton's particles have none), symplectic Euler,
  collisions off; the loss its drape (the mean height of its vertices at the last frame), wrt every spring's
  stiffness;
- a pile of PILE_BODIES (100) spheres of random radii (0.05 to 0.1 m, warp_sim.studies.contact_scenes'
  pile lattice, jittered, seeded) dropped on the ground, restitution PILE_RESTITUTION, friction FRICTION (0; a
  scene ws.gradient refuses has its row say why, NoAdjoint's message), symplectic Euler; the
  loss the mean height of their centres at the last frame, wrt their initial velocities;
- the ball throw: a particle of radius THROW["radius"] thrown from THROW["height"] at THROW["velocity"],
  bouncing once on the ground (restitution THROW["restitution"], friction THROW["friction"], sliding through the
  impact) before the last frame, rk4 (it integrates the parabola exactly and the plane pass bounces it at its
  time of impact, so the run is the closed form's); the loss its landing position w . p(T), w = THROW_WEIGHTS, wrt
  its initial velocity, held to the closed form (throw_closed_form) in the JSON.

Timed, after a warm-up that compiles or loads every module the runs use (the forward run and the gradient of a
small version of each scene over two frames, in contact where the scene is: a 4² cloth, two spheres in each
other and in the ground; the throw itself over its whole run), in ``--repeats`` rounds (default 3; --quick 1),
each round the forward run then the gradient, one after the other, on the CPU:

- forward: a plain ``Simulator`` (no adjoint: the fused step where there is one; its guard on, the default) made
  from the scene and run for the same frames (gradients.step_frames), its wall time, and of it the time making
  the Simulator took (the JSON's build_s; Newton's: its finalize, solver and states);
- forward + backward: ``ws.gradient`` on the same scene (a differentiable Simulator made from it, its forward run
  storing every frame, the loss on a tape, then each frame stepped again on a tape of its own going back), its
  wall time;
- the ratio: the median over rounds of the round's gradient time over its forward time (rounds.paired_ratio).

Newton (optional: "n/a (...)" when ``import newton`` fails): its differentiable cloth, as its diffsim examples
write it, on the same cloths (the same vertices, pinned ones massless, springs, masses, gravity, dt and
symplectic Euler: benchmarks/cloth.py's newton_builder), float32 (Newton's only precision), beside warp_sim on
the same cloth in float32 too. Newton's forward: the model finalized, two states stepped in turn; its gradient:
the model finalized with requires_grad=True, a state per step (the tape needs each), SolverSemiImplicit's steps
and the drape on a wp.Tape, tape.backward. The builder is made once (as warp_sim's Scene is); the finalize is in
the times, as the Simulator's construction is in warp_sim's. Rounds: warp_sim's forward and gradient, then
Newton's. Reported: each one's gradient over its forward, and warp_sim's gradient time over Newton's (and
forward over forward), medians of per-round ratios; the drape's derivative with respect to ln k (the sum of
k dL/dk) from each, as a check that both differentiate the same run. Nothing about times is asserted. Results: a
markdown table each and --out (JSON). See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from functools import partial
from pathlib import Path

import cloth
import gradients
import numpy as np
import rounds
import warp as wp
from common import device_name, environment, git_state, markdown, pick_device

import warp_sim as ws
from warp_sim.adjoints import NoAdjoint
from warp_sim.studies import contact_scenes

FPS, SUBSTEPS = gradients.FPS, gradients.SUBSTEPS
G = 9.81                            # [m/s^2] the Scene's default gravity, -y
#: the pile's bodies and ground: friction (0: frictionless, what a differentiable body contact covered when this
#: was written; 6cea9e9's taped response takes Coulomb friction, so it can be switched, e.g. to contact_scenes'
#: PILE_FRICTION, 0.5) and restitution
FRICTION = 0.0
PILE_RESTITUTION = contact_scenes.PILE_RESTITUTION
PILE_BODIES = 100
#: the throw: a particle of radius [m] from height [m] (its centre) at velocity [m/s] onto the ground
#: (restitution, friction); one bounce at t1 = 0.66 s, sliding through it, before T = THROW_SECONDS
THROW = {"height": 1.5, "velocity": (3.0, 1.0, 0.0), "radius": 0.05, "restitution": 0.5, "friction": 0.2}
THROW_SECONDS = 1.0                 # [s] the throw's run in either mode
THROW_WEIGHTS = (1.0, 1.0, 1.0)     # the loss w . p(T)
#: per mode: the cloths' resolutions, the pile's bodies, and the runs' length [s] (the throw's: THROW_SECONDS)
SIZES = {"full": {"cloth": (32, 64), "pile": PILE_BODIES, "seconds": 1.0},
         "quick": {"cloth": (8, 16), "pile": 8, "seconds": 0.5}}
REPEATS = {"full": 3, "quick": 1}
SEED = 0


# ---------------------------------------------------------------------------------------------------- losses

@wp.kernel
def weighted_position(x: wp.array2d(dtype=wp.vec3d), frame: int, w: wp.vec3d, weight: wp.float64,
                      out: wp.array(dtype=wp.float64)):
    """out += weight w . x[frame, i] for every i."""
    i = wp.tid()
    wp.atomic_add(out, 0, weight * wp.dot(w, x[frame, i]))


@wp.kernel
def mean_height32(x: wp.array(dtype=wp.vec3), weight: float, out: wp.array(dtype=float)):
    """out += weight y of every vertex (float32: warp_sim's float32 cloth at its last frame, Newton's state)."""
    i = wp.tid()
    wp.atomic_add(out, 0, weight * x[i][1])


def pile_height(traj):
    """The mean height of the bodies' centres at the last frame [m]."""
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    count = traj.body_x.shape[1]
    wp.launch(weighted_position, count, [traj.body_x, traj.frames, wp.vec3d(0.0, 1.0, 0.0), 1.0 / count, out])
    return out


def landing(traj):
    """The throw's landing position at the last frame, weighted: w . p(T) [m]."""
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    wp.launch(weighted_position, 1, [traj.particle_x, traj.frames, wp.vec3d(*THROW_WEIGHTS), 1.0, out])
    return out


def drape32(traj):
    """gradients.drape of a float32 cloth."""
    out = wp.zeros(1, dtype=wp.float32, requires_grad=True)
    count = traj.particle_x.shape[1]
    wp.launch(mean_height32, count, [traj.particle_x[traj.frames], 1.0 / count, out])
    return out


# ---------------------------------------------------------------------------------------------------- scenes

def pile(n: int, seed: int = SEED, friction: float = FRICTION) -> ws.Scene:
    """n spheres (contact_scenes.pile_bodies' radii and jittered lattice) above the ground, float64."""
    bodies = contact_scenes.pile_bodies(n, seed)
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=PILE_RESTITUTION, friction=friction)
    for radius, position in zip(bodies["size"][:, 0].tolist(), bodies["position"].tolist(), strict=True):
        scene.add_rigid_body(ws.Sphere(radius), density=contact_scenes.PILE_DENSITY, position=position,
                             restitution=PILE_RESTITUTION, friction=friction)
    return scene


def touching_spheres(friction: float = FRICTION) -> ws.Scene:
    """The warm-up pile: two spheres in each other and in the ground (every contact kernel runs)."""
    scene = ws.Scene(precision="float64")
    scene.add_ground(restitution=PILE_RESTITUTION, friction=friction)
    for x in (0.0, 0.15):
        scene.add_rigid_body(ws.Sphere(0.1), density=contact_scenes.PILE_DENSITY, position=(x, 0.09, 0.0),
                             restitution=PILE_RESTITUTION, friction=friction)
    return scene


def throw(velocity=THROW["velocity"]) -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_particles([(0.0, THROW["height"], 0.0)], velocities=[tuple(velocity)], radius=THROW["radius"])
    scene.add_ground(restitution=THROW["restitution"], friction=THROW["friction"])
    return scene


def throw_closed_form(T: float = THROW_SECONDS, throw_=THROW, weights=THROW_WEIGHTS) -> dict:
    """The throw's landing position and d (w . p(T)) / d v0, exactly one bounce before T, sliding through it.

    From height h (centre), radius r, velocity (vx, vy, vz = 0): it meets the ground at t1 = (vy + s) / g with
    s = sqrt(vy^2 + 2 g (h - r)), arriving at -s; the impact reflects the normal velocity to e s and takes
    c = mu (1 + e) s off the tangential speed (vx > c: it slides). After it, y(T) = r + e s tau - g tau^2 / 2
    with tau = T - t1, and x(T) = vx T - c tau, z(T) = 0. With ds/dvy = vy / s and dt1/dvy = (1 + vy / s) / g:
    dy/dvy = e (vy / s) tau - e (s + vy) / g + tau (1 + vy / s), dx/dvy = -mu (1 + e) (vy tau / s - (s + vy) / g),
    dx/dvx = T; a sideways vz turns the tangential velocity, scaled by (|vt| - c) / |vt| after the impact:
    dz/dvz = t1 + (1 - c / vx) tau. Every other entry is 0."""
    h, r, e, mu = throw_["height"], throw_["radius"], throw_["restitution"], throw_["friction"]
    vx, vy, vz = throw_["velocity"]
    assert vz == 0.0
    s = np.sqrt(vy * vy + 2.0 * G * (h - r))
    t1 = (vy + s) / G
    tau = T - t1
    c = mu * (1.0 + e) * s
    assert 0.0 < tau < 2.0 * e * s / G and vx > c, "exactly one bounce before T, sliding through it"
    position = np.array([vx * T - c * tau, r + e * s * tau - 0.5 * G * tau * tau, 0.0])
    jacobian = np.zeros((3, 3))   # d p(T)_i / d v0_j
    jacobian[0, 0] = T
    jacobian[0, 1] = -mu * (1.0 + e) * (vy * tau / s - (s + vy) / G)
    jacobian[1, 1] = e * (vy / s) * tau - e * (s + vy) / G + tau * (1.0 + vy / s)
    jacobian[2, 2] = t1 + (1.0 - c / vx) * tau
    w = np.asarray(weights, dtype=np.float64)
    return {"impact_time": t1, "landing_position": position.tolist(), "loss": float(w @ position),
            "d_loss_d_velocity": (w @ jacobian).tolist()}


def cases(mode: str) -> list[dict]:
    """The table's rows: key, label, the scene, its run [s], its warm-up (a small scene, its run [s]), the
    gradient's loss, wrt and integrator, the plain forward's options and its loss (final(state), of its last
    state), and what of the gradient the JSON keeps (summary(scene, grad))."""
    sizes = SIZES[mode]
    common = {"seconds": sizes["seconds"], "warm_seconds": 2.0 / FPS, "integrator": "symplectic_euler"}
    rows = [{**common, "key": f"cloth{n}", "label": f"cloth {n}²", "scene": partial(gradients.cloth, n, drag=0.0),
             "warm": partial(gradients.cloth, 4, drag=0.0), "loss": gradients.drape, "wrt": "spring_stiffness",
             "options": {"collisions": False}, "final": mean_height("particle_x"), "summary": cloth_summary}
            for n in sizes["cloth"]]
    rows.append({**common, "key": "pile", "label": f"pile of {sizes['pile']} spheres",
                 "scene": partial(pile, sizes["pile"]), "warm": touching_spheres, "loss": pile_height,
                 "wrt": "body_v", "options": {}, "final": mean_height("body_x"), "summary": pile_summary})
    rows.append({"key": "throw", "label": "ball throw (1 particle)", "scene": throw, "seconds": THROW_SECONDS,
                 "warm": throw, "warm_seconds": THROW_SECONDS, "integrator": "rk4", "loss": landing,
                 "wrt": "particle_v", "options": {}, "final": landed, "summary": throw_summary})
    return rows


def mean_height(field: str):
    """final(state): the mean height of the state's ``field`` (particle_x, body_x) [m], in numpy."""
    return lambda state: float(getattr(state, field).numpy()[:, 1].astype(np.float64).mean())


def landed(state) -> float:
    """The throw's loss from its last state: w . p(T) [m], in numpy."""
    return float(np.dot(THROW_WEIGHTS, state.particle_x.numpy()[0].astype(np.float64)))


def cloth_summary(scene: ws.Scene, grad: np.ndarray) -> dict:
    return {"d_drape_d_log_stiffness": float(np.dot(grad, scene.spring_array("stiffness")))}


def pile_summary(scene: ws.Scene, grad: np.ndarray) -> dict:
    return {"d_height_d_velocity_norm": float(np.linalg.norm(grad)),
            "d_height_d_mean_vertical_velocity": float(grad[:, 1].sum())}


def throw_summary(scene: ws.Scene, grad: np.ndarray) -> dict:
    closed = throw_closed_form()
    return {"d_loss_d_velocity": grad[0].tolist(), "closed_form": closed,
            "closed_form_error": float(np.abs(grad[0] - closed["d_loss_d_velocity"]).max())}


# ---------------------------------------------------------------------------------------------------- runs

def forward_value(case: dict, scene: ws.Scene, device) -> tuple[float, float]:
    """The plain forward run of ``case`` on ``scene``: (the loss of its last state, in numpy; the seconds its
    Simulator took to make, within the run's)."""
    start = time.perf_counter()
    sim = ws.Simulator(scene, case["integrator"], device=device.alias, **case["options"])
    built = time.perf_counter() - start
    gradients.step_frames(sim, case["seconds"])
    return case["final"](sim.state), built


def gradient_run(case: dict, scene: ws.Scene, device, seconds: float | None = None):
    return ws.gradient(scene, case["loss"], [case["wrt"]], seconds=seconds or case["seconds"], fps=FPS,
                       substeps=SUBSTEPS, integrator=case["integrator"], device=device.alias, **case["options"])


def timed(run):
    """(seconds, run()): wall time, the device synchronised after."""
    start = time.perf_counter()
    result = run()
    wp.synchronize()
    return time.perf_counter() - start, result


def bench_case(case: dict, device, repeats: int) -> dict:
    """Warm up, then ``repeats`` rounds of the forward run and the gradient of one scene."""
    warm = case["warm"]()
    gradients.run_frames(warm, case["warm_seconds"], case["integrator"], device=device.alias, **case["options"])
    scene = case["scene"]()
    result = {"key": case["key"], "label": case["label"], "integrator": case["integrator"], "wrt": case["wrt"],
              "particles": scene.particle_count, "springs": scene.spring_count, "bodies": scene.body_count,
              "seconds": case["seconds"], "frames": round(case["seconds"] * FPS),
              "steps": round(case["seconds"] * FPS) * SUBSTEPS}
    try:
        gradient_run(case, warm, device, case["warm_seconds"])
    except NoAdjoint as refusal:
        return {**result, "status": f"n/a (NoAdjoint: {refusal})"}
    forward_s, build_s, gradient_s = [], [], []
    for _ in range(repeats):
        seconds, (value, built) = timed(lambda: forward_value(case, scene, device))
        forward_s.append(seconds)
        build_s.append(built)
        seconds, (gradient_value, grads) = timed(lambda: gradient_run(case, scene, device))
        gradient_s.append(seconds)
        print(f"    {case['label']}: forward {forward_s[-1]:.3f} s, forward + backward {gradient_s[-1]:.3f} s",
              flush=True)
    grad = grads[case["wrt"]]
    return {**result, "status": "ok",
            "forward": {"seconds": forward_s, "median_s": statistics.median(forward_s), "loss": value,
                        "build_s": build_s, "median_build_s": statistics.median(build_s)},
            "gradient": {"seconds": gradient_s, "median_s": statistics.median(gradient_s), "loss": gradient_value,
                         "finite": bool(np.isfinite(grad).all()), "shape": list(grad.shape),
                         **case["summary"](scene, grad)},
            "ratio": rounds.paired_ratio(gradient_s, forward_s)}


# ---------------------------------------------------------------------------------------------------- Newton

class NewtonDiffCloth:
    """Newton's differentiable cloth on a warp_sim cloth scene (module docstring): forward() and gradient(), each
    from the builder, over ``steps`` steps of 1 / (FPS SUBSTEPS) s."""

    def __init__(self, newton, scene: ws.Scene, device, steps: int):
        self.newton, self.scene, self.device, self.steps = newton, scene, device, steps
        self.builder = cloth.newton_builder(newton, scene, gravity=scene.gravity)
        self.dt = 1.0 / (FPS * SUBSTEPS)

    def _model(self, requires_grad: bool):
        model = cloth.newton_model(self.builder, self.scene, self.device, requires_grad=requires_grad)
        return model, cloth.newton_solver(self.newton, model), model.control()

    def _drape(self, x: wp.array) -> wp.array:
        out = wp.zeros(1, dtype=float, device=x.device, requires_grad=True)
        wp.launch(mean_height32, x.shape[0], [x, 1.0 / x.shape[0], out], device=x.device)
        return out

    def forward(self) -> tuple[float, float]:
        """(the drape at the end [m], the seconds the model, solver and states took to make, within the run's)."""
        start = time.perf_counter()
        model, solver, control = self._model(False)
        states = [model.state(), model.state()]
        built = time.perf_counter() - start
        for _ in range(self.steps):
            states[0].clear_forces()
            solver.step(states[0], states[1], control, None, self.dt)
            states.reverse()
        return float(self._drape(states[0].particle_q).numpy()[0]), built

    def gradient(self) -> tuple[float, np.ndarray]:
        model, solver, control = self._model(True)
        states = [model.state() for _ in range(self.steps + 1)]
        tape = wp.Tape()
        with tape:
            for k in range(self.steps):
                states[k].clear_forces()
                solver.step(states[k], states[k + 1], control, None, self.dt)
            loss = self._drape(states[-1].particle_q)
        tape.backward(loss)
        return float(loss.numpy()[0]), model.spring_stiffness.grad.numpy().astype(np.float64)


def bench_newton(newton, resolution: int, device, repeats: int, mode: str) -> dict:
    """warp_sim (float32) and Newton on the same cloth: rounds of warp_sim's forward and gradient, then Newton's."""
    case = {**next(c for c in cases(mode) if c["key"].startswith("cloth")), "loss": drape32}
    scene = gradients.cloth(resolution, drag=0.0, precision="float32")
    warm = gradients.cloth(4, drag=0.0, precision="float32")
    steps = round(case["seconds"] * FPS) * SUBSTEPS
    gradients.run_frames(warm, 2.0 / FPS, case["integrator"], device=device.alias, **case["options"])
    gradient_run(case, warm, device, 2.0 / FPS)
    warm_newton = NewtonDiffCloth(newton, warm, device, 2)
    warm_newton.forward()
    warm_newton.gradient()
    peer = NewtonDiffCloth(newton, scene, device, steps)
    seconds = {"warp_sim_forward": [], "warp_sim_gradient": [], "newton_forward": [], "newton_gradient": [],
               "warp_sim_build": [], "newton_build": []}
    for _ in range(repeats):
        spent, (warp_value, built) = timed(lambda: forward_value(case, scene, device))
        seconds["warp_sim_forward"].append(spent)
        seconds["warp_sim_build"].append(built)
        spent, (warp_loss, warp_grads) = timed(lambda: gradient_run(case, scene, device))
        seconds["warp_sim_gradient"].append(spent)
        spent, (newton_value, built) = timed(peer.forward)
        seconds["newton_forward"].append(spent)
        seconds["newton_build"].append(built)
        spent, (newton_loss, newton_grad) = timed(peer.gradient)
        seconds["newton_gradient"].append(spent)
        print(f"    cloth {resolution}², float32: warp_sim {seconds['warp_sim_forward'][-1]:.3f} s, "
              f"{seconds['warp_sim_gradient'][-1]:.3f} s; Newton {seconds['newton_forward'][-1]:.3f} s, "
              f"{seconds['newton_gradient'][-1]:.3f} s", flush=True)
    stiffness = scene.spring_array("stiffness")
    warp_grad = warp_grads["spring_stiffness"]
    ratios = {"warp_sim_gradient_over_forward": rounds.paired_ratio(seconds["warp_sim_gradient"],
                                                                    seconds["warp_sim_forward"]),
              "newton_gradient_over_forward": rounds.paired_ratio(seconds["newton_gradient"],
                                                                  seconds["newton_forward"]),
              "warp_sim_over_newton_gradient": rounds.paired_ratio(seconds["warp_sim_gradient"],
                                                                   seconds["newton_gradient"]),
              "warp_sim_over_newton_forward": rounds.paired_ratio(seconds["warp_sim_forward"],
                                                                  seconds["newton_forward"])}
    warp_log, newton_log = float(np.dot(warp_grad, stiffness)), float(np.dot(newton_grad, stiffness))
    return {"resolution": resolution, "particles": scene.particle_count, "springs": scene.spring_count,
            "steps": steps, "precision": "float32", "status": "ok",
            "seconds": seconds, "median_s": {k: statistics.median(v) for k, v in seconds.items()}, **ratios,
            "warp_sim": {"forward_loss": warp_value, "loss": warp_loss, "d_drape_d_log_stiffness": warp_log,
                         "finite": bool(np.isfinite(warp_grad).all())},
            "newton": {"forward_loss": newton_value, "loss": newton_loss, "d_drape_d_log_stiffness": newton_log,
                       "finite": bool(np.isfinite(newton_grad).all())},
            "d_log_stiffness_relative_difference": abs(warp_log - newton_log) / max(abs(newton_log), 1e-30),
            "gradient_relative_difference": float(np.abs(warp_grad - newton_grad).max()
                                                  / max(np.abs(newton_grad).max(), 1e-30))}


# ---------------------------------------------------------------------------------------------------- tables

def speed_table(rows: list[dict]) -> str:
    cells = []
    for r in rows:
        if r["status"] != "ok":
            cells.append([r["label"], f"{r['steps']}", r["status"].replace("|", "/"), "-", "-", "-"])
            continue
        cells.append([r["label"], f"{r['steps']}", f"{r['forward']['median_s']:.3f}",
                      f"{r['forward']['median_build_s']:.3f}", f"{r['gradient']['median_s']:.3f}",
                      f"{r['ratio']:.1f}x"])
    return markdown(["scene", "steps", "forward [s]", "of it, making the Simulator [s]",
                     "forward + backward (ws.gradient) [s]", "gradient / forward"], cells, left=("scene",))


def newton_table(rows: list[dict]) -> str:
    cells = []
    for r in rows:
        if r["status"] != "ok":
            cells.append([f"cloth {r['resolution']}²", f"{r.get('steps', '-')}", r["status"].replace("|", "/")]
                         + ["-"] * 8)
            continue
        m = r["median_s"]
        cells.append([f"cloth {r['resolution']}²", f"{r['steps']}", f"{m['warp_sim_forward']:.3f}",
                      f"{m['warp_sim_gradient']:.3f}", f"{r['warp_sim_gradient_over_forward']:.1f}x",
                      f"{m['newton_forward']:.3f}", f"{m['newton_gradient']:.3f}",
                      f"{r['newton_gradient_over_forward']:.1f}x", f"{r['warp_sim_over_newton_forward']:.2f}x",
                      f"{r['warp_sim_over_newton_gradient']:.2f}x",
                      f"{r['d_log_stiffness_relative_difference']:.1e}"])
    return markdown(["cloth (float32)", "steps", "warp_sim forward [s]", "warp_sim gradient [s]",
                     "warp_sim gradient / forward", "Newton forward [s]", "Newton gradient [s]",
                     "Newton gradient / forward", "warp_sim / Newton, forward", "warp_sim / Newton, gradient",
                     "dL/d ln k, rel. difference"], cells, left=("cloth (float32)",))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="cloths of 8² and 16², a pile of 8, one round")
    parser.add_argument("--repeats", type=int, default=None, help="timed rounds (default 3, --quick 1)")
    parser.add_argument("--device", choices=("cpu", "cuda"), default="cpu", help="cpu (default), or cuda")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/gradient_speed.json"))
    args = parser.parse_args(argv)
    device = pick_device(parser, args.device)
    mode = "quick" if args.quick else "full"
    repeats = args.repeats or REPEATS[mode]
    if repeats < 1:
        parser.error("--repeats must be >= 1")
    newton, newton_status = cloth.optional_import("newton")
    newton_version = getattr(newton, "__version__", "?") if newton is not None else None
    name = device_name(device)
    print(f"warp {wp.__version__}, warp_sim {ws.__version__} on {device.alias} ({name}), {os.cpu_count()} cores; "
          f"newton {newton_version or newton_status}; {mode} run, {repeats} round(s) of "
          f"{SIZES[mode]['seconds']:g} s (the throw {THROW_SECONDS:g} s) at {FPS:g} fps, {SUBSTEPS} substeps",
          flush=True)
    started = time.perf_counter()
    rows = []
    for case in cases(mode):
        print(f"  {case['label']} ...", flush=True)
        rows.append(bench_case(case, device, repeats))
    newton_rows = []
    for n in SIZES[mode]["cloth"]:
        if newton is None:
            newton_rows.append({"resolution": n, "status": f"n/a ({newton_status})"})
            continue
        print(f"  cloth {n}², float32, warp_sim and Newton ...", flush=True)
        try:
            newton_rows.append(bench_newton(newton, n, device, repeats, mode))
        except Exception as error:   # an optional peer that cannot run this is reported, not fatal
            newton_rows.append({"resolution": n, "status": f"n/a ({type(error).__name__}: {error})"})
    print()
    print(speed_table(rows))
    print()
    print(newton_table(newton_rows))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {"device": device.alias, "device_name": name, "cpu_count": os.cpu_count(),
              "warp_version": wp.__version__, "warp_sim_version": ws.__version__, "numpy_version": np.__version__,
              "git": git_state(), "environment": environment(),
              "newton": {"status": newton_status, "version": newton_version}, "mode": mode,
              "repeats": repeats,
              "fps": FPS, "substeps": SUBSTEPS, "sizes": SIZES[mode], "friction": FRICTION,
              "pile_restitution": PILE_RESTITUTION, "throw": THROW, "throw_weights": THROW_WEIGHTS,
              "wall_s": time.perf_counter() - started, "rows": rows, "newton_cloth": newton_rows}
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

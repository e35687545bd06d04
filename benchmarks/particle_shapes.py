"""Continuous collision of particles and cloth with static colliders: its cost against the end-of-step projection.

    python benchmarks/particle_shapes.py [--device cpu|cuda] [--cases cloth terrain closed] [--cloth-sizes 32 64]
                                         [--particles 100000] [--steps N] [--repeats R]
                                         [--out benchmarks/results/particle_shapes.json]

Three cases, each run twice side by side in one process: "after", the particle-shape pass as it is (each
particle's motion over the step swept against the static colliders, then the end-of-step projection out of
every shape: kernels.particle_shapes.collide_particles), and "before", the projection alone
(``sim.particle_shapes.continuous = False``: kernels.particle_shapes.push_particles, what the pass did before the
sweep, which lets fast particles through thin shapes).

"cloth": benchmarks/cloth.py's cloth (1 m x 1 m, n x n vertices, density 0.2 kg/m^2, springs of 1e4, 1e4 and
1e3 N/m with dampers 0.01, 0.01 and 0.001 N s/m, radius 2 mm, nothing pinned) laid flat 0.35 m above the top of a
sphere collider of radius 0.3 m (friction 0.5, restitution 0) and draped over it, under implicit Euler at 1/60 s
(README's cloth settings, one step a frame), float32: it falls for --settle-cloth steps (by then most of it lies
on the sphere or hangs from it), then the timed steps.

"terrain": --particles particles (radius 1 cm, float32) at random in a 4 x 1 x 4 m box above an open terrain mesh
(``MeshShape(solid=False)``: a 65 x 65 height field y = 0.15 sin(1.3 x) cos(1.1 z) over 4 m x 4 m, 8192
triangles, restitution 0.3, friction 0.5), random velocities (N(0, 1) m/s a component), gravity, under
symplectic Euler at 1/480 s (benchmarks/particles.py's dt), for --settle-mesh steps (most have landed) and then
the timed steps. The projection differs here too: after, an open surface holds particles on both sides, so it
is the unsigned distance within the particle's radius (``wp.mesh_query_point_no_sign``), where before it was the
terrain's signed query over the mesh's whole bounding radius (``wp.mesh_query_point_sign_normal``).

"closed": the same particles over a closed mesh, an icosphere (1280 triangles) of radius 1.5 m centred 1.2 m below
the origin, the particles above its cap (in the cylinder x^2 + z^2 <= 1 m^2, 0.3 to 1.3 m up): the same signed
projection before and after, so the difference is the sweep's cost.

Both variants of a case start from the same scene and settle alike; then --repeats rounds of --steps steps
(common.time_steps) in turns, before, after, before, after, so that a drift of the machine's speed reaches both;
medians reported. Then --profile-steps more steps of each with every launch synchronised and timed on its own
(common.KernelProfile): the pass's kernel (push_particles before, collide_particles after) in ms per step, and
its share of the step. The ratios are after / before: of the whole step, and of the pass's kernel. Nothing is
asserted about times. Results in --out (JSON). See benchmarks/README.md.
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
from functools import partial
from pathlib import Path

import numpy as np
import trimesh
import warp as wp
from common import KernelProfile, device_name, markdown, pick_device, time_steps

import warp_sim as ws
from warp_sim.core.cpu_threads import cpu_threads

CLOTH = {"size": (1.0, 1.0), "density": 0.2, "stiffness": (1.0e4, 1.0e4, 1.0e3), "damping": (0.01, 0.01, 0.001),
         "radius": 0.002}   # benchmarks/cloth.py's cloth [m], [kg/m^2], [N/m], [N s/m], nothing pinned
FLAT = (-math.sin(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4))   # lays the grid flat, facing +Y
SPHERE_RADIUS, SPHERE_CENTRE = 0.3, (0.0, 0.5, 0.0)   # [m]
CLOTH_DT = 1.0 / 60.0   # [s]
MESH_DT = 1.0 / 480.0   # [s]
PASS_KERNELS = {"before": "push_particles", "after": "collide_particles"}


def cloth_scene(n: int) -> ws.Scene:
    """The n x n cloth 0.35 m above the top of a sphere collider (module docstring)."""
    scene = ws.Scene(precision="float32")
    scene.add_collider(ws.Sphere(SPHERE_RADIUS), position=SPHERE_CENTRE, restitution=0.0, friction=0.5)
    top = SPHERE_CENTRE[1] + SPHERE_RADIUS
    scene.add_cloth_grid(resolution=(n, n), position=(0.02, top + 0.35, 0.01), orientation=FLAT, **CLOTH)
    return scene


def terrain(cells: int = 64, half: float = 2.0) -> trimesh.Trimesh:
    """The open height field y = 0.15 sin(1.3 x) cos(1.1 z) over |x|, |z| <= half [m], cells x cells squares."""
    ticks = np.linspace(-half, half, cells + 1)
    x, z = np.meshgrid(ticks, ticks)
    vertices = np.stack([x, 0.15 * np.sin(1.3 * x) * np.cos(1.1 * z), z], axis=-1).reshape(-1, 3)
    n = cells + 1
    corner = (np.arange(cells)[:, None] * n + np.arange(cells)[None, :]).ravel()
    faces = np.concatenate([np.stack([corner, corner + n, corner + 1], 1),
                            np.stack([corner + 1, corner + n, corner + n + 1], 1)])
    return trimesh.Trimesh(vertices, faces, process=False)


def terrain_scene(count: int, seed: int = 0) -> ws.Scene:
    """``count`` particles above the open terrain (module docstring)."""
    rng = np.random.default_rng(seed)
    scene = ws.Scene(precision="float32")
    scene.add_collider(ws.MeshShape(terrain(), solid=False), restitution=0.3, friction=0.5)
    positions = rng.uniform((-2.0, 0.3, -2.0), (2.0, 1.3, 2.0), size=(count, 3))
    scene.add_particles(positions, rng.normal(0.0, 1.0, size=(count, 3)), mass=0.01, radius=0.01)
    return scene


BALL = trimesh.creation.icosphere(3, radius=1.5)
BALL_CENTRE = np.array([0.0, -1.2, 0.0])   # [m]


def closed_scene(count: int, seed: int = 0) -> ws.Scene:
    """``count`` particles above the cap of a closed icosphere (module docstring)."""
    rng = np.random.default_rng(seed)
    scene = ws.Scene(precision="float32")
    scene.add_collider(ws.MeshShape(BALL), position=BALL_CENTRE, restitution=0.3, friction=0.5)
    radius, angle = np.sqrt(rng.uniform(0.0, 1.0, count)), rng.uniform(0.0, 2.0 * math.pi, count)
    positions = np.stack([radius * np.cos(angle), rng.uniform(0.3, 1.3, count), radius * np.sin(angle)], 1)
    scene.add_particles(positions, rng.normal(0.0, 1.0, size=(count, 3)), mass=0.01, radius=0.01)
    return scene


def lowest_gap(sim, case: str) -> float:
    """The least clearance of a particle at the end [m]: its distance to the sphere less its radius (cloth), its
    height over the terrain's triangles less its radius (terrain), or its distance to the icosphere less its radius
    (closed, the farthest face plane's distance: never more than the true one), over the particles near it."""
    x = sim.state.particle_x.numpy().astype(np.float64)
    if case == "cloth":
        return float((np.linalg.norm(x - SPHERE_CENTRE, axis=1) - SPHERE_RADIUS - CLOTH["radius"]).min())
    if case == "closed":   # a convex polyhedron: the farthest face plane, a lower bound of the distance outside
        normals = np.asarray(BALL.face_normals)
        offsets = np.einsum("ij,ij->i", normals, np.asarray(BALL.triangles_center))
        near = x[np.linalg.norm(x - BALL_CENTRE, axis=1) < 1.6]
        planes = [((near[k:k + 4096] - BALL_CENTRE) @ normals.T - offsets).max(axis=1)
                  for k in range(0, len(near), 4096)]
        return float(np.concatenate(planes).min() - 0.01) if len(near) else float("nan")
    over = (np.abs(x[:, 0]) < 2.0) & (np.abs(x[:, 2]) < 2.0)
    return float((x[over, 1] - terrain_height(x[over, 0], x[over, 2]) - 0.01).min()) if over.any() else float("nan")


def terrain_height(x: np.ndarray, z: np.ndarray, cells: int = 64, half: float = 2.0) -> np.ndarray:
    """The height [m] of terrain()'s triangles (not of the smooth field) over (x, z) [m] inside it."""
    step = 2.0 * half / cells
    u, w = (x + half) / step, (z + half) / step
    i, j = np.minimum(np.floor(u), cells - 1), np.minimum(np.floor(w), cells - 1)
    fu, fw = u - i, w - j

    def corner(di, dj):
        cx, cz = -half + (i + di) * step, -half + (j + dj) * step
        return 0.15 * np.sin(1.3 * cx) * np.cos(1.1 * cz)

    # each square's triangles: (00, 01, 10) below the diagonal fu + fw = 1, (10, 01, 11) above it
    lower = corner(0, 0) + fu * (corner(1, 0) - corner(0, 0)) + fw * (corner(0, 1) - corner(0, 0))
    upper = corner(1, 1) + (1 - fu) * (corner(0, 1) - corner(1, 1)) + (1 - fw) * (corner(1, 0) - corner(1, 1))
    return np.where(fu + fw <= 1.0, lower, upper)


def bench_case(case: str, label: str, scene: ws.Scene, integrator: str, dt: float, device, settle: int, steps: int,
               repeats: int, profile_steps: int) -> dict:
    """Before and after on ``scene``: settle, timed rounds in turns, then a kernel profile of each."""
    profiles = {variant: KernelProfile() for variant in PASS_KERNELS}
    sims = {}
    for variant, profile in profiles.items():
        profile.enabled = False
        sims[variant] = profile.instrumented(partial(ws.Simulator, scene, integrator, device.alias))
        sims[variant].particle_shapes.continuous = variant == "after"
    settle_s = {variant: time_steps(sim, settle, dt) for variant, sim in sims.items()}
    seconds = {variant: [] for variant in sims}
    solves = {variant: solver_count(sim) for variant, sim in sims.items()}
    for _ in range(repeats):
        for variant, sim in sims.items():
            seconds[variant].append(time_steps(sim, steps, dt))
    solves = {variant: solver_count(sim, solves[variant]) for variant, sim in sims.items()}
    row = {"case": case, "label": label, "particles": sims["after"].model.particle_count, "integrator": integrator,
           "dt": dt, "settle_steps": settle, "steps": steps, "repeats": repeats, "profile_steps": profile_steps}
    for variant, sim in sims.items():
        kernels = profiles[variant].steps(sim, dt, profile_steps)
        total = sum(entry["ms"] for entry in kernels.values())
        pass_ms = kernels.get(PASS_KERNELS[variant], {}).get("ms", 0.0)
        ms = 1e3 * statistics.median(seconds[variant]) / steps
        row[variant] = {"ms_per_step": ms, "steps_per_s": 1e3 / ms, "seconds": seconds[variant],
                        "settle_s": settle_s[variant], "pass_kernel": PASS_KERNELS[variant],
                        "pass_ms_per_step": pass_ms,
                        "pass_share_of_kernels": pass_ms / total if total else 0.0,
                        "profiled_ms_per_step": total, "kernels_per_step": kernels,
                        "lowest_gap_m": lowest_gap(sim, case), "cg_iterations_per_solve": solves[variant]}
    row["step_ratio"] = row["after"]["ms_per_step"] / row["before"]["ms_per_step"]
    row["pass_ratio"] = row["after"]["pass_ms_per_step"] / max(row["before"]["pass_ms_per_step"], 1e-12)
    return row


def solver_count(sim, before=None):
    """implicit Euler's (solves, CG iterations) so far, or with ``before`` the mean iterations of a solve since then
    (None for other solvers): what a step's time depends on besides the contacts."""
    solver = sim.integrator
    if not hasattr(solver, "iterations_total"):
        return None
    now = (solver.solves, solver.iterations_total)
    if before is None:
        return now
    return (now[1] - before[1]) / max(now[0] - before[0], 1)


def table(device_alias: str, rows: list[dict]) -> str:
    lines = []
    for row in rows:
        b, a = row["before"], row["after"]
        lines.append([device_alias, row["label"], f"{row['particles']:,}", f"{b['ms_per_step']:.2f}",
                      f"{a['ms_per_step']:.2f}", f"{row['step_ratio']:.2f}x", f"{b['pass_ms_per_step']:.3f}",
                      f"{a['pass_ms_per_step']:.3f}", f"{row['pass_ratio']:.2f}x",
                      f"{a['pass_share_of_kernels']:.1%}", f"{b['lowest_gap_m'] * 1e3:+.3f}",
                      f"{a['lowest_gap_m'] * 1e3:+.3f}", cg(b), cg(a)])
    return markdown(["device", "case", "particles", "before ms/step", "after ms/step", "step after/before",
                     "before pass ms", "after pass ms", "pass after/before", "after pass share",
                     "before lowest gap mm", "after lowest gap mm", "before CG it.", "after CG it."], lines,
                    left=("device", "case"))


def cg(variant: dict) -> str:
    iterations = variant["cg_iterations_per_solve"]
    return "-" if iterations is None else f"{iterations:.1f}"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", choices=("cpu", "cuda"), default=None, help="default: cuda if present, else cpu")
    parser.add_argument("--cases", nargs="+", choices=("cloth", "terrain", "closed"),
                        default=["cloth", "terrain", "closed"])
    parser.add_argument("--cloth-sizes", type=int, nargs="+", default=[32, 64], help="cloth: n of n x n vertices")
    parser.add_argument("--particles", type=int, default=100_000, help="terrain, closed: particles")
    parser.add_argument("--settle-cloth", type=int, default=45, help="cloth: steps of 1/60 s before timing")
    parser.add_argument("--settle-mesh", type=int, default=240, help="terrain, closed: steps of 1/480 s before timing")
    parser.add_argument("--steps", type=int, default=30, help="timed steps per round")
    parser.add_argument("--repeats", type=int, default=5, help="timed rounds of each variant; medians reported")
    parser.add_argument("--profile-steps", type=int, default=10, help="steps of the kernel profile")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/particle_shapes.json"))
    args = parser.parse_args(argv)
    if min(args.cloth_sizes + [args.particles, args.steps, args.repeats, args.profile_steps]) < 1 or min(
            args.settle_cloth, args.settle_mesh) < 0:
        parser.error("sizes, --particles, --steps, --repeats and --profile-steps must be >= 1, settles >= 0")
    device = pick_device(parser, args.device)
    print(f"warp {wp.__version__}, device {device.alias} ({device_name(device)}), {cpu_threads()} CPU threads")
    rows = []
    if "cloth" in args.cases:
        for n in args.cloth_sizes:
            print(f"cloth {n}^2 on a sphere, implicit_euler at 1/60 s ...", flush=True)
            rows.append(bench_case("cloth", f"cloth {n}² on a sphere", cloth_scene(n), "implicit_euler", CLOTH_DT,
                                   device, args.settle_cloth, args.steps, args.repeats, args.profile_steps))
    for case, make in (("terrain", terrain_scene), ("closed", closed_scene)):
        if case in args.cases:
            print(f"{args.particles:,} particles on a {case} mesh, symplectic_euler at 1/480 s ...", flush=True)
            rows.append(bench_case(case, f"particles on a {case} mesh", make(args.particles), "symplectic_euler",
                                   MESH_DT, device, args.settle_mesh, args.steps, args.repeats, args.profile_steps))
    print()
    print(table(device.alias, rows))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    result = {"device": device.alias, "device_name": device_name(device), "cpu_threads": cpu_threads(),
              "warp_version": wp.__version__, "warp_sim_version": ws.__version__, "precision": "float32",
              "pass_kernels": PASS_KERNELS, "rows": rows}
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

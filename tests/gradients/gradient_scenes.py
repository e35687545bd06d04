"""Scenes and losses the gradient tests share: float64, small, with closed forms or smooth enough for central
differences."""
import types

import numpy as np
import warp as wp

import warp_sim as ws

#: a weighting of a final position's components (nothing special about it, every entry non-zero)
WEIGHTS = (0.3, -0.7, 1.1)


@wp.kernel
def weighted_final(x: wp.array2d(dtype=wp.vec3d), frame: int, w: wp.vec3d, out: wp.array(dtype=wp.float64)):
    """out += w . x[frame, i] for every element i."""
    i = wp.tid()
    wp.atomic_add(out, 0, wp.dot(w, x[frame, i]))


@wp.kernel
def chain_misfit(x: wp.array2d(dtype=wp.vec3d), v: wp.array2d(dtype=wp.vec3d), w: wp.vec3d,
                 out: wp.array(dtype=wp.float64)):
    """out += |x[k, i] - (0, -0.3 i, 0)|^2 w.x-ish mixture over every frame k and particle i, and a velocity term:
    a loss that reads every row of the trajectory, nonlinearly."""
    k, i = wp.tid()
    target = wp.vec3d(wp.float64(0.0), wp.float64(-0.3) * wp.float64(i), wp.float64(0.0))
    d = x[k, i] - target
    wp.atomic_add(out, 0, wp.dot(d, d) + wp.float64(0.01) * wp.dot(w, v[k, i]))


@wp.kernel
def spun_axis(q: wp.array2d(dtype=wp.quatd), frame: int, target: wp.vec3d, out: wp.array(dtype=wp.float64)):
    """out += target . R(q[frame, i]) e_x, the final direction of each body's x axis against a target."""
    i = wp.tid()
    axis = wp.quat_rotate(q[frame, i], wp.vec3d(wp.float64(1.0), wp.float64(0.0), wp.float64(0.0)))
    wp.atomic_add(out, 0, wp.dot(target, axis))


def final_position_loss(field: str = "particle_x", weights=WEIGHTS):
    """loss(traj) = sum over elements of w . x(T)."""
    def loss(traj):
        out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
        x = getattr(traj, field)
        wp.launch(weighted_final, x.shape[1], [x, traj.frames, wp.vec3d(*weights), out])
        return out
    return loss


def chain_loss(traj):
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    wp.launch(chain_misfit, traj.particle_x.shape, [traj.particle_x, traj.particle_v, wp.vec3d(*WEIGHTS), out])
    return out


def axis_loss(traj):
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    wp.launch(spun_axis, traj.body_q.shape[1], [traj.body_q, traj.frames, wp.vec3d(0.2, 0.9, -0.4), out])
    return out


def projectile(x0=(0.0, 1.0, 0.0), v0=(1.0, 2.0, 0.5)) -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_particles([x0], velocities=[v0])
    return scene


#: the hanging chain: 5 particles 0.3 m apart below the pinned first, springs between neighbours
CHAIN_STIFFNESS = np.array([60.0, 45.0, 50.0, 40.0])
CHAIN_MASS = np.array([1.0, 0.12, 0.1, 0.15, 0.08])
CHAIN_DAMPING = np.array([0.3, 0.2, 0.25, 0.15])
CHAIN_REST = np.array([0.25, 0.28, 0.27, 0.3])


def chain(stiffness=CHAIN_STIFFNESS, mass=CHAIN_MASS, damping=CHAIN_DAMPING, rest=CHAIN_REST,
          gravity=(0.0, -9.81, 0.0)) -> ws.Scene:
    scene = ws.Scene(gravity=gravity, precision="float64")
    positions = [(0.05 * i, -0.3 * i, 0.0) for i in range(5)]
    scene.add_particles(positions, mass=np.asarray(mass), pinned=[0])
    scene.add_springs([(i, i + 1) for i in range(4)], stiffness=np.asarray(stiffness),
                      damping=np.asarray(damping), rest_length=np.asarray(rest))
    return scene


def spinning_box(angular_velocity=(1.0, 2.0, 0.5), mass=2.0, linear_velocity=(0.0, 0.0, 0.0)) -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_rigid_body(ws.Box((0.2, 0.1, 0.05)), mass=mass, position=(0.0, 1.0, 0.0),
                         orientation=tuple(np.array([0.1, 0.2, 0.0, 0.97]) / np.linalg.norm([0.1, 0.2, 0.0, 0.97])),
                         linear_velocity=linear_velocity,
                         angular_velocity=angular_velocity)
    return scene


def central_difference(value, x: np.ndarray, step: float) -> np.ndarray:
    """d value / d x by central differences, entry by entry, with ``step`` relative to each entry (absolute where
    it is 0)."""
    x = np.asarray(x, dtype=np.float64)
    result = np.zeros_like(x)
    for index in np.ndindex(x.shape):
        h = step * (abs(x[index]) or 1.0)
        up, down = x.copy(), x.copy()
        up[index] += h
        down[index] -= h
        result[index] = (value(up) - value(down)) / (2.0 * h)
    return result


def forward_value(scene: ws.Scene, loss, seconds: float, fps: float = 60.0, substeps: int = 8,
                  integrator: str = "rk4", **options) -> float:
    """The loss of a forward-only run (a plain Simulator's frames 0 to round(seconds * fps), one more than
    ``frames(seconds)`` yields), on a trajectory of those frames. Its steps of 1 / (fps substeps) seconds are
    ws.gradient's 1 / fps / substeps bit for bit where substeps is a power of two (the tests' 4 and 8)."""
    sim = ws.Simulator(scene, integrator, **options)
    rows = [arrays for _, _, arrays in sim.frames(seconds + 1.0 / fps, fps, substeps)]
    traj = types.SimpleNamespace(frames=len(rows) - 1, fps=fps)
    for name, dtype, count in (("particle_x", wp.vec3d, scene.particle_count),
                               ("particle_v", wp.vec3d, scene.particle_count),
                               ("body_x", wp.vec3d, scene.body_count), ("body_q", wp.quatd, scene.body_count)):
        values = np.stack([row[name] for row in rows]) if count else np.zeros((len(rows), 0, 3 if dtype is wp.vec3d
                                                                                 else 4))
        setattr(traj, name, wp.array(values, dtype=dtype, requires_grad=True))
    return float(loss(traj).numpy()[0])

"""Fused steps: one kernel for a whole step of a hot (component, solver) pair, with the generic path's functions.

``symplectic_euler_particles`` is a step of semi-implicit Euler for particles (and cloth, whose springs are a force
term accumulated before it): the acceleration of kernels.particles, the kick, the drift, the plane impulses of
kernels.planes and the guard's check of kernels.guards, reading x and v once and writing them once. It calls the
same Warp functions as the generic path (solver stages, then passes, then the guard), in the same order, so the
two give the same state bit for bit (tests/solvers/test_fused.py). The rule for adding one is in
docs/architecture.md.

Private: for the simulator's own use (solvers.fused); its arguments may change between releases.
"""
from typing import Any

import warp as wp

from .guards import GuardRecord, check_element
from .particles import acceleration
from .planes import clear_of_planes, plane_response
from .precisions import register

__all__ = []

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile


@wp.func
def particle_step(i: int, x: wp.array(dtype=Any), v: wp.array(dtype=Any), force: wp.array(dtype=Any),
                  gravity: Any, drag: Any, wind: Any, material: Any, planes: Any, h: Any,
                  impacts: int, x_out: wp.array(dtype=Any), v_out: wp.array(dtype=Any),
                  touched_out: wp.array(dtype=wp.int32), max_speed: Any, step: int, record: GuardRecord):
    """symplectic_euler_particles' step of particle i."""
    xi = x[i]
    vi = v[i]
    forced = force.shape[0] > 0
    fi = type(gravity)()
    if forced:
        fi = force[i]
    v1 = vi + h * acceleration(vi, fi, forced, material.inv_mass[i], gravity, drag, wind)
    x1 = xi + h * v1
    if impacts != 0 and material.inv_mass[i] != type(h)(0.0) and not clear_of_planes(
            xi, vi, v1, material.radius[i], planes.normal, planes.offset, h):
        xe, ve, touched = plane_response(i, xi, vi, x1, v1, material, planes, h)
        if touched != 0:
            x1 = xe
            v1 = ve
            if touched_out.shape[0] > 0:
                touched_out[i] = 1
    x_out[i] = x1
    v_out[i] = v1
    if step > 0:
        check_element(i, x1, v1, max_speed, step, record)


@wp.kernel
def symplectic_euler_particles(x: wp.array(dtype=Any), v: wp.array(dtype=Any), force: wp.array(dtype=Any),
                               gravity: Any, drag: Any, wind: Any, material: Any, planes: Any, h: Any,
                               impacts: int, x_out: wp.array(dtype=Any), v_out: wp.array(dtype=Any),
                               touched_out: wp.array(dtype=wp.int32), max_speed: Any, step: int, record: GuardRecord,
                               base: int, chunk: int):
    """One semi-implicit Euler step of h seconds for the particles chunk * (base + tid) to chunk * (base + tid + 1)
    - 1: v' = v +
    h a(v), x' = x + h v', then (impacts 1) the time-of-impact plane response (skipped where
    kernels.planes.clear_of_planes shows that it would change nothing), then (step > 0) the guard's check of
    (x', v') as step ``step``.

    Launch with dim = ceil(particles / chunk). Each thread of a CPU kernel starts by copying all its arguments,
    the structs' arrays too (16 arrays here: 18.9 against 11.4 ns a particle in free flight at 10^5), and the CPU runs
    the threads one after another anyway, so there a thread steps a chunk of particles (solvers.fused: 256); on
    CUDA one (chunk 1). The particles are independent, so on the CPU a launch may be split into pieces that run
    at once on several cores (core.cpu_threads), each from its own base.

    Args:
        x, v: positions [m] and velocities [m/s] at the start (vec3)
        force: accumulated forces at the start, or an empty array (vec3) [N]
        gravity [m/s^2], drag [N s/m], wind [m/s]: as kernels.particles.particle_acceleration
        material: inverse masses (0: pinned), radii, restitution, friction (ParticleMaterial) [1/kg]
        planes: the planes (Planes) [m]; impacts: 1 to respond to them, 0 not (penalty contacts, no planes)
        h: the step [s]
        x_out, v_out: the end of the step, written (vec3) [m], [m/s]
        touched_out: set to 1 for each particle that touched a plane, or an empty array [1]
        max_speed: the guard's bound [m/s]; step: the step number to record, or 0 for no check [1]
        record: the particles' guard record (GuardRecord) [1]
        base: the first thread of this piece of the launch (0 for a whole launch) [1]
        chunk: particles a thread steps [1]
    """
    first = (base + wp.tid()) * chunk
    for i in range(first, wp.min(first + chunk, x.shape[0])):
        particle_step(i, x, v, force, gravity, drag, wind, material, planes, h, impacts, x_out, v_out, touched_out,
                      max_speed, step, record)


register(globals(), x_out="vec3", v_out="vec3")

"""Cloth gradients (float64): a small cloth hanging from its two top corners, its drape (the mean height of its
vertices after 1 s) against its stiffness, by central differences under symplectic Euler and implicit Euler, and
the stiffness recovered by Newton's method from the drape made at a known one. (A strain-limited cloth is refused:
warp_sim.adjoints says why.)"""
import numpy as np
import pytest
import warp as wp
from gradient_scenes import forward_value

import warp_sim as ws

#: the drape's cloth: 8 x 8 vertices, 0.5 m square, 0.5 kg, hanging in the x-y plane from its top corners, in air
#: (drag 0.1 N s/m a vertex: settled within about a second); its stiffness k for the structural and shear springs,
#: k / 20 for the bend springs
SECONDS, SUBSTEPS, FAMILIES = 1.0, 8, np.array([1.0, 1.0, 0.05])


@wp.kernel
def mean_height(x: wp.array2d(dtype=wp.vec3d), frame: int, weight: wp.float64, out: wp.array(dtype=wp.float64)):
    """out += weight y of every vertex at ``frame`` (weight 1 / count: the mean)."""
    i = wp.tid()
    wp.atomic_add(out, 0, weight * x[frame, i][1])


def drape(traj):
    """The mean height of the vertices at the last frame [m]."""
    out = wp.zeros(1, dtype=wp.float64, requires_grad=True)
    count = traj.particle_x.shape[1]
    wp.launch(mean_height, count, [traj.particle_x, traj.frames, 1.0 / count, out])
    return out


def cloth(k: float) -> ws.Scene:
    scene = ws.Scene(precision="float64", drag=0.1)
    scene.add_cloth_grid(resolution=(8, 8), size=(0.5, 0.5), mass=0.5, stiffness=tuple(k * FAMILIES),
                         damping=(0.02, 0.02, 0.002), pinned="top_corners")
    return scene


def drape_and_slope(k: float, integrator="symplectic_euler"):
    """The drape at stiffness k and d drape / d k (every spring's stiffness scaled with k: the sum of the per-spring
    gradients times d k_s / d k = k_s / k)."""
    value, grads = ws.gradient(cloth(k), drape, ["spring_stiffness"], seconds=SECONDS, substeps=SUBSTEPS,
                               integrator=integrator)
    springs = cloth(k).spring_array("stiffness")
    return value, float(np.dot(grads["spring_stiffness"], springs / k))


def drape_value(k: float, integrator="symplectic_euler") -> float:
    return forward_value(cloth(k), drape, SECONDS, substeps=SUBSTEPS, integrator=integrator)


def central(k: float, integrator, step=1e-5) -> float:
    h = step * k
    return (drape_value(k + h, integrator) - drape_value(k - h, integrator)) / (2.0 * h)


@pytest.mark.parametrize("integrator, bound", [("symplectic_euler", 1e-7), ("implicit_euler", 1e-3)])
def test_the_drapes_stiffness_gradient_against_central_differences(integrator, bound):
    """implicit_euler: CG to its default 1e-3, off the tape and again in the adjoint, so the two differ by about
    that tolerance's effect, not more."""
    value, slope = drape_and_slope(80.0, integrator)
    differences = central(80.0, integrator)
    error = abs(slope - differences) / abs(differences)
    print(f"{integrator}: drape {value:.6f} m, d drape / d k {slope:.9e} m/(N/m), {error:.1e} relative to central "
          f"differences")
    assert value == drape_value(80.0, integrator)
    assert error < bound


def test_newton_recovers_the_stiffness_from_a_target_drape():
    """The target: the drape made at k = 80 N/m. From k = 50 N/m, Newton's steps on drape(k) = target in the
    compliance c = 1 / k (the sag goes nearly as c: d drape / d c = -k^2 d drape / d k), each slope from
    ws.gradient, until the drape misses by under a micrometre."""
    known = 80.0
    target = drape_value(known)
    k, history = 50.0, []
    for _ in range(6):
        value, slope = drape_and_slope(k)
        history.append((k, value - target))
        if abs(value - target) < 1e-6:
            break
        k = 1.0 / (1.0 / k - (value - target) / (-k * k * slope))
    print("Newton on the drape: " + ", ".join(f"k {k_:.4f} N/m (misses {miss * 1000:+.4f} mm)"
                                              for k_, miss in history))
    assert abs(k - known) < 0.02 * known
    assert len(history) <= 5

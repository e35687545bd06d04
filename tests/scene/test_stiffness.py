"""The stiffest spring mode of a scene (scene.stiffness) against dense eigenvalues of the same linearisation."""
import math

import numpy as np
import pytest

import warp_sim as ws
from warp_sim.scene.stiffness import stiffest_mode
from warp_sim.studies.cases import CASES, lattice_cloth, linear_omega


def dense_damping_rate(scene) -> float:
    """The top eigenvalue of W^1/2 C W^1/2, C = sum kd d d^T, formed densely (pinned particles fixed)."""
    x, mass = scene.particle_array("position"), scene.particle_array("mass")
    free = ~scene.particle_array("pinned").astype(bool)
    n = len(x)
    C = np.zeros((3 * n, 3 * n))
    for (i, j), kd in zip(scene.spring_array("pairs"), scene.spring_array("damping")):
        d = (x[j] - x[i]) / np.linalg.norm(x[j] - x[i])
        for a, b, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
            C[3 * a:3 * a + 3, 3 * b:3 * b + 3] += sign * kd * np.outer(d, d)
    keep = np.repeat(free, 3)
    scale = 1.0 / np.sqrt(np.repeat(mass, 3)[keep])
    return float(np.linalg.eigvalsh(C[np.ix_(keep, keep)] * np.outer(scale, scale)).max()) + scene.drag / mass.min()


@pytest.mark.parametrize("name", ["cloth", "mass_ratio_1e6", "light_particles", "zero_rest_length", "pendulum_179",
                                  "spring_1e4"])
def test_the_stiffest_mode_matches_dense_eigenvalues(name):
    """Within 1e-4 (Lanczos converges on the top of the spectrum) and never below it by more than that."""
    scene = CASES[name].build()
    assert stiffest_mode(scene).omega == pytest.approx(linear_omega(scene), rel=1e-4)


def test_a_pinned_cloth_with_uneven_masses_and_dampers_matches_dense_eigenvalues():
    """A 12 x 9 cloth grid (mass by area: corners a quarter of the inner vertices), pinned at two corners, with
    dampers and drag: omega and the damping rate within 1e-4 of the dense ones, and the mode at a light vertex."""
    scene = ws.Scene(drag=0.01, precision="float64")
    ids = scene.add_cloth_grid(resolution=(12, 9), size=(1.2, 0.9), stiffness=(400.0, 200.0, 20.0),
                               damping=(0.05, 0.02, 0.002), pinned=["top_corners"])
    mode = stiffest_mode(scene)
    assert mode.omega == pytest.approx(linear_omega(scene), rel=1e-4)
    assert mode.damping == pytest.approx(dense_damping_rate(scene), rel=1e-4)
    assert mode.particle in ids


def test_the_infinite_lattice_bound_and_a_chain_closed_form():
    """The 12 x 12 lattice's omega^2 = 9.752 k/m (the study's theory); a chain of N equal masses pinned at one end
    has omega = 2 sqrt(k/m) sin((2N - 1) pi / (2 (2N + 1))) (its fastest normal mode)."""
    lattice = lattice_cloth()
    assert stiffest_mode(lattice).omega ** 2 * 0.01 / 100.0 == pytest.approx(9.752, abs=1e-3)
    k, m, links = 2000.0, 0.05, 20
    scene = ws.Scene(precision="float64")
    ids = scene.add_particles([(0.1 * i, 3.0, 0.0) for i in range(links + 1)], mass=m, pinned=[0])
    scene.add_springs(np.stack([ids[:-1], ids[1:]], axis=1), stiffness=k)
    exact = 2.0 * math.sqrt(k / m) * math.sin((2 * links - 1) * math.pi / (2 * (2 * links + 1)))
    assert stiffest_mode(scene).omega == pytest.approx(exact, rel=1e-6)


def test_no_springs_or_only_pinned_ends_have_no_mode():
    scene = ws.Scene()
    scene.add_particles([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], pinned=[0, 1])
    assert stiffest_mode(scene) is None
    scene.add_springs([[0, 1]], stiffness=100.0)
    assert stiffest_mode(scene) is None

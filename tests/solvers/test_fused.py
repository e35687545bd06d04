"""The fused particle step against the generic path (solver stages, plane impulses, guard), at frame-rate steps.

The fused kernel calls the generic path's Warp functions in the same order, so the two must agree bit for bit, in
float64 and in float32 alike (no reassociation happens: each value is formed by the same expression).
"""
import numpy as np
import pytest

import warp_sim as ws

H = 1.0 / 60.0


def _falling_box(precision):
    """200 particles thrown about a box of four walls and a floor, with drag and wind; some pinned."""
    rng = np.random.default_rng(7)
    scene = ws.Scene(precision=precision, drag=0.05, wind=(1.0, 0.0, 0.5))
    pinned = np.arange(0, 200, 37)
    scene.add_particles(rng.uniform((-1, 0.05, -1), (1, 2, 1), (200, 3)), velocities=rng.normal(0, 3, (200, 3)),
                        mass=rng.uniform(0.5, 2.0, 200), radius=0.02, pinned=pinned)
    scene.add_ground(restitution=0.6, friction=0.3)
    for normal, offset in (((1, 0, 0), -1.2), ((-1, 0, 0), -1.2), ((0, 0, 1), -1.2), ((0, 0, -1), -1.2)):
        scene.add_plane(normal, offset, restitution=0.8, friction=0.1)
    return scene


def _cloth(precision):
    """A 12 x 12 cloth hanging from two corners, swinging down to the ground (springs as the force term)."""
    scene = ws.Scene(precision=precision)
    scene.add_cloth_grid(resolution=(12, 12), size=(1.0, 1.0), position=(0.0, 0.6, 0.0), mass=5.0,
                         stiffness=(500.0, 500.0, 50.0), pinned=(0, 11))
    scene.add_ground()
    return scene


def _fountain(precision):
    """An emitter with turbulence over the ground: births and deaths after the fused step."""
    scene = ws.Scene(precision=precision)
    scene.add_emitter(rate=400.0, lifetime=(0.5, 1.0), speed=(2.0, 4.0), spread=30.0, position=(0.0, 0.1, 0.0))
    scene.add_field(ws.Turbulence(strength=2.0, scale=0.5))
    scene.add_ground()
    return scene


def _grazing(precision):
    """2000 fast particles at every distance from the ground and a tilted plane, from touching to a few steps'
    travel: the fused step's clear_of_planes test lets some skip the contact search and not others, right at its
    bound (speeds to about 20 m/s: 0.8 m a step at 1/24 s)."""
    rng = np.random.default_rng(11)
    scene = ws.Scene(precision=precision, drag=0.02)
    scene.add_particles(rng.uniform((-1, 0.02, -1), (1, 3, 1), (2000, 3)), velocities=rng.normal(0, 8, (2000, 3)),
                        radius=0.02)
    scene.add_ground(restitution=0.5, friction=0.5)
    scene.add_plane((0.6, 0.8, 0.0), -1.0, restitution=0.9, friction=0.2)
    return scene


def _states(build, precision, fused, steps, h, **options):
    sim = ws.Simulator(build(precision), integrator="symplectic_euler", device="cpu", fused=fused, **options)
    assert (sim.fused is not None) == fused
    for _ in range(steps):
        sim.step(h)
    return sim.state.particle_x.numpy(), sim.state.particle_v.numpy()


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("build, steps, h", [(_falling_box, 90, H), (_falling_box, 36, 1.0 / 24.0),
                                             (_cloth, 60, 1.0 / 600.0), (_fountain, 48, 1.0 / 240.0),
                                             (_grazing, 24, 1.0 / 24.0), (_grazing, 60, H)])
def test_fused_step_equals_the_generic_path_bit_for_bit(build, steps, h, precision):
    x_fused, v_fused = _states(build, precision, True, steps, h)
    x_generic, v_generic = _states(build, precision, False, steps, h)
    assert np.abs(x_generic).max() > 0.0 and np.isfinite(x_generic).all()
    np.testing.assert_array_equal(x_fused, x_generic)
    np.testing.assert_array_equal(v_fused, v_generic)


@pytest.mark.parametrize("h", [H, 1.0 / 24.0])
def test_fused_step_holds_the_particles_above_the_planes_at_frame_rate(h):
    """At 1/60 s and 1/24 s: no particle below the ground or outside the walls by more than rounding."""
    x, _ = _states(_falling_box, "float64", True, 120, h)
    assert x[:, 1].min() >= 0.02 - 1e-12
    assert np.abs(x[:, [0, 2]]).max() <= 1.2 - 0.02 + 1e-12


def test_fused_step_folds_the_guard_in():
    """A particle thrown faster than max_speed is caught at that step, naming it, as the generic guard does."""
    messages = []
    for fused in (True, False):
        scene = ws.Scene(precision="float64")
        scene.add_particles([[0.0, 1.0, 0.0], [0.0, 2.0, 0.0]], velocities=[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
        scene.add_ground()
        sim = ws.Simulator(scene, integrator="symplectic_euler", device="cpu", fused=fused, max_speed=5.0)
        sim.step(H, steps=10)
        sim.state.particle_v.assign(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 50.0]]))
        with pytest.raises(ws.SimulationDiverged) as caught:
            sim.step(H, steps=3)
        messages.append(str(caught.value))
        assert "step 11" in messages[-1] and "particle 1" in messages[-1]
    assert messages[0] == messages[1]


def test_fused_step_is_taken_only_where_nothing_runs_in_between():
    """rk4, bodies and strain limiting keep the generic path; particles under symplectic_euler take the fused one."""
    assert ws.Simulator(_cloth("float32"), integrator="rk4", device="cpu").fused is None
    scene = _cloth("float32")
    scene.add_rigid_body(ws.Sphere(0.1), position=(0.0, 1.0, 0.0))
    assert ws.Simulator(scene, integrator="symplectic_euler", device="cpu").fused is None
    assert ws.Simulator(_cloth("float32"), integrator="symplectic_euler", device="cpu").fused is not None
    with pytest.raises(ValueError, match="fused"):
        ws.Simulator(_cloth("float32"), integrator="symplectic_euler", device="cpu", fused="yes")

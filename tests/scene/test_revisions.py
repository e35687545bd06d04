"""A scene changed after its Simulator was built is refused at the next step(), frames() or run(), with a message
that says to build a new Simulator; before, particles added then were ignored silently (scene/revisions.py)."""
import numpy as np
import pytest

import warp_sim as ws

CHANGED = "the scene changed after its Simulator was built"


def built():
    scene = ws.Scene()
    scene.add_particles([[0.0, 1.0, 0.0]])
    return scene, ws.Simulator(scene, integrator="symplectic_euler", device="cpu")


@pytest.mark.parametrize("change", [
    lambda s: s.add_particles([[0.0, 2.0, 0.0]]),
    lambda s: s.add_ground(),
    lambda s: s.add_rigid_body(ws.Sphere(0.1)),
    lambda s: s.add_cloth_grid(resolution=(2, 2)),
    lambda s: setattr(s, "gravity", np.zeros(3)),
    lambda s: setattr(s, "drag", 0.1),
])
def test_each_change_is_refused_at_the_next_step(change):
    scene, sim = built()
    sim.step(0.01)
    change(scene)
    with pytest.raises(ValueError, match=rf"^scene=Scene\(.*{CHANGED} \(an add_\* call.*build a new one"):
        sim.step(0.01)
    fresh = ws.Simulator(scene, integrator="symplectic_euler", device="cpu")   # a new one reads the changes
    fresh.step(0.01)


def test_frames_and_run_refuse_it_too(tmp_path):
    scene, sim = built()
    scene.add_particles([[0.0, 2.0, 0.0]])
    with pytest.raises(ValueError, match=CHANGED):
        sim.frames(0.1)
    with pytest.raises(ValueError, match=CHANGED):
        sim.run(0.1, progress=False)
    with pytest.raises(ValueError, match=CHANGED):
        sim.run(0.1, usd=tmp_path / "out.usdc", progress=False)
    assert not (tmp_path / "out.usdc").exists()


def test_a_failed_add_counts_and_the_arrays_cannot_change_in_place():
    scene, sim = built()
    with pytest.raises(ValueError):
        scene.add_particles([[0.0, np.nan, 0.0]])
    with pytest.raises(ValueError, match=CHANGED):   # a failed add_* may have added part of what it was given
        sim.step(0.01)
    with pytest.raises(ValueError, match="read-only"):
        scene.gravity[1] = 0.0
    with pytest.raises(ValueError, match="read-only"):
        scene.wind[0] = 1.0


def test_an_unchanged_scene_steps_and_its_revision_is_a_count():
    scene, sim = built()
    revision = scene.revision
    sim.step(0.01, steps=3)
    list(sim.frames(0.05, fps=60))
    assert scene.revision == revision
    scene.add_ground()
    assert scene.revision == revision + 1

"""benchmarks/joints.py: the engine-neutral scenes, their gap measure, and the translations to warp_sim and (where
installed) MuJoCo start where the description says. Nothing about times."""
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import joints  # noqa: E402


def test_the_scenes_are_trees_whose_anchors_meet_at_the_start():
    chain, dolls = joints.chain(5), joints.ragdolls(3)
    assert (len(chain.bodies), len(chain.joints)) == (5, 5)
    assert (len(dolls.bodies), len(dolls.joints)) == (45, 42)   # 15 bodies, 14 joints a ragdoll
    for scene in (chain, dolls):
        children = [j.child for j in scene.joints]
        assert len(set(children)) == len(children)              # a forest: one joint above each body at most
        assert all(j.parent < j.child for j in scene.joints)     # parents first (Newton's articulations, MJCF)
        assert scene.gaps(*scene.poses()).max() < 1e-12
    assert dolls.lowest(*dolls.poses()) == pytest.approx(joints.DROP)
    kinds = sorted(j.kind for j in dolls.joints[:14])
    assert kinds.count("revolute") == 8 and kinds.count("ball") == 6   # elbows, wrists, knees, ankles


def test_the_gap_measure_is_the_anchor_distance():
    scene = joints.chain(2)
    x, q = scene.poses()
    moved = x.copy()
    moved[1] += (0.0, 0.003, 0.004)   # the second link 5 mm off its joint with the first
    gaps = scene.gaps(moved, q)
    assert gaps[0] == pytest.approx(0.0, abs=1e-12)
    assert gaps[1] == pytest.approx(0.005)


def test_warp_sim_translation_matches_its_own_gaps():
    engine = joints.WarpSimJoints(joints.chain(4))
    scene = joints.chain(4)
    assert scene.gaps(*engine.poses()).max() < 1e-6
    for _ in range(3):
        engine.frame()
    x, q = engine.poses()
    assert np.abs(engine.own_gaps() - scene.gaps(x, q)).max() < 1e-6


def test_mujoco_translation_starts_at_the_described_poses():
    mujoco = pytest.importorskip("mujoco")
    scene = joints.ragdolls(2)
    engine = joints.MujocoJoints(mujoco, scene)
    x, q = engine.poses()
    x0, q0 = scene.poses()
    assert np.abs(x - x0).max() < 1e-9
    assert np.abs(np.abs(np.sum(q * q0, axis=1)) - 1.0).max() < 1e-9   # the same rotations (q or -q)
    assert engine.model.nbody == 31 and engine.model.njnt == 2 + 28   # world, 2 freejoints, 28 joints

"""Recorded launches: a replay with new scalars and thread counts computes what a fresh wp.launch computes, on the
direct CPU path and on Warp's own; the counters, the log and the profile see every launch."""
import numpy as np
import warp as wp

from warp_sim.core.launcher import Launcher
from warp_sim.kernels import integrate


def fresh(y, h, dy, dim):
    out = wp.zeros_like(y)
    wp.launch(integrate.axpy, dim, [y, h, dy, out], device="cpu")
    return out.numpy()


def test_replays_match_fresh_launches_with_new_scalars_and_thread_counts():
    rng = np.random.default_rng(0)
    y = wp.array(rng.normal(size=64), dtype=wp.float64, device="cpu")
    dy = wp.array(rng.normal(size=64), dtype=wp.float64, device="cpu")
    out = wp.zeros_like(y)
    launcher = Launcher(wp.get_device("cpu"))
    for h, dim in ((0.5, 64), (0.25, 17), (2.0, 1), (0.25, 64), (-1.0, 40)):
        out.zero_()
        launcher.launch(integrate.axpy, dim, [y, wp.float64(h), dy, out])
        assert np.array_equal(out.numpy(), fresh(y, wp.float64(h), dy, dim))
    assert len(launcher._recorded) == 1                    # one record, replayed
    assert launcher._recorded[next(iter(launcher._recorded))].direct is not None   # the direct CPU path
    assert launcher.launches == 5 and launcher.single_thread["axpy"] == 1


def test_prepared_launch_sets_one_input_and_logs_and_profiles():
    y = wp.array(np.arange(8.0), dtype=wp.float32, device="cpu")
    dy = wp.array(np.ones(8), dtype=wp.float32, device="cpu")
    out = wp.zeros_like(y)
    launcher = Launcher(wp.get_device("cpu"))
    launcher.log, launcher.profile = [], {}
    prepared = launcher.prepare(integrate.axpy, 8, [y, 1.0, dy, out])
    for h, dim in ((1.0, 8), (3.0, 4), (3.0, 8)):
        prepared.set(1, h)
        prepared.run(dim)
        expected = np.zeros(8, np.float32)
        expected[:dim] = np.arange(8.0)[:dim] + h
        assert np.array_equal(out.numpy()[:dim], expected[:dim])
    assert launcher.log == [("axpy", 8), ("axpy", 4), ("axpy", 8)]
    launches, seconds, nbytes = launcher.profile["axpy"]
    assert launches == 3 and seconds > 0.0 and nbytes == 3 * 3 * 8 * 4
    assert launcher.prepare(integrate.axpy, 8, [y, 1.0, dy, out]) is prepared   # the same record

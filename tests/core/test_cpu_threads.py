"""CPU launches split into pieces on several cores (core.cpu_threads): the same states bit for bit as one thread,
the guard's record naming the lowest bad particle, and the thread count's checks."""
import ctypes
import time

import numpy as np
import pytest

import warp_sim as ws
from warp_sim.core import cpu_threads as cpu_threads_module
from warp_sim.core.cpu_threads import VARIABLE, CpuPool, available_cores, cpu_threads
from warp_sim.core.launcher import Launcher

H = 1.0 / 60.0


def _particles(precision, n=3000, seed=5):
    """n particles thrown about over the ground and a tilted wall, at every distance from them (some pinned)."""
    rng = np.random.default_rng(seed)
    scene = ws.Scene(precision=precision, drag=0.02, wind=(0.5, 0.0, 0.0))
    scene.add_particles(rng.uniform((-1, 0.02, -1), (1, 2, 1), (n, 3)), velocities=rng.normal(0, 4, (n, 3)),
                        mass=rng.uniform(0.5, 2.0, n), radius=0.02, pinned=np.arange(0, n, 101))
    scene.add_ground(restitution=0.5, friction=0.4)
    scene.add_plane((0.6, 0.8, 0.0), -1.0, restitution=0.9, friction=0.2)
    return scene


@pytest.fixture
def small_pieces(monkeypatch):
    """Pieces of 200 particles, so that a test scene of thousands splits into many."""
    monkeypatch.setattr(cpu_threads_module, "MIN_PIECE", 200)


def _simulator(scene, threads, **options):
    return ws.Simulator(scene, integrator="symplectic_euler", device="cpu", cpu_threads=threads, **options)


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("h, steps", [(H, 90), (1.0 / 24.0, 36)])
def test_pieces_on_several_threads_give_the_states_of_one_thread_bit_for_bit(small_pieces, precision, h, steps):
    states = []
    for threads in (1, 3):
        sim = _simulator(_particles(precision), threads)
        assert sim.fused is not None and sim.fused.pieces == 15 and sim.model.launcher.pool.threads == threads
        sim.step(h, steps=steps)
        states.append((sim.state.particle_x.numpy(), sim.state.particle_v.numpy()))
    (x1, v1), (x3, v3) = states
    assert np.isfinite(x1).all() and x1[:, 1].min() >= 0.02 - 1e-5   # resting on the ground, not through it
    np.testing.assert_array_equal(x3, x1)
    np.testing.assert_array_equal(v3, v1)


@pytest.mark.parametrize("integrator, h", [("rk4", H), ("verlet", 1.0 / 24.0), ("midpoint", H)])
def test_the_generic_path_on_several_threads_gives_the_states_of_one_thread_bit_for_bit(monkeypatch, integrator, h):
    """The generic path's elementwise kernels (axpy, rk4_combine, copy, the particle accelerations) run over views
    of their arrays, the plane pass from its bases, as pieces at once: the states of one thread, bit for bit."""
    monkeypatch.setattr(Launcher, "elementwise_piece", 500)
    monkeypatch.setattr(cpu_threads_module, "MIN_PIECE", 200)
    states = []
    for threads in (1, 3):
        sim = ws.Simulator(_particles("float32"), integrator=integrator, device="cpu", cpu_threads=threads)
        sim.step(h, steps=40)
        assert sim.fused is None and (sim.impacts.pieces == 15) and (len(sim.model.launcher._split) > 0) == (
            threads > 1)   # the generic path, split into pieces
        launches = sim.model.launcher.launches
        sim.step(h)
        states.append((sim.state.particle_x.numpy(), sim.state.particle_v.numpy(),
                       sim.model.launcher.launches - launches))
    (x1, v1, launches1), (x3, v3, launches3) = states
    assert np.isfinite(x1).all() and x1[:, 1].min() >= 0.02 - 1e-5
    assert launches3 == launches1   # a launch in pieces counts once
    np.testing.assert_array_equal(x3, x1)
    np.testing.assert_array_equal(v3, v1)


def test_pieces_run_on_the_workers(small_pieces):
    """The pool's workers take the pieces after the first (the launch is split, not run whole)."""
    sim = _simulator(_particles("float32"), 2)
    sim.step(H, steps=3)
    assert sim.model.launcher.pool._workers is not None


def test_the_guard_names_the_lowest_bad_particle_whichever_piece_holds_it(small_pieces):
    """Every 7th particle from 1500 on, and particle 1234, thrown faster than max_speed: the error names step 1 and
    particle 1234, as on one thread, though several pieces record bad particles at once."""
    messages = []
    for threads in (1, 3):
        scene = _particles("float64")
        sim = _simulator(scene, threads, max_speed=50.0)
        v = sim.state.particle_v.numpy()
        bad = np.r_[1234, np.arange(1500, 3000, 7)]
        v[bad] = (0.0, 0.0, 80.0)
        sim.state.particle_v.assign(v)
        with pytest.raises(ws.SimulationDiverged) as caught:
            sim.step(H)
        assert caught.value.step == 1 and caught.value.element == 1234
        messages.append(str(caught.value))
    assert messages[0] == messages[1]


def test_a_small_scene_stays_one_piece():
    """Below 2 x MIN_PIECE particles a second thread costs more than it saves: one piece."""
    assert _simulator(_particles("float32", n=2 * cpu_threads_module.MIN_PIECE - 1), 4).fused.pieces == 1


def test_thread_counts_are_checked(monkeypatch):
    monkeypatch.delenv(VARIABLE, raising=False)
    assert cpu_threads() == available_cores() >= 1
    assert cpu_threads(3) == 3
    monkeypatch.setenv(VARIABLE, "2")
    assert cpu_threads() == 2
    assert cpu_threads(1) == 1   # the argument before the variable
    for text in ("0", "two", "1.5"):
        monkeypatch.setenv(VARIABLE, text)
        with pytest.raises(ValueError, match=f"{VARIABLE}='{text}' is invalid: must be a whole number >= 1"):
            cpu_threads()
    monkeypatch.delenv(VARIABLE)
    for value in (0, 2.0, True):
        with pytest.raises(ValueError, match="cpu_threads"):
            _simulator(_particles("float32", n=10), value)


def test_an_interrupted_call_returns_only_once_every_piece_is_done():
    """Ctrl-C (here an exception in the caller's own piece) while workers still run their pieces: call() waits
    for them before it raises, so no piece writes into a state after the Simulator has moved on."""
    finished = []

    def entry(bounds, _arguments):
        piece = bounds._obj.value
        if piece == 0:
            raise KeyboardInterrupt
        time.sleep(0.2)
        finished.append(piece)

    pool = CpuPool(3)
    calls = [(entry, ctypes.c_int(k), ctypes.c_int(0)) for k in range(3)]
    with pytest.raises(KeyboardInterrupt):
        pool.call(calls)
    assert sorted(finished) == [1, 2]

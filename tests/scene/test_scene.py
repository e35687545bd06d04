"""Bad input raises ValueError naming the argument, the value and what is valid."""
import math

import numpy as np
import pytest

import warp_sim as ws


def scene_with(n=3):
    scene = ws.Scene()
    scene.add_particles(np.arange(3 * n, dtype=float).reshape(n, 3))
    return scene


@pytest.mark.parametrize("call, argument, value", [
    (lambda s: s.add_particles([[0, math.nan, 0]]), "positions", "nan"),
    (lambda s: s.add_particles([[0, math.inf, 0]]), "positions", "inf"),
    (lambda s: s.add_particles([[0, 0]]), "positions", "shape"),
    (lambda s: s.add_particles([[0, 0, 0]], velocities=[[1, 2, 3], [4, 5, 6]]), "velocities", "shape"),
    (lambda s: s.add_particles([[0, 0, 0]], mass=0.0), "mass", "> 0"),
    (lambda s: s.add_particles([[0, 0, 0], [1, 0, 0]], mass=[1.0, -2.0]), "mass", "-2"),
    (lambda s: s.add_particles([[0, 0, 0]], mass=[1.0, 2.0]), "mass", "shape"),
    (lambda s: s.add_particles([[0, 0, 0]], radius=-0.1), "radius", ">= 0"),
    (lambda s: s.add_particles([[0, 0, 0]], pinned=[3]), "pinned", "[0, 1)"),
    (lambda s: s.add_particles([[0, 0, 0]], restitution=1.5), "restitution", "[0, 1]"),
    (lambda s: s.add_springs([[0, 7]], 10.0), "pairs", "[0, 3)"),
    (lambda s: s.add_springs([[1, 1]], 10.0), "pairs", "itself"),
    (lambda s: s.add_springs([[0, 1, 2]], 10.0), "pairs", "shape"),
    (lambda s: s.add_springs([[0, 1]], -5.0), "stiffness", ">= 0"),
    (lambda s: s.add_springs([[0, 1]], 5.0, damping=-1.0), "damping", ">= 0"),
    (lambda s: s.add_springs([[0, 1]], 5.0, rest_length=-1.0), "rest_length", ">= 0"),
    (lambda s: s.add_plane((0, 0, 0)), "normal", "non-zero"),
    (lambda s: s.add_plane((0, 1, 0), restitution=2.0), "restitution", "<= 1"),
    (lambda s: s.add_plane((0, 1, 0), friction=-0.1), "friction", ">= 0"),
    (lambda s: s.add_plane((0, 1, 0), offset=math.nan), "offset", "finite"),
])
def test_scene_rejects(call, argument, value):
    with pytest.raises(ValueError) as caught:
        call(scene_with())
    message = str(caught.value)
    assert message.startswith(f"{argument}=") and value in message


def test_zero_length_spring_needs_a_rest_length():
    scene = ws.Scene()
    scene.add_particles([[0, 0, 0], [0, 0, 0]])
    with pytest.raises(ValueError, match="rest_length=None.*coincident particles"):
        scene.add_springs([[0, 1]], 10.0)
    scene.add_springs([[0, 1]], 10.0, rest_length=0.0)   # zero rest length, given explicitly, is fine


@pytest.mark.parametrize("kwargs, argument", [
    ({"precision": "float16"}, "precision"), ({"gravity": (0, 1)}, "gravity"), ({"drag": -1}, "drag"),
])
def test_scene_arguments(kwargs, argument):
    with pytest.raises(ValueError, match=f"^{argument}="):
        ws.Scene(**kwargs)


@pytest.mark.parametrize("kwargs, argument", [
    ({"integrator": "leapfrog"}, "integrator"), ({"device": "tpu"}, "device"),
    ({"contact": "magic"}, "contact"), ({"max_speed": 0.0}, "max_speed"),
    ({"penalty_stiffness": -1.0}, "penalty_stiffness"),
])
def test_simulator_arguments(kwargs, argument):
    with pytest.raises(ValueError, match=f"^{argument}="):
        ws.Simulator(scene_with(), **kwargs)


def test_unknown_integrator_lists_the_valid_names():
    with pytest.raises(ValueError) as caught:
        ws.Simulator(scene_with(), integrator="leapfrog")
    assert all(name in str(caught.value) for name in ws.INTEGRATORS)


def test_empty_scene_is_refused():
    with pytest.raises(ValueError, match="^scene=.*nothing to simulate"):
        ws.Simulator(ws.Scene())


@pytest.mark.parametrize("dt", [0.0, -1e-3, math.nan, math.inf])
def test_step_rejects_bad_dt(dt):
    with pytest.raises(ValueError, match="^dt="):
        ws.Simulator(scene_with(), device="cpu").step(dt)


@pytest.mark.parametrize("kwargs, argument", [
    ({"seconds": 0.0}, "seconds"), ({"seconds": 1.0, "fps": -30}, "fps"),
    ({"seconds": 1.0, "substeps": 0}, "substeps"), ({"seconds": 1.0, "substeps": 2.5}, "substeps"),
    ({"seconds": 0.001, "fps": 60}, "seconds"),
])
def test_run_rejects(kwargs, argument):
    with pytest.raises(ValueError, match=f"^{argument}="):
        ws.Simulator(scene_with(), device="cpu").run(progress=False, **kwargs)


def test_bad_usd_extension_names_the_argument(tmp_path):
    with pytest.raises(ValueError, match="path"):
        ws.Simulator(scene_with(), device="cpu").run(seconds=0.1, usd=tmp_path / "out.abc", progress=False)
    assert list(tmp_path.iterdir()) == []

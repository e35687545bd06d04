"""Values outside the scene's precision are refused where they are given (scene/ranges.py), naming the argument and
the precision, instead of a "non-finite position of particle 0" at the first step: in float32 (largest 3.4e38) a
mass of 1e-300 kg (1/m = 1e300), a radius or a stiffness of 1e300, gravity of 1e39 m/s^2; the same values that fit
float64 are accepted there."""
import numpy as np
import pytest

import warp_sim as ws

F32 = "float32"
ONE = [[0.0, 1.0, 0.0]]
TWO = [[0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]


def springs(scene, **options):
    scene.add_particles(TWO, mass=options.pop("mass", 1.0))
    scene.add_springs([[0, 1]], **options)


CASES = {   # name -> (what to add to a float32 scene, the argument named, the words that must follow)
    "a tiny particle mass": (lambda s: s.add_particles(ONE, mass=1e-300), "mass=1e-300", "1/mass[0] is 1e+300"),
    "a huge particle mass": (lambda s: s.add_particles(ONE, mass=1e39), "mass=1e+39", "entry 0 is 1e+39"),
    "a huge radius": (lambda s: s.add_particles(ONE, radius=1e300), "radius=1e+300", "entry 0 is 1e+300"),
    "a huge stiffness": (lambda s: springs(s, stiffness=1e300), "stiffness=1e+300", "entry 0 is 1e+300"),
    "stiffness over a light mass": (lambda s: springs(s, stiffness=1e30, mass=1e-10), "stiffness=1e+30",
                                    "stiffness/mass[0] is 2e+40"),
    "damping over a light mass": (lambda s: springs(s, stiffness=1.0, damping=1e30, mass=1e-10), "damping=1e+30",
                                  "damping/mass[0] is 2e+40"),
    "a tiny body mass": (lambda s: s.add_rigid_body(ws.Box(0.1), mass=1e-300), "mass=1e-300", "1/mass is 1e+300"),
    "a huge sphere": (lambda s: s.add_rigid_body(ws.Sphere(1e30)), "mass=4.18879", "does not fit"),
    "a huge collider": (lambda s: s.add_collider(ws.Sphere(1e39)), "shape=Sphere(radius=1e+39)",
                        "its bounding radius [m] is 1e+39"),
    "a tiny cloth": (lambda s: s.add_cloth_grid(resolution=(2, 2), mass=1e-300), "mass=", "1/mass[0] is 4e+300"),
    "a tiny emitted mass": (lambda s: s.add_emitter(mass=1e-300), "mass=[1.e-300 1.e-300]", "1/mass[0] is 1e+300"),
    "a far plane": (lambda s: s.add_plane((0, 1, 0), offset=1e39), "offset=1e+39", "it is 1e+39"),
}


@pytest.mark.parametrize("name", list(CASES))
def test_a_value_beyond_float32_is_refused_naming_the_argument_and_the_precision(name):
    add, argument, words = CASES[name]
    scene = ws.Scene(precision=F32)
    with pytest.raises(ValueError) as caught:
        add(scene)
    text = str(caught.value)
    assert text.startswith(argument) and words in text and "precision float32 (largest 3.4e+38)" in text, text


@pytest.mark.parametrize("argument, value", [("gravity", (0.0, -1e39, 0.0)), ("wind", (1e39, 0.0, 0.0)),
                                             ("drag", 1e39), ("angular_drag", 1e39)])
def test_scene_arguments_must_fit(argument, value):
    with pytest.raises(ValueError, match=rf"^{argument}=.*does not fit the scene's precision float32"):
        ws.Scene(precision=F32, **{argument: value})
    ws.Scene(precision="float64", **{argument: value})


def test_the_drag_over_a_light_particle_must_fit():
    scene = ws.Scene(precision=F32, drag=1e10)
    with pytest.raises(ValueError, match=r"^mass=1e-30 is invalid: drag/mass\[0\] is 1e\+40"):
        scene.add_particles(ONE, mass=1e-30)


@pytest.mark.parametrize("name", ["a tiny particle mass", "a huge stiffness", "stiffness over a light mass",
                                  "a tiny body mass"])
def test_float64_holds_them(name):
    add, _, _ = CASES[name]
    add(ws.Scene(precision="float64"))


def test_a_light_particle_within_float32_steps(device):
    """1e-30 kg is within float32 (1/m = 1e30): accepted, and it falls as any particle does."""
    scene = ws.Scene(precision=F32)
    scene.add_particles(ONE, mass=1e-30)
    sim = ws.Simulator(scene, integrator="symplectic_euler", device=device)
    sim.step(0.01, steps=10)
    assert np.all(np.isfinite(sim.state.particle_x.numpy()))

"""What the differentiable mode refuses, before anything compiles or runs, each message naming the part and why
(the same from Simulator(differentiable=True) and from ws.gradient); and the bad arguments of ws.gradient, each a
ValueError naming the argument."""
import time

import numpy as np
import pytest
import warp as wp
from gradient_scenes import final_position_loss, projectile

import warp_sim as ws
from warp_sim.adjoints import NoAdjoint

LOSS = final_position_loss()


def two_balls(**options) -> ws.Scene:
    scene = ws.Scene(precision="float64", **options)
    scene.add_rigid_body(ws.Sphere(0.1), mass=1.0, position=(0.0, 1.0, 0.0))
    scene.add_rigid_body(ws.Sphere(0.1), mass=1.0, position=(0.5, 1.0, 0.0))
    return scene


def two_boxes() -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), mass=1.0, position=(0.0, 1.0, 0.0))
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), mass=1.0, position=(0.5, 1.0, 0.0))
    return scene


def particles_on_ground() -> ws.Scene:
    scene = projectile()
    scene.add_ground()
    return scene


def particle_and_collider() -> ws.Scene:
    scene = projectile()
    scene.add_collider(ws.Box((0.5, 0.1, 0.5)), position=(0.0, -1.0, 0.0))
    return scene


def cloth(**options) -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_cloth_grid(resolution=(4, 4), pinned="top_corners", **options)
    return scene


def jointed(**joint) -> ws.Scene:
    scene = two_balls()
    scene.add_joint("ball", 0, 1, anchor=(0.25, 1.0, 0.0), **joint)
    return scene


def kinematic() -> ws.Scene:
    scene = ws.Scene(precision="float64")
    scene.add_rigid_body(ws.Box((0.1, 0.1, 0.1)), mass=1.0,
                         kinematic=([0.0, 1.0], [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0)], [(0, 0, 0, 1), (0, 0, 0, 1)]))
    return scene


def emitter() -> ws.Scene:
    scene = projectile()
    scene.add_emitter(rate=10.0, lifetime=1.0)
    return scene


def attracted() -> ws.Scene:
    scene = projectile()
    scene.add_field(ws.Attractor(position=(0.0, 0.0, 0.0), strength=1.0))
    return scene


#: (scene, Simulator options, words the message must hold)
REFUSED = {
    "body contacts": (two_boxes, {}, ["body contacts", "pairs of bodies other than two spheres",
                                       "collisions=False"]),
    "particles and colliders": (particle_and_collider, {}, ["particle contacts with bodies and colliders"]),
    "plane penalty": (particles_on_ground, {"contact": "penalty"}, ["penalty contacts of particles on planes"]),
    "body penalty": (two_balls, {"contact": "penalty"}, ["penalty contacts of bodies", "collisions=False"]),
    "strain limiter": (lambda: cloth(max_stretch=0.1), {}, ["the strain limiter", "grows without bound",
                                                            "max_stretch=None"]),
    "aerodynamics": (lambda: cloth(drag=1.0), {}, ["aerodynamic drag and lift"]),
    "breakable joints": (lambda: jointed(break_force=10.0), {"collisions": False},
                         ["joints", "break forces and torques", "cannot break"]),
    "kinematic": (kinematic, {}, ["kinematic bodies"]),
    "emitters": (emitter, {}, ["emitters", "births and deaths"]),
    "fields": (attracted, {}, ["force fields"]),
    "rk45": (projectile, {"integrator": "rk45"}, ["integrator 'rk45'", "step-size control"]),
}


@pytest.mark.parametrize("case", REFUSED)
def test_a_part_without_an_adjoint_is_refused_by_name(case):
    make, options, words = REFUSED[case]
    started = time.perf_counter()
    with pytest.raises(NoAdjoint) as simulator:
        ws.Simulator(make(), differentiable=True, **options)
    gradient_options = dict(options)
    integrator = gradient_options.pop("integrator", None)
    with pytest.raises(ValueError) as gradient:
        ws.gradient(make(), LOSS, ["particle_x"] if make().particle_count else ["body_x"], seconds=0.1,
                    integrator=integrator, **gradient_options)
    message = str(gradient.value)
    print(f"{case}: {message} ({time.perf_counter() - started:.2f} s, both)")
    assert str(simulator.value).startswith("Simulator(differentiable=True): no adjoint yet for ")
    assert message.startswith("ws.gradient: no adjoint yet for ") and all(word in message for word in words)


def test_capture_is_refused():
    with pytest.raises(ValueError, match=r"capture=True is invalid: .*differentiable=True"):
        ws.Simulator(projectile(), differentiable=True, capture=True)


def test_what_is_covered_is_accepted_with_collisions_off():
    """Bodies that would collide, without contacts (collisions=False); springs, bodies and particles together."""
    scene = two_balls()
    scene.add_particles([(0.0, 2.0, 0.0), (0.1, 2.0, 0.0)])
    scene.add_springs([(0, 1)], stiffness=10.0)
    sim = ws.Simulator(scene, differentiable=True, collisions=False)
    assert sim.differentiable and sim.fused is None and sim.settings["differentiable"]
    assert "differentiable" not in ws.Simulator(projectile()).settings


@pytest.mark.parametrize("wrt, words", [
    ("particle_x", "expected a list of names"),
    (["particle_y"], "wrt='particle_y' is invalid: no such name"),
    (["body_x"], "wrt='body_x' is invalid: it is the initial centres of mass"),
    (["spring_stiffness"], "the scene has none"),
    (["particle_x", "particle_x"], "expected each name once"),
])
def test_bad_wrt_names_it(wrt, words):
    with pytest.raises(ValueError, match="^wrt=") as error:
        ws.gradient(projectile(), LOSS, wrt, seconds=0.1)
    assert words in str(error.value)


@pytest.mark.parametrize("controls, words", [
    ({"particle_force": np.zeros((5, 1, 3))}, "is invalid: expected shape (6, 1, 3), got (5, 1, 3)"),
    ({"body_force": np.zeros((6, 1, 3))}, "controls='body_force' is invalid: a force at each body's centre of mass "
                                          "[N], world frame, and the scene has no bodies"),
    ({"wind": np.zeros((6, 1, 3))}, "controls='wind' is invalid: no such control"),
    ([np.zeros((6, 1, 3))], "is invalid: expected a dict of per-frame controls"),
    ({"particle_force": np.full((6, 1, 3), np.nan)}, "is invalid: every entry must be finite"),
])
def test_bad_controls_name_them(controls, words):
    with pytest.raises(ValueError, match="^controls") as error:
        ws.gradient(projectile(), LOSS, ["particle_force"], seconds=0.1, controls=controls)
    assert words in str(error.value)


def test_a_loss_must_return_a_one_element_array_with_a_gradient():
    for loss, words in [(lambda traj: 1.0, "it returned float"),
                        (lambda traj: wp.zeros(2, dtype=wp.float64, requires_grad=True), "it returned (2,)"),
                        (lambda traj: wp.zeros(1, dtype=wp.float64), "requires_grad=True")]:
        with pytest.raises(ValueError, match="^loss=") as error:
            ws.gradient(projectile(), loss, ["particle_x"], seconds=0.1)
        assert words in str(error.value)
    with pytest.raises(ValueError, match="^loss="):
        ws.gradient(projectile(), "loss", ["particle_x"], seconds=0.1)


def test_other_bad_arguments():
    with pytest.raises(ValueError, match="^differentiable=False is invalid: ws.gradient sets it"):
        ws.gradient(projectile(), LOSS, [], seconds=0.1, differentiable=False)
    with pytest.raises(ValueError, match="^seconds=0.001 is invalid: covers no frame"):
        ws.gradient(projectile(), LOSS, [], seconds=0.001)
    with pytest.raises(ValueError, match="^substeps=0 is invalid"):
        ws.gradient(projectile(), LOSS, [], seconds=0.1, substeps=0)
    with pytest.raises(ValueError, match="^scene="):
        ws.gradient("scene", LOSS, [], seconds=0.1)
    with pytest.raises(ValueError, match="^differentiable="):
        ws.Simulator(projectile(), differentiable=1)

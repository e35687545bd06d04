"""The public kernels of warp_sim.kernels as an API: each module's ``__all__``, a docstring line with a
meaning and a [unit] for every argument, docs/kernels.md up to date with them, and launches on a user's
own arrays (and argument blocks, warp_sim.kernels.blocks) checked against numpy."""
import importlib
import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest
import warp as wp
from helpers import load_tool

ROOT = Path(__file__).resolve().parents[2]


kernel_docs = load_tool("kernel_docs")

PUBLIC = {
    "integrate": ["axpy", "copy", "rk4_combine"],
    "springs": ["spring_forces"],
    "particles": ["particle_acceleration"],
    "fields": ["attractor_forces", "vortex_forces", "turbulence_forces"],
    "rigid": ["body_momentum_rates", "body_position_rates", "normalize_orientations", "body_velocities",
              "rotation_matrices", "apply_impulse"],
    "planes": ["resolve_plane_impacts"],
    "penalty": ["plane_penalty_forces"],
    "cloth": ["aerodynamic_forces"],
    "guards": ["check_finite_and_bounded"],
}
PRIVATE = ["contacts", "joints", "detection", "manifolds", "emitters", "implicit", "particle_shapes", "geometry",
           "precisions", "fused", "impulses", "contact_adjoint", "joint_frames", "joint_adjoint"]
HELPERS = {"blocks": ["of", "fill"]}   # public modules without kernels

PUBLIC_KERNELS = [(topic, name) for topic, names in PUBLIC.items() for name in names]


def _kernel(topic, name):
    return getattr(importlib.import_module(f"warp_sim.kernels.{topic}"), name)


# the API and its documentation -------------------------------------------------------------------
def test_public_kernels_are_each_modules_all():
    for topic, names in PUBLIC.items():
        module = importlib.import_module(f"warp_sim.kernels.{topic}")
        assert sorted(module.__all__) == sorted(names), topic
        assert all(isinstance(getattr(module, name), wp.Kernel) for name in module.__all__), topic
        assert "Public (``__all__``)" in module.__doc__, topic
    for name in PRIVATE:
        module = importlib.import_module(f"warp_sim.kernels.{name}")
        assert module.__all__ == [], name
        assert "Private:" in module.__doc__, name
    for name, names in HELPERS.items():
        module = importlib.import_module(f"warp_sim.kernels.{name}")
        assert module.__all__ == names, name
        assert not any(isinstance(value, wp.Kernel) for value in vars(module).values()), name
    assert set(kernel_docs.TOPICS) == set(PUBLIC) and set(kernel_docs.PRIVATE) == set(PRIVATE)
    assert set(kernel_docs.HELPERS) == set(HELPERS)


def test_docs_kernels_md_is_up_to_date():
    diff = kernel_docs.check()
    assert diff == [], "docs/kernels.md is out of date: run python tools/kernel_docs.py\n" + "".join(diff[:60])
    text = (ROOT / "docs" / "kernels.md").read_text(encoding="utf-8")
    for topic, name in PUBLIC_KERNELS:
        assert f"### {topic}.{name}" in text
    for name in PRIVATE:
        assert f"`warp_sim.kernels.{name}`" in text
    for name in kernel_docs.block_names():
        assert f"| `{name}` |" in text, f"block {name} is not in the page's table of blocks"


def test_block_and_struct_arguments_are_documented_from_their_structs():
    """A block argument's dtype lists its struct's fields and element types, and its concrete type is the block of
    the precision; a concrete struct argument (GuardRecord) lists its own fields."""
    from warp_sim.kernels import blocks, guards, springs

    names = list(kernel_docs.block_names())
    assert names == list(vars(blocks.of(wp.float64)))
    assert {"Bodies", "BodyMass", "Wrench", "Springs", "Planes", "ParticleMaterial"} <= set(names)
    argument = {a.name: a for a in kernel_docs.kernel_arguments(springs.spring_forces)}["springs"]
    assert argument.kind == "Springs" and argument.is_block
    assert argument.dtype() == ("`kernels.blocks` [Springs](#argument-blocks) struct of the precision: "
                                "pairs (vec2i array), stiffness, damping, rest_length (scalar arrays)")
    assert argument.concrete("float32") is blocks.of(wp.float32).Springs
    assert argument.concrete("float64") is blocks.of(wp.float64).Springs
    record = {a.name: a for a in kernel_docs.kernel_arguments(guards.check_finite_and_bounded)}["record"]
    assert record.kind == "GuardRecord" and not record.generic
    assert record.dtype() == "`kernels.guards` GuardRecord struct: first_step, first_key (int32 arrays)"
    assert record.concrete("float32") is guards.GuardRecord is record.concrete("float64")
    for name in names:   # every field of every block is named in blocks.py's docstring, with its unit
        fields = [field for field, _, _ in kernel_docs.block_fields(name)]
        assert fields == list(getattr(blocks.of(wp.float64), name).vars)
        assert kernel_docs.block_docs()[name]


@pytest.mark.parametrize("topic, name", PUBLIC_KERNELS)
def test_every_argument_has_a_docstring_line_with_a_unit(topic, name):
    kernel = _kernel(topic, name)
    doc = kernel.func.__doc__
    assert doc, f"{topic}.{name} has no docstring"
    for arg in kernel.adj.args:
        lines = [line for line in doc.splitlines() if re.match(rf"^\s+{arg.label}: \S", line)]
        assert len(lines) == 1, f"{topic}.{name}: argument {arg.label} needs one docstring line 'name: meaning [unit]'"
        assert re.search(r"\S \[[^\[\]]+\]$", lines[0]), f"{topic}.{name}: {lines[0].strip()!r} has no [unit]"
    # the generator reads the same lines, in signature order, each with a meaning and a unit
    arguments = kernel_docs.kernel_arguments(kernel)
    assert [a.name for a in arguments] == [arg.label for arg in kernel.adj.args]
    assert all(a.meaning and a.unit.strip() for a in arguments)


def _zeros_like_type(t, count=2):
    """A zero value of Warp type ``t``: an array of ``count`` zeros, or a struct (an argument block, GuardRecord)
    with each field such an array of the field's dtype."""
    from warp_sim.kernels import blocks

    if isinstance(t, wp.array):
        return wp.zeros(count, dtype=t.dtype, device="cpu")
    if wp.types.type_is_struct(t):
        return blocks.fill(t, **{name: _zeros_like_type(var.type, count) for name, var in t.vars.items()})
    return t()


@pytest.mark.parametrize("topic, name", PUBLIC_KERNELS)
def test_documented_dtypes_launch_in_both_precisions(topic, name):
    """The dtypes docs/kernels.md gives (float32 and float64, the vec3/quat/mat33 it names) are the ones the
    kernel compiles and runs with; arrays the docs call elementwise also take vec3, quat and mat33."""
    kernel = _kernel(topic, name)
    arguments = kernel_docs.kernel_arguments(kernel)
    variants = []
    for precision, suffix in (("float32", "f"), ("float64", "d")):
        types = kernel_docs.concrete_types(kernel, precision)
        variants.append(types)
        for kind in ("vec3", "quat", "mat33"):
            element = getattr(wp, kind + suffix)
            if any(a.kind == "elementwise" for a in arguments):
                variants.append({a.name: wp.array(dtype=element) if a.kind == "elementwise" else types[a.name]
                                 for a in arguments})
    for types in variants:
        wp.overload(kernel, types)   # all first: the module compiles once
    for types in variants:
        wp.launch(kernel, 1, [_zeros_like_type(t) for t in types.values()], device="cpu")
    wp.synchronize_device("cpu")


# launches on the user's own arrays, against numpy ---------------------------------------------------
def test_spring_forces_on_own_arrays(device):
    """Three particles, two springs (0-1, 1-2) in a float64 Springs block: f2 = (-ks (L - L0) - kd (v2 - v1).d) d,
    f1 = -f2, added to what ``force`` held; rel 1e-12 of the largest force."""
    from warp_sim.kernels import blocks, springs

    rng = np.random.default_rng(7)
    x = rng.normal(size=(3, 3))
    v = rng.normal(size=(3, 3))
    pairs = np.array([[0, 1], [1, 2]], dtype=np.int32)
    ks = np.array([50.0, 120.0])
    kd = np.array([0.7, 1.3])
    rest = np.array([0.8, 1.5])
    initial = rng.normal(size=(3, 3))

    force = wp.array(initial, dtype=wp.vec3d, device=device)
    block = blocks.fill(blocks.of(wp.float64).Springs, pairs=wp.array(pairs, dtype=wp.vec2i, device=device),
                        stiffness=wp.array(ks, dtype=wp.float64, device=device),
                        damping=wp.array(kd, dtype=wp.float64, device=device),
                        rest_length=wp.array(rest, dtype=wp.float64, device=device))
    wp.launch(springs.spring_forces, 2,
              inputs=[wp.array(x, dtype=wp.vec3d, device=device), wp.array(v, dtype=wp.vec3d, device=device),
                      block, force], device=device)

    expected = initial.copy()
    for s, (p1, p2) in enumerate(pairs):
        delta = x[p2] - x[p1]
        length = np.linalg.norm(delta)
        d = delta / length
        f2 = (-ks[s] * (length - rest[s]) - kd[s] * np.dot(v[p2] - v[p1], d)) * d
        expected[p2] += f2
        expected[p1] -= f2
    got = force.numpy()
    scale = np.abs(expected).max()
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * scale)


TOLERANCE = {"float32": 1e-6, "float64": 1e-14}   # relative to the scale of the terms summed


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_integrator_stages_on_own_arrays(device, precision):
    """integrate.axpy: out = y + h dy, also in place (out = y); integrate.rk4_combine:
    out = y + h/6 (k1 + 2 k2 + 2 k3 + k4). Random arrays; |out - exact| <= rel (|y| + |h| sum |terms|) with
    rel 1e-6 (float32) and 1e-14 (float64), the exact value computed in float64 from the same inputs."""
    from warp_sim.kernels import integrate

    scalar = getattr(wp, precision)
    np_scalar = np.dtype(precision)
    rel = TOLERANCE[precision]
    rng = np.random.default_rng(11)
    n = 1000
    y, dy, k1, k2, k3, k4 = (rng.normal(size=n).astype(np_scalar) for _ in range(6))
    h = scalar(0.0137)
    h64 = float(np_scalar.type(0.0137))

    def array(values):
        return wp.array(values, dtype=scalar, device=device)

    def check(got, exact, scale):
        error = np.abs(got.astype(np.float64) - exact)
        assert np.all(error <= rel * scale), f"max error / scale {np.max(error / scale):.3g} > {rel}"

    out = wp.empty(n, dtype=scalar, device=device)
    wp.launch(integrate.axpy, n, inputs=[array(y), h, array(dy), out], device=device)
    y64, dy64 = y.astype(np.float64), dy.astype(np.float64)
    check(out.numpy(), y64 + h64 * dy64, np.abs(y64) + abs(h64) * np.abs(dy64))

    in_place = array(y)
    wp.launch(integrate.axpy, n, inputs=[in_place, h, array(dy), in_place], device=device)
    np.testing.assert_array_equal(in_place.numpy(), out.numpy())

    out = wp.empty(n, dtype=scalar, device=device)
    wp.launch(integrate.rk4_combine, n, inputs=[array(y), h, array(k1), array(k2), array(k3), array(k4), out],
              device=device)
    k = [a.astype(np.float64) for a in (k1, k2, k3, k4)]
    exact = y64 + h64 / 6.0 * (k[0] + 2.0 * k[1] + 2.0 * k[2] + k[3])
    scale = np.abs(y64) + abs(h64) * (np.abs(k[0]) + 2.0 * np.abs(k[1]) + 2.0 * np.abs(k[2]) + np.abs(k[3]))
    check(out.numpy(), exact, scale)


@pytest.mark.parametrize("with_force", [True, False])
def test_particle_acceleration_on_own_arrays(device, with_force):
    """dv = gravity + (f + drag (wind - v)) / m in float64, rel 1e-13 of the terms' scale; the pinned
    particle (inverse mass 0) gets exactly zero; without force terms ``force`` is an empty array."""
    from warp_sim.kernels import particles

    rng = np.random.default_rng(3)
    n = 4
    v = rng.normal(size=(n, 3))
    f = rng.normal(size=(n, 3)) if with_force else np.zeros((n, 3))
    mass = np.array([0.5, 2.0, 1.0, 3.0])
    inv_mass = 1.0 / mass
    inv_mass[2] = 0.0                               # pinned
    gravity = np.array([0.0, -9.81, 0.0])
    drag = 0.3
    wind = np.array([2.0, 0.0, -1.0])

    force = wp.array(f, dtype=wp.vec3d, device=device) if with_force else wp.empty(0, dtype=wp.vec3d, device=device)
    dv = wp.empty(n, dtype=wp.vec3d, device=device)
    wp.launch(particles.particle_acceleration, n,
              inputs=[wp.array(v, dtype=wp.vec3d, device=device), force,
                      wp.array(inv_mass, dtype=wp.float64, device=device), wp.vec3d(*gravity), wp.float64(drag),
                      wp.vec3d(*wind), dv], device=device)
    got = dv.numpy()

    free = inv_mass > 0.0
    expected = gravity + (f + drag * (wind - v)) / mass[:, None]
    scale = np.abs(gravity) + (np.abs(f) + drag * (np.abs(wind) + np.abs(v))) / mass[:, None]
    assert np.all(np.abs(got[free] - expected[free]) <= 1e-13 * scale[free])
    np.testing.assert_array_equal(got[~free], 0.0)


def _rotation(q):
    """The rotation matrix of the unit quaternion q = (x, y, z, w)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_body_velocities_on_own_blocks(device):
    """rigid.body_velocities on a float64 Bodies and BodyMass block of five bodies, random unit quaternions and
    symmetric positive definite I_body^-1: v = P inv_mass, omega = R I_body^-1 R^T L; rel 1e-12 of each
    quantity's largest component."""
    from warp_sim.kernels import blocks, rigid

    rng = np.random.default_rng(5)
    n = 5
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    P = rng.normal(size=(n, 3))
    L = rng.normal(size=(n, 3))
    inv_mass = rng.uniform(0.2, 2.0, size=n)
    inv_inertia = np.empty((n, 3, 3))
    for i in range(n):
        a = rng.normal(size=(3, 3))
        inv_inertia[i] = a @ a.T + 0.5 * np.eye(3)

    B = blocks.of(wp.float64)
    bodies = blocks.fill(B.Bodies, x=wp.array(rng.normal(size=(n, 3)), dtype=wp.vec3d, device=device),
                         q=wp.array(q, dtype=wp.quatd, device=device), P=wp.array(P, dtype=wp.vec3d, device=device),
                         L=wp.array(L, dtype=wp.vec3d, device=device))
    mass = blocks.fill(B.BodyMass, inv_mass=wp.array(inv_mass, dtype=wp.float64, device=device),
                       inv_inertia=wp.array(inv_inertia, dtype=wp.mat33d, device=device))
    v = wp.empty(n, dtype=wp.vec3d, device=device)
    omega = wp.empty(n, dtype=wp.vec3d, device=device)
    wp.launch(rigid.body_velocities, n, inputs=[bodies, mass, v, omega], device=device)

    expected_v = P * inv_mass[:, None]
    expected_omega = np.array([_rotation(q[i]) @ inv_inertia[i] @ _rotation(q[i]).T @ L[i] for i in range(n)])
    for got, expected in ((v.numpy(), expected_v), (omega.numpy(), expected_omega)):
        scale = np.abs(expected).max()
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * scale)

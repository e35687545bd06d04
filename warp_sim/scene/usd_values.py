"""A stage's authored values, checked where they enter ``Scene.from_usd``: each bad one is a ValueError naming the
prim (its path), the attribute (or the stage's metadata key), the value and what is valid, on one line (as the
``warp-sim`` command prints it).

usd-core's parser and mass computation quietly replace what they cannot use (a negative ``size`` by its magnitude,
a negative ``physics:mass`` or ``physics:density`` by the default, a zero scale by a tiny one), so the authored
attributes are read here, before the parser's descriptions are used. Units: as authored (stage units, degrees,
kg per ``kilogramsPerUnit``); the checks are of sign, finiteness and consistency, not of size, which
``scene.ranges`` checks against the precision once converted to SI.

A mirror (an odd number of negative scales) at or above a simulated rigid body's prim is refused: a rigid pose is
a rotation, and the overlay writes a body back as translate, orient and its scale's magnitudes, so the mirror of
the body's own children could not be kept. Below the body (on its shapes' prims) and on static colliders a mirror
is read: a mesh takes the signed scale with its winding reversed (usd_geometry), and a box, sphere, capsule or
cylinder is its own mirror image. Cloth, particles and emitters take their points through the transform and may
be mirrored.
"""
from __future__ import annotations

import math
from contextlib import contextmanager

import numpy as np
from pxr import Gf, UsdGeom, UsdPhysics

from ..util import checks
from .shapes import TRIANGLE_SLACK
from .usd_units import TO_Y_UP, StageUnits

AXES = ("X", "Y", "Z")
HANDEDNESS = ("rightHanded", "leftHanded")


def show(value) -> str:
    """An authored value as typed in a .usda: floats to 7 digits (float32's), vectors and quaternions as tuples."""
    if isinstance(value, (Gf.Quatf, Gf.Quatd, Gf.Quath)):
        value = (value.GetReal(), *value.GetImaginary())
    if value is None or isinstance(value, (bool, np.bool_, str, int)):
        return repr(value)
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.7g}"
    try:
        items = list(value)
    except TypeError:
        return checks._show(value)
    kind = type(value).__name__
    tuple_like = isinstance(value, tuple) or (kind.startswith(("Vec", "Quat", "Matrix")) and not kind.endswith("Array"))
    opening, closing = "()" if tuple_like else "[]"
    if len(items) > 6:
        return f"{opening}{', '.join(show(item) for item in items[:3])}, ... {len(items)} in all{closing}"
    return opening + ", ".join(show(item) for item in items) + closing


def error(path, name: str, value, valid: str, when: str = "") -> ValueError:
    """The ValueError for attribute ``name`` of the prim at ``path`` holding ``value`` (``when``: " at time code
    10"), saying what is valid."""
    return ValueError(f"{path}: {name}={show(value)}{when} is invalid: {valid}")


def _finite(values) -> bool:
    try:
        return bool(np.all(np.isfinite(np.asarray(values, dtype=np.float64))))
    except (TypeError, ValueError):
        return False


def _get(prim, name: str, time=None):
    attribute = prim.GetAttribute(name)
    if not attribute:
        return None
    return attribute.Get() if time is None else attribute.Get(time)


@contextmanager
def named(path, names: dict | None = None):
    """Turn a ValueError raised inside (by Scene.add_*, a shape, MassProperties) into one naming the prim at
    ``path``: its argument (``mass=``) becomes the attribute that fed it (``names``: keyword -> attribute)."""
    try:
        yield
    except ValueError as failure:
        text = str(failure)
        if text.startswith("/"):   # already names its prim
            raise
        for keyword, attribute in (names or {}).items():
            if text.startswith(keyword + "="):
                text = attribute + text[len(keyword):]
                break
        raise ValueError(f"{path}: {text}") from None


# ---- the stage's metadata ------------------------------------------------------------------------------------------
def stage_units(stage, label: str) -> StageUnits:
    """The stage's metersPerUnit and kilogramsPerUnit (finite, > 0) and upAxis ("Y" or "Z"); ``label``: the file."""
    meters = UsdGeom.GetStageMetersPerUnit(stage)
    kilograms = UsdPhysics.GetStageKilogramsPerUnit(stage)
    up = str(UsdGeom.GetStageUpAxis(stage))
    for key, value, unit in (("metersPerUnit", meters, "metres per stage unit, e.g. 0.01 for centimetres"),
                             ("kilogramsPerUnit", kilograms, "kilograms per stage unit of mass, e.g. 1")):
        if not (_finite(value) and value > 0.0):
            raise ValueError(f"{label}: metadata {key}={show(float(value))} is invalid: expected a finite number "
                             f"> 0 ({unit})")
    if up not in TO_Y_UP:
        raise ValueError(f"{label}: metadata upAxis={up!r} is invalid: expected 'Y' or 'Z'")
    return StageUnits(float(meters), float(kilograms), up)


def gravity(prim, units: StageUnits, precision: str) -> None:
    """A UsdPhysics.Scene's gravityDirection finite (zero: minus the up axis) and gravityMagnitude finite >= 0
    [stage units/s^2] or -inf (the schema's default: Earth's), fitting the precision once in m/s^2."""
    path = prim.GetPath()
    physics = UsdPhysics.Scene(prim)
    direction = physics.GetGravityDirectionAttr().Get()
    magnitude = physics.GetGravityMagnitudeAttr().Get()
    if direction is not None and not _finite(direction):
        raise error(path, "physics:gravityDirection", direction, "expected a finite direction ((0, 0, 0): minus the "
                                                                 "up axis)")
    if magnitude is not None and not (magnitude == -math.inf or (_finite(magnitude) and magnitude >= 0.0)):
        raise error(path, "physics:gravityMagnitude", magnitude, "expected a finite number >= 0 [stage units/s^2] "
                                                                 "(or -inf, the schema's default: Earth's gravity)")
    if magnitude is not None and magnitude != -math.inf:
        with named(path, {"gravity": "physics:gravityMagnitude"}):
            checks.fits("gravity", units.meters_per_unit * float(magnitude), precision, given=magnitude,
                        derived="its magnitude in m/s^2")


# ---- transforms ------------------------------------------------------------------------------------------------------
def transform(prim, time, rigid: bool, when: str = "") -> None:
    """Every xform op of ``prim`` and its ancestors at ``time`` finite and invertible (no zero scale); for a rigid
    body or shape (``rigid``), the ops at or above its simulated body's prim not mirrored (see the module's
    docstring). ``when``: words after the op's name in an error (" at time code 10")."""
    mirrored = []
    body = _simulated_body(prim) if rigid else None
    current = prim
    while current and not current.IsPseudoRoot():
        xformable = UsdGeom.Xformable(current)
        if xformable:
            for op in xformable.GetOrderedXformOps():
                _op(current.GetPath(), op, time, mirrored, when)
            if xformable.GetResetXformStack():
                break
        current = current.GetParent()
    mirrored = [m for m in mirrored if body is not None and body.HasPrefix(m[0])]
    if len(mirrored) % 2:
        path, name, value = mirrored[0]
        whose = "the rigid body" if path == body else f"the rigid body {body}"
        raise error(path, name, value, f"it mirrors {whose} (a negative determinant), whose pose is a rotation and "
                                       "is written back with positive scales; put the mirror on the prims below the "
                                       "body (its collision and visual meshes), or use positive scales and a "
                                       "rotation of 180 degrees (a box, sphere, capsule or cylinder is its own "
                                       "mirror image)", when)


def _simulated_body(prim):
    """The path of the rigid body ``prim`` is, or is inside of, if it is simulated (not rigidBodyEnabled = false);
    else None (the shapes of none, or of a disabled body, are static colliders)."""
    current = prim
    while current and not current.IsPseudoRoot():
        if current.HasAPI(UsdPhysics.RigidBodyAPI):
            enabled = UsdPhysics.RigidBodyAPI(current).GetRigidBodyEnabledAttr().Get()
            return current.GetPath() if enabled is None or enabled else None
        current = current.GetParent()
    return None


def _op(path, op, time, mirrored: list, when: str) -> None:
    name = op.GetOpName()
    value = op.Get(time)
    if value is None:
        return
    raw = value if op.GetOpType() != UsdGeom.XformOp.TypeTransform else list(np.array(value).ravel())
    if not _finite(raw if not isinstance(value, (Gf.Quatf, Gf.Quatd, Gf.Quath)) else
                   (value.GetReal(), *value.GetImaginary())):
        raise error(path, name, value, "every entry must be finite", when)
    try:
        matrix = np.array(op.GetOpTransform(time), dtype=np.float64)
    except Exception:   # noqa: BLE001 - pxr.Tf.ErrorException: an inverted op that cannot be inverted
        matrix = np.zeros((4, 4))
    determinant = float(np.linalg.det(matrix[:3, :3])) if _finite(matrix) else math.nan
    if not (_finite(determinant) and determinant != 0.0):
        raise error(path, name, value, "the transform must be invertible: a scale (or matrix) of zero along an "
                                       "axis flattens the prim; every scale must be non-zero", when)
    if determinant < 0.0:
        mirrored.append((path, name, value))


# ---- geometry --------------------------------------------------------------------------------------------------------
def _positive(path, name: str, value, unit: str, zero: bool = False) -> None:
    if value is None:
        return
    if not (_finite(value) and (value >= 0.0 if zero else value > 0.0)):
        raise error(path, name, value, f"expected a finite number {'>=' if zero else '>'} 0 [{unit}]")


def _axis(path, prim) -> None:
    axis = _get(prim, "axis")
    if axis is not None and str(axis) not in AXES:
        raise error(path, "axis", str(axis), "expected 'X', 'Y' or 'Z'")


def shape(prim, time) -> None:
    """A collision shape's own attributes: a Cube's size, a Sphere's radius, a Capsule's or Cylinder's radius,
    height and axis (finite, > 0; a capsule's height >= 0), a Plane's axis, a Mesh's points and faces."""
    path = prim.GetPath()
    if prim.IsA(UsdGeom.Cube):
        _positive(path, "size", _get(prim, "size", time), "stage units")
    elif prim.IsA(UsdGeom.Sphere):
        _positive(path, "radius", _get(prim, "radius", time), "stage units")
    elif prim.IsA(UsdGeom.Capsule) or prim.IsA(UsdGeom.Cylinder):
        _positive(path, "radius", _get(prim, "radius", time), "stage units")
        _positive(path, "height", _get(prim, "height", time), "stage units", zero=prim.IsA(UsdGeom.Capsule))
        _axis(path, prim)
    elif prim.IsA(UsdGeom.Plane):
        _axis(path, prim)
    elif prim.IsA(UsdGeom.Mesh):
        mesh_faces(prim, time)


def mesh_faces(prim, time) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A Mesh's (points (N, 3), faceVertexCounts (F,), faceVertexIndices), checked: at least one point, every point
    finite, every face of >= 3 corners, as many indices as the counts sum to, each in [0, N); orientation a known
    token."""
    path = prim.GetPath()
    mesh = UsdGeom.Mesh(prim)
    points = mesh.GetPointsAttr().Get(time)
    if not points:
        raise error(path, "points", points, "a mesh needs points")
    points = np.array(points, dtype=np.float64).reshape(-1, 3)
    bad = np.flatnonzero(~np.all(np.isfinite(points), axis=1))
    if len(bad):
        raise error(path, "points", mesh.GetPointsAttr().Get(time), f"every point must be finite; point {bad[0]} "
                                                                    f"is {show(tuple(points[bad[0]]))}")
    counts = mesh.GetFaceVertexCountsAttr().Get(time)
    indices = mesh.GetFaceVertexIndicesAttr().Get(time)
    counts = np.array(counts if counts is not None else [], dtype=np.int64)
    indices = np.array(indices if indices is not None else [], dtype=np.int64)
    if len(counts) == 0:
        raise error(path, "faceVertexCounts", mesh.GetFaceVertexCountsAttr().Get(time), "a mesh needs faces")
    small = np.flatnonzero(counts < 3)
    if len(small):
        raise error(path, "faceVertexCounts", mesh.GetFaceVertexCountsAttr().Get(time),
                    f"every face needs >= 3 corners; face {small[0]} has {counts[small[0]]}")
    if int(counts.sum()) != len(indices):
        raise error(path, "faceVertexIndices", mesh.GetFaceVertexIndicesAttr().Get(time),
                    f"it has {len(indices)} entries, but faceVertexCounts sum to {int(counts.sum())} (one index per "
                    "corner of every face)")
    outside = np.flatnonzero((indices < 0) | (indices >= len(points)))
    if len(outside):
        raise error(path, "faceVertexIndices", mesh.GetFaceVertexIndicesAttr().Get(time),
                    f"indices must lie in [0, {len(points)}) (the points); entry {outside[0]} is "
                    f"{indices[outside[0]]}")
    orientation = str(mesh.GetOrientationAttr().Get())
    if orientation not in HANDEDNESS:
        raise error(path, "orientation", orientation, "expected 'rightHanded' or 'leftHanded'")
    return points, counts, indices


# ---- bodies, masses and materials ----------------------------------------------------------------------------------
def body(prim, time) -> None:
    """A rigid body's physics:velocity [stage units/s] and physics:angularVelocity [degrees/s]: finite."""
    for name in ("physics:velocity", "physics:angularVelocity"):
        value = _get(prim, name, time)
        if value is not None and not _finite(value):
            raise error(prim.GetPath(), name, value, "every entry must be finite")


def mass(prim, time) -> None:
    """A PhysicsMassAPI's values: mass and density finite >= 0 (0: unset), centerOfMass finite (or the schema's
    unset -inf), diagonalInertia finite >= 0 ((0, 0, 0): unset; otherwise all > 0 and I1 + I2 >= I3, as every real
    body's), principalAxes finite."""
    if not prim.HasAPI(UsdPhysics.MassAPI):
        return
    path = prim.GetPath()
    for name, unit in (("physics:mass", "kg / kilogramsPerUnit"),
                       ("physics:density", "kilogramsPerUnit / stage unit^3")):
        value = _get(prim, name, time)
        if value is not None and not (_finite(value) and value >= 0.0):
            raise error(path, name, value, f"expected a finite number >= 0 [{unit}] (0: unset)")
    com = _get(prim, "physics:centerOfMass", time)
    if com is not None and not _finite(com) and not all(v == -math.inf for v in com):
        raise error(path, "physics:centerOfMass", com, "every entry must be finite (or all -inf: unset)")
    diagonal = _get(prim, "physics:diagonalInertia", time)
    if diagonal is not None:
        moments = np.sort(np.array(list(diagonal), dtype=np.float64))
        if not (_finite(moments) and np.all(moments >= 0.0)):
            raise error(path, "physics:diagonalInertia", diagonal, "expected three finite principal moments >= 0 "
                                                                   "((0, 0, 0): unset)")
        if np.any(moments) and not moments[0] > 0.0:
            raise error(path, "physics:diagonalInertia", diagonal, "every principal moment must be > 0 (a body "
                                                                   "turns about every axis); (0, 0, 0): unset")
        if np.any(moments) and moments[0] + moments[1] < moments[2] * (1.0 - TRIANGLE_SLACK):
            raise error(path, "physics:diagonalInertia", diagonal, "the moments break the triangle inequality I1 + "
                                                                   "I2 >= I3, which every real body obeys")
    axes = _get(prim, "physics:principalAxes", time)
    if axes is not None and not _finite((axes.GetReal(), *axes.GetImaginary())):
        raise error(path, "physics:principalAxes", axes, "every entry must be finite ((0, 0, 0, 0): unset)")


def material(prim) -> None:
    """A PhysicsMaterialAPI's restitution in [0, 1], static and dynamic friction and density finite >= 0."""
    path = prim.GetPath()
    for name, high in (("physics:restitution", 1.0), ("physics:dynamicFriction", None),
                       ("physics:staticFriction", None), ("physics:density", None)):
        value = _get(prim, name)
        if value is not None and not (_finite(value) and value >= 0.0 and (high is None or value <= high)):
            valid = "in [0, 1]" if high is not None else ">= 0" + (" (0: unset)" if name.endswith("density") else "")
            raise error(path, name, value, f"expected a finite number {valid}")


def counts(path, name: str, value, count: int, allowed: str) -> np.ndarray:
    """A Points prim's per-point values (widths, velocities): finite, 1 or ``count`` of them (``allowed``)."""
    array = np.array(value, dtype=np.float64)
    if not _finite(array):
        raise error(path, name, value, "every entry must be finite")
    if len(array) not in ((1, count) if allowed == "one or each" else (count,)):
        raise error(path, name, value, f"expected {allowed} of the {count} points, got {len(array)}")
    return array


"""A rigid body's mass properties and its shapes' physics materials, as ``Scene.from_usd`` reads them.

Masses are usd-core's: ``UsdPhysics.RigidBodyAPI.ComputeMassProperties`` applies the schema's precedence of mass,
density and materials, and calls back for every ``PhysicsCollisionAPI`` prim below the body, the body's own prim
included (a Cube that is both body and collider, Isaac-style, or an Xform carrying CollisionAPI). warp_sim's shape
supplies a shape's volume, unit-density inertia and centre of mass; a CollisionAPI prim that is no shape warp_sim
built (an Xform, a nested body's collider, a cone) gets volume 0, so it adds no mass. (A volume < 0, usd-core's "no
information", makes it add a unit mass at an uninitialised pose instead: a NaN centre of mass and infinite inertia.)
What comes back is checked before use (``check``), and usd-core's principal axes, which it leaves
unset when the body's MassAPI gives mass, inertia and centre of mass but no axes, are then the identity.

A body without an enabled collider (a joint's anchor) takes its mass from its MassAPI alone (``without_collider``),
as usd-core does for one: ``physics:mass``, ``physics:diagonalInertia`` (unset: a 0.1 m solid sphere's of that mass,
usd-core's stand-in), ``physics:centerOfMass`` (scaled by the prim's world scale) and ``physics:principalAxes``. With
no mass either, usd-core answers mass -1 and inertia (1, 1, 1), "possibly invalid": the body gets mass 1 and
inertia (1, 1, 1) in stage units, PhysX's defaults, with a warning naming it.

Materials: usd-core's parser reads a shape's ``material:binding:physics`` only where ``MaterialBindingAPI`` is
applied, but DCC tools and OpenUSD's own examples author the relationship without it, and PhysX reads it either way.
``bound_material`` resolves the relationship itself (the nearest binding up the prim's ancestors, unless one above
says ``bindMaterialAs = "strongerThanDescendants"``). Its ``physics:density`` reaches usd-core's mass computation
through ``density_scale`` where usd-core's own lookup does not find the material.
"""
from __future__ import annotations

import numpy as np
from pxr import Gf, Usd, UsdGeom, UsdPhysics, UsdShade

from ..util.rotations import matrix_to_quat
from . import usd_attributes, usd_values
from .shapes import DEFAULT_DENSITY, TRIANGLE_SLACK, MassProperties

SMALL_SPHERE = 0.1   # [m] radius of usd-core's stand-in sphere for the inertia of a body with a mass and no collider
BINDING = "material:binding:physics"
UNBOUND_NOTE = ("physics materials bound by material:binding:physics without MaterialBindingAPI (read, as PhysX "
                "reads them; apply MaterialBindingAPI to these prims)")
NO_MASS_NOTE = ("rigid bodies without a collider or a physics:mass (mass 1 and, where physics:diagonalInertia is "
                "unset, inertia (1, 1, 1), in stage units: PhysX's defaults; author PhysicsMassAPI physics:mass and "
                "physics:diagonalInertia)")
NO_INERTIA_NOTE = (f"rigid bodies without a collider or a physics:diagonalInertia (the inertia of a {SMALL_SPHERE} m "
                   "solid sphere of their mass, as usd-core gives them; author PhysicsMassAPI physics:diagonalInertia)")
NO_VOLUME = ("no physics:mass > 0 is authored on the body and its collision shapes give no volume; author "
             "PhysicsMassAPI physics:mass (and physics:diagonalInertia) on the body, or give it a collision shape "
             "warp_sim builds (a Cube, Sphere, Capsule, Cylinder or closed Mesh)")


def _vec(v) -> np.ndarray:
    return np.array(list(v), dtype=np.float64)


def _quat(q) -> np.ndarray:
    """A Gf quaternion as (w, x, y, z)."""
    return np.array([q.GetReal(), *q.GetImaginary()], dtype=np.float64)


class _Authored:
    """The body prim's own PhysicsMassAPI values (stage units), each None where unset (the schema's sentinels:
    a mass or density of 0, a zero inertia or axes, a non-finite centre of mass)."""

    def __init__(self, prim, time):
        self.mass = self.density = self.diagonal = self.com = self.axes = None
        if not prim.HasAPI(UsdPhysics.MassAPI):
            return
        api = UsdPhysics.MassAPI(prim)
        mass, density = api.GetMassAttr().Get(time), api.GetDensityAttr().Get(time)
        diagonal, com = api.GetDiagonalInertiaAttr().Get(time), api.GetCenterOfMassAttr().Get(time)
        axes = api.GetPrincipalAxesAttr().Get(time)
        self.mass = float(mass) if mass else None
        self.density = float(density) if density else None
        self.diagonal = _vec(diagonal) if diagonal is not None and any(diagonal) else None
        self.com = _vec(com) if com is not None and np.all(np.isfinite(list(com))) else None
        self.axes = _quat(axes) if axes is not None and np.any(_quat(axes)) else None


# ---- usd-core's mass computation -----------------------------------------------------------------------------------
def mass_information(made, units, scale: float = 1.0):
    """usd-core's callback answer for one CollisionAPI prim: the volume, unit-density inertia and centre of mass of
    warp_sim's shape ``made`` ((shape, R, p): its frame in the body's), in stage units, times ``scale`` (a density
    usd-core does not see, ``density_scale``); volume 0 for None (no shape warp_sim built: it adds no mass)."""
    info = UsdPhysics.RigidBodyAPI.MassInformation()
    info.localRot = Gf.Quatf(1.0)
    info.localPos = info.centerOfMass = Gf.Vec3f(0.0)
    info.inertia = Gf.Matrix3f(0.0)
    info.volume = 0.0
    if made is None:
        return info
    shape, Rs, ps = made
    unit = shape.mass_properties(density=1.0)
    length = units.meters_per_unit
    info.volume = scale * unit.mass / length ** 3
    info.inertia = Gf.Matrix3f(*(scale * unit.inertia / length ** 5).ravel().tolist())   # density 1, stage units
    info.centerOfMass = Gf.Vec3f(*(unit.com / length).tolist())
    info.localPos = Gf.Vec3f(*(ps / length).tolist())
    q = matrix_to_quat(Rs)
    info.localRot = Gf.Quatf(float(q[3]), float(q[0]), float(q[1]), float(q[2]))
    return info


def computed(prim, time, built: dict, units, unbound: list) -> tuple:
    """(mass, diagonal inertia (3,), centre of mass (3,), principal axes (w, x, y, z)) of body ``prim``, stage units,
    from usd-core's ComputeMassProperties; ``built``: CollisionAPI prim path -> warp_sim's (shape, R, p); ``unbound``:
    the shapes whose material usd-core's parser did not find (their density_scale). Not checked yet (``properties``)."""
    stage = prim.GetStage()
    for below in Usd.PrimRange(prim):   # the CollisionAPI prims usd-core asks about
        mass = below.GetAttribute("physics:mass").Get(time) if below.HasAPI(UsdPhysics.MassAPI) else None
        if below.HasAPI(UsdPhysics.CollisionAPI) and str(below.GetPath()) not in built and mass and mass > 0.0:
            whose = "the body's own prim" if below == prim else f"this prim, below the body {prim.GetPath()},"
            raise usd_values.error(below.GetPath(), "physics:mass", mass, (
                f"{whose} has PhysicsCollisionAPI but is no collision shape warp_sim builds (a prim of type "
                f"{below.GetTypeName() or 'none'}, or a nested body's shape), so it has no volume, and usd-core's "
                "mass computation would count this mass as a shape's of no volume (a NaN inertia); remove "
                "PhysicsCollisionAPI from it, or author the mass on the body's collision shapes"))
    scales = {path: density_scale(stage.GetPrimAtPath(path), prim, bound_material(stage.GetPrimAtPath(path))[0],
                                  time, units) for path in unbound}
    mass, diagonal, com, axes = UsdPhysics.RigidBodyAPI(prim).ComputeMassProperties(
        lambda shape_prim: mass_information(built.get(str(shape_prim.GetPath())), units,
                                            scales.get(str(shape_prim.GetPath()), 1.0)))
    own = _Authored(prim, time)
    axes = _quat(axes)
    if own.axes is None and own.mass and own.diagonal is not None and own.com is not None:
        axes = np.array([1.0, 0.0, 0.0, 0.0])   # usd-core took all from the MassAPI, and left the axes unset
    return float(mass), _vec(diagonal), _vec(com), axes


# ---- a body without a collider -------------------------------------------------------------------------------------
def without_collider(prim, time, units, notes: dict) -> tuple:
    """(mass, diagonal inertia, centre of mass, principal axes (w, x, y, z)) of body ``prim`` without an enabled
    collider, stage units, from its MassAPI (see the module's docstring); ``notes``: what -> prim paths, warned."""
    own = _Authored(prim, time)
    path = str(prim.GetPath())
    mass, diagonal = own.mass, own.diagonal
    if mass is None:
        mass = 1.0
        notes.setdefault(NO_MASS_NOTE, []).append(path)
        diagonal = np.ones(3) if diagonal is None else diagonal
    elif diagonal is None:
        notes.setdefault(NO_INERTIA_NOTE, []).append(path)
        radius = SMALL_SPHERE / units.meters_per_unit
        diagonal = np.full(3, 0.4 * mass * radius ** 2)
    com = np.zeros(3)
    if own.com is not None:   # usd-core scales an authored centre of mass by the prim's world scale
        scale = Gf.Transform(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time)).GetScale()
        com = own.com * np.abs(_vec(scale))
    axes = own.axes if own.axes is not None else np.array([1.0, 0.0, 0.0, 0.0])
    return mass, diagonal, com, axes


# ---- checked, in SI ------------------------------------------------------------------------------------------------
def check(path, mass, diagonal, com, axes, source: str) -> None:
    """A body's resolved mass properties (stage units; ``source`` says whence: usd-core's mass computation or its
    MassAPI alone) before use: mass finite > 0, centre of mass finite, principal moments finite > 0 obeying I1 + I2
    >= I3, principal axes (w, x, y, z) finite and not zero. Each bad one is a ValueError naming the prim, the MassAPI
    attribute it stands for and what to author there (usd_values.error)."""
    when = f" ({source})"
    if not (np.isfinite(mass) and mass > 0.0):
        raise usd_values.error(path, "physics:mass", float(mass), f"no valid mass results: {NO_VOLUME}", when)
    if not np.all(np.isfinite(com)):
        raise usd_values.error(path, "physics:centerOfMass", tuple(com), "expected a finite point; author "
                               "PhysicsMassAPI physics:centerOfMass on the body", when)
    moments = np.sort(np.asarray(diagonal, dtype=np.float64))
    if not (np.all(np.isfinite(moments)) and moments[0] > 0.0 and
            moments[0] + moments[1] >= moments[2] * (1.0 - TRIANGLE_SLACK)):
        raise usd_values.error(path, "physics:diagonalInertia", tuple(diagonal), "expected three finite principal "
                               "moments > 0 with I1 + I2 >= I3; author PhysicsMassAPI physics:diagonalInertia (and "
                               "physics:principalAxes) on the body", when)
    if not (np.all(np.isfinite(axes)) and np.linalg.norm(axes) > 0.0):
        raise usd_values.error(path, "physics:principalAxes", tuple(axes), "expected a finite rotation quaternion, "
                               "not zero; author PhysicsMassAPI physics:principalAxes on the body", when)


def properties(path, values: tuple, units, Rs: np.ndarray, ps: np.ndarray, source: str) -> MassProperties:
    """The body's MassProperties in its shape's frame (R, p: the shape's frame in the body prim's) from ``values``
    (computed or without_collider), checked first (``check``: a ValueError naming the prim, the attribute and what
    to author); ``source``: where they came from, for the error."""
    mass, diagonal, com, axes = values
    check(path, mass, diagonal, com, axes, source)
    w, x, y, z = axes / np.linalg.norm(axes)
    P = np.array(Gf.Matrix3d(Gf.Rotation(Gf.Quatd(w, x, y, z))), dtype=np.float64).T
    inertia = P @ np.diag(units.inertia(diagonal)) @ P.T
    with usd_values.named(path):
        return MassProperties(units.mass(mass), Rs.T @ (units.length(com) - ps), Rs.T @ inertia @ Rs)


# ---- physics materials ---------------------------------------------------------------------------------------------
def bound_material(prim):
    """(the physics material prim bound to ``prim`` or None, the prim whose binding it is where that prim lacks
    MaterialBindingAPI or None), from
    the ``material:binding:physics`` relationships of ``prim`` and its ancestors themselves: the nearest one, unless
    one above says ``bindMaterialAs = "strongerThanDescendants"`` (then the topmost such); a target without
    PhysicsMaterialAPI binds nothing, as in usd-core."""
    found = None
    current = prim
    while current and not current.IsPseudoRoot():
        relationship = current.GetRelationship(BINDING)
        targets = relationship.GetTargets() if relationship else []
        if targets and (found is None or relationship.GetMetadata("bindMaterialAs") == "strongerThanDescendants"):
            found = (targets[0], current)
        current = current.GetParent()
    if found is None:
        return None, None
    material = prim.GetStage().GetPrimAtPath(found[0])
    if not material or "PhysicsMaterialAPI" not in usd_attributes.applied_schemas(material):
        return None, None
    return material, None if found[1].HasAPI(UsdShade.MaterialBindingAPI) else found[1]


def density_scale(shape_prim, body_prim, material, time, units) -> float:
    """The factor by which a shape's volume and inertia carry its bound ``material``'s ``physics:density`` into
    usd-core's mass computation where usd-core's own binding lookup does not find the material (a binding without
    MaterialBindingAPI, in a usd-core that ignores those): density / the default density, in stage units; 1 where
    usd-core sees it, or a MassAPI density of the shape or the body takes precedence."""
    density = material.GetAttribute("physics:density").Get() if material else None
    if not density or density <= 0.0 or _Authored(shape_prim, time).density or \
            _Authored(body_prim, time).density:
        return 1.0
    seen = UsdShade.MaterialBindingAPI(shape_prim).ComputeBoundMaterial("physics")[0]
    if seen and seen.GetPrim().GetPath() == material.GetPath():
        return 1.0
    default = DEFAULT_DENSITY * units.meters_per_unit ** 3 / units.kilograms_per_unit   # usd-core's, stage units
    return float(density) / default

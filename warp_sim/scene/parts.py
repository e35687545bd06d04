"""The records a Scene holds: particle groups, planes, cloth and soft-body meshes, rigid bodies, static colliders."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..util import checks
from .shapes import MassProperties, Shape
from .tracks import Track


@dataclass(frozen=True)
class ParticleGroup:
    """The particles one add_particles call (or an emitter, or a cloth) made.

    name: its USD prim name
    start, count: global particle indices start .. start + count - 1
    color: RGB in [0, 1]
    pooled: True for the slots of an emitter's pool, of which only the live ones exist at any time
    """
    name: str
    start: int
    count: int
    color: tuple
    pooled: bool = False


@dataclass(frozen=True)
class Plane:
    """The static plane normal . x = offset; bodies stay on the side the unit normal points to.

    name: its USD prim name
    normal: unit normal, (3,)
    offset: [m]
    restitution, friction: its contact materials (a contact takes the mean with the other side's) [1]
    """
    name: str
    normal: np.ndarray
    offset: float
    restitution: float
    friction: float


@dataclass(frozen=True)
class SurfaceMesh:
    """A cloth or soft body: particles start .. start + count - 1 drawn as one UsdGeom.Mesh.

    name: its USD prim name
    start, count: its first global particle index and its particle count
    face_counts: (F,) vertices per face
    face_indices: (sum of face_counts,) vertex indices local to the mesh (0 .. count - 1)
    triangles: (T, 3) the faces split into triangles, global particle indices (for aerodynamics)
    springs: global spring indices of its "structural", "shear" and "bend" families (dict of arrays)
    color: RGB in [0, 1]
    drag, lift: aerodynamic coefficients C_D, C_L (dimensionless; 0: none)
    air_density: rho [kg/m^3]
    max_stretch: the strain limit of its structural and shear springs (0.1 = 10 %), or None
    """
    name: str
    start: int
    count: int
    face_counts: np.ndarray
    face_indices: np.ndarray
    triangles: np.ndarray
    springs: dict
    color: tuple
    drag: float = 0.0
    lift: float = 0.0
    air_density: float = 1.2
    max_stretch: float | None = None

    def parameter(self, key: str, **bounds) -> float:
        """The value of field ``key`` checked by checks.scalar(**bounds); the error names the mesh too."""
        try:
            return checks.scalar(key, getattr(self, key), **bounds)
        except ValueError as error:
            raise ValueError(f"{error} (mesh {self.name!r})") from None


@dataclass(frozen=True)
class RigidBody:
    """One rigid body as added: its shape, mass properties and initial state (world frame).

    name: its USD prim name
    shape: the Shape; mass: its MassProperties (mass [kg], centre of mass com [m], inertia [kg m^2])
    position: the centre of mass [m] (the shape's origin sits at position - R com)
    orientation: unit quaternion (x, y, z, w)
    momentum: P [kg m/s]
    angular_momentum: L [kg m^2/s]
    drag: [N s/m]
    angular_drag: [N m s/rad]
    restitution, friction: contact materials [1]
    color: RGB in [0, 1]
    track: for a kinematic body, its keyframed motion (tracks.Track), else None
    """
    name: str
    shape: Shape
    mass: MassProperties
    position: np.ndarray
    orientation: np.ndarray
    momentum: np.ndarray
    angular_momentum: np.ndarray
    drag: float
    angular_drag: float
    restitution: float
    friction: float
    color: tuple
    track: Track | None = None


@dataclass(frozen=True)
class Collider:
    """A static collider: a shape with infinite mass that never moves (world frame).

    name: its USD prim name
    shape: the Shape
    position: where the shape's origin lies [m], (3,)
    orientation: unit quaternion (x, y, z, w), (4,)
    restitution, friction: contact materials [1]
    color: RGB in [0, 1]
    """
    name: str
    shape: Shape
    position: np.ndarray
    orientation: np.ndarray
    restitution: float
    friction: float
    color: tuple

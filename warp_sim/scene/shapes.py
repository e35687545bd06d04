"""Rigid-body shapes and their exact mass properties (mass, centre of mass, inertia tensor), in SI units.

Every shape has its own frame: primitives are centred on its origin (capsule and
cylinder axes along +Y); a mesh or a set of point masses is kept in the frame its
coordinates were given in, and the centre of mass is reported in that frame.
Solids have uniform density; ``mass_properties`` takes a density [kg/m^3] or a
total mass [kg] (default: density 1000 kg/m^3, water).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np
import trimesh

from ..util import checks

DEFAULT_DENSITY = 1000.0  # [kg/m^3]
SINGULAR_RATIO = 1e-12  # smallest / largest principal moment at or below which a body cannot rotate
BOUND_SLACK = 1e-6  # relative round-off allowed before a mesh volume exceeds its enclosing volume
DEGENERATE_RATIO = 1e-12  # twice a face's area / its longest edge^2 at or below which the face has zero area
SYMMETRY_SLACK = 1e-9  # |I - I^T| / the largest |I| allowed as round-off of a symmetric inertia tensor
TRIANGLE_SLACK = 1e-6  # I1 + I2 may fall this far (relative to I3) below I3: float32 rounding of a flat body's moments


@dataclass(frozen=True, eq=False)
class MassProperties:
    """Mass [kg], centre of mass (3,) [m] in the shape frame, inertia (3, 3) [kg m^2] about the centre of mass.

    Checked when made (ValueError naming ``mass``, ``com`` or ``inertia``): a finite mass > 0, a finite centre,
    and a finite, symmetric (to SYMMETRY_SLACK of its largest entry), positive-definite inertia whose principal
    moments obey the triangle inequality I1 + I2 >= I3 (to TRIANGLE_SLACK of I3), as every real mass distribution's
    do. The arrays are read-only copies; the inertia tensor is made exactly symmetric, shape frame axes.
    """

    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def __post_init__(self):
        object.__setattr__(self, "mass", checks.scalar("mass", self.mass, low=0.0, low_open=True))
        com = checks.finite_array("com", self.com, (3,))
        inertia = checks.finite_array("inertia", self.inertia, (3, 3))
        _require_physical(inertia)
        for name, array in (("com", com), ("inertia", (inertia + inertia.T) / 2.0)):
            array.setflags(write=False)
            object.__setattr__(self, name, array)


def _require_physical(inertia: np.ndarray) -> None:
    """Raise unless ``inertia`` [kg m^2] is symmetric, positive definite and obeys the triangle inequality."""
    largest = float(np.max(np.abs(inertia)))
    asymmetry = float(np.max(np.abs(inertia - inertia.T)))
    if asymmetry > SYMMETRY_SLACK * largest:
        raise checks.fail("inertia", inertia, f"an inertia tensor is symmetric; entries across the diagonal differ by "
                                              f"up to {asymmetry:.6g} kg m^2")
    moments = np.linalg.eigvalsh((inertia + inertia.T) / 2.0)
    if not moments[0] > 0.0:
        raise checks.fail("inertia", inertia, f"an inertia tensor is positive definite: every principal moment > 0 "
                                              f"kg m^2, here {_moments(moments)}")
    if moments[0] + moments[1] < moments[2] * (1.0 - TRIANGLE_SLACK):
        raise checks.fail("inertia", inertia, f"its principal moments {_moments(moments)} break the triangle "
                                              f"inequality I1 + I2 >= I3 ({moments[0] + moments[1]:.6g} < "
                                              f"{moments[2]:.6g}), which every real mass distribution obeys")


def _moments(moments) -> str:
    return "(" + ", ".join(f"{m:.6g}" for m in moments) + ")"


def _require_rotatable(name: str, value, inertia: np.ndarray) -> None:
    """Raise if the inertia tensor is singular: the body would have no resistance to turning about some axis."""
    moments, axes = np.linalg.eigh(inertia)
    if moments[0] <= SINGULAR_RATIO * moments[-1]:
        axis = np.round(axes[:, 0], 6) + 0.0
        raise checks.fail(name, value, f"the inertia tensor is singular (principal moments {moments} kg m^2), so "
                          f"the body could not rotate about the axis {tuple(axis.tolist())} (zero moment of inertia "
                          "about it: a torque there would give an infinite angular acceleration); give it extent off "
                          "that axis (for point masses: add a point off the line through the others)")


class Shape:
    """A rigid-body shape: ``kind``, ``size`` [m], ``volume`` [m^3], ``bounding_radius`` [m], ``mass_properties``."""

    kind: str = ""
    size: tuple[float, ...] = ()

    def _unit_properties(self) -> MassProperties:
        """Mass properties at density 1 kg/m^3 (so the mass is the volume)."""
        raise NotImplementedError

    def _scale(self, density, mass) -> float:
        """The factor from the unit properties to those asked for (exactly one of density, mass; neither: default)."""
        if mass is not None:
            return checks.scalar("mass", mass, low=0.0, low_open=True) / self._unit_properties().mass
        return checks.scalar("density", DEFAULT_DENSITY if density is None else density, low=0.0, low_open=True)

    @property
    def volume(self) -> float:
        """The volume [m^3]."""
        return self._unit_properties().mass

    @property
    def bounding_radius(self) -> float:
        """The radius [m] of the sphere about the centre of mass that encloses the whole shape."""
        raise NotImplementedError

    def _require_finite(self, name: str, value) -> None:
        """Refuse a size whose volume or inertia (at density 1) overflows or vanishes in float64 (a radius of
        1e300 m, or of 1e-200 m)."""
        try:
            unit = self._unit_properties()
            finite = math.isfinite(unit.mass) and bool(np.all(np.isfinite(unit.inertia)))
        except (OverflowError, ValueError):
            finite = False
        if not finite:
            raise checks.fail(name, value, "out of range: the shape's volume or inertia would overflow or vanish "
                                           "in float64 (sizes from about 1e-60 to 1e60 m)")

    def mass_properties(self, density: float | None = None, mass: float | None = None) -> MassProperties:
        """Mass properties for a uniform ``density`` [kg/m^3] or a total ``mass`` [kg]; default density 1000."""
        if density is not None and mass is not None:
            raise checks.fail("density, mass", (density, mass),
                              "give either density [kg/m^3] or mass [kg], not both")
        unit = self._unit_properties()
        scale = self._scale(density, mass)
        total = float(mass) if mass is not None else unit.mass * scale
        _require_rotatable("inertia", unit.inertia * scale, unit.inertia * scale)
        return MassProperties(total, unit.com, unit.inertia * scale)


def _solid(volume: float, diagonal) -> MassProperties:
    """Unit-density properties of a solid centred on its frame's origin, principal axes along the frame's."""
    return MassProperties(volume, np.zeros(3), np.diag(diagonal))


class Sphere(Shape):
    """A solid sphere of ``radius`` [m] centred on the origin: I = 2/5 m r^2."""

    kind = "sphere"

    def __init__(self, radius: float):
        self.radius = checks.scalar("radius", radius, low=0.0, low_open=True)
        self.size = (self.radius,)
        self._require_finite("radius", radius)

    def _unit_properties(self) -> MassProperties:
        r = self.radius
        volume = 4.0 / 3.0 * math.pi * r**3
        return _solid(volume, [0.4 * volume * r**2] * 3)

    @property
    def bounding_radius(self) -> float:
        return self.radius

    def __repr__(self) -> str:
        return f"Sphere(radius={self.radius!r})"


class Box(Shape):
    """A solid box with ``half_extents`` (a, b, c) [m] (a scalar: a cube): I_xx = m (b^2 + c^2) / 3, etc."""

    kind = "box"

    def __init__(self, half_extents):
        self.half_extents = checks.per_element("half_extents", half_extents, 3, 0.0, low_open=True)
        self.half_extents.setflags(write=False)
        self.size = tuple(float(a) for a in self.half_extents)
        self._require_finite("half_extents", half_extents)

    def _unit_properties(self) -> MassProperties:
        a, b, c = self.size
        volume = 8.0 * a * b * c
        return _solid(volume, [volume * (b * b + c * c) / 3.0, volume * (a * a + c * c) / 3.0,
                               volume * (a * a + b * b) / 3.0])

    @property
    def bounding_radius(self) -> float:
        return float(np.linalg.norm(self.half_extents))

    def __repr__(self) -> str:
        return f"Box(half_extents={self.size!r})"


class Cylinder(Shape):
    """A solid cylinder along Y: ``radius`` [m], ``half_height`` [m]; I_yy = m r^2 / 2, I_xx = m (r^2/4 + h^2/3)."""

    kind = "cylinder"

    def __init__(self, radius: float, half_height: float):
        self.radius = checks.scalar("radius", radius, low=0.0, low_open=True)
        self.half_height = checks.scalar("half_height", half_height, low=0.0, low_open=True)
        self.size = (self.radius, self.half_height)
        self._require_finite("radius, half_height", (radius, half_height))

    def _unit_properties(self) -> MassProperties:
        r, h = self.size
        volume = 2.0 * math.pi * r * r * h
        across = volume * (r * r / 4.0 + h * h / 3.0)
        return _solid(volume, [across, volume * r * r / 2.0, across])

    @property
    def bounding_radius(self) -> float:
        return math.hypot(self.radius, self.half_height)

    def __repr__(self) -> str:
        return f"Cylinder(radius={self.radius!r}, half_height={self.half_height!r})"


class Capsule(Shape):
    """A solid capsule along Y: a cylinder of ``radius`` [m] and ``half_height`` [m] capped by two hemispheres.

    With m_c the cylinder's and m_h each hemisphere's mass: I_yy = m_c r^2/2 + 2 (2/5) m_h r^2 and
    I_xx = I_zz = m_c (r^2/4 + h^2/3) + 2 m_h (2/5 r^2 + h^2 + 3/4 h r) (a hemisphere's centre of mass
    lies 3/8 r from its flat face; parallel axis theorem). half_height 0 is a sphere.
    """

    kind = "capsule"

    def __init__(self, radius: float, half_height: float):
        self.radius = checks.scalar("radius", radius, low=0.0, low_open=True)
        self.half_height = checks.scalar("half_height", half_height, low=0.0)
        self.size = (self.radius, self.half_height)
        self._require_finite("radius, half_height", (radius, half_height))

    def _unit_properties(self) -> MassProperties:
        r, h = self.size
        cylinder = 2.0 * math.pi * r * r * h
        cap = 2.0 / 3.0 * math.pi * r**3
        along = cylinder * r * r / 2.0 + 2.0 * 0.4 * cap * r * r
        across = cylinder * (r * r / 4.0 + h * h / 3.0) + 2.0 * cap * (0.4 * r * r + h * h + 0.75 * h * r)
        return _solid(cylinder + 2.0 * cap, [across, along, across])

    @property
    def bounding_radius(self) -> float:
        return self.half_height + self.radius

    def __repr__(self) -> str:
        return f"Capsule(radius={self.radius!r}, half_height={self.half_height!r})"


def _enclosing_volume(vertices: np.ndarray, axes: np.ndarray) -> float:
    """An upper bound [m^3] on the volume a non-self-intersecting closed surface through these vertices can enclose.

    The convex hull would be tightest, but trimesh's hull needs scipy (not a dependency), so this is
    the smaller of the axis-aligned bounding box in the mesh frame and in the principal-axis frame.
    """
    boxes = [np.ptp(vertices, axis=0), np.ptp(vertices @ axes, axis=0)]
    return float(min(np.prod(box) for box in boxes))


class MeshShape(Shape):
    """A solid of uniform density bounded by a closed triangle mesh (a ``trimesh.Trimesh``, vertices in [m]),
    or with ``solid=False`` a surface (e.g. an open terrain) that only a static collider can use; a surface collides
    from both sides (which side a body is on comes from where it is, not from the winding).

    The mesh is copied (geometry only) and checked; each failure raises ValueError saying how to fix it:
    - empty, non-finite vertices, face indices out of range; a surface: also zero-area faces,
      and nothing below (it has no volume, mass properties or centre of mass);
    - open (boundary edges) or non-manifold (edges shared by more than two faces);
    - inconsistent face winding; inside out (negative signed volume) or zero volume;
    - anything else ``trimesh`` does not call a volume (``mesh.is_volume``);
    - a signed volume larger than a bounding box of the vertices allows (``_enclosing_volume``),
      which no closed, non-self-intersecting surface can have: gross self-intersection or
      overlapping shells, whose overlap is counted twice.
    Not detected: self-intersections and interpenetrating or nested shells whose signed volume
    stays within that bound; they give the winding-number weighted volume (overlaps counted
    twice), not that of the union. Disjoint closed shells are allowed and form one rigid body;
    an inward-facing inner shell is a cavity.
    """

    kind = "mesh"

    def __init__(self, mesh, solid: bool = True):
        if not isinstance(solid, (bool, np.bool_)):
            raise checks.fail("solid", solid, "expected True (a closed solid) or False (a surface, static only)")
        self.solid = bool(solid)
        if not isinstance(mesh, trimesh.Trimesh):
            raise checks.fail("mesh", mesh, f"expected a trimesh.Trimesh, got {type(mesh).__name__} (load files with "
                              "MeshShape.from_file, which flattens scenes into one mesh)")
        if len(mesh.vertices) == 0 or len(mesh.faces) == 0:
            raise checks.fail("mesh", mesh, f"the mesh is empty ({len(mesh.vertices)} vertices, "
                              f"{len(mesh.faces)} faces); {'a solid needs closed' if solid else 'it needs'} triangles")
        vertices = checks.finite_array("mesh.vertices", mesh.vertices, (-1, 3))
        faces = checks.indices("mesh.faces", mesh.faces, len(vertices), (-1, 3))
        self.mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
        self.vertices = np.array(self.mesh.vertices, dtype=np.float64)
        self.faces = np.array(self.mesh.faces, dtype=np.int32)
        for array in (self.vertices, self.faces):
            array.setflags(write=False)
        if not self.solid:
            self._check_faces(mesh)
            return
        self._check_closed(mesh)
        unit = trimesh.triangles.mass_properties(self.mesh.triangles, density=1.0)
        self._check_volume(mesh, float(unit.volume), np.asarray(unit.center_mass), np.asarray(unit.inertia))
        self._unit = MassProperties(unit.volume, unit.center_mass, unit.inertia)

    def _check_faces(self, original) -> None:
        """Reject zero-area faces (coincident or collinear corners, to round-off): a surface has no normal there."""
        a, b, c = np.moveaxis(self.vertices[self.faces], 1, 0)
        twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
        longest = np.max([np.sum((b - a) ** 2, axis=1), np.sum((c - b) ** 2, axis=1),
                          np.sum((a - c) ** 2, axis=1)], axis=0)
        bad = np.flatnonzero(twice_area <= DEGENERATE_RATIO * longest)
        if len(bad):
            raise checks.fail("mesh", original, f"{len(bad)} of {len(self.faces)} faces have zero area (coincident "
                              f"or collinear corners), the first face {bad[0]} with vertices "
                              f"{tuple(self.faces[bad[0]].tolist())}; remove them, e.g. "
                              "mesh.update_faces(mesh.nondegenerate_faces())")

    def _check_closed(self, original) -> None:
        mesh = self.mesh
        if not mesh.is_watertight:
            uses = np.unique(mesh.edges_sorted, axis=0, return_counts=True)[1]
            open_edges, shared = int(np.sum(uses == 1)), int(np.sum(uses > 2))
            found = "; ".join([f"{open_edges} boundary edges (used by one face)"] * bool(open_edges)
                              + [f"{shared} non-manifold edges (shared by more than two faces)"] * bool(shared))
            raise checks.fail("mesh", original, f"mesh is {'open' if open_edges else 'not closed'}: {found}, so it "
                              "bounds no volume; close it (e.g. mesh.fill_holes(), or repair in a modeller); a "
                              "triangle soup with duplicated vertices needs mesh.merge_vertices() first; an open "
                              "surface such as a terrain can only be a static collider: MeshShape(mesh, "
                              "solid=False) with scene.add_collider")
        if not mesh.is_winding_consistent:
            raise checks.fail("mesh", original, "the face winding is inconsistent (neighbouring faces point opposite "
                              "ways), so the volume would be wrong; fix it with trimesh.repair.fix_winding(mesh)")

    def _check_volume(self, original, volume: float, com: np.ndarray, inertia: np.ndarray) -> None:
        """Refuse a solid whose unit-density volume [m^3], centre [m] and inertia [m^5] no closed surface has."""
        if volume < 0.0:
            raise checks.fail("mesh", original, f"the mesh is inside out (signed volume {volume:.6g} m^3 < 0: the face "
                              "normals point inwards); fix it with mesh.invert() or trimesh.repair.fix_normals(mesh)")
        if not volume > 0.0:
            raise checks.fail("mesh", original, f"the mesh encloses no volume ({volume:.6g} m^3); a solid needs a "
                              "closed surface around a non-zero volume")
        if not self.mesh.is_volume:
            raise checks.fail("mesh", original, "trimesh does not consider it a solid volume (mesh.is_volume is "
                              "False); repair it (trimesh.repair, or in a modeller)")
        _require_rotatable("mesh", original, inertia)
        bound = _enclosing_volume(self.vertices - com, np.linalg.eigh(inertia)[1])
        if volume > bound * (1.0 + BOUND_SLACK):
            raise checks.fail("mesh", original, f"the signed volume {volume:.6g} m^3 exceeds the {bound:.6g} m^3 of a "
                              "box around its vertices, impossible for a closed surface that does not cross "
                              "itself: it is likely self-intersecting or made of overlapping shells; merge "
                              "them into one surface (a boolean union in a modeller)")

    @classmethod
    def from_file(cls, path, solid: bool = True) -> MeshShape:
        """Load a mesh file (OBJ, STL, PLY, GLB, ...; coordinates in [m]) with ``trimesh.load(path, force="mesh")``;
        ``solid`` as for MeshShape."""
        if not isinstance(path, (str, os.PathLike)) or not os.path.isfile(path):
            raise checks.fail("path", path, "no such file")
        try:
            mesh = trimesh.load(path, force="mesh")
        except Exception as error:  # noqa: BLE001 - trimesh's loaders raise ValueError, IndexError, ImportError ...
            raise checks.fail("path", path, f"could not be read as a mesh ({type(error).__name__}: {error})") from None
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            raise checks.fail("path", path, "the file holds no triangles")
        try:
            return cls(mesh, solid)
        except ValueError as error:
            raise checks.fail("path", path, str(error)) from None

    def _unit_properties(self) -> MassProperties:
        if not self.solid:
            raise checks.fail("shape", self, "a surface mesh (solid=False) bounds no volume, so it has no volume or "
                              "mass properties and cannot be a dynamic rigid body; it can only be a static collider "
                              "(scene.add_collider(shape, ...))")
        return self._unit

    @property
    def bounding_radius(self) -> float:
        """The radius [m] about the centre of mass (a surface: about the shape origin) enclosing every vertex."""
        centre = self._unit.com if self.solid else np.zeros(3)
        return float(np.max(np.linalg.norm(self.vertices - centre, axis=1)))

    def __repr__(self) -> str:
        shown = f"volume={self.volume:.6g}" if self.solid else "solid=False"
        return f"MeshShape(vertices={len(self.vertices)}, faces={len(self.faces)}, {shown})"


class PointMasses(Shape):
    """Point masses (N,) [kg] at ``positions`` (N, 3) [m], rigidly joined; ``radius`` [m] only for drawing.

    About the centre of mass c, with r_i = q_i - c = (x, y, z):
    I_xx = sum m (y^2 + z^2), I_yy = sum m (x^2 + z^2), I_zz = sum m (x^2 + y^2) and the products
    I_xy = -sum m x y, I_xz = -sum m x z, I_yz = -sum m y z. The minus signs belong to the tensor
    (I = sum m (|r|^2 E - r r^T)); the lecture slide's I_xy = +sum m x y omits them, which
    would make L = I omega wrong for any body whose products of inertia are not zero.
    ``mass_properties(mass=M)`` scales the masses to sum to M; no argument keeps them;
    a density is rejected (points have no volume). Collinear points (or one) cannot turn about
    their line, so they are rejected.
    """

    kind = "points"

    def __init__(self, positions, masses, radius: float = 0.02):
        self.positions = checks.finite_array("positions", positions, (-1, 3))
        if len(self.positions) == 0:
            raise checks.fail("positions", positions, "expected at least one point")
        self.masses = checks.per_element("masses", masses, len(self.positions), 0.0, low_open=True)
        self.radius = checks.scalar("radius", radius, low=0.0)
        for array in (self.positions, self.masses):
            array.setflags(write=False)
        total = float(np.sum(self.masses))
        com = self.masses @ self.positions / total
        r = self.positions - com
        inertia = np.eye(3) * np.sum(self.masses * np.sum(r * r, axis=1)) - (self.masses[:, None] * r).T @ r
        inertia = (inertia + inertia.T) / 2.0  # exactly symmetric despite round-off in the products
        _require_rotatable("positions", positions, inertia)
        self._unit = MassProperties(total, com, inertia)

    def _unit_properties(self) -> MassProperties:
        """The properties of the masses as given."""
        return self._unit

    def _scale(self, density, mass) -> float:
        if density is not None:
            raise checks.fail("density", density, "point masses have no volume; give mass= [kg] or neither")
        return 1.0 if mass is None else super()._scale(None, mass)

    @property
    def volume(self) -> float:
        """Point masses have no volume: 0.0 m^3."""
        return 0.0

    @property
    def bounding_radius(self) -> float:
        return float(np.max(np.linalg.norm(self.positions - self._unit.com, axis=1))) + self.radius

    def __repr__(self) -> str:
        return f"PointMasses(count={len(self.masses)}, total_mass={self._unit.mass:.6g}, radius={self.radius!r})"


class NoShape(Shape):
    """No shape: a body that collides with nothing (a USD rigid body without a collider, such as a joint's anchor).
    It has no volume, so its mass properties are given: ``scene.add_rigid_body(None, mass_properties=...)``."""

    kind = "none"

    def _unit_properties(self) -> MassProperties:
        raise checks.fail("shape", None, "a body without a shape has no volume: give mass_properties= (a "
                                         "MassProperties) instead of a density or mass")

    @property
    def volume(self) -> float:
        """No shape, no volume: 0.0 m^3."""
        return 0.0

    @property
    def bounding_radius(self) -> float:
        return 0.0

    def __repr__(self) -> str:
        return "NoShape()"

"""What the user describes, on the host (numpy only, checked on entry): the Scene and its parts.

Shapes with their mass properties, cloth and soft-body topology builders, emitter and
force-field descriptions. Nothing here touches a device.
"""
from .emitters import Emitter, Ramp
from .fields import Attractor, Field, Turbulence, Vortex
from .joints import D6, Drive, Joint
from .parts import Collider, ParticleGroup, Plane, RigidBody, SurfaceMesh
from .scene import PRECISIONS, Scene
from .shapes import Box, Capsule, Cylinder, MassProperties, MeshShape, PointMasses, Shape, Sphere

__all__ = ["Scene", "ParticleGroup", "Plane", "SurfaceMesh", "RigidBody", "Collider", "PRECISIONS", "Emitter",
           "Ramp", "Field", "Attractor", "Vortex", "Turbulence", "Shape", "Sphere", "Box", "Capsule", "Cylinder",
           "MeshShape", "PointMasses", "MassProperties", "Joint", "Drive", "D6"]

"""Passes run after each solver step, in the order warp_sim.assembly lists them: kinematic bodies, strain
limiting, body contacts, particles against shapes, particles against planes, the components' projection, emitter
pools, kinematic bodies again."""
from .body_contacts import BodyContacts
from .emitters import EmitterPools
from .joints import Joints
from .kinematic import KinematicBodies
from .particle_shapes import ParticleShapeContacts
from .plane_contacts import PlaneImpacts
from .projection import ComponentProjection
from .strain import StrainLimiter, colour_springs

__all__ = ["BodyContacts", "EmitterPools", "Joints", "KinematicBodies", "ParticleShapeContacts", "PlaneImpacts",
           "ComponentProjection", "StrainLimiter", "colour_springs"]

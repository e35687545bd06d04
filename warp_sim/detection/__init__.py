"""Collision detection shared by the penalty forces and the contact passes: shapes on the device,
growable buffers, the broad and narrow phases, contact manifolds coloured for a parallel solve."""
from .buffers import GrowableBuffer
from .detector import Detection
from .geometry import ContactGeometry, shape_samples
from .manifolds import ContactManifolds

__all__ = ["ContactGeometry", "ContactManifolds", "Detection", "GrowableBuffer", "shape_samples"]

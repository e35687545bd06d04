"""Collision detection shared by the penalty forces and the contact passes: shapes on the device,
growable buffers, the broad and narrow phases."""
from .buffers import GrowableBuffer
from .detector import Detection
from .geometry import ContactGeometry, shape_samples

__all__ = ["ContactGeometry", "Detection", "GrowableBuffer", "shape_samples"]

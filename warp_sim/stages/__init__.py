"""USD output: an atomic, frame-by-frame animation writer and a stage validator (no warp import)."""

from .validate import validate_stage
from .writer import BodySpec, ColliderSpec, MeshSpec, PlaneSpec, PointsGroup, StageLayout, StageWriter

__all__ = ["BodySpec", "ColliderSpec", "MeshSpec", "PlaneSpec", "PointsGroup", "StageLayout", "StageWriter",
           "validate_stage"]

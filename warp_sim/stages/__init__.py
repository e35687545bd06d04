"""USD output: the specs of what a stage holds, a scene's layout, an atomic frame-by-frame animation writer and
a stage validator (no warp import)."""

from .layout import stage_layout
from .specs import BodySpec, ColliderSpec, MeshSpec, PlaneSpec, PointsGroup, StageLayout
from .validate import validate_stage
from .writer import StageWriter

__all__ = ["BodySpec", "ColliderSpec", "MeshSpec", "PlaneSpec", "PointsGroup", "StageLayout", "StageWriter",
           "stage_layout", "validate_stage"]

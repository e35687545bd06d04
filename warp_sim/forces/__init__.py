"""Force terms: what fills the force accumulators before the components turn forces into rates."""
from .aerodynamics import AeroForces
from .fields import FieldForces
from .penalty import BodyPenalty, PlanePenalty
from .springs import Springs

__all__ = ["Springs", "FieldForces", "AeroForces", "PlanePenalty", "BodyPenalty"]

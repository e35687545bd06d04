"""Strain limiting (Provot 1995): a pass after each step that keeps cloth springs from over-stretching.

For every mesh with ``max_stretch`` = tau, each of its structural and shear springs
longer than (1 + tau) L0 (L0 its rest length) is shortened to (1 + tau) L0 by
moving its two endpoints along the spring, in proportion to their inverse masses:
dx_i = w_i / (w_i + w_j) e d and dx_j = -w_j / (w_i + w_j) e d, with e = L - (1 + tau) L0
the excess and d the unit vector from i to j (see Method for the over-relaxed
sweeps, which shorten by more than e). A pinned end (w = 0) does not
move; a spring with both ends pinned, or with L0 = 0, is left alone. The moves keep
sum m dx = 0, so the limiter conserves the cloth's linear momentum and centre of mass
(exactly, when no end is pinned). Springs at or below the limit, compressed ones
included, are never touched.

Velocities: each moved vertex also gets v += dx / h. The solver's step took the
vertex from x0 to x1 with velocity v1; moving it to x1 + dx and correcting v1 by
dx / h keeps the velocity the motion it actually made over the step (for x1 = x0 +
h v1 exactly so). Without it the stretching velocity would survive the pass, the
next step would carry the vertex straight back out, and the limiter would have to
undo it again every step while the cloth kept that momentum.

Method: successive over-relaxation (SOR) Gauss-Seidel over a colouring of the
springs, computed once on the host: greedy in spring order, no two springs of one
colour share a particle (a grid cloth with structural and shear springs takes 8
colours). A sweep is one launch per colour, the springs of a colour projected in
parallel with no atomics on the particles; on the CPU, whose launches run their
threads in order, one launch over every spring (they are stored colour by colour), the
same sweep bit for bit. The first sweep of a step is Provot's
projection exactly (each over-long spring shortened to its limit); later sweeps
over-relax: a spring still over its limit is shortened by ``relaxation`` times its
excess, but never below its rest length. Plain Gauss-Seidel (relaxation 1) spreads
a correction along a chain of springs like diffusion, so a cloth hanging from pinned
particles needs sweeps in proportion to its height squared (an 8 x 8 hanging cloth:
over 50 sweeps per step for 1e-6); over-relaxed, about 6 to 10. Sweeps repeat
until one finds no spring longer than its limit times (1 + tolerance) (that sweep
moves nothing), or ``max_iterations`` sweeps have moved something. ``apply`` works
in place on the end state of a step.
"""
from __future__ import annotations

import numpy as np
import warp as wp

from ..core.model import Model
from ..core.protocols import Pass
from ..core.state import State
from ..kernels import cloth as cloth_kernels
from ..util import checks

#: the relative tolerance on the limit by precision: float32 lengths of millimetre springs a metre
#: from the origin carry rounding errors of about 1e-5 of their length, so 1e-6 is out of reach there
DEFAULT_TOLERANCE = {"float64": 1e-6, "float32": 1e-4}
FAMILIES = ("structural", "shear")


def colour_springs(pairs: np.ndarray, particle_count: int) -> np.ndarray:
    """Greedy edge colouring: per spring, the smallest colour used by no earlier spring at either end.

    pairs: (K, 2) particle indices. Returns (K,) colours; no two springs of one colour
    share a particle, and at most 2 D - 1 colours are used (D: the most springs at one
    particle). One pass over the springs with a bit set of used colours per particle.
    """
    used = [0] * particle_count
    colours = np.empty(len(pairs), dtype=np.int64)
    for k, (i, j) in enumerate(pairs.tolist()):
        taken = used[i] | used[j]
        bit = ~taken & (taken + 1)          # the lowest colour free at both ends
        colours[k] = bit.bit_length() - 1
        used[i] |= bit
        used[j] |= bit
    return colours


class StrainLimiter(Pass):
    """Provot strain limiting of the structural and shear springs of every mesh with max_stretch.

    max_iterations: the most sweeps that move something per apply, an integer >= 1
    tolerance: relative slack on the limit that ends the iteration (a spring counts as over its limit when
        longer than (1 + max_stretch) L0 (1 + tolerance)), >= 0; None: 1e-6 in float64, 1e-4 in float32
    relaxation: the over-relaxation factor of the sweeps after the first, in [1, 2) (1: plain Gauss-Seidel)
    Raises ValueError for these, and for a mesh's max_stretch <= 0 or springs that are not spring indices.

    After each ``apply``:
    last_iterations: the sweeps that found and shortened an over-long spring (0: nothing was over its limit)
    converged: whether every spring ended within its limit (False only when max_iterations ran out)
    max_strain: the largest L / L0 - 1 of the limited springs in the end state [1]
    constraint_count: springs limited; colour_count: their colours; sweep_launches: a sweep's (first spring,
    springs) launches: one per colour, or one on the CPU
    """

    kernels = ("cloth",)

    def __init__(self, model: Model, scene, max_iterations: int = 50, tolerance: float | None = None,
                 relaxation: float = 1.9):
        self.max_iterations = checks.count("max_iterations", max_iterations)
        self.tolerance = DEFAULT_TOLERANCE[model.precision] if tolerance is None else checks.scalar(
            "tolerance", tolerance, low=0.0)
        self.relaxation = checks.scalar("relaxation", relaxation)
        if not 1.0 <= self.relaxation < 2.0:
            raise checks.fail("relaxation", relaxation, "must be >= 1.0 and < 2 (1: plain Gauss-Seidel)")
        self.model = model
        ids, limits = [np.zeros(0, dtype=np.int64)], [np.zeros(0)]
        for mesh in scene.meshes:
            if mesh.max_stretch is None:
                continue
            tau = mesh.parameter("max_stretch", low=0.0, low_open=True)
            springs = getattr(mesh, "springs", None) or {}
            for family in FAMILIES:
                if family not in springs or len(np.asarray(springs[family])) == 0:
                    continue
                try:
                    family_ids = checks.indices(f"springs[{family!r}]", springs[family], scene.spring_count, (-1,))
                except ValueError as error:
                    raise ValueError(f"{error} (mesh {mesh.name!r})") from None
                ids.append(family_ids)
                limits.append(np.full(len(family_ids), 1.0 + tau))
        ids, factor = np.concatenate(ids), np.concatenate(limits)
        order = np.lexsort((factor, ids))              # a spring listed twice keeps its tightest limit
        ids, factor = ids[order], factor[order]
        first = np.ones(len(ids), dtype=bool)
        first[1:] = ids[1:] != ids[:-1]
        ids, factor = ids[first], factor[first]
        if len(ids):
            pairs = scene.spring_array("pairs")[ids]
            rest = scene.spring_array("rest_length")[ids]
            inv_mass = model.particle_inv_mass.numpy().astype(np.float64)
            keep = (rest > 0.0) & ((inv_mass[pairs[:, 0]] > 0.0) | (inv_mass[pairs[:, 1]] > 0.0))
            pairs, rest, factor = pairs[keep], rest[keep], factor[keep]
        else:
            pairs, rest = np.zeros((0, 2), dtype=np.int64), np.zeros(0)
        colours = colour_springs(pairs, model.particle_count)
        order = np.argsort(colours, kind="stable")
        counts = np.bincount(colours, minlength=0)
        self.constraint_count = len(pairs)
        self.colour_count = len(counts)
        #: (offset, count) of each colour's springs in the arrays below
        self.colours = [(int(start), int(count)) for start, count in zip(np.cumsum(counts) - counts, counts)]
        dtype, device = model.numpy_scalar, model.device
        self.pairs = wp.array(pairs[order].astype(np.int32), dtype=wp.vec2i, device=device)
        self.limit = wp.array((factor * rest)[order].astype(dtype), dtype=model.scalar, device=device)
        self.inv_rest = wp.array((1.0 / rest[order]).astype(dtype), dtype=model.scalar, device=device)
        self._violations = wp.zeros(1, dtype=wp.int32, device=device)
        self._max_strain = wp.zeros(1, dtype=model.scalar, device=device)
        #: the (offset, count) launches of a sweep: one per colour, or on the CPU, which runs a launch's threads in
        #: order, one over every spring (stored colour by colour, so the same sweep bit for bit)
        self.sweep_launches = [(0, self.constraint_count)] if device.is_cpu and self.colours else self.colours
        #: the count of springs over their limit, read after each sweep (on the CPU a view of its memory)
        self._violation_count = self._violations.numpy() if device.is_cpu else None
        self.last_iterations = 0
        self.converged = True
        self._measured = False

    @property
    def max_strain(self) -> float | None:
        """The largest strain L / L0 - 1 among the limited springs at the end of the last apply
        (None before the first apply, or when no spring is limited)."""
        if not self._measured:
            return None
        return float(self._max_strain.numpy()[0])

    def _reset(self) -> None:
        m = self.model
        m.launch(cloth_kernels.reset_strain_counters, 1, [self._violations, self._max_strain, m.scalar(-1.0)])

    def apply(self, start: State, end: State, t: float, h: float) -> None:
        """Limit the springs of ``end`` in place (positions and velocities); h: the step [s].
        ``start`` is not read."""
        if self.constraint_count == 0:
            return
        m = self.model
        x, v = end.particle_x, end.particle_v
        tolerance, inv_h = m.scalar(self.tolerance), m.scalar(1.0 / h)
        self._measured = True
        for sweep in range(self.max_iterations):
            relax = m.scalar(1.0 if sweep == 0 else self.relaxation)
            self._reset()
            for offset, count in self.sweep_launches:
                m.launch(cloth_kernels.limit_strain, count,
                         [x, v, m.particle_inv_mass, self.pairs, self.limit, self.inv_rest, offset, tolerance, relax,
                          inv_h, self._violations, self._max_strain])
            if self._violations_now() == 0:     # nothing was over its limit, so nothing moved
                self.last_iterations, self.converged = sweep, True
                return
        self._reset()
        m.launch(cloth_kernels.measure_strain, self.constraint_count,
                 [x, self.pairs, self.limit, self.inv_rest, tolerance, self._violations, self._max_strain])
        self.last_iterations = self.max_iterations
        self.converged = self._violations_now() == 0

    def _violations_now(self) -> int:
        """Springs found over their limit since the last reset."""
        view = self._violation_count if self._violation_count is not None else self._violations.numpy()
        return int(view[0])

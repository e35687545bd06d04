"""Implicit Euler for stiff springs: the linearised backward Euler step of Baraff and Witkin (1998).

For the particles, one step solves the linear system

    (M - h dF/dv - h^2 dF/dx) dv = h (F + h dF/dx v0),   v1 = v0 + dv,   x1 = x0 + h v1,

that is backward Euler with the forces linearised about the start of the step (exact
backward Euler when the forces are linear). What is implicit and what is explicit:

- F is the full force on each particle from the Dynamics, F = m a with a from
  ``Dynamics.velocity_derivative``: gravity, drag, wind, force fields, springs, penalty
  contacts, whatever force terms are present.
- The Jacobians are those of the damped springs (dF/dx and dF/dv, assembled on the
  device into a 3x3-block sparse matrix) and of the linear drag (dF/dv = -c I, c the
  scene's drag). Every other force (fields, penalty contacts, wind) is treated
  explicitly: it enters through F only.
- For a compressed spring (L < L0) the geometric term (1 - L0/L)(I - d d^T) of dF/dx
  is negative and would make the system indefinite; it is clamped at zero (Choi and
  Ko 2002), which keeps the matrix symmetric positive definite for conjugate gradient.
  The damper's derivative with respect to positions (not symmetric) is left out, as
  Baraff and Witkin do. Both only change how the step is linearised, not its fixed
  points: a state at rest in equilibrium stays exactly at rest.
- Pinned particles (inverse mass 0, including dead emitter slots) are eliminated: their
  rows and columns are the identity with a zero right-hand side, and the velocity update
  writes dv = 0 for them, so their velocity change is exactly 0.
- Rigid bodies, if present, advance by symplectic Euler inside the same step (their
  momenta kicked with the forces at the start, then a drift with the new momenta):
  implicit in the springs, explicit elsewhere.

The system is solved by preconditioned conjugate gradient (``warp.optim.linear.CG``,
block-Jacobi by default) to a relative residual ``tolerance``; ``last_iterations`` and
``last_residual`` record the last solve, ``stats()`` running aggregates of every solve (counts, sums, extremes:
a fixed handful of numbers, however long the run, which checkpoints keep exactly). Both precisions work:
Warp's BSR matrices and CG accept float32 (mat33f) and float64 (mat33d) blocks.

The defaults, chosen by measurement on the cloth benchmark's cloth at h = 1/60 s (k = 1e4
N/m, 0.2 kg/m^2): a relative residual of 1e-3 moves no particle by more than float32
rounding (1.2e-7 m after 30 steps) against solves to 1e-6 at 32^2 and 64^2, at a quarter of
the iterations; and block-Jacobi CG needs iterations in proportion to the grid's side (the
condition number grows with the square of the particle count along it), so the cap grows
with sqrt(particles): max(200, 4 sqrt(n)). A solve that still stops at the cap is counted,
and the Simulator warns once per step() or run() call with their number and the worst
residual.
"""
from __future__ import annotations

import numpy as np
import warp as wp
import warp.optim.linear as wp_linear
import warp.sparse as wp_sparse

try:   # a private class of Warp's CG, replaced on the CPU when it has the expected form (see below)
    from warp._src.optim.linear import TiledDot
except ImportError:   # another Warp version: CG keeps its own dot products
    TiledDot = None

from ..core.tape import paused
from ..kernels import implicit as implicit_kernels
from ..util import checks
from .partitioned import Partitioned, SymplecticEuler

PRECONDITIONERS = ("block_jacobi", "diag", "none")


class ImplicitEuler(Partitioned):
    """Linearised backward Euler (Baraff and Witkin 1998), implicit in the springs and the linear drag.

    First order, unconditionally stable for the springs (at any step a linear spring
    oscillator loses amplitude by 1 / sqrt(1 + h^2 w^2) per step: numerical damping).

    Options (``Simulator(scene, integrator=ImplicitEuler(tolerance=1e-8))``):
    tolerance: relative residual of the conjugate gradient solve, 0 < tolerance < 1 (default 1e-3)
    absolute_tolerance: CG stops once |b - A dv| <= max(tolerance |b|, absolute_tolerance) (or below Warp's
        floor, eps^(9/4) of the precision) [N s], >= 0
    max_iterations: the cap on CG iterations per step (a solve that reaches it uses its last iterate and is
        counted in ``unconverged_solves``), >= 1; None (default): max(200, 4 sqrt(particles))
    preconditioner: "block_jacobi" (the inverse of each particle's 3x3 diagonal block, default), "diag"
        (Jacobi) or "none"
    warm_start: start CG from the last step's dv instead of 0 (on cloth it saved under 5 % of the
        iterations; with absolute_tolerance 0 it makes a scene at rest iterate to the cap, since |b| = 0 there)
    check_every: CG reads its residual back (a device-to-host copy) every this many iterations, so
        ``last_iterations`` is exact with 1 and rounded up to a multiple otherwise, >= 1

    After each step:
    last_iterations: CG iterations of the last solve
    last_residual: |b - A dv| of the last solve, CG's recursively updated residual [N s]
    last_tolerance: the absolute threshold it was held to [N s]
    last_converged: whether the last solve reached it
    unconverged_solves: the solves that stopped at max_iterations above the threshold
    solves, iterations_min, iterations_max, iterations_total, residual_total, residual_max: running aggregates
        of every solve (CG iterations; relative residuals |b - A dv| / |b|, 0 where b = 0), not per-solve lists
    stats(): solves, iterations (min, mean, max), relative residuals (mean, max), unconverged solves
    """

    name, order = "implicit_euler", 1
    position_response = 1.0
    differentiable = True
    kernels = ("integrate", "implicit")
    capturable = False   # the conjugate-gradient solve stops on a residual read back
    persistent = ("dv", "last_iterations", "last_residual", "last_tolerance", "last_converged",
                  "unconverged_solves", "solves", "iterations_min", "iterations_max", "iterations_total",
                  "residual_total", "residual_max", "_reported", "_worst_unreported")

    def __init__(self, tolerance: float = 1.0e-3, max_iterations: int | None = None,
                 preconditioner: str = "block_jacobi", warm_start: bool = False, check_every: int = 1,
                 absolute_tolerance: float = 0.0):
        super().__init__()
        self.tolerance = checks.scalar("tolerance", tolerance, low=0.0, low_open=True)
        if self.tolerance >= 1.0:
            raise checks.fail("tolerance", tolerance, "must be > 0 and < 1 (a relative residual)")
        self.absolute_tolerance = checks.scalar("absolute_tolerance", absolute_tolerance, low=0.0)
        self.max_iterations = None if max_iterations is None else checks.count("max_iterations", max_iterations)
        self.check_every = checks.count("check_every", check_every)
        self.preconditioner = checks.choice("preconditioner", preconditioner, PRECONDITIONERS)
        if not isinstance(warm_start, bool):
            raise checks.fail("warm_start", warm_start, "expected True or False")
        self.warm_start = warm_start
        self.last_iterations = 0
        self.last_residual = 0.0
        self.last_tolerance = 0.0
        self.last_converged = True
        self.unconverged_solves = 0
        self.solves = 0                  # running aggregates of every solve: their count,
        self.iterations_min = 0          # CG iterations (fewest, most, sum)
        self.iterations_max = 0
        self.iterations_total = 0
        self.residual_total = 0.0        # relative residuals |b - A dv| / |b| (sum, largest; 0 when b = 0)
        self.residual_max = 0.0
        self._reported = 0                         # unconverged solves already warned about
        self._worst_unreported = 0.0

    def __repr__(self) -> str:
        return f"ImplicitEuler(tolerance={self.tolerance:g}, max_iterations={self.max_iterations})"

    def amplification(self, h, w2, c, stiff=True):
        """Backward Euler for a spring or drag, (I - hA)^-1; a penalty contact's force is explicit in F, so it
        steps as symplectic Euler does (Integrator.amplification)."""
        if not stiff:
            return SymplecticEuler.amplification(self, h, w2, c)
        return np.linalg.inv(np.eye(2) - h * np.array([[0.0, 1.0], [-w2, -c]]))

    def stats(self) -> dict:
        """Every solve so far: their count ("solves"), CG iterations ("iterations": min, mean, max), relative
        residuals |b - A dv| / |b| ("residuals": mean, max, the worst), the unconverged solves ("unconverged":
        stopped at the cap above the tolerance), "max_iterations" and "tolerance"."""
        count = self.solves
        mean_iterations = self.iterations_total / count if count else 0.0
        mean_residual = self.residual_total / count if count else 0.0
        return {"solves": count, "iterations": (self.iterations_min, mean_iterations, self.iterations_max),
                "residuals": (mean_residual, self.residual_max), "unconverged": self.unconverged_solves,
                "max_iterations": self.max_iterations, "tolerance": self.tolerance}

    def _count(self, iterations: int, relative: float) -> None:
        """Fold one solve into the running aggregates."""
        first = self.solves == 0
        self.solves += 1
        self.iterations_min = iterations if first else min(self.iterations_min, iterations)
        self.iterations_max = max(self.iterations_max, iterations)
        self.iterations_total += iterations
        self.residual_total += relative
        self.residual_max = max(self.residual_max, relative)

    def pending_warning(self) -> str | None:
        """How many solves stopped unconverged since the last warning, and the worst relative residual."""
        new = self.unconverged_solves - self._reported
        if new <= 0:
            return None
        worst = self._worst_unreported
        self._reported, self._worst_unreported = self.unconverged_solves, 0.0
        return (f"implicit_euler: {new} conjugate gradient solve(s) stopped at the cap of {self.max_iterations} "
                f"iterations above the tolerance {self.tolerance:g} (worst relative residual {worst:.2e}); raise "
                f"ImplicitEuler(max_iterations=...) or tolerance, or take smaller steps")

    def allocate(self, dynamics):
        super().allocate(dynamics)
        self.model = dynamics.model
        if self.model.particle_count:
            self._build_system()

    # set-up ----------------------------------------------------------------------
    def _build_system(self) -> None:
        """Allocate the matrix (fixed topology: diagonal + each spring's four blocks), the triplet
        values, the vectors and the CG solver, once."""
        m = self.model
        n, springs, device = m.particle_count, m.spring_count, m.device
        if self.max_iterations is None:
            self.max_iterations = max(200, int(np.ceil(4.0 * np.sqrt(n))))
        self.vec3 = m.vec3
        self.mat33 = m.mat33
        rows, cols = [np.arange(n)], [np.arange(n)]
        if springs:
            pairs = m.spring_pairs.numpy().astype(np.int64)
            p1, p2 = pairs[:, 0], pairs[:, 1]
            rows.append(np.stack([p1, p2, p1, p2], axis=1).ravel())   # triplet N + 4 s + (0, 1, 2, 3)
            cols.append(np.stack([p1, p2, p2, p1], axis=1).ravel())
        rows, cols = np.concatenate(rows).astype(np.int32), np.concatenate(cols).astype(np.int32)
        self.triplets = wp.zeros(len(rows), dtype=self.mat33, device=device)
        self.diagonal_triplets = self.triplets[:n]          # views kept, so recorded launches stay valid
        self.A = wp_sparse.bsr_zeros(n, n, self.mat33, device=device)
        #: each triplet's block row and column (the adjoint of the solve reads them)
        self.triplet_rows = wp.array(rows, dtype=int, device=device)
        self.triplet_cols = wp.array(cols, dtype=int, device=device)
        self.mapping = wp_sparse.bsr_set_from_triplets(
            self.A, self.triplet_rows, self.triplet_cols, self.triplets, prune_numerical_zeros=False,
            build_mapping=True)
        self.A.nnz_sync()   # tightens the block count the value gathers launch over
        self.rhs = wp.zeros(n, dtype=self.vec3, device=device)
        self.dv = wp.zeros(n, dtype=self.vec3, device=device)
        self.diagonal_blocks = wp.zeros(n, dtype=self.mat33, device=device)
        self.inverse_blocks = wp.zeros(n, dtype=self.mat33, device=device)
        self._preconditioner_launches = {}
        M = None
        if self.preconditioner != "none":
            M = wp_linear.LinearOperator((3 * n, 3 * n), self.mat33, device, self._apply_preconditioner)
        # atol given explicitly: left as None, Warp's cg uses atol = tol, an absolute floor of
        # `tolerance` N s that would end the solve of any small step before its first iteration
        self.solver = wp_linear.cg(self.A, self.rhs, self.dv, tol=self.tolerance, atol=self.absolute_tolerance,
                                   maxiter=self.max_iterations, M=M, check_every=self.check_every, run=False)
        if device.is_cpu:
            _small_cpu_dot_tiles(self.solver, 3 * n, self.scalar, device)

    def _apply_preconditioner(self, x, y, z, alpha, beta) -> None:
        """z = alpha P x + beta y, P the block (or scalar) Jacobi inverse of A's diagonal.

        CG calls this on the same few buffers (new array views of them each solve), so each
        (x, y, z) buffer triple's launch is recorded once, keyed by the buffers' addresses,
        which stay valid as long as the solver that owns them."""
        key = (x.ptr, y.ptr, z.ptr)
        entry = self._preconditioner_launches.get(key)
        if entry is None:
            command = wp.launch(implicit_kernels.apply_blocks, self.model.particle_count,
                                [self.inverse_blocks, x, y, z, self.scalar(alpha), self.scalar(beta)],
                                device=self.model.device, record_cmd=True)
            self._preconditioner_launches[key] = (command, (x, y, z))   # the views kept alive with it
        else:
            command = entry[0]
            command.set_param_at_index(4, self.scalar(alpha))
            command.set_param_at_index(5, self.scalar(beta))
        command.launch()

    # the step --------------------------------------------------------------------
    def step(self, state_in, state_out, t, h):
        # forces and rates of every component at the start; an explicit kick of the whole
        # velocity block (the bodies' symplectic Euler kick), whose particle part is then replaced
        rates = self.kick(state_in, state_in, state_out, t, h)
        if self.model.particle_count:
            self._solve_particles(state_in, state_out, h, rates)
        self.drift(state_in, state_out, h)   # x1 = x0 + h v1 for particles; bodies as symplectic Euler

    def _solve_particles(self, state_in, state_out, h: float, rates) -> None:
        """The particles' system assembled at ``state_in`` (accelerations from ``rates``), solved for dv, and
        v1 = v0 + dv into ``state_out``. In a differentiable run the assembly and the update are taped, each step
        with triplets, right-hand side and dv of its own; the solve runs off the tape, which records its adjoint
        instead (``_solve_adjoint``)."""
        m, scalar = self.model, self.scalar
        n = m.particle_count
        if m.differentiable:
            triplets, rhs, dv = (wp.zeros_like(a, requires_grad=True) for a in (self.triplets, self.rhs, self.dv))
        else:
            triplets, rhs, dv = self.triplets, self.rhs, self.dv
        self.launch(implicit_kernels.particle_system, n,
                    [rates.particle_v, m.particle_inv_mass, scalar(h), scalar(h * m.drag_value),
                     int(self.warm_start), self.diagonal_triplets if triplets is self.triplets else triplets[:n],
                     rhs, dv])
        if m.spring_count:
            self.launch(implicit_kernels.spring_system, m.spring_count,
                        [state_in.particle_x, state_in.particle_v, m.springs, m.particle_inv_mass, scalar(h), n,
                         triplets, rhs])
        if dv is self.dv:
            self._count_solve(*self._solve(triplets))
        else:
            with paused() as tape:
                wp.copy(self.rhs, rhs)
                wp.copy(self.dv, dv)
                self._count_solve(*self._solve(triplets))
                wp.copy(dv, self.dv)
            if tape is not None:
                tape.record_func(lambda: self._solve_adjoint(triplets, rhs, dv), [triplets, rhs, dv])
        self.launch(implicit_kernels.velocity_update, n,
                    [state_in.particle_v, dv, m.particle_inv_mass, state_out.particle_v])

    def _solve(self, triplets) -> tuple:
        """A from ``triplets``, its preconditioner, and CG on A self.dv = self.rhs from self.dv: returns CG's
        (iterations, residual, absolute tolerance)."""
        m = self.model
        wp_sparse.bsr_set_from_mapped_values(self.A, self.mapping, triplets, reduction="gather")
        if self.preconditioner != "none":
            wp_sparse.bsr_get_diag(self.A, out=self.diagonal_blocks)
            self.launch(implicit_kernels.invert_blocks, m.particle_count,
                        [self.diagonal_blocks, int(self.preconditioner == "diag"), self.inverse_blocks])
        return self.solver()

    def _count_solve(self, iterations, residual, atol) -> None:
        self.last_iterations = int(iterations)
        self.last_residual = float(residual)
        self.last_tolerance = float(atol)
        self.last_converged = self.last_residual <= self.last_tolerance
        rhs_norm = self.last_tolerance / self.tolerance if self.absolute_tolerance == 0.0 else None
        relative = self.last_residual / rhs_norm if rhs_norm else 0.0
        self._count(self.last_iterations, relative)
        if not self.last_converged:
            self.unconverged_solves += 1
            self._worst_unreported = max(self._worst_unreported, relative)

    def _solve_adjoint(self, triplets, rhs, dv) -> None:
        """The adjoint of a step's solve A dv = b (a function on the tape, in its backward pass): lam = A^-1 dv_bar
        by the same CG (A is symmetric positive definite, so A^-T = A^-1; to the same tolerance, not counted in
        the stats), then b_bar += lam and, per triplet, A_bar = -lam dv^T (kernels.implicit.system_adjoint), which
        the assembly kernels' adjoints take on; dv_bar is used up (CG's result does not depend on its guess)."""
        wp.copy(self.rhs, dv.grad)
        self.dv.zero_()
        self._solve(triplets)
        wp.launch(implicit_kernels.system_adjoint, triplets.shape[0],
                  [self.dv, dv, self.triplet_rows, self.triplet_cols, self.model.particle_count, rhs.grad,
                   triplets.grad], device=self.model.device, record_tape=False)
        dv.grad.zero_()


CPU_DOT_TILE = 8


def _small_cpu_dot_tiles(solver, length: int, scalar, device) -> None:
    """Give a CG solver on the CPU dot products reduced in tiles of CPU_DOT_TILE, not Warp's 512.

    Warp 1.19 runs a tile reduction on the CPU at a cost that grows with the square of the
    tile size, so CG's default 512-wide dot products take ~40 ms for 12 000 scalars (about
    25 times a sparse matrix-vector product); 8-wide tiles make them ~0.7 ms. This replaces
    a private attribute of ``warp.optim.linear.CG`` (``_tiled_dot``, a ``TiledDot``) when it
    has the expected form, and leaves the solver as it is otherwise.
    """
    if TiledDot is None:
        return
    current = getattr(solver, "_tiled_dot", None)
    if not isinstance(current, TiledDot) or current.batch_offsets is not None or current.max_column_count != 2:
        return
    solver._tiled_dot = TiledDot(max_length=length, scalar_type=scalar, tile_size=CPU_DOT_TILE, device=device,
                                 max_column_count=2)


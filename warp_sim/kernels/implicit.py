"""Linearised backward Euler (Baraff and Witkin 1998) for particles: system assembly and the preconditioner.

The step solves A dv = b for the particles' velocity changes dv [m/s] with

    A = M + h c I - h dF/dv - h^2 dF/dx       [kg]
    b = h (F + h dF/dx v0)                     [kg m/s = N s]

where M is the lumped mass, c the scene's linear drag [N s/m], F the full force on
each particle [N] and dF/dx, dF/dv the Jacobians of the damped springs. A is stored
as a 3x3-block sparse (BSR) matrix whose values come from a triplet list of fixed
layout, summed into the blocks by ``warp.sparse.bsr_set_from_mapped_values``:

- triplet i < N: the diagonal block (M_i + h c) I of particle i, or I for a pinned one;
- triplets N + 4 s + (0, 1, 2, 3): spring s's blocks (p1, p1), (p2, p2), (p1, p2), (p2, p1),
  which are +B, +B, -B, -B with the symmetric 3x3 block

      B = h kd d d^T + h^2 ks (d d^T + max(0, 1 - L0 / L) (I - d d^T))     [kg]

  (d the unit vector from p1 to p2, L its length [m], L0 the rest length [m]).

Pinned particles (inverse mass 0: pinned, or a dead emitter slot) are eliminated: their
row and column hold the identity block and nothing else, their right-hand side and initial
guess are 0, so conjugate gradient leaves their dv at exactly 0 (and the update writes 0).

Every kernel is generic over the precision: pass float arrays and scalars of one type
(``wp.float32`` with vec3f and mat33f, or ``wp.float64`` with vec3d and mat33d).

In a differentiable run the solve's adjoint (``system_adjoint``, after the same CG on A lam = dv_bar: A is
symmetric) hands b_bar and A_bar to the adjoints of the assembly kernels, which take them to the state, the
masses and the springs' parameters.

Private: every kernel here is for the simulator's own use (the implicit Euler solver);
their arguments may change between releases. ``__all__`` is empty.
"""
from typing import Any

import warp as wp

from .precisions import register

wp.set_module_options({"enable_backward": False})  # forward simulation only: no adjoint kernels to compile

__all__ = []


@wp.kernel
def particle_system(
    a: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    h: Any,
    h_drag: Any,
    warm_start: int,
    diagonal: wp.array(dtype=Any),
    rhs: wp.array(dtype=Any),
    dv: wp.array(dtype=Any),
):
    """Per particle: the mass-and-drag diagonal block, the force part of the right-hand side, the initial guess.

    a: accelerations [m/s^2] from the Dynamics (0 for a pinned particle); inv_mass: 1/m [1/kg];
    h: step [s]; h_drag: h times the linear drag coefficient [kg]; warm_start: 1 to keep
    ``dv`` (the last step's velocity changes) as the initial guess, 0 to start from zero.
    Writes diagonal[i] = (m + h c) I [kg] (I for a pinned particle), rhs[i] = h m a [N s]
    (0 when pinned) and, for a pinned particle or without warm start, dv[i] = 0 [m/s].
    """
    i = wp.tid()
    w = inv_mass[i]
    zero = type(h)(0.0)
    one = type(h)(1.0)
    eye = wp.identity(n=3, dtype=type(h))
    if w > zero:
        diagonal[i] = (one / w + h_drag) * eye
        rhs[i] = (h / w) * a[i]
        if warm_start == 0:
            dv[i] = type(a[i])()
    else:
        diagonal[i] = eye
        rhs[i] = type(a[i])()
        dv[i] = type(a[i])()


@wp.kernel
def spring_system(
    x: wp.array(dtype=Any),
    v: wp.array(dtype=Any),
    springs: Any,
    inv_mass: wp.array(dtype=Any),
    h: Any,
    particle_count: int,
    triplets: wp.array(dtype=Any),
    rhs: wp.array(dtype=Any),
):
    """Per spring: its four blocks of A and its stiffness term h^2 dF/dx v0 of the right-hand side.

    x: positions [m]; v: velocities [m/s] at the start of the step; springs: a kernels.blocks Springs
    (pairs (p1, p2), stiffness ks [N/m], damping kd [N s/m], rest_length L0 [m]); inv_mass: 1/m [1/kg]
    (0 = pinned: that particle's blocks are eliminated); h: step [s]; particle_count N:
    the triplets of spring s start at N + 4 s. Writes triplets[N + 4 s + 0 .. 3] =
    B, B, -B, -B [kg] (the blocks touching a pinned particle are 0) and atomically adds
    to rhs [N s] of each free end h^2 (dF/dx v0): -h^2 S (v2 - v1) on p2 and +h^2 S (v2 - v1)
    on p1, with S = ks (d d^T + max(0, 1 - L0/L) (I - d d^T)) the clamped stiffness [N/m].

    The (1 - L0/L) term of a compressed spring (L < L0) is negative and would make A
    indefinite; it is clamped at 0 (Choi and Ko 2002), so A stays symmetric positive
    definite. The damper's derivative with respect to x (not symmetric) is left out, as
    in Baraff and Witkin. A spring of zero length has no direction and contributes nothing.
    """
    s = wp.tid()
    i = springs.pairs[s][0]
    j = springs.pairs[s][1]
    zero = type(h)(0.0)
    one = type(h)(1.0)
    delta = x[j] - x[i]
    length = wp.length(delta)
    eye = wp.identity(n=3, dtype=type(h))
    block = eye * zero
    base = particle_count + 4 * s
    if length > zero:
        d = delta / length
        ddt = wp.outer(d, d)
        geometric = wp.max(zero, one - springs.rest_length[s] / length)
        S = springs.stiffness[s] * (ddt + geometric * (eye - ddt))
        block = h * springs.damping[s] * ddt + h * h * S
        free_i = inv_mass[i] > zero
        free_j = inv_mass[j] > zero
        hhSdv = h * h * (S * (v[j] - v[i]))
        if free_i:
            triplets[base + 0] = block
            wp.atomic_add(rhs, i, hhSdv)
        else:
            triplets[base + 0] = eye * zero
        if free_j:
            triplets[base + 1] = block
            wp.atomic_sub(rhs, j, hhSdv)
        else:
            triplets[base + 1] = eye * zero
        if free_i and free_j:
            triplets[base + 2] = -block
            triplets[base + 3] = -block
        else:
            triplets[base + 2] = eye * zero
            triplets[base + 3] = eye * zero
    else:
        triplets[base + 0] = block
        triplets[base + 1] = block
        triplets[base + 2] = block
        triplets[base + 3] = block


@wp.kernel
def invert_blocks(diagonal: wp.array(dtype=Any), diagonal_only: int, inverse: wp.array(dtype=Any)):
    """inverse[i] = diagonal[i]^-1 [1/kg]: the blocks of the block-Jacobi preconditioner.

    diagonal: the 3x3 diagonal blocks of A [kg], symmetric positive definite (a free
    particle's holds at least its mass, a pinned one's is I); diagonal_only: 1 for the
    scalar Jacobi preconditioner (invert only the blocks' diagonal entries). A block
    that is not invertible (A never makes one) falls back to the identity.
    """
    i = wp.tid()
    block = diagonal[i]
    zero = type(block[0, 0])(0.0)
    one = type(block[0, 0])(1.0)
    eye = wp.identity(n=3, dtype=type(block[0, 0]))
    if diagonal_only != 0:
        inv = eye * zero
        for k in range(3):
            if block[k, k] != zero:
                inv[k, k] = one / block[k, k]
            else:
                inv[k, k] = one
        inverse[i] = inv
    elif wp.determinant(block) != zero:
        inverse[i] = wp.inverse(block)
    else:
        inverse[i] = eye


@wp.kernel
def apply_blocks(
    blocks: wp.array(dtype=Any),
    x: wp.array(dtype=Any),
    y: wp.array(dtype=Any),
    z: wp.array(dtype=Any),
    alpha: Any,
    beta: Any,
):
    """z[i] = alpha blocks[i] x[i] + beta y[i]: a block-diagonal operator (z may alias y or x)."""
    i = wp.tid()
    z[i] = alpha * (blocks[i] * x[i]) + beta * y[i]


@wp.kernel
def velocity_update(
    v0: wp.array(dtype=Any),
    dv: wp.array(dtype=Any),
    inv_mass: wp.array(dtype=Any),
    v1: wp.array(dtype=Any),
):
    """v1 = v0 + dv [m/s] for free particles; v1 = v0 (and dv = 0) for pinned ones (inv_mass [1/kg] 0)."""
    i = wp.tid()
    if inv_mass[i] > type(inv_mass[i])(0.0):
        v1[i] = v0[i] + dv[i]
    else:
        dv[i] = type(dv[i])()
        v1[i] = v0[i]


@wp.kernel
def system_adjoint(
    lam: wp.array(dtype=Any),
    dv: wp.array(dtype=Any),
    rows: wp.array(dtype=int),
    cols: wp.array(dtype=int),
    particle_count: int,
    rhs_grad: wp.array(dtype=Any),
    triplets_grad: wp.array(dtype=Any),
):
    """The adjoint of the solve A dv = b, given lam = A^-T dv_bar (A symmetric: the same CG): b_bar = lam and
    A_bar = -lam dv^T, that is per triplet t at block (rows[t], cols[t]) the 3x3 -lam[row] dv[col]^T [1/kg ...]
    added into triplets_grad[t], and lam[i] added into rhs_grad[i] for each particle i (the triplets' first
    ``particle_count`` are the diagonal's, rows[i] = i). Launch with dim = the number of triplets."""
    t = wp.tid()
    triplets_grad[t] = triplets_grad[t] - wp.outer(lam[rows[t]], dv[cols[t]])
    if t < particle_count:
        rhs_grad[t] = rhs_grad[t] + lam[t]


register(globals(), y="vec3", z="vec3", lam="vec3", rhs_grad="vec3", triplets_grad="mat33")

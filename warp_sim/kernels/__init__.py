"""Warp kernels, one file per topic; each file is one Warp module.

Warp compiles and loads per module, so a scene that never launches a topic's
kernels never compiles that topic. Every kernel is generic over precision: pass
all float arrays and scalars of one precision (``wp.float32`` with ``wp.vec3f``
or ``wp.float64`` with ``wp.vec3d``). Units are SI throughout.

Topics:
- ``integrate``: element-wise combinations of flat state buffers (the ODE solvers' arithmetic)
- ``particles``: the particle derivative (gravity, drag, wind, accumulated forces)
- ``springs``: the damped Hooke spring forces
- ``fields``: force fields on particles (point attractors, vortices, curl-noise turbulence)
- ``emitters``: particle births into pools, ageing, deaths and attributes over life
- ``cloth``: aerodynamic drag and lift on triangles, Provot strain limiting
- ``blocks`` (no kernels): the argument structs many kernels share, one set per precision
- ``implicit``: the spring Jacobians and solves of the implicit Euler step
- ``rigid``: rigid-body rates (x, q, P, L), orientation renormalisation, impulses, derived v, omega and R
- ``planes``: particle-plane contacts, the time-of-impact impulse response
- ``penalty``: penalty contacts (one damping model): particles on planes, bodies on bodies, colliders, planes
- ``geometry``: signed distances of every shape, segment and polygon helpers (functions only)
- ``detection``: body collision shapes on the device, hash-grid broad phase, narrow phase
- ``contacts``: body contact response (time of impact, impulses, friction, warm starting, projection)
- ``impulses`` (no kernels): one contact's impulse and projection updates on values, which ``contacts`` and
  ``contact_adjoint`` share
- ``contact_adjoint``: the body contact response as launches a wp.Tape can take back (a differentiable run's)
- ``manifolds``: contacts grouped by pair, and the pairs coloured for the parallel Gauss-Seidel solve
- ``particle_shapes``: particles pushed by bodies and static colliders
- ``joints``: joint rows (points, axes, limits, PD drives, cones, distances), warm start, position projection, breaks
- ``joint_frames`` (no kernels): a joint's sides, angles, limit and drive rows and pushes on values, which
  ``joints`` and ``joint_adjoint`` share
- ``joint_adjoint``: the joint solve as launches a wp.Tape can take back (a differentiable run's)
- ``precisions`` (no kernels): registers each module's generic kernels at import; declares their overloads
  for the precision in use (a Model calls ``declare``)
- ``guards``: detection of non-finite or runaway states
"""

#: seconds each module takes to compile cold, its thread's precompiled header already built (about 1.6 s more on
#: a thread's first module): float64, one core of a 2-core AMD EPYC, ``python benchmarks/startup.py --modules``.
#: Simulator compiles a simulation's modules the longest first, so that no core is left alone with a long one at
#: the end (sizes of the Python sources mislead: particle_shapes is small and compiles the shapes' distances).
COMPILE_SECONDS = {
    "joint_adjoint": 6.44, "joints": 4.53, "contact_adjoint": 4.16, "detection": 3.64, "contacts": 3.27,
    "particle_shapes": 2.56, "fields": 1.27, "emitters": 0.98, "rigid": 0.83, "planes": 0.71, "manifolds": 0.64,
    "fused": 0.52, "integrate": 0.51, "implicit": 0.48, "penalty": 0.47, "cloth": 0.36, "guards": 0.26,
    "springs": 0.22, "particles": 0.13,
}
#: contact_adjoint and joint_adjoint are built only with their adjoints (a differentiable run: compiling.ADJOINT_FACTOR
#: times the entry): 9.56 s and 14.81 s cold with them, 2.31 s and 2.76 s without, float64, one core of a shared
#: 2-core machine (a single cold compile each)

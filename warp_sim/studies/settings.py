"""The studies' settings: step counts, tolerances, bisection and growth criteria (read by the studies, their
reports and their plots)."""
from __future__ import annotations

import math

# the accuracy study -------------------------------------------------------------------------------------------
REFINE, QUICK_REFINE = 4, 2   # reference runs: rk4 at the finest step / REFINE
#: solvers whose step costs about 20x an explicit one (a CG solve): their step counts are halved until the
#: finest is at most COSTLY_STEPS (full) or QUICK_COSTLY_STEPS (quick)
COSTLY_STEPS, QUICK_COSTLY_STEPS = 1024, 256
TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
QUICK_TOLERANCES = (1e-3, 1e-5, 1e-7)
ATOL_PER_RTOL = 1e-2           # adaptive runs: atol = rtol x 0.01 (in the state's SI units)
ADAPTIVE_CALLS = 10            # adaptive runs: Simulator.step calls per run (each to an exact time)
UNTIMED = 2                    # the first steps (calls) of a run record the launches of both state buffers
REPEAT_SECONDS, QUICK_REPEAT_SECONDS = 1.0, 0.05   # a point stops repeating once its runs took this long [s]
FLOOR, CEILING = 1e-12, 0.1    # errors outside (FLOOR, CEILING) are rounding or not asymptotic
TARGETS = (1e-2, 1e-4, 1e-6, 1e-8)


# the stability study ------------------------------------------------------------------------------------------
GROWTH = 2.0            # unstable: the second half's largest size > GROWTH x the first half's
BLOWUP = 1e4            # or any size > BLOWUP x the initial one (so fast it could saturate in the first half)
STEPS, QUICK_STEPS = 2000, 300          # steps per run of a case without a duration
MAX_STEPS, QUICK_MAX_STEPS = 20000, 5000   # the most steps a run of a case with a duration may take
COSTLY_DIVISOR = 16     # COSTLY solvers run 16x fewer steps per run (their h range shrinks accordingly)
BISECTIONS, QUICK_BISECTIONS = 9, 8     # final bracket 4^(1/512) (0.27 %) and 4^(1/256) (0.54 %)
H_MAX = 100.0           # the search stops at h_max = H_MAX / omega (or the case's own h_max)
SAMPLES = 200           # size samples per run of a case with a duration (every step without one)
DAMPING_STEPS = (0.1, 1.0, 10.0, 100.0)   # omega h at which implicit Euler's numerical damping is measured
#: theory for an undamped linear oscillator: the largest stable omega h (None: no limit, it grows at any step)
THEORY = {"euler": None, "midpoint": None, "rk4": 2.0 * math.sqrt(2.0), "symplectic_euler": 2.0, "verlet": 2.0,
          "implicit_euler": math.inf}

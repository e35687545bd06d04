

def test_frame_rate_stack_limit_is_above_the_default_contact_step():
    """The stability study's stack of ten, under symplectic Euler without sub-steps: it stands (no box moves 5 mm
    in 10 s) up to a step above 1/120 s, the Simulator's default contact_step (measured: 0.0107 s), and falls
    within the search (the bisection brackets the limit to 1 %)."""
    result = studies.stability(cases=["stack_10"], integrators=["symplectic_euler"], quick=True)
    row = result.rows[0]
    assert row["limit"] > 1.0 / 120.0
    assert row["unstable"] < 0.25 and row["unstable"] / row["limit"] < 1.01

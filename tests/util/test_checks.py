"""util/checks.py: arrays that are not real numbers are named with the argument and what is valid, never numpy's
own message ("setting an array element with a sequence", "inhomogeneous shape"), and complex numbers are refused,
not cast to their real parts."""
import numpy as np
import pytest

import warp_sim as ws
from warp_sim.util import checks


@pytest.mark.parametrize("value, words", [
    ([[0, 0, 0], [1, 2]], "its rows have different lengths (a ragged list)"),
    ([[0, [1, 2], 0]], "its rows have different lengths (a ragged list)"),
    ([[1 + 2j, 0, 0]], "complex numbers have no place here"),
    (np.array([[1 + 2j, 0, 0]]), "complex numbers have no place here"),
    (np.array([[1 + 0j, 0, 0]]), "complex numbers have no place here"),
    ([[None, 0, 0]], "an entry is None, not a number"),
    ([[0, 0, "a"]], "not booleans or text"),
    (np.array([[1, 2, 3]], dtype="datetime64[s]"), "not datetime64[s]"),
    ({"x": 1}, "expected real numbers in an array of shape (N, 3)"),
    ([1, 2, 3], "expected shape (N, 3), got (3,)"),
    ([[0, 0, np.inf]], "every entry must be finite; entry (0, 2) is inf"),
])
def test_positions_that_are_not_real_numbers_are_named(value, words):
    with pytest.raises(ValueError) as caught:
        ws.Scene().add_particles(value)
    text = str(caught.value)
    assert text.startswith("positions=") and words in text and "\n" not in text, text
    assert "inhomogeneous" not in text and "setting an array element" not in text


def test_a_one_dimensional_entry_is_a_plain_index():
    with pytest.raises(ValueError, match=r"entry 1 is nan"):
        checks.finite_array("times", [0.0, np.nan], (-1,))


def test_a_matrix_is_shown_on_one_line():
    assert "\n" not in str(checks.fail("inertia", np.eye(3), "anything"))

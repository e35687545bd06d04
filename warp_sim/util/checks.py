"""Input validation: every bad value raises ValueError naming the argument, the value and what is valid."""
from __future__ import annotations

import math
import warnings

import numpy as np


def _show(value) -> str:
    """The value as a user would type it: plain numbers (0, not np.int64(0)), arrays abbreviated."""
    if isinstance(value, np.generic):
        value = value.item()
    try:
        text = np.array2string(np.asarray(value), threshold=6, edgeitems=2) if np.ndim(value) else repr(value)
    except ValueError:   # ragged: not an array
        text = repr(value)
    text = " ".join(text.split())   # one line: a matrix's rows side by side
    return text if len(text) <= 120 else text[:117] + "..."


#: the largest magnitude each precision holds
LARGEST = {"float32": float(np.finfo(np.float32).max), "float64": float(np.finfo(np.float64).max)}


def fits(name: str, array, precision: str, given=None, derived: str | None = None) -> np.ndarray:
    """``array`` (numbers), refused when an entry does not fit the scene's precision (float32 ends at 3.4e38).

    given: the argument as the user gave it, shown in the error (default ``array``); derived: what ``array`` is
    when it is computed from the argument (``"1/mass"``, ``"stiffness/mass"``), named in the error."""
    values = np.asarray(array, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        bad = np.argwhere(~(np.abs(values) <= LARGEST[precision]))
    if len(bad):
        where = tuple(int(j) for j in bad[0])
        at = where[0] if len(where) == 1 else where
        if derived is None:
            shown = f"entry {at}" if values.ndim else "it"
        else:
            shown = f"{derived}[{', '.join(str(j) for j in where)}]" if values.ndim else derived
        raise fail(name, array if given is None else given,
                   f"{shown} is {values[where]:g}, which does not fit the scene's precision {precision} (largest "
                   f"{LARGEST[precision]:.3g})" + ("" if precision == "float64" else "; or use precision float64"))
    return values


def reciprocal_fits(name: str, array, precision: str, given=None, derived: str | None = None) -> np.ndarray:
    """``array`` (numbers > 0), refused when the reciprocal of an entry does not fit the precision (a mass of
    1e-300 kg: 1/m = 1e300 is infinite in float32); ``derived`` names the reciprocal (default ``"1/<name>"``)."""
    values = np.asarray(array, dtype=np.float64)
    with np.errstate(divide="ignore", over="ignore"):
        inverse = np.where(values > 0.0, 1.0 / np.where(values > 0.0, values, 1.0), 0.0)
    fits(name, inverse, precision, given=array if given is None else given, derived=derived or f"1/{name}")
    return values


def fail(name: str, value, valid: str) -> ValueError:
    """The ValueError for argument `name` holding `value`, saying what would be valid."""
    return ValueError(f"{name}={_show(value)} is invalid: {valid}")


def _as_numbers(name: str, value, what: str) -> np.ndarray:
    """``value`` as a float64 array, or the ValueError saying why it is not real numbers (text, booleans, a ragged
    list, complex numbers, None, dates)."""
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise fail(name, value, f"{what}, not booleans or text")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):   # numpy refuses a ragged list
        raise fail(name, value, f"{what}; its rows have different lengths (a ragged list)") from None
    if raw.dtype.kind == "O":
        flat = list(raw.flat)
        if any(item is None for item in flat):
            raise fail(name, value, f"{what}; an entry is None, not a number")
        if any(isinstance(item, (list, tuple, np.ndarray)) for item in flat):
            raise fail(name, value, f"{what}; its rows have different lengths (a ragged list)")
        if any(isinstance(item, (complex, np.complexfloating)) for item in flat):
            raise fail(name, value, f"{what}; complex numbers have no place here (real numbers only)")
    kind = raw.dtype.kind
    if kind in "bUS":
        raise fail(name, value, f"{what}, not booleans or text")
    if kind == "c":
        raise fail(name, value, f"{what}; complex numbers have no place here (real numbers only)")
    if kind in "mMV":
        raise fail(name, value, f"{what}, not {raw.dtype}")
    try:
        return np.array(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise fail(name, value, what) from None


def finite_array(name: str, value, shape: tuple) -> np.ndarray:
    """A float64 copy of `value` with the given shape (-1 = any length), all finite."""
    shown = tuple("N" if s == -1 else s for s in shape)
    shown = f"({shown[0]},)" if len(shown) == 1 else "(" + ", ".join(str(s) for s in shown) + ")"
    array = _as_numbers(name, value, f"expected real numbers in an array of shape {shown}")
    if array.ndim != len(shape) or any(s != -1 and s != n for s, n in zip(shape, array.shape)):
        raise fail(name, value, f"expected shape {shown}, got {array.shape}")
    bad = np.argwhere(~np.isfinite(array))
    if len(bad):
        where = tuple(int(j) for j in bad[0])
        raise fail(name, value, f"every entry must be finite; entry {where[0] if len(where) == 1 else where} is "
                                f"{array[where]}")
    return array


def unit_interval(name: str, value, shape: tuple) -> np.ndarray:
    """finite_array(name, value, shape) with every entry in [0, 1] (a colour or an opacity)."""
    array = finite_array(name, value, shape)
    bad = np.argwhere((array < 0.0) | (array > 1.0))
    if len(bad):
        where = tuple(int(j) for j in bad[0])
        raise fail(name, value, f"every entry must lie in [0, 1]; entry {where} is {array[where]:g}")
    return array


def vec3(name: str, value) -> np.ndarray:
    """A finite 3-vector."""
    return finite_array(name, value, (3,))


def unit_vec3(name: str, value) -> np.ndarray:
    """A finite non-zero 3-vector, normalised."""
    vector = vec3(name, value)
    length = float(np.linalg.norm(vector))
    if length == 0.0:
        raise fail(name, value, "a direction must be non-zero")
    return vector / length


def scalar(name: str, value, low: float | None = None, high: float | None = None,
           low_open: bool = False) -> float:
    """A finite real number in [low, high] (or (low, high] with low_open): not a bool, not a string."""
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise fail(name, value, "expected a real number")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise fail(name, value, "expected a real number") from None
    if not math.isfinite(number):
        raise fail(name, value, "must be finite")
    if low is not None and (number < low or (low_open and number == low)):
        above = f"must be {'>' if low_open else '>='} {low}"
        raise fail(name, value, above + (f" and <= {high}" if high is not None else ""))
    if high is not None and number > high:
        below = f"must be <= {high}"
        raise fail(name, value, below + (f" and {'>' if low_open else '>='} {low}" if low is not None else ""))
    return number


def per_element(name: str, value, count: int, low: float, low_open: bool = False) -> np.ndarray:
    """A scalar or a length-`count` array, finite and >= low (> low with low_open), as a float64 array."""
    if np.ndim(value) == 0:
        return np.full(count, scalar(name, value, low=low, low_open=low_open))
    array = finite_array(name, value, (count,))
    bad = np.flatnonzero(array <= low if low_open else array < low)
    if len(bad):
        bound = f"{'>' if low_open else '>='} {low}"
        raise fail(name, value, f"every entry must be {bound}; entry {bad[0]} is {array[bad[0]]}")
    return array


def indices(name: str, value, count: int, shape: tuple) -> np.ndarray:
    """Integer indices in [0, count) with the given shape, as int64."""
    array = np.asarray(value)
    if array.size == 0:
        array = array.reshape([0 if s == -1 else s for s in shape])
    if not (np.issubdtype(array.dtype, np.integer) or array.size == 0):
        whole = np.issubdtype(array.dtype, np.floating) and np.all(np.isfinite(array))
        if not whole or np.any(array != np.round(array)):
            raise fail(name, value, "expected integer indices")
    array = array.astype(np.int64)
    if array.ndim != len(shape) or any(s != -1 and s != n for s, n in zip(shape, array.shape)):
        shown = tuple("K" if s == -1 else s for s in shape)
        raise fail(name, value, f"expected shape {shown}, got {array.shape}")
    bad = np.argwhere((array < 0) | (array >= count))
    if len(bad):
        where = tuple(int(j) for j in bad[0])
        raise fail(name, value, f"indices must lie in [0, {count}); entry {where} is {array[where]}")
    return array


def count(name: str, value, low: int = 1) -> int:
    """A whole number >= low: a Python or numpy integer, not a bool and not a float."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise fail(name, value, f"expected an integer >= {low}")
    return int(value)


def substeps(name: str, value):
    """A substep setting: "auto" (chosen from the scene's stability), or a whole number >= 1."""
    if isinstance(value, str) and value == "auto":
        return value
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise fail(name, value, "expected 'auto' or an integer >= 1")
    return int(value)


def choice(name: str, value, options) -> str:
    """One of the named options."""
    if value not in options:
        raise fail(name, value, f"expected one of {', '.join(repr(o) for o in options)}")
    return value


def unit_quaternion(name: str, value) -> np.ndarray:
    """A finite non-zero quaternion (x, y, z, w), normalised.

    A norm off 1 by more than 1e-6 is normalised with a UserWarning naming the
    argument (typed-in values such as 0.7071 are common); zero is rejected.
    """
    q = finite_array(name, value, (4,))
    norm = float(np.linalg.norm(q))
    if norm == 0.0:
        raise fail(name, value, "a rotation quaternion (x, y, z, w) must be non-zero, e.g. (0, 0, 0, 1)")
    if abs(norm - 1.0) > 1e-6:
        warnings.warn(f"{name}={_show(value)} has norm {norm:.9g}; normalised to a unit quaternion", stacklevel=3)
    return q / norm

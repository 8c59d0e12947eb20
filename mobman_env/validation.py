"""One home for checking user-given numbers (every package validates scalars through these functions) and the
names of folders it creates from user-given text (`folder_name`).

Rules (the same everywhere, so the messages read alike):

* `bool` is never a number (`obs_noise=True` would otherwise be 1 m of noise), nor is a string, even a numeric
  one (`"0.5"`), nor a complex number: they are refused, not converted.
* Python and numpy integers and floats are accepted; the value must be finite.
* Bounds are inclusive unless named in `open_low` / `open_high`; the message names the value, the accepted
  range and, where given, how to fix it.

`number()` returns a `float`, `integer()` an `int`, `vector()` a float64 array of real numbers under the same
rules. `folder_name()` returns a name that is one plain path component (no separator, not `.` or `..`, no NUL),
so that `parent / name` stays inside `parent`. All raise `ValueError` (or the `error` class given, which must accept one message argument: eval passes
its `EvalError`).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["folder_name", "integer", "number", "vector"]


def _range_text(low: float | None, high: float | None, open_low: bool, open_high: bool) -> str:
    def shown(v: float) -> str:
        return str(v) if isinstance(v, int) else f"{v:g}"

    parts = []
    if low is not None:
        parts.append(f"{'>' if open_low else '>='} {shown(low)}")
    if high is not None:
        parts.append(f"{'<' if open_high else '<='} {shown(high)}")
    return " and ".join(parts)


def _plain(value: Any) -> Any:
    """numpy scalars and arrays as plain Python values, so messages never read `np.float64(...)`."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if hasattr(value, "item") and hasattr(value, "dtype"):
        return value.item()
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    return value


def _fail(error: type[Exception], name: str, what: str, value: Any, hint: str) -> Exception:
    shown = repr(_plain(value))
    return error(f"{name} must be {what}, got {shown}" + (f" ({hint})" if hint else ""))


def number(
    name: str,
    value: Any,
    *,
    low: float | None = None,
    high: float | None = None,
    open_low: bool = False,
    open_high: bool = False,
    hint: str = "",
    error: type[Exception] = ValueError,
) -> float:
    """Return `value` as a float if it is a finite real number within the bounds; else raise `error`.
    (The message is built only on failure: hot paths, such as the wear drift's `RobotParams.scaled` every step,
    check numbers too.)"""
    if type(value) is float or (not isinstance(value, bool) and isinstance(value, numbers.Real)):
        v = float(value)
        if (
            math.isfinite(v)
            and (low is None or (v > low if open_low else v >= low))
            and (high is None or (v < high if open_high else v <= high))
        ):
            return v
    bounds = _range_text(low, high, open_low, open_high)
    raise _fail(error, name, "a finite number" + (f" {bounds}" if bounds else ""), value, hint)


def integer(
    name: str,
    value: Any,
    *,
    low: int | None = None,
    high: int | None = None,
    hint: str = "",
    error: type[Exception] = ValueError,
) -> int:
    """Return `value` as an int if it is an integer (Python or numpy, not bool) within the bounds."""
    bounds = _range_text(low, high, False, False)
    what = "an integer" + (f" {bounds}" if bounds else "")
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise _fail(error, name, what, value, hint)
    v = int(value)
    if (low is not None and v < low) or (high is not None and v > high):
        raise _fail(error, name, what, value, hint)
    return v


def _in_range(v: Any, low: float | None, high: float | None) -> bool:
    if isinstance(v, bool) or not isinstance(v, numbers.Real):
        return False
    x = float(v)
    return math.isfinite(x) and (low is None or x >= low) and (high is None or x <= high)


def vector(
    name: str,
    value: Any,
    *,
    sizes: Sequence[int],
    low: float | None = None,
    high: float | None = None,
    hint: str = "",
    error: type[Exception] = ValueError,
) -> np.ndarray:
    """Return `value` as a float64 array if it is a flat list, tuple or 1-D array whose length is one of `sizes`
    and whose every entry is a finite real number within the (inclusive) bounds; else raise `error`.

    Entries follow `number()`'s rules: bools, strings and complex numbers are refused, also inside numpy arrays.
    """
    bounds = _range_text(low, high, False, False)
    what = f"{' or '.join(str(n) for n in sizes)} finite numbers" + (f" {bounds}" if bounds else "")
    if isinstance(value, np.ndarray):
        items = value.tolist() if value.ndim == 1 and value.dtype.kind in "iuf" else None
    elif isinstance(value, (list, tuple)):
        items = list(value)
    else:
        items = None
    if items is None or len(items) not in sizes or not all(_in_range(v, low, high) for v in items):
        raise _fail(error, name, what, value, hint)
    return np.array(items, dtype=float)


def folder_name(name: str, value: Any, *, hint: str = "", error: type[Exception] = ValueError) -> str:
    """`value` if it is a plain folder name (one path component: not empty, not `.` or `..`, without `/`, `\\`
    or NUL), else `error` naming it, what is accepted and `hint`."""
    if (
        not isinstance(value, str)
        or value in ("", ".", "..")
        or any(c in value for c in "/\\\0")
        or value != value.strip()
    ):
        raise _fail(
            error, name, "a plain name (one path component: no '/', '\\', '..' or surrounding spaces)", value, hint
        )
    return value

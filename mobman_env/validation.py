"""One home for checking user-given numbers: every package validates scalars through these two functions.

Rules (the same everywhere, so the messages read alike):

* `bool` is never a number (`obs_noise=True` would otherwise be 1 m of noise), nor is a string, even a numeric
  one (`"0.5"`), nor a complex number: they are refused, not converted.
* Python and numpy integers and floats are accepted; the value must be finite.
* Bounds are inclusive unless named in `open_low` / `open_high`; the message names the value, the accepted
  range and, where given, how to fix it.

`number()` returns a `float`, `integer()` an `int`. Both raise `ValueError` (or the `error` class given, which
must accept one message argument: eval passes its `EvalError`).
"""

from __future__ import annotations

import math
import numbers
from typing import Any

__all__ = ["integer", "number"]


def _range_text(low: float | None, high: float | None, open_low: bool, open_high: bool) -> str:
    parts = []
    if low is not None:
        parts.append(f"{'>' if open_low else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if open_high else '<='} {high:g}")
    return " and ".join(parts)


def _fail(error: type[Exception], name: str, what: str, value: Any, hint: str) -> Exception:
    shown = repr(value.item()) if hasattr(value, "item") and hasattr(value, "dtype") else repr(value)
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
    """Return `value` as a float if it is a finite real number within the bounds; else raise `error`."""
    bounds = _range_text(low, high, open_low, open_high)
    what = "a finite number" + (f" {bounds}" if bounds else "")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise _fail(error, name, what, value, hint)
    v = float(value)
    if not math.isfinite(v):
        raise _fail(error, name, what, value, hint)
    if low is not None and (v <= low if open_low else v < low):
        raise _fail(error, name, what, value, hint)
    if high is not None and (v >= high if open_high else v > high):
        raise _fail(error, name, what, value, hint)
    return v


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

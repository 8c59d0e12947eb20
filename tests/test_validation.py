"""The one number validator every package uses: bools, strings and complex numbers are refused, bounds named."""

import math

import numpy as np
import pytest

from mobman_env.validation import integer, number


@pytest.mark.parametrize("value", [True, False, "0.5", 1 + 2j, None, [1.0], math.nan, math.inf, -math.inf])
def test_number_refuses_non_numbers_and_non_finite(value):
    with pytest.raises(ValueError, match=r"obs_noise must be a finite number >= 0, got .* \(metres\)"):
        number("obs_noise", value, low=0.0, hint="metres")


@pytest.mark.parametrize(
    ("value", "expected"), [(0, 0.0), (2, 2.0), (0.25, 0.25), (np.float32(0.5), 0.5), (np.int64(3), 3.0)]
)
def test_number_accepts_real_numbers_and_returns_float(value, expected):
    out = number("x", value, low=0.0)
    assert out == expected and type(out) is float


def test_number_bounds_inclusive_and_open():
    assert number("x", 1.0, low=1.0, high=1.0) == 1.0
    with pytest.raises(ValueError, match=r"x must be a finite number > 0 and < 1, got 0.0"):
        number("x", 0.0, low=0.0, high=1.0, open_low=True, open_high=True)
    with pytest.raises(ValueError, match=r"< 1, got 1.0"):
        number("x", 1.0, low=0.0, high=1.0, open_high=True)
    with pytest.raises(ValueError, match=r"<= 2, got 2.5"):
        number("x", 2.5, high=2.0)


def test_numpy_values_are_shown_plainly():
    with pytest.raises(ValueError, match=r"got -1.5$") as exc:
        number("q", np.float64(-1.5), low=0.0)
    assert "np.float64" not in str(exc.value)


def test_integer():
    assert integer("n", np.int64(4), low=1) == 4 and type(integer("n", 4)) is int
    for bad in (True, 2.0, "3", 1.5):
        with pytest.raises(ValueError, match="n must be an integer >= 1"):
            integer("n", bad, low=1)
    with pytest.raises(ValueError, match=r"n_terms must be an integer >= 1 and <= 64, got 10000000 \(fewer terms\)"):
        integer("n_terms", 10**7, low=1, high=64, hint="fewer terms")


def test_custom_error_class():
    class MyError(ValueError):
        pass

    with pytest.raises(MyError):
        number("x", "a", error=MyError)

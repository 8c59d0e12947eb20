"""Chaotic controllers are printed with the precision they have: eval.precision's table, its formatting, and
the measurement (eval.bench.chaos) that the table records."""

import pytest

from eval.bench import chaos
from eval.output import precision as P


@pytest.mark.parametrize(
    "x, spec, expected",
    [
        (0.1614, "nnbc", "~200"),  # one significant digit, marked
        (0.000397, "nnbc-full", "~0.4"),
        (0.0123, "nnbc:gamma=10", "~10"),  # a spec with keys is still that policy
        (0.01234, "oracle:gamma=10", "12"),  # the paper's oracle: two digits (a spec's own entry)
        (0.00456, "oracle:gamma=10", "4.6"),
        (0.01234, "oracle", "12.34"),  # the default-gain oracle: regular
        (0.0123, "broyden", "~10"),
        (0.000397, "nnbc-plus", "0.40"),  # measured regular: the normal two decimals
        (0.0567, "mine:Policy", "56.70"),  # not measured: the normal precision
        (None, "nnbc", "-"),
        (float("nan"), "jmpi", "-"),
    ],
)
def test_format_mm(x, spec, expected):
    assert P.format_mm(x, spec) == expected


def test_chaotic_set_is_the_one_digit_policies():
    assert {"nnbc", "nnbc-full", "broyden", "rls"} == P.CHAOTIC
    assert P.is_chaotic("nnbc:gamma=20") and not P.is_chaotic("nnbc-plus")
    assert P.significant_digits("sb3:runs/x/model.zip") is None


def test_digits_from_spreads():
    assert chaos.digits([0.3, 2.5]) == 1
    assert chaos.digits([8e-3, 1e-9]) == 2
    assert chaos.digits([1e-12]) == 4
    assert chaos.digits([0.0]) == 4
    assert chaos.digits([float("inf")]) == 1


@pytest.mark.slow
def test_nnbc_is_chaotic_and_jmpi_is_not():
    # the measurement behind SIGNIFICANT_DIGITS, on three development seeds of one task (about 5 s)
    env = ("WheeledPuma-Circle-v0",)
    nnbc = chaos.measure("nnbc", env, seeds=range(3))
    jmpi = chaos.measure("jmpi", env, seeds=range(3))
    assert max(nnbc) > 0.1  # a 1e-12 rad change moves the max error by more than 10%
    assert max(jmpi) < 1e-8
    assert chaos.digits(nnbc) == P.SIGNIFICANT_DIGITS["nnbc"]
    assert chaos.digits(jmpi) == P.SIGNIFICANT_DIGITS["jmpi"]

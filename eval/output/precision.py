"""How many significant digits a policy's results have, and number formatting that prints no more than that.

Some controllers are chaotic: a change far below any physical meaning moves their results by a large factor,
so their figures have at most one significant digit, whatever the seed count. `SIGNIFICANT_DIGITS` records, per
built-in policy name, how many significant digits its per-episode max tracking error keeps under such a change;
Markdown and console tables format every error of that policy with that many significant digits (chaotic ones
also get a "~" and a footnote), the others with their normal fixed precision.

How it was measured (`eval.bench.chaos.measure`, rerun it when a controller changes): the same episodes twice,
the second with the initial angle of joint 1 moved by 1e-12 rad (env argument `arm_joint_pos`), kinematic
dynamics, default 5% wear, the four WheeledPuma tasks, development seeds 0-9 (40 episode pairs per policy). The
spread is the largest relative change of the max error |e' - e| / e over the pairs; digits = floor(-log10(spread))
clipped to [1, 4]. Measured on a 2-core x86-64 machine (OpenBLAS 0.3.31, SkylakeX kernel): the first block at
commit 2bb11a9 (gamma 10 for the oracles), the second at 626b74f (release 0.2 baselines, default gains 20):

| policy | largest relative change | median | digits |
|---|---|---|---|
| `nnbc` | 4.7 (Lemniscate; Circle 2.5, Random 1.5, Line 0.19) | 0.24 | 1 (chaotic) |
| `nnbc-full` | 8.1 (Circle; Lemniscate 3.5, Line 2.4, Random 1.2) | 0.37 | 1 (chaotic) |
| `oracle:gamma=10` (the paper's gain) | 8.0e-3 (one Line seed: joint limits; other tasks <= 2.6e-6) | 1.7e-11 | 2 |
| `oracle-full` (gamma 10) | 1.1e-5 | 1.2e-9 | 4 |
| `nnbc-plus` | 2.0e-6 | 0 | 4 |
| `jmpi` | 7.9e-12 | 1.0e-12 | 4 |
| `jmpi-full` | 1.5e-9 | 4.1e-12 | 4 |
| `zero`, `random` | 5.2e-13 (Circle only, seeds 0-9) | | 4 |
| `nnbc` (626b74f) | 4.6 | 0.29 | 1 (chaotic) |
| `broyden` | 9.6 | 0.47 | 1 (chaotic) |
| `rls` | 1.0 (one pair of 40; the others <= 1e-5) | 2.3e-6 | 1 (chaotic in some episodes) |
| `oracle` (gamma 20) | 4.9e-5 | 1.2e-11 | 4 |
| `clik` | 8.8e-7 | 1.1e-11 | 4 |
| `clik-full` | 1.7e-6 | 1.4e-10 | 4 |
| `qp` | 2.7e-6 | 3.8e-8 | 4 |
| `qp-oracle` | 8.5e-5 | 1.4e-7 | 4 |
| `nnbc-plus` (626b74f) | 2.2e-6 | 0 | 4 |
| `calib-qp` (6b8f08d) | 8.2e-5 (Circle; Line 5.0e-6) | 1.1e-7 | 4 |
| `mpc` (issue 36, branch mpc) | 1.5e-4 | 5.0e-6 | 3 |
| `mpc-oracle` (issue 36, branch mpc; its errors are ~0.006 mm, so 1e-3 is ~6e-9 m) | 1.0e-3 | 8.9e-5 | 2 |

The median max error of `nnbc` over the first 40 episodes moved from 161 mm to 321 mm under this change.
An entry may be a whole spec (`oracle:gamma=10`), looked up before the policy's name.

A policy without an entry (the user's, SB3 agents, controllers added later) is printed with the normal precision
until it is measured: absence is not a claim that it is not chaotic.

Imports: the standard library only.
"""

from __future__ import annotations

import math

#: Significant digits of the per-episode max error of each built-in policy (see the module docstring).
SIGNIFICANT_DIGITS: dict[str, int] = {
    "nnbc": 1,
    "nnbc-full": 1,
    "broyden": 1,
    "rls": 1,
    "oracle:gamma=10": 2,
    "oracle": 4,
    "oracle-full": 4,
    "clik": 4,
    "clik-full": 4,
    "qp": 4,
    "qp-oracle": 4,
    "calib-qp": 4,
    "mpc": 3,
    "mpc-oracle": 2,
    "nnbc-plus": 4,
    "jmpi": 4,
    "jmpi-full": 4,
    "zero": 4,
    "random": 4,
}

#: Digits at and above which a policy counts as regular: printed with the normal fixed precision (the
#: measurement caps digits here; 1e-4 relative is below every other uncertainty of a 20-seed result).
REGULAR_DIGITS = 4

#: Policies whose results have one significant digit at most: printed with "~" and a footnote.
CHAOTIC: frozenset[str] = frozenset(name for name, d in SIGNIFICANT_DIGITS.items() if d <= 1)

#: The footnote tables add when they print a chaotic policy.
CHAOTIC_NOTE = (
    "~ chaotic controller: a 1e-12 rad change of the initial arm pose moves its per-episode max error by up "
    "to a factor of several (eval.output.precision), so its figures have one significant digit"
)


def policy_name(spec: str) -> str:
    """The registry name of a spec (`nnbc:gamma=10` -> `nnbc`); other forms are returned unchanged."""
    name, _, rest = str(spec).partition(":")
    return name if rest and "=" in rest else str(spec)


def significant_digits(spec: str) -> int | None:
    """Measured significant digits of the policy's results (the spec's own entry, else its name's); None when
    it has not been measured."""
    spec = str(spec)
    return SIGNIFICANT_DIGITS.get(spec, SIGNIFICANT_DIGITS.get(policy_name(spec)))


def is_chaotic(spec: str) -> bool:
    digits = significant_digits(spec)
    return digits is not None and digits <= 1


def format_value(x: float | None, spec: str, decimals: int = 2, scale: float = 1.0) -> str:
    """`x * scale` with `decimals` decimals, or fewer when the policy's results have fewer (< REGULAR_DIGITS)
    significant digits
    (then rounded to them: 0.1614 m as mm with one digit -> "~200"); "-" for None or non-finite values.
    Chaotic policies get a leading "~"."""
    if x is None or not math.isfinite(x):
        return "-"
    v = x * scale
    digits = significant_digits(spec)
    chaotic = is_chaotic(spec)
    if digits is None or digits >= REGULAR_DIGITS or v == 0:
        return f"{v:.{decimals}f}"
    exponent = math.floor(math.log10(abs(v)))
    places = digits - 1 - exponent  # decimals that hold `digits` significant digits
    if places >= decimals:
        text = f"{v:.{decimals}f}"
    elif places >= 0:
        text = f"{round(v, places):.{places}f}"
    else:
        text = f"{round(v, places):.0f}"
    return ("~" if chaotic else "") + text


def format_mm(x_m: float | None, spec: str, decimals: int = 2) -> str:
    """A length in m printed in mm by `format_value`."""
    return format_value(x_m, spec, decimals, 1e3)

"""`python -m mobman_env.robots COMMAND`: regenerate the figures quoted in this package's docstrings.

| command | prints | quoted in |
|---|---|---|
| `table` | the starts table (reach, circle ratios, sigma_min, DLS tracking) | `mobman_env.robots.starts` |
| `select` | the start search for the UR5 and the Panda (minutes) | `mobman_env.robots.starts` (`STARTS`) |
| `acceptance` | the random arms' start-rule acceptance, seeds 0-999 and 10000-10999 | `mobman_env.robots.random_arms` |
| `ceiling` | the acceptance under `kinematic_ceiling`, seeds 0-199 and 10000-10199 (minutes) | `mobman_env.robots.random_arms` |
| `report` | `table`, `acceptance` and `ceiling` as one Markdown file (minutes) | `docs/results/robots-v1/robots.md`, docs/tasks.md |

May import: the standard library, `mobman_env.robots.*`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from mobman_env.robots import random_arms, starts
from mobman_env.robots.catalogue import PANDA, UR5

COMMANDS = ("table", "select", "acceptance", "ceiling", "report")


def _acceptance_lines() -> list[str]:
    lines = []
    for seeds in (range(1000), range(10_000, 11_000)):
        rate, mean = random_arms.acceptance(seeds)
        lines.append(
            f"{100 * rate:.1f}% of draws pass the start rule, {mean:.2f} draws per arm on average "
            f"(seeds {seeds.start}-{seeds.stop - 1})"
        )
    return lines


def _ceiling_lines() -> list[str]:
    lines = []
    for seeds in (range(200), range(10_000, 10_200)):
        arms, calls, mean = starts.ceiling_acceptance(seeds)
        lines.append(
            f"{100 * arms / calls:.1f}% of the draws that pass the rule are accepted ({arms} of {calls}), "
            f"{mean:.2f} draws per arm (seeds {seeds.start}-{seeds.stop - 1})"
        )
    return lines


def report() -> str:
    """The Markdown report of `report`: the starts table and the random arms' acceptance."""
    return "\n".join(
        [
            "# Robots: starts and the random arms' acceptance (`python -m mobman_env.robots report`)",
            "",
            "## Starts",
            "",
            "Every robot starts at heading pi, the platform at the origin. The PUMA at the paper's theta(0); the UR5 "
            "and the Panda at the configuration `mobman_env.robots.starts.select_start` found (400 candidates "
            "inside the joint limits that pass the random-arm start rule, the circle's far side within 95% of the "
            "reach, tracked by arm-only damped least squares to < 1 mm; the winner keeps the largest smallest "
            "singular value along the circle), rounded to 0.01 rad; a random arm at its draw's start (the start "
            "rule of `mobman_env.robots.random_arms`). Kinematic checks of each start:",
            "",
            starts.table(),
            "",
            "## Random-arm acceptance",
            "",
            "Start rule alone (`random_arm(default_rng(seed))`):",
            "",
            *[f"* {line}" for line in _acceptance_lines()],
            "",
            "With the env's ceiling check (`kinematic_ceiling`: whole-body damped least squares on the drawn design "
            "tracks the paper's circle within 1 mm without meeting a joint limit), what `WheeledRandomArm-*` ids "
            "draw:",
            "",
            *[f"* {line}" for line in _ceiling_lines()],
            "",
        ]
    )


def main(argv: Sequence[str] | None = None) -> None:
    """Parse `argv` (default: the command line) and print what the command computes."""
    parser = argparse.ArgumentParser(prog="python -m mobman_env.robots", description=__doc__.split("\n")[0])
    parser.add_argument("command", choices=COMMANDS)
    args = parser.parse_args(argv)
    if args.command == "table":
        print(starts.table())
    elif args.command == "select":
        for arm in (UR5, PANDA):
            start, rec = starts.select_start(arm)
            print(arm.name, start, rec)
    elif args.command == "acceptance":
        print("\n".join(_acceptance_lines()))
    elif args.command == "ceiling":
        print("\n".join(_ceiling_lines()))
    else:
        print(report(), end="")


if __name__ == "__main__":
    main()

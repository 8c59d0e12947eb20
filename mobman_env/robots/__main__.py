"""`python -m mobman_env.robots COMMAND`: regenerate the figures quoted in this package's docstrings.

| command | prints | quoted in |
|---|---|---|
| `table` | the starts table (reach, circle ratios, sigma_min, DLS tracking) | `mobman_env.robots.starts` |
| `select` | the start search for the UR5 and the Panda (minutes) | `mobman_env.robots.starts` (`STARTS`) |
| `acceptance` | the random arms' start-rule acceptance, seeds 0-999 and 10000-10999 | `mobman_env.robots.random_arms` |
| `ceiling` | the acceptance under `kinematic_ceiling`, seeds 0-199 and 10000-10199 (minutes) | `mobman_env.robots.random_arms` |
| `bench` | kinematics timing (machine-dependent) | `mobman_env.robots.kinematics` |

May import: the standard library, `mobman_env.robots.*`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

from mobman_env.robots import bench, random_arms, starts
from mobman_env.robots.catalogue import PANDA, UR5

COMMANDS = ("table", "select", "acceptance", "ceiling", "bench")


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
        for seeds in (range(1000), range(10_000, 11_000)):
            rate, mean = random_arms.acceptance(seeds)
            print(
                f"{100 * rate:.1f}% of draws pass the start rule, {mean:.2f} draws per arm on average "
                f"(seeds {seeds.start}-{seeds.stop - 1})"
            )
    elif args.command == "ceiling":
        for seeds in (range(200), range(10_000, 10_200)):
            arms, calls, mean = starts.ceiling_acceptance(seeds)
            print(
                f"{100 * arms / calls:.1f}% of the draws that pass the rule are accepted ({arms} of {calls}), "
                f"{mean:.2f} draws per arm (seeds {seeds.start}-{seeds.stop - 1})"
            )
    else:
        print(bench.table(bench.measure()))


if __name__ == "__main__":
    main()

"""Old against new single-env step speed, interleaved in one process (writes `step-ab.md`).

`mobman-eval speed` reports absolute steps/s, which move with the machine (the same code ran at half the speed
on two VMs of this project's kind on one day). This script measures what a code change did: it extracts
`mobman_env` of an older git revision into a temporary folder under another package name, builds the same env
from both (`OrderEnforcing(PassiveEnvChecker(env))`, as `gym.make` does), and times blocks of random-action
steps alternately old/new, CPU time of this process, reporting the median speed-up over the blocks and its
quartiles. The results of both are not compared here (the recorded-episode tests do that).

Usage (from the repository root):

    PYTHONPATH=$PWD python docs/results/speed/step_ab.py --old 24bc55f --out docs/results/speed/step-ab.md
"""

from __future__ import annotations

import argparse
import importlib
import io
import os
import platform
import re
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np

#: (label, dynamics, robot) of the timed cases
CASES = (
    ("PUMA, kinematic", "kinematic", "puma560"),
    ("UR5, kinematic", "kinematic", "ur5"),
    ("PUMA, physics (2 substeps)", "physics", "puma560"),
)


def old_package(rev: str, root: Path) -> str:
    """Extract `mobman_env` at git `rev` into `root/mobman_old` (imports renamed); returns the package name."""
    tar = subprocess.run(["git", "archive", rev, "mobman_env"], capture_output=True, check=True).stdout
    with tarfile.open(fileobj=io.BytesIO(tar)) as t:
        t.extractall(root, filter="data")
    (root / "mobman_env").rename(root / "mobman_old")
    for path in (root / "mobman_old").rglob("*.py"):
        path.write_text(re.sub(r"\bmobman_env\b", "mobman_old", path.read_text()))
    sys.path.insert(0, str(root))
    return "mobman_old"


def speed_up(old_cls, new_cls, dynamics: str, robot: str, blocks: int, steps: int) -> dict:
    from gymnasium.wrappers import OrderEnforcing, PassiveEnvChecker

    envs = {
        k: OrderEnforcing(PassiveEnvChecker(c(robot=robot, dynamics=dynamics)))
        for k, c in (("old", old_cls), ("new", new_cls))
    }
    n = envs["new"].action_space.shape[0]
    actions = np.random.default_rng(0).uniform(-1.0, 1.0, (steps, n))
    times: dict[str, list[float]] = {"old": [], "new": []}
    for b in range(blocks):
        for name in ("old", "new") if b % 2 else ("new", "old"):
            env = envs[name]
            env.reset(seed=b)
            t = time.process_time()
            for a in actions:
                env.step(a)
            times[name].append(time.process_time() - t)
    for env in envs.values():
        env.close()
    ratios = [o / w for o, w in zip(times["old"], times["new"])]
    return {
        "old_steps_per_s": steps / statistics.median(times["old"]),
        "new_steps_per_s": steps / statistics.median(times["new"]),
        "speed_up": statistics.median(ratios),
        "q1": float(np.percentile(ratios, 25)),
        "q3": float(np.percentile(ratios, 75)),
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--old", required=True, help="git revision of the old code")
    p.add_argument("--blocks", type=int, default=30, help="timed blocks per version and case")
    p.add_argument("--steps", type=int, default=400, help="steps per block")
    p.add_argument("--out", default=None, help="Markdown file to write (default: print)")
    a = p.parse_args(argv)
    new_rev = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], capture_output=True, text=True).stdout.strip()
    old_rev = subprocess.run(["git", "rev-parse", "--short=12", a.old], capture_output=True, text=True).stdout.strip()
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        old_cls = importlib.import_module(old_package(a.old, Path(tmp)) + ".env").WheeledPumaEnv
        from mobman_env.env import WheeledPumaEnv as new_cls

        rows = [(label, speed_up(old_cls, new_cls, dyn, robot, a.blocks, a.steps)) for label, dyn, robot in CASES]
    lines = [
        "# Single-env step: old against new, interleaved",
        "",
        f"From `docs/results/speed/step_ab.py --old {a.old}` (git {old_rev} against {new_rev}); {a.blocks} blocks "
        f"of {a.steps} random-action steps per version and case, alternating, CPU time of one process; "
        f"{os.cpu_count()} CPUs ({platform.platform()}), load average {load:.1f} at the start (1 min).",
        "",
        "## Speed-up",
        "",
        "| case | old steps/s | new steps/s | speed-up, median over blocks [quartiles] |",
        "|---|---|---|---|",
    ]
    for label, r in rows:
        lines.append(
            f"| {label} | {r['old_steps_per_s']:,.0f} | {r['new_steps_per_s']:,.0f} | "
            f"{r['speed_up']:.2f}x [{r['q1']:.2f}-{r['q3']:.2f}] |"
        )
    text = "\n".join(lines) + "\n"
    if a.out:
        Path(a.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()

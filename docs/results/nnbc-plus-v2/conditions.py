"""The conditions of issue 16 (`nnbc-plus` v2) and the script that runs and summarises them.

Every condition is built from existing env options (no env change):

| condition | tasks | modes | env arguments / reset options |
|---|---|---|---|
| `default` | all four | kinematic, physics | the env's defaults (5% wear) |
| `noise` | all four | both | `obs_noise` 0.001 m and `obs_noise_vel` 0.01 m/s |
| `joint-vel-noise` | all four | both | `obs_noise_joint_vel` 0.01 rad/s |
| `delay1`, `delay2` | all four | both | `obs_delay` 1, 2 control steps |
| `circle-5s`, `circle-10s` | Circle | both | the paper's circle with `duration` 5 s, 10 s |
| `circle-0.5m` | Circle | both | the paper's circle with `radius` 0.5 m |
| `random-start` | all four | both | `arm_joint_pos` = the paper's theta(0) + U(-0.3, 0.3) rad per joint (rule below) |
| `drift` | all four | kinematic (the env refuses wear drift in physics) | `wear_rate` 0.005 1/s |
| `wear30` | all four | both | `model_error` 0.3 |
| `ur5`, `panda`, `random-arm` | all four | kinematic (the robots bench's mode) | the env defaults on `WheeledUR5-*`, `WheeledPanda-*`, `WheeledRandomArm-*` (issue 13's robots) |

Random-start rule (seeded, documented): for the episode seed S, theta(0) = PAPER_ARM_JOINT_POS +
`np.random.default_rng([S, 0x5354]).uniform(-0.3, 0.3, 6)`, passed to the env constructor as `arm_joint_pos`;
the env's own draws (true robot, path, noise) still come from `reset(seed=S)`.

Usage (from the repository root; seeds 0-999 for development, >= 10,000 for reporting):

    PYTHONPATH=$PWD python docs/results/nnbc-plus-v2/conditions.py run --seeds 10000 20 --workers 2 \
        --out docs/results/nnbc-plus-v2/results.json
    PYTHONPATH=$PWD python docs/results/nnbc-plus-v2/conditions.py summary docs/results/nnbc-plus-v2/results.json \
        --out docs/results/nnbc-plus-v2/summary.md
    PYTHONPATH=$PWD python docs/results/nnbc-plus-v2/conditions.py run --ablation --seeds 0 3 --workers 2 \
        --out docs/results/nnbc-plus-v2/ablation.json
    PYTHONPATH=$PWD python docs/results/nnbc-plus-v2/conditions.py summary docs/results/nnbc-plus-v2/ablation.json \
        --title Ablation --out docs/results/nnbc-plus-v2/ablation.md
    PYTHONPATH=$PWD python docs/results/nnbc-plus-v2/conditions.py run --ablation21 --seeds 0 10 --workers 2 \
        --out docs/results/nnbc-plus-v2/ablation21.json
    PYTHONPATH=$PWD python docs/results/nnbc-plus-v2/conditions.py summary docs/results/nnbc-plus-v2/ablation21.json \
        --title "Ablation v2.1" --out docs/results/nnbc-plus-v2/ablation21.md

`run` writes one record per episode (condition, task, mode, seed, max error, success, predict time, joint-limit
hits); `summary` writes summary.md next to it (the generated blocks of docs/nnbc-plus-v3.md copy its sections).
"""

from __future__ import annotations

import argparse
import json
import platform
import signal
import statistics
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

TASKS = ("Circle", "Line", "Lemniscate", "Random")
BOTH = ("kinematic", "physics")
RANDOM_START_STREAM = 0x5354
RANDOM_START_RANGE = 0.3  # rad
TOLERANCE = 0.006  # m


def _circle(**change: float) -> dict:
    from mobman_env.env import PAPER_CIRCLE

    return {**PAPER_CIRCLE, **change}


#: name -> (tasks, modes, env kwargs, what it tests); path changes are env kwargs too ("path").
CONDITIONS: dict[str, tuple[tuple[str, ...], tuple[str, ...], dict[str, Any], str]] = {
    "default": (TASKS, BOTH, {}, "env defaults (5% wear)"),
    "noise": (TASKS, BOTH, {"obs_noise": 0.001, "obs_noise_vel": 0.01}, "1 mm position + 0.01 m/s velocity noise"),
    "joint-vel-noise": (TASKS, BOTH, {"obs_noise_joint_vel": 0.01}, "0.01 rad/s joint-speed noise"),
    "delay1": (TASKS, BOTH, {"obs_delay": 1}, "observations 1 control step old"),
    "delay2": (TASKS, BOTH, {"obs_delay": 2}, "observations 2 control steps old"),
    "circle-5s": (("Circle",), BOTH, {"path": "circle:duration=5"}, "the paper's circle in 5 s"),
    "circle-10s": (("Circle",), BOTH, {"path": "circle:duration=10"}, "the paper's circle in 10 s"),
    "circle-0.5m": (("Circle",), BOTH, {"path": "circle:radius=0.5"}, "a 0.5 m circle"),
    "random-start": (TASKS, BOTH, {"arm_joint_pos": "random"}, "theta(0) + U(-0.3, 0.3) rad"),
    "drift": (TASKS, ("kinematic",), {"wear_rate": 0.005}, "lengths drift 0.5%/s"),
    "wear30": (TASKS, BOTH, {"model_error": 0.3}, "30% wear"),
    "ur5": (TASKS, ("kinematic",), {"robot": "UR5"}, "the UR5 arm (issue 13)"),
    "panda": (TASKS, ("kinematic",), {"robot": "Panda"}, "the Panda arm (issue 13)"),
    "random-arm": (TASKS, ("kinematic",), {"robot": "RandomArm"}, "a random arm per seed (issue 13)"),
}


#: The ablation (development seeds): each v2 mechanism switched off on the conditions it targets, beside v2.
ABLATION: dict[str, tuple[str, ...]] = {
    "nnbc-plus": ("noise", "joint-vel-noise", "delay2", "circle-5s", "circle-0.5m", "random-start"),
    "nnbc-plus:noise_rate=0": ("noise", "joint-vel-noise"),
    "nnbc-plus:max_delay=0": ("delay2",),
    "nnbc-plus:probe_tracking=false": ("circle-5s",),
    "nnbc-plus:sing_threshold=0": ("circle-0.5m",),
    "nnbc-plus:block_release=0": ("random-start",),
}

#: The ablation of v2.1 (development seeds; `run --ablation21`): joint stops checked every step, beside v2's
#: every 4th step, on the robots whose stops Line-v0 reaches. `ablation21.json` also holds a third spec,
#: `nnbc-plus:wheel_weight=16`: an option release 0.3 deleted (docs/nnbc-plus.md, "What did not work").
ABLATION21: dict[str, tuple[str, ...]] = {
    "nnbc-plus": ("ur5", "random-arm"),
    "nnbc-plus:block_every=4": ("ur5", "random-arm"),
}


def random_start(seed: int) -> list[float]:
    """theta(0) of the random-start condition for episode seed `seed` (see the module docstring)."""
    from mobman_env.env import PAPER_ARM_JOINT_POS

    d = np.random.default_rng([seed, RANDOM_START_STREAM]).uniform(-RANDOM_START_RANGE, RANDOM_START_RANGE, 6)
    return [float(a + b) for a, b in zip(PAPER_ARM_JOINT_POS, d)]


def env_kwargs(condition: str, seed: int) -> dict[str, Any]:
    """The env constructor arguments of one episode of `condition` (its seeded random start resolved)."""
    kw = dict(CONDITIONS[condition][2])
    kw.pop("robot", None)
    if kw.get("arm_joint_pos") == "random":
        kw["arm_joint_pos"] = random_start(seed)
    if isinstance(kw.get("path"), str):
        _, _, change = kw["path"].partition(":")
        key, _, value = change.partition("=")
        kw["path"] = _circle(**{key: float(value)})
    return kw


def episode(job: tuple[str, str, str, int, str]) -> dict[str, Any]:
    """One episode: (policy spec, condition, task, mode, seed) -> its record."""
    spec, condition, task, mode, seed = job[0], job[1], job[2], job[3], int(job[4])
    from eval.rollout import make_env, make_policy, rollout

    robot = CONDITIONS[condition][2].get("robot", "Puma")
    env = make_env(f"Wheeled{robot}-{task}-v0", dynamics=mode, env_kwargs=env_kwargs(condition, seed))
    try:
        policy = make_policy(spec, env, seed)
        rec, _ = rollout(env, policy, seed)
    finally:
        env.close()
    return {
        "policy": spec,
        "condition": condition,
        "task": task,
        "dynamics": mode,
        "seed": seed,
        "status": rec["status"],
        "max_error_m": rec["max_error_m"],
        "success": bool(rec["max_error_m"] is not None and rec["max_error_m"] <= TOLERANCE),
        "predict_us_median": rec["predict_us_median"],
        "joint_limit_hits": rec.get("joint_limit_hits"),
    }


def jobs(
    specs: list[str],
    conditions: list[str],
    seeds: list[int],
    tasks: list[str] | None = None,
    ablation: dict[str, tuple[str, ...]] | None = None,
) -> list[tuple]:
    """The grid in seed-major order (every cell gets its first seed before any gets its second), so a run
    stopped early (SIGTERM) still covers every cell evenly."""
    out = []
    for s in seeds:
        for spec in specs:
            for cond in ablation[spec] if ablation else conditions:
                ctasks, modes, _, _ = CONDITIONS[cond]
                for task in ctasks:
                    if tasks and task not in tasks:
                        continue
                    out.extend((spec, cond, task, mode, s) for mode in modes)
    return out


def run(
    specs,
    conditions,
    seeds,
    workers,
    tasks=None,
    modes=None,
    progress: Path | None = None,
    ablation: dict[str, tuple[str, ...]] | None = None,
) -> list[dict]:
    """Every episode of the grid, in grid order; each record is also appended to `progress` (JSON lines) as it
    arrives, so an interrupted run keeps what it did."""
    todo = [j for j in jobs(specs, conditions, seeds, tasks, ablation) if not modes or j[3] in modes]
    out: list[dict] = []
    pool = ProcessPoolExecutor(max(workers, 1))
    try:
        for rec in pool.map(episode, todo):
            out.append(rec)
            if progress is not None:
                with progress.open("a") as f:
                    f.write(json.dumps(rec) + "\n")
    except (KeyboardInterrupt, SystemExit):  # stopped: keep the episodes done (the summary says how many)
        print(f"stopped after {len(out)} of {len(todo)} episodes", file=sys.stderr)
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
    return out


def _git() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "unknown"


def table(records: list[dict], by: str = "condition") -> str:
    """Markdown table: one row per (policy, condition), kinematic and physics columns."""
    keys: dict[tuple, dict[str, list[dict]]] = {}
    for r in records:
        keys.setdefault((r["policy"], r[by]), {}).setdefault(r["dynamics"], []).append(r)
    lines = [
        "| controller | condition | kinematic: success | median / max error (mm) | physics: success | median / max error (mm) |",
        "|---|---|---|---|---|---|",
    ]
    for (pol, cond), per_mode in keys.items():
        cells = []
        for mode in BOTH:
            rs = per_mode.get(mode)
            if not rs:
                cells += ["-", "-"]
                continue
            errs = [r["max_error_m"] * 1e3 if r["max_error_m"] is not None else float("inf") for r in rs]
            ok = sum(r["success"] for r in rs)
            cells += [f"{ok}/{len(rs)} ({100 * ok / len(rs):.0f}%)", f"{statistics.median(errs):.2f} / {max(errs):.3g}"]
        lines.append(f"| `{pol}` | `{cond}` | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--policy", action="append", default=None)
    r.add_argument("--conditions", nargs="*", default=list(CONDITIONS))
    r.add_argument("--tasks", nargs="*", default=None)
    r.add_argument("--modes", nargs="*", default=None)
    r.add_argument("--seeds", nargs=2, type=int, metavar=("START", "N"), required=True)
    r.add_argument("--workers", type=int, default=1)
    r.add_argument("--out", required=True)
    r.add_argument("--ablation", action="store_true", help="run the ABLATION table (its policies and conditions)")
    r.add_argument("--ablation21", action="store_true", help="run the ABLATION21 table (v2.1's changes)")
    s = sub.add_parser("summary")
    s.add_argument("results")
    s.add_argument("--title", default="Conditions", help="section title of the Markdown file written")
    s.add_argument("--out", default=None, help="Markdown file to write (default: print)")
    a = p.parse_args(argv)
    if a.cmd == "run":
        unknown = sorted(set(a.conditions) - set(CONDITIONS))
        if unknown:
            p.error(f"unknown condition(s) {unknown}; accepted: {list(CONDITIONS)}")
        seeds = list(range(a.seeds[0], a.seeds[0] + a.seeds[1]))
        t0 = time.time()
        git = _git()  # the code the episodes run (read at the start: later commits must not be credited)
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
        progress = Path(a.out + ".progress.jsonl")
        progress.unlink(missing_ok=True)
        table_ = ABLATION if a.ablation else ABLATION21 if a.ablation21 else None
        specs = list(table_) if table_ else (a.policy or ["nnbc-plus"])
        planned = sum(not a.modes or j[3] in a.modes for j in jobs(specs, a.conditions, seeds, a.tasks, table_))
        recs = run(specs, a.conditions, seeds, a.workers, a.tasks, a.modes, progress, table_)
        meta = {
            "command": " ".join(sys.argv),
            "git": git,
            "seeds": [seeds[0], seeds[-1]],
            "wall_s": round(time.time() - t0, 1),
            "workers": a.workers,
            "planned": planned,
            "stopped": len(recs) < planned,
            "machine": platform.processor() or platform.machine(),
        }
        Path(a.out).write_text(json.dumps({"meta": meta, "episodes": recs}, indent=1) + "\n")
        progress.unlink(missing_ok=True)
        print(table(recs))
    else:
        from eval.output.compact import stored_bytes

        data = json.loads(stored_bytes(a.results))  # the file, or its compacted twin (`mobman-eval compact`)
        text = markdown(data, a.title, Path(a.results).name)
        if a.out:
            Path(a.out).write_text(text)
        else:
            print(text)


def markdown(data: dict, title: str, source: str) -> str:
    """The Markdown file of one results file: a header (provenance) and one section `## title` with the table
    and the predict time."""
    recs = data["episodes"]
    meta = data["meta"]
    seeds = sorted({r["seed"] for r in recs})
    us = [r["predict_us_median"] for r in recs if r["predict_us_median"] is not None]
    failed = sum(r["status"] != "ok" for r in recs)
    head = (
        f"# nnbc-plus v2: {title.lower()}\n\nFrom `{source}` (`{meta['command']}`, git {meta['git']}, "
        f"{meta['machine']}); written by `conditions.py summary`.\n\n"
    )
    cells: dict[tuple, int] = {}
    for r in recs:
        key = (r["policy"], r["condition"], r["task"], r["dynamics"])
        cells[key] = cells.get(key, 0) + 1
    per = (
        f"{min(cells.values())}"
        if min(cells.values()) == max(cells.values())
        else (f"{min(cells.values())}-{max(cells.values())}")
    )
    stopped = (
        f" The run was stopped at the deadline after {len(recs)} episodes (the grid is seed-major, so every cell"
        " has its first seeds)."
        if meta.get("stopped")
        else ""
    )
    body = (
        f"{len(recs)} episodes ({failed} failed), seeds {seeds[0]}-{seeds[-1]}, {per} per task, condition, mode "
        f"and controller; success = max tracking error <= {TOLERANCE * 1e3:.0f} mm; conditions defined in "
        f"`docs/results/nnbc-plus-v2/conditions.py`.{stopped}\n\n" + table(recs) + "\n"
        f"`predict`, median over episodes of the per-episode median: {statistics.median(us):.0f} us (all "
        f"episodes, run {meta['workers']} at a time on a shared machine; `mobman-eval speed` times it alone).\n"
    )
    return head + f"## {title}\n\n" + body


if __name__ == "__main__":
    main()

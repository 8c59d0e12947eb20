"""`mobman-eval timings`: time the README's steps (first compile, the main job, the tests) into one file.

The README and the docs quote how long mobman's first hour takes; those figures came from three places and
disagreed (77, 108 and 7 s for the paper run; "about 4 minutes" for a suite that took 16.6 minutes on a loaded
machine). This command is their one source: it runs each step as the README runs it, in a subprocess, and records

* `wall_s`: the wall clock, s (what a reader waits; it grows with the machine's load);
* `cpu_s`: the CPU time of the step's processes, s (user + system of the finished children, `resource`): the
  figure that survives a busy machine (a parallel step's CPU exceeds its wall clock);
* `load_before`, `load_after`: the 1-minute load average around the step, and `cores` (`os.cpu_count()`), so a
  reader can tell a quiet run from a loaded one;
* `returncode`: a failed step is recorded as failed, never timed as if it had passed.

Steps (`STEPS`, in order): `compile` (`python -m mobman_env && python -m policies` with an empty numba cache, so
the compile every fresh install pays is measured, not a warm cache's load), `main` (`mobman-eval paper`, the
README's main job, into a temporary folder: its figures are not the ones committed), `tests` (the README's test
command, `python -m pytest -q -n auto`, from the repository's root: it needs the checkout's `tests/`). The
install is left out: it depends on the network and the package cache, not on mobman.

`timings.json` holds the records with the provenance (`eval.output.provenance`); `timings.md` the same as a
sentence and a table, which README and docs blocks quote (`mobman-eval readme`). This module imports the standard
library and `eval` (errors, output).
"""

from __future__ import annotations

import os
import resource
import shlex
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from eval.errors import EvalError

#: The README's steps, in order: name -> (what it is, its command as the README gives it). `{out}` is a
#: temporary folder of the run.
STEPS: dict[str, tuple[str, str]] = {
    "compile": ("first compile of the kernels (empty numba cache)", "python -m mobman_env && python -m policies"),
    "main": ("the main job: mobman-eval paper", "mobman-eval paper --out {out}/paper"),
    "tests": ("the README's test command", "python -m pytest -q -n auto -p no:cacheprovider"),
}


@dataclass(frozen=True)
class TimingsConfig:
    """Options of `mobman-eval timings`."""

    steps: tuple[str, ...] = tuple(STEPS)
    """The steps to time, in the README's order (compile, main, tests)."""
    out: str | None = None
    """Output directory for timings.json and timings.md; None: `runs/timings-<UTC timestamp>`."""
    overwrite: bool = False
    """Write into an existing non-empty --out."""
    progress: bool = True
    """Say which step runs (stderr)."""

    def validate(self) -> None:
        unknown = [s for s in self.steps if s not in STEPS]
        if unknown or not self.steps:
            raise EvalError(
                f"unknown step(s) {', '.join(map(repr, unknown)) or '(none given)'}; accepted: {', '.join(STEPS)} "
                "(e.g. --steps compile,main)"
            )


def run_step(command: str, cwd: Path, env: Mapping[str, str]) -> dict[str, Any]:
    """Run one shell command and time it: wall and CPU seconds (its processes, children included), the load
    average around it, its exit code."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    proc = subprocess.run(
        command, shell=True, cwd=cwd, env=dict(env), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {
        "command": command,
        "wall_s": round(wall, 1),
        "cpu_s": round(cpu, 1),
        "load_before": round(load_before, 2),
        "load_after": round(os.getloadavg()[0], 2),
        "returncode": proc.returncode,
        "stderr_tail": proc.stderr.decode("utf-8", "replace")[-2000:] if proc.returncode else "",
    }


def repository_root() -> Path:
    """The checkout this module belongs to (the folder holding pyproject.toml and tests/); the tests step needs it."""
    root = Path(__file__).resolve().parents[1]
    if not (root / "pyproject.toml").is_file() or not (root / "tests").is_dir():
        raise EvalError(
            f"the tests step runs the README's test command from a checkout, and {root} is not one (no "
            "pyproject.toml and tests/ there): clone the repository and run mobman-eval timings there, or leave "
            "the step out (--steps compile,main)"
        )
    return root


def measure(
    steps: Sequence[str],
    commands: Mapping[str, tuple[str, str]] = STEPS,
    progress: Callable[[str], None] = lambda msg: None,
) -> dict[str, Any]:
    """Time `steps` (names of `commands`) one after the other; a failed step is recorded and the next still runs."""
    root = repository_root() if "tests" in steps else Path.cwd()
    records = []
    with tempfile.TemporaryDirectory(prefix="mobman-timings-") as tmp:
        for name in steps:
            what, command = commands[name]
            env = {**os.environ, "PYTHONUNBUFFERED": "1", "MPLBACKEND": "Agg"}
            if name == "compile":
                env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "numba-cache")  # empty: the first compile of a fresh install
            progress(f"timings: {name}: {what} ({command.format(out=tmp)})")
            rec = run_step(command.format(out=shlex.quote(tmp)), root, env)
            records.append({"step": name, "what": what, **rec, "command": command.format(out="DIR")})
            state = "ok" if rec["returncode"] == 0 else f"FAILED (exit {rec['returncode']})"
            progress(f"timings: {name}: {state}, {rec['wall_s']:.0f} s wall, {rec['cpu_s']:.0f} s CPU")
    return {"schema": 1, "cores": os.cpu_count(), "python": sys.version.split()[0], "steps": records}


def markdown(result: Mapping[str, Any]) -> str:
    """timings.md: one section ("Timings") with a sentence and a table, for the README's and the docs' blocks."""
    steps = result["steps"]
    cores = result["cores"]
    loads = ", ".join(f"{s['load_before']:g}" for s in steps)
    lines = [
        "# Timings of the README's steps",
        "",
        "Made by `mobman-eval timings` (`eval.timings`); the data is `timings.json` beside this file.",
        "",
        "## Timings",
        "",
        f"Measured on a {cores}-core machine (1-minute load average before each step: {loads}); CPU time is the "
        "processes' user + system time, the figure a busy machine does not change much; wall clock grows with the "
        "load. The install is not timed (it depends on the network and the package cache).",
        "",
        "| step | command | wall clock | CPU time | result |",
        "|---|---|---|---|---|",
    ]
    for s in steps:
        ok = "passed" if s["returncode"] == 0 else f"failed (exit {s['returncode']})"
        lines.append(f"| {s['what']} | `{s['command']}` | {_duration(s['wall_s'])} | {_duration(s['cpu_s'])} | {ok} |")
    return "\n".join(lines) + "\n"


def _duration(seconds: float) -> str:
    """`75 s` or `4.2 min` (seconds to the second, minutes to a tenth)."""
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"

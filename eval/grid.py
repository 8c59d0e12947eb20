"""The one grid engine: how `run`, `sweep` (and through them `bench` and `paper`) run a list of episodes.

`run_tasks(config, user, tasks, user_bytes, journal, ...)` hands the tasks (`eval.execution.tasks.Task`: one
episode each) to `eval.execution.dispatch.execute` (local processes or Ray; kinematic episodes of built-in specs
batched through vector envs), takes every record as its episode ends, appends it to the output folder's journal
(`eval.output.journal`: what finished survives a crash, a full disk or a kill) and advances one progress bar. A
record without a result at all (a dead worker, a failed Ray task: `pid` None) is kept aside and not journaled,
so a resumed sweep runs that episode again. Ctrl-C or SIGTERM stops the workers and returns what finished
(`interrupted`); the caller writes its report from it and then raises. Before the bar starts, a cold numba
cache is compiled and announced (`eval.execution.warmup`), so the bar's ETA holds no compile. Everything before
(the checks) and after (the files) is the caller's: `run` writes a run folder, `sweep` rebuilds its table from the journal.

**One code version per result.** Every record gets `code`: the hash of the code that ran it
(`eval.output.provenance.code_hash`, the four packages' source; this process's, which its local workers share:
they are spawned from the same tree). A resumed run, sweep or bench passes its journal's records through
`same_code` before planning: records of other code (or of none: written before the field existed, code
unknown) are refused with both fixes (another `--out`, or `--rerun-changed`), or with `rerun_changed` dropped,
so their episodes run again and the old records stay out of the result (the journal keeps their lines; the new
record, appended later, wins on loading). Decisions: refused by default, because mixing is silent and a
changed controller may be the very thing measured; only the episodes that enter the result are checked (a
journal's records outside the grid are in no result); an unknown code is a different code, because nothing
proves it the same.

Layer 6 of `eval` (below `checks` and `output`, above `runner` and `sweep`): imports `eval.config`, `eval.execution`,
`eval.output`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from eval import metrics as M
from eval.config import EvalConfig
from eval.errors import EvalError
from eval.execution.dispatch import execute
from eval.execution.tasks import ExecutionInterrupted, Task
from eval.execution.warmup import warm_kernels
from eval.output.files import to_jsonable
from eval.output.journal import Journal, episode_key
from eval.output.progress import progress_bar
from eval.output.provenance import code_hash

#: settings that must not change when a run or sweep is resumed (they change every episode's result), with the
#: value a folder written before the key existed had
FIXED_KEYS = {"env_kwargs": {}, "tolerance": M.DEFAULT_TOLERANCE, "settle_time": M.DEFAULT_SETTLE_TIME}
#: a run's too: its model_error and obs_noise are one value for every episode, not part of the episode's key
RUN_FIXED_KEYS = {**FIXED_KEYS, "model_error": None, "obs_noise": None}

#: the option that re-runs the episodes a journal holds from other code (run, sweep, bench)
RERUN_CHANGED = "--rerun-changed"


@dataclass
class GridRun:
    """What `run_tasks` returns."""

    records: dict[int, dict] = field(default_factory=dict)  # task index -> its record, as it was journaled
    lost: dict[int, dict] = field(default_factory=dict)  # task index -> a record without a result (not journaled)
    arrays: dict[int, dict] = field(default_factory=dict)  # task index -> per-step arrays, where kept
    n_run: int = 0  # records received now
    wall_s: float = 0.0
    interrupted: bool = False


def run_tasks(
    config: EvalConfig,
    user: dict[str, Any],
    tasks: list[Task],
    user_bytes: bytes | None,
    journal: Journal,
    *,
    progress: bool,
    desc: str,
) -> GridRun:
    """Run `tasks` (see the module docstring); never raises for an interruption (`GridRun.interrupted`)."""
    grid = GridRun()
    code = code_hash()
    if tasks:
        warm_kernels(announce=progress)  # a cold numba cache compiles here, said, and before the bar's clock starts
    bar = progress_bar(len(tasks), desc, "ep", progress and bool(tasks))

    def on_result(rec: dict) -> None:
        rec = {**to_jsonable(rec), "code": code}
        if rec.get("pid") is not None:
            journal.append(rec)
        grid.n_run += 1
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(
                f"{rec['policy']} seed {rec['seed']}: "
                + (f"max {rec['max_error_m'] * 1e3:.2f} mm" if rec.get("max_error_m") is not None else rec["status"]),
                refresh=False,
            )

    t0 = time.perf_counter()
    by_index: dict[int, dict] = {}
    try:
        if tasks:
            by_index, grid.arrays = execute(config, user, tasks, user_bytes, on_result)
    except ExecutionInterrupted as exc:
        by_index, grid.arrays, grid.interrupted = exc.records, exc.arrays, True
    finally:
        if bar is not None:
            bar.close()
        grid.wall_s = time.perf_counter() - t0
    for i, rec in by_index.items():
        rec = {**to_jsonable(rec), "code": code}
        (grid.lost if rec.get("pid") is None else grid.records)[i] = rec
    return grid


def name_conditions(done: dict[tuple, dict], env_kwargs: dict) -> dict[tuple, dict]:
    """`done` ({episode_key: record}, a journal's) with every record written before records named their condition
    given the name its env arguments make (the axes and the grid's `env_kwargs`, as `eval.output.results`
    upgrades an old file), keyed again: such a record is then the same episode as the grid's task, so `same_code`
    refuses it (code unknown) instead of the grid running it again beside it."""
    from eval.conditions import condition_name

    out: dict[tuple, dict] = {}
    for key, rec in done.items():
        if rec.get("condition") is None and rec.get("dynamics") is not None:
            axes = {k: rec.get(k) for k in ("dynamics", "model_error", "obs_noise")}
            rec = {**rec, "condition": condition_name({**env_kwargs, **axes})}
            key = episode_key(rec)
        out[key] = rec
    return out


def same_code(
    done: dict[tuple, dict], tasks: list[Task], rerun_changed: bool, where: str, key: Callable = episode_key
) -> dict[tuple, dict]:
    """The journaled records `done` ({key: record}, keyed by `key`: `episode_key`, or a run's `run_key`) that a
    resumed grid of `tasks` may use: all of them when every record of a task carries this process's
    `code_hash()`; else, with `rerun_changed`, those that do (the others' episodes then run again); else
    EvalError naming the hashes there and now and both fixes. `where` names the folder in the message
    ("--out 'runs/x'"). Records of episodes outside `tasks` are in no result and are left as they are (see the
    module docstring)."""
    code = code_hash()
    keys = {key(t) for t in tasks}
    changed = [k for k, rec in done.items() if k in keys and rec.get("code") != code]
    if not changed:
        return done
    if rerun_changed:
        drop = set(changed)
        return {k: rec for k, rec in done.items() if k not in drop}
    there = sorted({str(done[k].get("code") or "unknown") for k in changed})
    unknown = " ('unknown': written before mobman recorded the code of each episode)" if "unknown" in there else ""
    raise EvalError(
        f"{where} holds {len(changed)} episode(s) run by other code than this: code {', '.join(there)} there, "
        f"{code} now{unknown}; one result never mixes two code versions. Use another --out to start over, or pass "
        f"{RERUN_CHANGED} to run those {len(changed)} episode(s) again with this code (the others are kept)"
    )


def same_settings(old: dict, new: dict, out, command: str, fixed: dict = FIXED_KEYS) -> None:
    """EvalError unless the config `old` of the `command` folder `out` and the `new` one agree on `fixed`
    (`FIXED_KEYS`: the settings that change every episode's result; the grid itself may grow)."""
    changed = [k for k, before in fixed.items() if old.get(k, before) != new[k]]
    if changed:
        diff = "; ".join(f"{k}: {old.get(k, fixed[k])!r} there, {new[k]!r} now" for k in changed)
        raise EvalError(
            f"--out {str(out)!r} holds a {command} with other settings ({diff}); its episodes would not be "
            f"comparable: use another --out, or delete that directory to start over"
        )

"""The one grid engine: how `run`, `sweep` (and through them `bench` and `paper`) run a list of episodes.

`run_tasks(config, user, tasks, user_bytes, journal, ...)` hands the tasks (`eval.execution.tasks.Task`: one
episode each) to `eval.execution.dispatch.execute` (local processes or Ray; kinematic episodes of built-in specs
batched through vector envs), takes every record as its episode ends, appends it to the output folder's journal
(`eval.output.journal`: what finished survives a crash, a full disk or a kill) and advances one progress bar. A
record without a result at all (a dead worker, a failed Ray task: `pid` None) is kept aside and not journaled,
so a resumed sweep runs that episode again. Ctrl-C or SIGTERM stops the workers and returns what finished
(`interrupted`); the caller writes its report from it and then raises. Before the bar starts, a cold numba
cache is compiled and announced (`eval.execution.warmup`), so the bar's ETA holds no compile. Everything before (the checks) and after
(the files) is the caller's: `run` writes a run folder, `sweep` rebuilds its table from the journal.

Layer 6 of `eval` (below `checks` and `output`, above `runner` and `sweep`): imports `eval.config`, `eval.execution`,
`eval.output`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from eval.config import EvalConfig
from eval.execution.dispatch import execute
from eval.execution.tasks import ExecutionInterrupted, Task
from eval.execution.warmup import warm_kernels
from eval.output.files import to_jsonable
from eval.output.journal import Journal
from eval.output.progress import progress_bar


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
    if tasks:
        warm_kernels(announce=progress)  # a cold numba cache compiles here, said, and before the bar's clock starts
    bar = progress_bar(len(tasks), desc, "ep", progress and bool(tasks))

    def on_result(rec: dict) -> None:
        rec = to_jsonable(rec)
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
        rec = to_jsonable(rec)
        (grid.lost if rec.get("pid") is None else grid.records)[i] = rec
    return grid

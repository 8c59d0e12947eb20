"""`run(config, policies=None)`: check everything, run every episode (in this process or N workers), report.

Order of work, so that mistakes cost nothing:

1. the config, the output directory (an existing non-empty one needs `overwrite`), every env id and env
   argument (each env is built once) and every policy spec (each is built once with `policies.make`) are
   checked before the first rollout; problems raise `EvalError` listing what is available;
2. the episodes run; a crash inside one is recorded as `status: "failed"` with its traceback and the rest go on;
3. results.json, results.csv, summary.md, config.json, episodes.npz, plots and videos are written, each to a
   temporary name and renamed.

Batches: kinematic episodes of one env, condition and built-in policy spec run up to `batch_size` at a time
through one vector env and one batched policy (`eval.execution.batches`), with the records of the single path
(a batch that raises is run again episode by episode). Workers: `workers=N > 1` starts N spawned processes,
each with its own PyBullet client(s). The batches and single episodes are dealt round-robin (worker i runs units
i, i + N, ... of the run's list), so every worker really runs and the results do not depend on scheduling: every episode starts from `env.reset(seed=S + k)` and
`policy.reset(..., seed=policy_seed(S + k))` (`policies.base.policy_seed`), whichever process runs it. Results equal those of `workers=1` except the
timing fields (`wall_s`, `predict_us_*`) and `pid`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval.checks import check_all, check_user_policies
from eval.config import EvalConfig
from eval.errors import EvalError, RunInterrupted
from eval.execution.dispatch import execute
from eval.execution.tasks import ExecutionInterrupted, interrupted_record, make_tasks
from eval.output.files import check_out, make_out, remove_stale, resolve_out, sigint_deferred
from eval.output.progress import progress_bar
from eval.output.results import RUN_OUTPUTS, ResultsView, arrays_key, build_results, print_results, write_run
from eval.output.video import video_format, write_videos
from eval.rollout import RECORD_KEYS, _known_policies_text


@dataclass
class RunResult(ResultsView):
    """What `run` returns: the output directory, the results.json content and the per-step arrays kept in
    memory (those of episode 0 of every condition, or all with save_arrays="all"), keyed by task index."""

    out: Path
    results: dict
    arrays: dict[int, dict] = field(default_factory=dict)


# --- the entry point -------------------------------------------------------------------------------------


def run(config: EvalConfig, policies: dict[str, Any] | None = None) -> RunResult:
    """Benchmark `config.policies` (specs) and `policies` ({name: object with predict/reset}) side by side.

    Every (env, dynamics, policy) faces the same `config.episodes` episodes (seeds S .. S + episodes - 1).
    Writes the report files into the output directory and returns a `RunResult`. With `workers > 1` the
    workers are spawned processes: a script calling this needs the usual `if __name__ == "__main__":` guard.

    Ctrl-C (KeyboardInterrupt) while episodes run stops the workers, writes the report with the finished
    episodes (the others have status "interrupted" and are left out of the aggregate) and raises
    `RunInterrupted`.
    """
    user = dict(policies or {})
    config.validate()
    if not config.policies and not user:
        raise EvalError(f"no policy given; pass --policy SPEC ({_known_policies_text()})")
    # Ray pickles policy objects itself (and ray_backend words its own error): check for local workers only
    user_bytes = check_user_policies(user, config.policies, config.workers if config.backend == "local" else 1)
    out = resolve_out(config.out, config.command)
    check_out(out, config.overwrite)
    check_all(config, user)
    if config.video:
        video_format()  # the encoder is there (or a clear message) before any episode runs
    out = make_out(out, exclusive=not config.out)

    names = list(config.policies) + list(user)
    tasks = make_tasks(config, names)
    rec_by_index, arrays, wall, interrupted = _execute_with_progress(config, user, tasks, user_bytes)
    records = [rec_by_index.get(t.index) or interrupted_record(t) for t in tasks]
    for t, rec in zip(tasks, records):
        for key in RECORD_KEYS:  # records of episodes that never ran (dead worker) get every field too
            rec.setdefault(key, False if key in ("success", "tipped_over", "terminated") else None)
        rec["index"] = t.index
        rec["arrays_key"] = (
            arrays_key(t.index)
            if (
                t.index in arrays
                and (config.save_arrays == "all" or (config.save_arrays == "first" and t.episode == 0))
            )
            else None
        )

    cfg = config.to_dict()
    cfg["out"] = str(out)
    cfg["policy_objects"] = {name: type(obj).__name__ for name, obj in user.items()}
    finished = [r for r in records if r["status"] != "interrupted"]
    results = build_results(cfg, records, M.aggregate(finished), wall_s=wall)
    result = RunResult(out=out, results=results, arrays=arrays)
    with sigint_deferred(reraise=not interrupted):  # a Ctrl-C now does not cut the report short
        written = write_run(result, config)
    if interrupted:
        raise RunInterrupted(
            f"interrupted: {len(finished)} of {len(records)} episodes finished; results written to {out} "
            f'(the others have status "interrupted")'
        )
    if config.video:
        written += write_videos(result, config, user)
    if config.overwrite:
        remove_stale(out, RUN_OUTPUTS, set(written))
    if config.progress:
        print_results(results, out, config.stdout_format)
    return result


def _execute_with_progress(
    config: EvalConfig, user: dict, tasks: list, user_bytes: bytes | None
) -> tuple[dict[int, dict], dict[int, dict], float, bool]:
    """Run the tasks with a progress bar: (records by index, arrays by index, wall time in s, interrupted)."""
    bar = progress_bar(len(tasks), "episodes", "ep", config.progress)

    def on_result(rec):
        if bar is not None:
            bar.update(1)
            bar.set_postfix_str(
                f"{rec['policy']} seed {rec['seed']}: "
                + (f"max {rec['max_error_m'] * 1e3:.2f} mm" if rec.get("max_error_m") is not None else rec["status"]),
                refresh=False,
            )

    t0 = time.perf_counter()
    interrupted = False
    try:
        rec_by_index, arrays = execute(config, user, tasks, user_bytes, on_result)
    except ExecutionInterrupted as exc:
        rec_by_index, arrays, interrupted = exc.records, exc.arrays, True
    finally:
        if bar is not None:
            bar.close()
    return rec_by_index, arrays, time.perf_counter() - t0, interrupted

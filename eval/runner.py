"""`run(config, policies=None)`: check everything, run every episode (in this process or N workers), report.

Order of work, so that mistakes cost nothing:

1. the config, the output directory (an existing non-empty one needs `overwrite`), every env id and env
   argument (each env is built once) and every policy spec (each is built once with `policies.make`) are
   checked before the first rollout; problems raise `EvalError` listing what is available;
2. the episodes run; a crash inside one is recorded as `status: "failed"` with its traceback and the rest go on;
3. results.json, results.csv, summary.md, config.json, episodes.npz, plots and videos are written, each to a
   temporary name and renamed. Meanwhile every record was appended to `episodes.jsonl` as its episode ended
   (`eval.output.journal`, as a sweep's), so a crash or a full disk keeps the finished episodes; a file that
   cannot be written is an EvalError naming it and the command that resumes.

**Resuming** (`resume`, `--out DIR --resume`): config.json is written before the first episode, so a folder
stopped by a full disk or a kill holds the settings and the journal; the same command with `--resume` keeps the
journaled episodes (their records as they were: not run again), runs the others and writes every file. The
settings that change episodes must be the same (`eval.grid.same_settings`), and so must the code
(`eval.grid.same_code`: a journal of other code is refused, or its episodes run again with `rerun_changed`).
Decisions: an explicit flag, not an automatic resume, because `--out` of an existing folder is refused to
protect it and that protection stays; the message of a full disk names the exact command (the CLI prints it
from `EvalError.resume`), because "run again" alone would be refused.

Batches: kinematic episodes of one env, condition and built-in policy spec run up to `batch_size` at a time
through one vector env and one batched policy (`eval.execution.batches`), with the records of the single path
(a batch that raises is run again episode by episode). Workers: `workers=N > 1` starts N spawned processes,
each with its own PyBullet client(s). The batches and single episodes are dealt round-robin (worker i runs units
i, i + N, ... of the run's list), so every worker really runs and the results do not depend on scheduling: every episode starts from `env.reset(seed=S + k)` and
`policy.reset(..., seed=policy_seed(S + k))` (`policies.base.policy_seed`), whichever process runs it. Results equal those of `workers=1` except the
timing fields (`wall_s`, `predict_us_*`) and `pid`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval.checks import check_all, check_user_policies
from eval.config import EvalConfig
from eval.errors import EvalError, RunInterrupted
from eval.execution.tasks import interrupted_record, make_tasks
from eval.grid import RUN_FIXED_KEYS, run_tasks, same_code, same_settings
from eval.output.files import (
    WriteError,
    atomic_write_json,
    check_out,
    interrupts_deferred,
    make_out,
    read_folder_record,
    remove_stale,
    resolve_out,
    write_error,
)
from eval.output.journal import JOURNAL, Journal, run_key
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
    tasks = make_tasks(config, list(config.policies) + list(user))
    if config.resume:
        _resumable(config, user, out, tasks, repair=False)  # read only: checked again under the lock
    else:
        check_out(out, config.overwrite)
    check_all(config, user)
    if config.video:
        video_format()  # the encoder is there (or a clear message) before any episode runs
    out = make_out(out, exclusive=not config.out)
    journal = Journal(out / JOURNAL, command="run")
    journal.open(fresh=not config.resume)  # locked: a second run into this --out stops here
    try:
        done = _resumable(config, user, out, tasks, repair=True) if config.resume else {}
        try:
            atomic_write_json(out / "config.json", _config_record(config, user, out))  # what --resume compares
            return _run(config, user, user_bytes, out, journal, tasks, done)
        except WriteError as exc:  # a full disk: say the command that resumes (the journal is kept)
            if config.command != "run":  # `paper`, `speed` and train's evaluations have no --resume
                raise
            again = f"resume: the same command with --out {out} --resume"
            resume = ("--out", str(out), "--resume")
            raise write_error(exc.path, exc.os_error, exc.kept, again=again, resume=resume) from None
    finally:
        journal.close()


def _config_record(config: EvalConfig, user: dict, out: Path) -> dict:
    """config.json of a run: the resolved config, the output folder and the user's policy objects' classes."""
    cfg = config.to_dict()
    cfg["out"] = str(out)
    cfg["policy_objects"] = {name: type(obj).__name__ for name, obj in user.items()}
    return cfg


def _resumable(config: EvalConfig, user: dict, out: Path, tasks: list, repair: bool) -> dict[tuple, dict]:
    """The journaled records a `--resume` of `out` keeps ({episode key: record}); EvalError if `out` holds no
    run of `config.command`, a run with other settings, or episodes of other code (`eval.grid.same_code`)."""
    if not (out / JOURNAL).is_file():
        raise EvalError(f"--out {str(out)!r} holds no {config.command} to resume (no {JOURNAL}); drop --resume")
    done, _ = Journal(out / JOURNAL, command="run").load(repair=repair, key=run_key)
    if not done:  # nothing to keep (the disk was full before the first episode ended): nothing to compare
        return done
    old = read_folder_record(out, "config.json", config.command)
    same_settings(old, config.to_dict(), out, config.command, RUN_FIXED_KEYS)
    return same_code(done, tasks, config.rerun_changed, f"--out {str(out)!r}", key=run_key)


def _run(
    config: EvalConfig,
    user: dict,
    user_bytes: bytes | None,
    out: Path,
    journal: Journal,
    tasks: list,
    done: dict[tuple, dict],
) -> RunResult:
    """The episodes not in `done` (the grid engine: each record journaled as it ends) and the report of `run`,
    once everything is checked; `done` holds the journaled records a `--resume` keeps."""
    todo = [t for t in tasks if run_key(t) not in done]
    grid = run_tasks(config, user, todo, user_bytes, journal, progress=config.progress, desc="episodes")
    arrays, wall, interrupted = grid.arrays, grid.wall_s, grid.interrupted
    rec_by_index = {**grid.lost, **grid.records}
    ran = {t.index for t in todo}
    rec_by_index.update({t.index: {**done[run_key(t)], "episode": t.episode} for t in tasks if t.index not in ran})
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

    cfg = _config_record(config, user, out)
    finished = [r for r in records if r["status"] != "interrupted"]
    results = build_results(cfg, records, M.aggregate(finished), wall_s=wall)
    result = RunResult(out=out, results=results, arrays=arrays)
    with interrupts_deferred(reraise=not interrupted):  # a Ctrl-C or SIGTERM now does not cut the report short
        try:
            written = write_run(result, config) + [journal.path]
        except WriteError as exc:  # a full disk: what finished is in the journal
            raise write_error(
                exc.path, exc.os_error, f"the {len(finished)} finished episodes are in {journal.path}"
            ) from None
    if interrupted:
        raise RunInterrupted(
            f"interrupted: {len(finished)} of {len(records)} episodes finished; results written to {out} "
            f'(the others have status "interrupted"'
            + (f"; the same command with --out {out} --resume runs them)" if config.command == "run" else ")")
        )
    if config.video:
        written += write_videos(result, config, user)
    if config.overwrite:
        remove_stale(out, RUN_OUTPUTS, set(written))
    if config.progress:
        print_results(results, out, config.stdout_format)
    return result

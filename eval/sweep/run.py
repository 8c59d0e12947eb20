"""`run_sweep`: run the episodes of a sweep grid not yet in its journal, then rebuild the tables (resumable; see
the package docstring)."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval.checks import check_all, check_user_policies
from eval.conditions import condition_name
from eval.config import EvalConfig, Execution
from eval.errors import EvalError
from eval.execution.tasks import Task
from eval.grid import FIXED_KEYS, name_conditions, run_tasks, same_code, same_settings
from eval.output.files import atomic_write_json, check_out, read_folder_record, slug
from eval.output.journal import JOURNAL, Journal, episode_key
from eval.output.results import ResultsView, build_results
from eval.rollout import make_env
from eval.sweep.config import SweepConfig
from eval.sweep.report import write_tables
from mobman_env.validation import integer

__all__ = [
    "FIXED_KEYS",
    "GridResult",
    "SweepResult",
    "check_sweep",
    "grid_tasks",
    "run_grid",
    "run_sweep",
]  # FIXED_KEYS: eval.grid's


def grid_tasks(sweep: SweepConfig, policy_names: list[str]) -> list[Task]:
    """Every episode of the grid in table order: env, dynamics, model_error, obs_noise, policy, seed. Each
    (dynamics, model_error, obs_noise) is one condition, named from its env arguments (the table's name when they
    are exactly a table entry's: `eval.conditions.condition_name`)."""
    tasks: list[Task] = []
    for env_id in sweep.envs:
        for dyn in sweep.dynamics:
            for me in sweep.model_error:
                for on in sweep.obs_noise:
                    cond = condition_name({**sweep.env_kwargs, "dynamics": dyn, "model_error": me, "obs_noise": on})
                    for name in policy_names:
                        for k, seed in enumerate(sweep.seeds):
                            tasks.append(Task(len(tasks), env_id, dyn, name, k, seed, me, on, cond))
    return tasks


@dataclass
class SweepResult(ResultsView):
    """What `run_sweep` returns: the output directory, the results.json content and this run's counts."""

    out: Path
    results: dict
    n_run: int  # episodes run now
    n_skipped: int  # episodes already in the journal
    n_left: int  # episodes of the grid still to run (max_episodes, or interrupted)


def default_out(source: str | None) -> Path:
    stem = Path(source).stem if source else "sweep"
    return Path("runs") / f"sweep-{slug(stem)}"


def run_sweep(
    sweep: SweepConfig,
    out: str | Path | None = None,
    *,
    backend: str = "local",
    address: str | None = None,
    workers: int = 1,
    batch_size: int = EvalConfig.batch_size,
    max_episodes: int | None = None,
    retry_failed: bool = False,
    rerun_changed: bool = False,
    plots: bool = True,
    progress: bool = True,
    policies: dict[str, Any] | None = None,
    source: str | None = None,
    checked: tuple[EvalConfig, bytes | None, bool] | None = None,
) -> SweepResult:
    """Run the episodes of `sweep` not yet in `out`, then rebuild the table, summary and plots.

    A journal holding episodes of other code than this is refused (EvalError), or with `rerun_changed` those
    episodes run again (`eval.grid.same_code`: one result, one code version). `policies` adds the user's own objects ({name: object with predict/reset}) beside the specs; `source` is
    the YAML file's path (recorded, and naming the default output directory); `checked` is what `check_sweep`
    returned for these arguments, when the caller (a bench) checked them already."""
    user = dict(policies or {})
    out = Path(out) if out is not None else default_out(source)
    if max_episodes is not None:
        integer("max_episodes", max_episodes, low=0, error=EvalError)
    base, user_bytes, resuming = checked or check_sweep(
        sweep, out, backend, address, workers, batch_size, user, rerun_changed
    )

    tasks = grid_tasks(sweep, list(sweep.policies) + list(user))
    cfg = {
        "command": "sweep",
        "source": source,
        **sweep.to_dict(),
        "policy_objects": {name: type(obj).__name__ for name, obj in user.items()},
        **{
            "out": str(out),
            "backend": backend,
            "address": address,
            "workers": workers,
            "batch_size": batch_size,
            "n_episodes": len(tasks),
        },
    }
    res = run_grid(
        tasks,
        base,
        user,
        user_bytes,
        out,
        cfg,
        retry_failed=retry_failed,
        rerun_changed=rerun_changed,
        max_episodes=max_episodes,
        progress=progress,
        resuming=resuming,
        command="sweep",
    )
    write_tables(out, res.results, sweep.tolerance, plots)  # interrupted or not: the table shows what finished
    if res.interrupted:
        raise KeyboardInterrupt
    return SweepResult(out=out, results=res.results, n_run=res.n_run, n_skipped=res.n_skipped, n_left=res.n_left)


@dataclass
class GridResult:
    """What `run_grid` returns: the results.json content of the whole grid and this run's counts."""

    results: dict
    n_run: int
    n_skipped: int
    n_left: int
    interrupted: bool


def run_grid(
    tasks: list[Task],
    base: EvalConfig,
    user: dict[str, Any],
    user_bytes: bytes | None,
    out: Path,
    cfg: dict,
    *,
    retry_failed: bool,
    rerun_changed: bool,
    max_episodes: int | None,
    progress: bool,
    resuming: bool,
    command: str,
) -> GridResult:
    """Run the `tasks` not yet in `out`'s journal (one journal, one results file: a sweep's or a bench's grid)
    and return the results of every task that has a record; config.json is `cfg`. The caller writes the files
    and raises KeyboardInterrupt when `interrupted`."""
    out.mkdir(parents=True, exist_ok=True)
    journal = Journal(out / JOURNAL, command)
    journal.open()  # locked before anything is written or read: a second grid on this --out stops here
    try:
        atomic_write_json(out / "config.json", cfg)  # the directory is this command's from now on
        done, dropped = journal.load()
        done = name_conditions(done, dict(base.env_kwargs))
        done = same_code(done, tasks, rerun_changed, f"--out {str(out)!r}")  # under the lock, as it runs
        if dropped and progress:
            print(
                f"{command}: dropped {dropped} unreadable line(s) of {journal.path} (torn by an interruption, or "
                f"not an episode record); their episodes run again",
                file=sys.stderr,
            )
        todo, n_skipped = _plan(tasks, done, retry_failed, max_episodes)
        if progress:
            print(
                f"{command}: {len(tasks)} episodes in the grid, {n_skipped} already in {out}"
                f"{' (resuming)' if resuming else ''}, {len(todo)} to run now",
                file=sys.stderr,
            )
        grid = run_tasks(base, user, todo, user_bytes, journal, progress=progress, desc=command)
        done.update({episode_key(r): r for r in grid.records.values()})
        lost = {episode_key(r): r for r in grid.lost.values()}
        records = _grid_records(tasks, done, lost)
        results = build_results(cfg, records, M.aggregate(records), wall_s=grid.wall_s)
    finally:
        journal.close()
    n_left = sum(episode_key(t) not in done for t in tasks)
    return GridResult(results, grid.n_run, n_skipped, n_left, grid.interrupted)


def check_sweep(
    sweep: SweepConfig,
    out: Path,
    backend: str = "local",
    address: str | None = None,
    workers: int = 1,
    batch_size: int = EvalConfig.batch_size,
    user: dict[str, Any] | None = None,
    rerun_changed: bool = False,
    checked: tuple[str, ...] = (),
) -> tuple[EvalConfig, bytes | None, bool]:
    """Every check of `run_sweep` before it writes anything (the settings, the output folder and the code of its
    journal's episodes, every env and policy of the grid): (the episodes' EvalConfig, the pickled user
    policies, whether `out` is resumed); EvalError naming what is wrong. A bench checks all its conditions with
    it before writing bench.json (`checked`: the specs its pre-flight built on these envs already,
    `eval.checks.check_all`)."""
    user = user or {}
    base = _episode_config(sweep, out, backend, address, workers, batch_size)
    if not sweep.policies and not user:
        raise EvalError("no policy given; list policy specs under 'policies' in the sweep file")
    user_bytes = check_user_policies(user, sweep.policies, workers if backend == "local" else 1)
    resuming = _check_out_dir(out, sweep, check_out)
    if resuming:  # read only (no lock yet): run_sweep checks again under the lock
        done, _ = Journal(out / JOURNAL).load(repair=False)
        done = name_conditions(done, dict(sweep.env_kwargs))
        same_code(done, grid_tasks(sweep, list(sweep.policies) + list(user)), rerun_changed, f"--out {str(out)!r}")
    check_all(base, user, checked)
    _check_conditions(sweep)
    return base, user_bytes, resuming


def _episode_config(
    sweep: SweepConfig, out: Path, backend: str, address: str | None, workers: int, batch_size: int
) -> EvalConfig:
    """The `EvalConfig` every episode of the sweep runs under (each task brings its own condition and seed)."""
    return Execution(backend, address, workers, batch_size).episode_config(
        out,
        "sweep",
        envs=sweep.envs,
        policies=sweep.policies,
        episodes=len(sweep.seeds),
        seed=sweep.seeds[0],
        dynamics=sweep.dynamics,
        model_error=sweep.model_error[0],
        obs_noise=sweep.obs_noise[0],
        env_kwargs=sweep.env_kwargs,
        tolerance=sweep.tolerance,
        settle_time=sweep.settle_time,
    )


def _plan(
    tasks: list[Task], done: dict[tuple, dict], retry_failed: bool, max_episodes: int | None
) -> tuple[list[Task], int]:
    """(the tasks to run now, in grid order; how many the journal already has): episodes without a record, and
    with `retry_failed` those recorded as failed; at most `max_episodes` of them."""
    todo = [
        t for t in tasks if episode_key(t) not in done or (retry_failed and done[episode_key(t)].get("status") != "ok")
    ]
    n_skipped = len(tasks) - len(todo)
    return (todo if max_episodes is None else todo[:max_episodes]), n_skipped


def _grid_records(tasks: list[Task], done: dict[tuple, dict], lost: dict[tuple, dict]) -> list[dict]:
    """The records of the grid's episodes that have one, in grid order (whatever order they ran in)."""
    records: list[dict] = []
    for t in tasks:
        rec = done.get(episode_key(t)) or lost.get(episode_key(t))
        if rec is not None:
            records.append({**rec, "episode": t.episode, "index": len(records), "arrays_key": None})
    return records


def _check_out_dir(out: Path, sweep: SweepConfig, check_out) -> bool:
    """True if `out` holds a sweep to resume; EvalError if it holds something else or an incompatible sweep."""
    if not out.is_dir() or not any(out.iterdir()):
        check_out(out, overwrite=False)
        return False
    same_settings(read_folder_record(out, "config.json", "sweep"), sweep.to_dict(), out, "sweep")
    return True


def _check_conditions(sweep: SweepConfig) -> None:
    """Every model_error and obs_noise value builds an env (the other grid values were checked by check_all)."""

    for me in sweep.model_error:
        for on in sweep.obs_noise:
            try:
                env = make_env(sweep.envs[0], sweep.dynamics[0], me, on, sweep.env_kwargs)
            except Exception as exc:
                raise EvalError(
                    f"cannot make {sweep.envs[0]!r} with model_error={me!r}, obs_noise={on!r}: {exc}"
                ) from None
            env.close()

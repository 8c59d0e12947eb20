"""`mobman-eval sweep --config sweep.yaml`: a grid of episodes, one tidy results table, summary plots; resumable.

The grid (`eval.sweep_config`): every (env, dynamics, model_error, obs_noise, policy, seed) is one episode, run
by the same executors as `mobman-eval run` (`--workers N` local processes or `--backend ray`), so a sweep
episode equals the `run` episode of the same settings.

Output directory (default `runs/sweep-<config file stem>`, so running the same command again resumes):

| file | content |
|---|---|
| `episodes.jsonl` | the journal: one complete episode record per line, appended (one `write`) as each ends |
| `results.json` | schema 1 like `mobman-eval run`: config, versions, git, episodes (grid order), aggregate |
| `results.csv` | the tidy table: one row per episode, the columns of `run`'s results.csv |
| `aggregate.csv` | per (env, policy, dynamics, model_error, obs_noise): n, failures, success rate, error stats |
| `summary.md` | success rate and max error per policy and condition, in mm |
| `config.json` | the resolved sweep (grid, env_kwargs, tolerance) and how it last ran |
| `plots/<env>_<dynamics>_vs_<variable>.png` | success rate and max error vs model_error or obs_noise, per policy |

**Resuming.** An episode is identified by (env, policy, seed, dynamics, model_error, obs_noise). Episodes with a
record in the journal are skipped; the others run, in grid order. The journal is append-only and written by
this process alone (the workers send records back): a record is either complete or, if the process was
killed in the middle of its line, a torn last line that the next run drops (and runs that episode again). The
table files are rebuilt from the journal, in grid order, after every run and written atomically, so a sweep
interrupted at any point and run again gives the same table as one uninterrupted run (timing and pid fields
aside). `--max-episodes N` runs at most N new episodes (a job that must fit a time slot). Episodes that
produced no result at all (their worker process died, their Ray task failed twice) are in the table as failed
but not in the journal, so the next run tries them again; episodes that crashed inside the rollout are results
(status failed, traceback) and are skipped unless `--retry-failed`. The grid may grow between runs (more seeds,
policies, noise levels); `env_kwargs` and `tolerance` may not change (start a new --out).
"""

from __future__ import annotations

import csv
import io
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval import report
from eval.config import BACKEND_CHOICES, EvalConfig, EvalError
from eval.sweep_config import SweepConfig, example_path, load_sweep
from eval.workers import Task

JOURNAL = "episodes.jsonl"

#: settings that must not change when a sweep is resumed (they change every episode's result)
FIXED_KEYS = ("env_kwargs", "tolerance")


def episode_key(rec: dict | Task) -> tuple:
    """(env, policy, seed, dynamics, model_error, obs_noise) of a record or a task: what identifies an episode."""
    get = rec.get if isinstance(rec, dict) else lambda k: getattr(rec, k)
    return (
        get("env"),
        get("policy"),
        int(get("seed")),
        get("dynamics"),
        float(get("model_error")),
        float(get("obs_noise")),
    )


def grid_tasks(sweep: SweepConfig, policy_names: list[str]) -> list[Task]:
    """Every episode of the grid in table order: env, dynamics, model_error, obs_noise, policy, seed."""
    tasks = []
    for env_id in sweep.envs:
        for dyn in sweep.dynamics:
            for me in sweep.model_error:
                for on in sweep.obs_noise:
                    for name in policy_names:
                        for k, seed in enumerate(sweep.seeds):
                            tasks.append(Task(len(tasks), env_id, dyn, name, k, seed, me, on))
    return tasks


# --- the journal -----------------------------------------------------------------------------------------


class Journal:
    """`episodes.jsonl`: one complete JSON episode record per line; later lines win for the same episode."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self._fd: int | None = None

    def load(self) -> tuple[dict[tuple, dict], int]:
        """({key: record}, number of torn lines dropped). A torn last line (the process was killed while
        writing it) is cut off the file; any other unreadable line is an error naming it."""
        if not self.path.exists():
            return {}, 0
        data = self.path.read_bytes()
        records: dict[tuple, dict] = {}
        end = data.rfind(b"\n") + 1  # everything after the last newline is a torn write
        for n, line in enumerate(data[:end].splitlines(), 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
                records[episode_key(rec)] = rec
            except (ValueError, KeyError, TypeError) as exc:
                raise EvalError(
                    f"{self.path} line {n} is not an episode record ({exc}); the file was edited or "
                    f"damaged: delete that line (its episode then runs again)"
                ) from None
        dropped = 0
        if end < len(data):
            dropped = 1
            os.truncate(self.path, end)
        return records, dropped

    def open(self) -> None:
        """Open for appending, holding an exclusive lock: two sweeps cannot write one directory at once."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            import fcntl

            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except ImportError:  # pragma: no cover - not POSIX: no lock
            pass
        except OSError:
            os.close(fd)
            raise EvalError(
                f"another sweep is writing to {self.path.parent}; wait for it or use another --out"
            ) from None
        self._fd = fd

    def append(self, rec: dict) -> None:
        """One record as one line, written with a single `write` call (the kernel appends it whole)."""
        data = (json.dumps(rec, allow_nan=False) + "\n").encode()
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]

    def close(self) -> None:
        if self._fd is not None:
            try:
                os.fsync(self._fd)
            finally:
                os.close(self._fd)
                self._fd = None


# --- the run ---------------------------------------------------------------------------------------------


@dataclass
class SweepResult(report.ResultsView):
    """What `run_sweep` returns: the output directory, the results.json content and this run's counts."""

    out: Path
    results: dict
    n_run: int  # episodes run now
    n_skipped: int  # episodes already in the journal
    n_left: int  # episodes of the grid still to run (max_episodes, or interrupted)


def default_out(source: str | None) -> Path:
    stem = Path(source).stem if source else "sweep"
    return Path("runs") / f"sweep-{report.slug(stem)}"


def run_sweep(
    sweep: SweepConfig,
    out: str | Path | None = None,
    *,
    backend: str = "local",
    address: str | None = None,
    workers: int = 1,
    max_episodes: int | None = None,
    retry_failed: bool = False,
    plots: bool = True,
    progress: bool = True,
    policies: dict[str, Any] | None = None,
    source: str | None = None,
) -> SweepResult:
    """Run the episodes of `sweep` not yet in `out`, then rebuild the table, summary and plots.

    `policies` adds the user's own objects ({name: object with predict/reset}) beside the specs; `source` is
    the YAML file's path (recorded, and naming the default output directory)."""
    from eval.checks import check_all, check_out, check_user_policies

    user = dict(policies or {})
    out = Path(out) if out is not None else default_out(source)
    if max_episodes is not None and (
        isinstance(max_episodes, bool) or not isinstance(max_episodes, int) or max_episodes < 0
    ):
        raise EvalError(f"max_episodes must be an integer >= 0, got {max_episodes!r}")
    base = EvalConfig(
        envs=sweep.envs,
        policies=sweep.policies,
        episodes=len(sweep.seeds),
        seed=sweep.seeds[0],
        out=str(out),
        overwrite=True,
        workers=workers,
        backend=backend,
        address=address,
        dynamics=sweep.dynamics,
        model_error=sweep.model_error[0],
        obs_noise=sweep.obs_noise[0],
        env_kwargs=sweep.env_kwargs,
        tolerance=sweep.tolerance,
        plots=False,
        save_arrays="none",
        progress=False,
        command="sweep",
    )
    base.validate()
    if not sweep.policies and not user:
        raise EvalError("no policy given; list policy specs under 'policies' in the sweep file")
    user_bytes = check_user_policies(user, sweep.policies, workers if backend == "local" else 1)
    resuming = _check_out_dir(out, sweep, check_out)
    check_all(base, user)
    _check_conditions(sweep)

    names = list(sweep.policies) + list(user)
    tasks = grid_tasks(sweep, names)
    cfg = {
        "command": "sweep",
        "source": source,
        **sweep.to_dict(),
        "policy_objects": {name: type(obj).__name__ for name, obj in user.items()},
        "out": str(out),
        "backend": backend,
        "address": address,
        "workers": workers,
        "n_episodes": len(tasks),
    }
    out.mkdir(parents=True, exist_ok=True)
    report.atomic_write_json(out / "config.json", cfg)  # first: the directory is a sweep's from now on
    journal = Journal(out / JOURNAL)
    journal.open()  # locked before reading: no other sweep appends meanwhile
    try:
        done, dropped = journal.load()
        if dropped and progress:
            print(f"sweep: dropped a torn last line of {journal.path} (its episode runs again)", file=sys.stderr)
        todo = [
            t
            for t in tasks
            if episode_key(t) not in done or (retry_failed and done[episode_key(t)].get("status") != "ok")
        ]
        n_skipped = len(tasks) - len(todo)
        if max_episodes is not None:
            todo = todo[:max_episodes]
        if progress:
            print(
                f"sweep: {len(tasks)} episodes in the grid, {n_skipped} already in {out}"
                f"{' (resuming)' if resuming else ''}, {len(todo)} to run now",
                file=sys.stderr,
            )
        lost: dict[tuple, dict] = {}  # episodes without any result (dead worker, failed Ray task): not journaled
        n_run = 0
        bar = _progress_bar(len(todo)) if progress and todo else None

        def on_result(rec: dict) -> None:
            nonlocal n_run
            rec = report.to_jsonable(rec)
            if rec.get("pid") is None:
                lost[episode_key(rec)] = rec
            else:
                journal.append(rec)
                done[episode_key(rec)] = rec
                lost.pop(episode_key(rec), None)
            n_run += 1
            if bar is not None:
                bar.update(1)

        t0 = time.perf_counter()
        try:
            if todo:
                from eval.workers import execute

                execute(base, user, todo, user_bytes, on_result)
        finally:  # interrupted or not: the table shows what the journal holds
            if bar is not None:
                bar.close()
            records = []
            for t in tasks:  # grid order, whatever order the episodes ran in
                rec = done.get(episode_key(t)) or lost.get(episode_key(t))
                if rec is not None:
                    records.append({**rec, "episode": t.episode, "index": len(records), "arrays_key": None})
            results = report.build_results(cfg, records, M.aggregate(records), wall_s=time.perf_counter() - t0)
            write_tables(out, results, sweep.tolerance, plots)
    finally:
        journal.close()
    n_left = sum(episode_key(t) not in done for t in tasks)
    return SweepResult(out=out, results=results, n_run=n_run, n_skipped=n_skipped, n_left=n_left)


def _check_out_dir(out: Path, sweep: SweepConfig, check_out) -> bool:
    """True if `out` holds a sweep to resume; EvalError if it holds something else or an incompatible sweep."""
    cfg_path = out / "config.json"
    if not out.is_dir() or not any(out.iterdir()):
        check_out(out, overwrite=False)
        return False
    try:
        old = json.loads(cfg_path.read_text())
    except (OSError, ValueError):
        old = None
    if not isinstance(old, dict) or old.get("command") != "sweep":
        raise EvalError(
            f"--out {str(out)!r} exists and does not hold a sweep (no sweep config.json); choose another --out"
        )
    new = sweep.to_dict()
    changed = [k for k in FIXED_KEYS if old.get(k) != new[k]]
    if changed:
        diff = "; ".join(f"{k}: {old.get(k)!r} there, {new[k]!r} now" for k in changed)
        raise EvalError(
            f"--out {str(out)!r} holds a sweep with other settings ({diff}); its episodes would not be "
            f"comparable: use another --out, or delete that directory to start over"
        )
    return True


def _check_conditions(sweep: SweepConfig) -> None:
    """Every model_error and obs_noise value builds an env (the other grid values were checked by check_all)."""
    from eval.rollout import make_env

    for me in sweep.model_error:
        for on in sweep.obs_noise:
            try:
                env = make_env(sweep.envs[0], sweep.dynamics[0], me, on, sweep.env_kwargs)
            except Exception as exc:
                raise EvalError(
                    f"cannot make {sweep.envs[0]!r} with model_error={me!r}, obs_noise={on!r}: {exc}"
                ) from None
            env.close()


def _progress_bar(total: int):
    from tqdm import tqdm

    tty = hasattr(sys.stderr, "isatty") and sys.stderr.isatty()
    return tqdm(
        total=total, desc="sweep", unit="ep", file=sys.stderr, dynamic_ncols=True, mininterval=0.1 if tty else 5.0
    )


# --- tables, summary, plots ------------------------------------------------------------------------------

AGGREGATE_COLUMNS = (
    "env",
    "policy",
    "dynamics",
    "model_error",
    "obs_noise",
    "n",
    "n_failed",
    "n_tipped_over",
    "success_rate",
)


def aggregate_csv_text(aggregate: list[dict]) -> str:
    """One tidy row per condition; each summarised metric m gives columns m_median, m_mean, m_std, m_min, m_max."""
    stats = ("median", "mean", "std", "min", "max")
    columns = list(AGGREGATE_COLUMNS) + [f"{m}_{s}" for m in M.SUMMARY_METRICS for s in stats]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    for a in aggregate:
        row = {k: a.get(k) for k in AGGREGATE_COLUMNS}
        for m in M.SUMMARY_METRICS:
            for s in stats:
                row[f"{m}_{s}"] = (a.get(m) or {}).get(s)
        w.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return buf.getvalue()


SUMMARY_HEADER = (
    "policy",
    "model_error",
    "obs_noise (mm)",
    "n",
    "failed",
    "success",
    "max err median (mm)",
    "max err mean ± std (mm)",
    "rms median (mm)",
)


def _summary_row(a: dict) -> list[str]:
    me = a["max_error_m"]
    return [
        str(a["policy"]),
        f"{a['model_error']:g}",
        f"{a['obs_noise'] * 1e3:g}",
        str(a["n"]),
        str(a["n_failed"]),
        f"{a['success_rate'] * 100:.0f}%",
        report._mm(me["median"]),
        "-" if me["mean"] is None else f"{me['mean'] * 1e3:.2f} ± {me['std'] * 1e3:.2f}",
        report._mm(a["rms_error_m"]["median"]),
    ]


def summary_markdown(results: dict) -> str:
    cfg = results["config"]
    eps = results["episodes"]
    lines = [
        "# mobman-eval sweep",
        "",
        f"{len(eps)} of {cfg['n_episodes']} episodes of the grid; seeds {_seed_text(cfg['seeds'])}; success = max "
        f"tracking error <= {cfg['tolerance'] * 1e3:g} mm (failed or tipped-over episodes are not successes). "
        f"Errors in mm over the episodes that ran (status ok). git {results['git']}.",
        "",
    ]
    groups: dict[tuple, list[dict]] = {}
    for a in results["aggregate"]:
        groups.setdefault((a["env"], a["dynamics"]), []).append(a)
    for (env, dyn), rows in groups.items():
        rows = sorted(rows, key=lambda a: (str(a["policy"]), a["model_error"], a["obs_noise"]))
        lines += [f"## {env} — {dyn}", "", report.markdown_table(SUMMARY_HEADER, [_summary_row(a) for a in rows]), ""]
    lines += report.failed_episode_lines(
        eps,
        lambda r: (
            f"{r['env']} / {r['dynamics']} / {r['policy']} / model_error {r['model_error']} / "
            f"obs_noise {r['obs_noise']} / seed {r['seed']}"
        ),
    )
    return "\n".join(lines)


def _seed_text(seeds: list[int]) -> str:
    if seeds == list(range(seeds[0], seeds[0] + len(seeds))):
        return f"{seeds[0]}..{seeds[-1]}"
    return ", ".join(map(str, seeds))


def write_tables(out: Path, results: dict, tolerance: float, plots: bool = True) -> list[Path]:
    """results.json, results.csv, aggregate.csv, summary.md and the plots, each written atomically."""
    report.atomic_write_json(out / "results.json", results)
    report.atomic_write_text(out / "results.csv", report.csv_text(results["episodes"]))
    report.atomic_write_text(out / "aggregate.csv", aggregate_csv_text(results["aggregate"]))
    report.atomic_write_text(out / "summary.md", summary_markdown(results))
    written = []
    if plots and results["aggregate"]:
        import matplotlib.pyplot as plt

        from eval.sweep_plots import sweep_figures

        for name, fig in sweep_figures(results["aggregate"], tolerance):
            path = out / "plots" / f"{name}.png"
            report.atomic_save_figure(fig, path)
            plt.close(fig)
            written.append(path)
    return written


def print_summary(result: SweepResult) -> None:
    from rich import box
    from rich.console import Console
    from rich.table import Table

    console = Console()
    groups: dict[tuple, list[dict]] = {}
    for a in result.aggregate:
        groups.setdefault((a["env"], a["dynamics"]), []).append(a)
    for (env, dyn), rows in groups.items():
        table = Table(
            title=f"{env} — {dyn}",
            box=box.SIMPLE_HEAD,
            padding=(0, 1),
            caption="max error in mm: median over the episodes that ran",
        )
        for h in ("policy", "model err", "noise mm", "n", "failed", "succ", "max med"):
            table.add_column(h, justify="left" if h == "policy" else "right")
        for a in sorted(rows, key=lambda a: (str(a["policy"]), a["model_error"], a["obs_noise"])):
            table.add_row(
                str(a["policy"]),
                f"{a['model_error']:g}",
                f"{a['obs_noise'] * 1e3:g}",
                str(a["n"]),
                str(a["n_failed"]),
                f"{a['success_rate'] * 100:.0f}%",
                report._mm(a["max_error_m"]["median"], 1),
            )
        console.print(table)


# --- command line ----------------------------------------------------------------------------------------


def add_parser(sub) -> None:
    from eval.cli import HelpFormatter, add_backend_arguments

    p = sub.add_parser(
        "sweep",
        help="run a grid of policies x envs x seeds x model errors x noise levels from a YAML file (resumable)",
        description=__doc__.split("\n\n")[0] + " Run the same command again to resume.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--config", metavar="YAML", help="the sweep file (`--example` prints one to start from)")
    p.add_argument(
        "--out",
        default=None,
        help="output directory (default: runs/sweep-<config file stem>); an existing sweep there is resumed",
    )
    add_backend_arguments(p)
    p.add_argument(
        "--max-episodes",
        type=int,
        default=None,
        metavar="N",
        help="run at most N episodes not yet done, then write the table and stop (run again to go on)",
    )
    p.add_argument("--retry-failed", action="store_true", help="run again the episodes recorded as failed")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no table")
    p.add_argument("--example", action="store_true", help="print the example sweep file and exit")
    p.set_defaults(func=_main)


def _main(args) -> int:
    if args.example:
        sys.stdout.write(example_path().read_text())
        return 0
    if not args.config:
        raise EvalError("--config YAML is required (`mobman-eval sweep --example > sweep.yaml` writes an example)")
    if args.backend not in BACKEND_CHOICES:  # pragma: no cover - argparse checks it
        raise EvalError(f"unknown backend {args.backend!r}")
    sweep = load_sweep(args.config)
    try:
        result = run_sweep(
            sweep,
            args.out,
            backend=args.backend,
            address=args.address,
            workers=args.workers,
            max_episodes=args.max_episodes,
            retry_failed=args.retry_failed,
            plots=not args.no_plots,
            progress=not args.quiet,
            source=args.config,
        )
    except KeyboardInterrupt:
        out = Path(args.out) if args.out else default_out(args.config)
        print(
            f"\nsweep interrupted; the episodes that ended are in {out / JOURNAL} and the table; run the same "
            f"command again to go on",
            file=sys.stderr,
        )
        return 130
    if not args.quiet:
        print_summary(result)
        n_failed = sum(r["status"] != "ok" for r in result.episodes)
        n_grid = result.results["config"]["n_episodes"]
        print(
            f"{len(result.episodes)} of {n_grid} episodes in {result.out / 'results.csv'} "
            f"({result.n_run} run now, {result.n_skipped} from earlier runs, {n_failed} failed)"
        )
        if result.n_left:
            print(f"{result.n_left} episodes left: run the same command again to go on")
    return 0

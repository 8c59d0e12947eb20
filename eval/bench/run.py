"""`run_bench`: run the episodes of a bench not yet done (one grid over every condition), then write the scorecard.

Output directory (default `runs/bench`; running the same command again resumes):

| file | content |
|---|---|
| `bench.json` | the resolved bench (protocol, notes) and how it last ran |
| `episodes.jsonl` | the journal: one record per finished episode, each naming its condition |
| `results.json`, `results.csv`, `aggregate.csv`, `summary.md` | the whole grid (results schema 4), as a sweep writes them |
| `scorecard.json` | the statistics per (condition, task, controller) and pooled over tasks, read from results.json's episodes |
| `scorecard.md` | the same as Markdown, errors in mm |
| `plots/success_<condition>.png`, `plots/error_vs_wear.png` | success vs tolerance; max error vs wear |

A bench is one grid (`eval.sweep.run.run_grid`, as a sweep's): every episode of every condition in one journal
and one results file, each record naming its condition, so the scorecard groups them by that name and nothing is
re-joined. Resuming follows the sweep's rules: episodes in the journal are skipped, more seeds, controllers or
conditions may be added later; the tolerance, settle time and extra env arguments may not change (start a new
--out), nor the code (a journal of other code is refused before anything is written; `--rerun-changed` runs its
episodes again: `eval.grid.same_code`). `max_episodes` bounds the new episodes of the whole bench, in grid order
(conditions in order). A folder of mobman < 0.4's layout (one sweep per condition) is refused, not mixed.
"""

from __future__ import annotations

import sys
import time
from contextlib import nullcontext
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from eval.bench import against as A
from eval.bench.config import CONDITIONS, HELDOUT_COMMIT, HELDOUT_SHA256, PROTOCOL_VERSION, BenchConfig
from eval.bench.preflight import check_cells
from eval.bench.scorecard import (
    build_scorecard,
    scorecard_figures,
    scorecard_json_text,
    scorecard_markdown,
    track_episodes,
)
from eval.checks import check_all
from eval.config import EvalConfig, Execution
from eval.errors import EvalError
from eval.grid import same_code
from eval.output.files import atomic_save_figure, atomic_write_json, atomic_write_text, check_out, read_folder_record
from eval.output.journal import JOURNAL, FolderLock, Journal
from eval.sweep.report import write_tables
from eval.sweep.run import run_grid
from mobman_env.validation import integer

#: bench settings that must not change within one output directory
FIXED_KEYS = ("version", "tolerance", "settle_time", "env_kwargs")

DEFAULT_OUT = Path("runs") / "bench"


@dataclass
class BenchResult:
    """What `run_bench` returns: the output directory, the scorecard dict and this run's counts."""

    out: Path
    scorecard: dict
    n_run: int
    n_skipped: int
    n_left: int


def protocol_dict(cfg: BenchConfig) -> dict:
    """The resolved protocol as recorded in bench.json and scorecard.json."""
    assert cfg.conditions is not None and cfg.policies is not None
    envs = list(dict.fromkeys(e for name in cfg.conditions for e in cfg.env_ids(name)))
    return {
        "version": PROTOCOL_VERSION,
        "track": cfg.track,
        "heldout_sha256": HELDOUT_SHA256,
        "heldout_commit": HELDOUT_COMMIT,
        "heldout_release": _heldout_release(),
        "robots": list(dict.fromkeys(r for name in cfg.conditions for r in cfg.condition_robots(name))),
        "tasks": list(cfg.tasks),
        "envs": envs,
        "conditions": {
            name: {**CONDITIONS[name].to_dict(), "envs": list(cfg.env_ids(name)), "seeds": list(cfg.seed_list(name))}
            for name in cfg.conditions
        },
        "policies": list(cfg.policies),
        "seeds": list(cfg.seed_list(cfg.conditions[0])),
        "seed_start": cfg.seed_start,
        "kinematic_seeds": cfg.seeds,
        "physics_seeds": cfg.physics_seeds,
        "tolerance": cfg.tolerance,
        "settle_time": cfg.settle_time,
        "env_kwargs": dict(cfg.env_kwargs),
    }


def _heldout_release() -> dict:
    """Protocol v3's held-out draw of the newest release: its seed's committed hash and commit, and whether it is
    revealed (its conditions are then the heldout track)."""
    from eval import heldout as H

    release = max(H.RELEASE_SEED_SHA256, key=lambda r: tuple(int(x) for x in r.split(".")))
    return {
        "release": release,
        "seed_sha256": H.RELEASE_SEED_SHA256[release],
        "seed_commit": H.RELEASE_SEED_COMMIT[release],
        "revealed": release in H.REVEALED_SEEDS,
    }


def run_bench(
    config: BenchConfig,
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
    against: str | Path | None = None,
    command_line: str | None = None,
) -> BenchResult:
    """Run what is left of the bench in `out`, then write scorecard.json, scorecard.md and the plots.

    `rerun_changed`: run again the episodes the journal holds from other code (else refused: `eval.grid.same_code`).
    `command_line`: the command that ran it, kept in bench.json (None from Python). `against`: a committed bench
    (folder or scorecard.json) whose baselines' rows are reused after a sample of them is run again bit for bit
    (`eval.bench.against`); then only `config.policies` run."""
    committed, against_record = _load_against(config, against)
    cfg, notes = config.resolved()
    out = Path(out) if out is not None else DEFAULT_OUT
    _check_execution(max_episodes, workers, backend, address, batch_size)
    assert cfg.conditions is not None and cfg.policies is not None
    _check_cells(cfg, progress)
    baselines: list[str] = []
    if committed is not None and against_record is not None:
        cfg, notes, baselines = _sample_baselines(cfg, notes, committed, against_record, progress)
    protocol = protocol_dict(cfg)
    assert cfg.policies is not None
    resuming = _check_out_dir(out, protocol)
    tasks = cfg.tasks_of(cfg.policies)
    base = _episode_config(cfg, out, backend, address, workers, batch_size)
    if resuming:  # read only (no lock yet): run_grid checks again under the lock
        done, _ = Journal(out / JOURNAL).load(repair=False)
        same_code(done, tasks, rerun_changed, f"--out {str(out)!r}")
    if backend == "ray":
        check_all(replace(base, envs=()), {}, checked=cfg.policies)  # Ray installed, the address reachable
    out.mkdir(parents=True, exist_ok=True)
    with FolderLock(out, "bench"):  # a second bench on this --out stops here, before anything is written
        execution = {"backend": backend, "address": address, "workers": workers, "batch_size": batch_size}
        record = {"command": "bench", "command_line": command_line, **protocol, "notes": notes, "out": str(out)}
        atomic_write_json(out / "bench.json", {**record, **execution, "against": against_record})
        if progress:
            _announce(cfg, notes, len(tasks), out)
        t0 = time.perf_counter()
        with _ray_session(backend, address, workers):
            res = run_grid(
                tasks,
                base,
                {},
                None,
                out,
                {"command": "bench", **protocol, "out": str(out), "n_episodes": len(tasks)},
                retry_failed=retry_failed,
                rerun_changed=rerun_changed,
                max_episodes=max_episodes,
                progress=progress,
                resuming=resuming,
                command="bench",
            )
        write_tables(out, res.results, cfg.tolerance, plots=False)
        sc = build_scorecard(protocol, notes, res.results, n_expected=len(tasks), wall_s=time.perf_counter() - t0)
        if committed is not None and baselines:
            sc = A.merge(committed, sc, baselines, track_episodes(protocol, res.results))
            sc["notes"] = [
                *sc["notes"],
                f"the rows of {', '.join(baselines)} are those of {against} (samples re-run here bit for bit)",
            ]
        write_scorecard(out, sc, plots)
    if res.interrupted:
        raise KeyboardInterrupt
    return BenchResult(out=out, scorecard=sc, n_run=res.n_run, n_skipped=res.n_skipped, n_left=res.n_left)


def _load_against(config: BenchConfig, against: str | Path | None) -> tuple[dict | None, dict[str, Any] | None]:
    """The committed scorecard `--against` names and the record bench.json keeps of it (None, None without)."""
    if against is None:
        return None, None
    if config.policies is None:
        raise EvalError(
            "--against runs only your controllers beside the committed scorecard's: name them with --policy "
            "(e.g. --policy mymod:Ctrl)"
        )
    committed, sha = A.load_against(against, typed=config.policies)
    return committed, {"scorecard": str(against), "sha256": sha}


def _check_execution(
    max_episodes: int | None, workers: int, backend: str, address: str | None, batch_size: int
) -> None:
    """Refuse bad execution options before anything runs, naming the value."""
    if max_episodes is not None and (
        isinstance(max_episodes, bool) or not isinstance(max_episodes, int) or max_episodes < 0
    ):
        raise EvalError(f"max_episodes must be an integer >= 0, got {max_episodes!r}")
    EvalConfig(workers=workers, backend=backend, address=address).validate_backend()
    integer("batch_size", batch_size, low=1, hint="e.g. --batch-size 64", error=EvalError)


def _sample_baselines(
    cfg: BenchConfig, notes: list[str], committed: dict, against_record: dict[str, Any], progress: bool
) -> tuple[BenchConfig, list[str], list[str]]:
    """`--against`: run a sample of the committed baselines' episodes again (recorded in `against_record`). Equal
    bit for bit: (cfg, notes, the baselines whose committed rows are reused). Otherwise the baselines join the
    run and none is reused, with a note."""
    A.check_protocol(committed, protocol_dict(cfg))
    assert cfg.policies is not None and cfg.conditions is not None
    baselines = [q for q in committed["protocol"]["policies"] if q not in cfg.policies]
    samples = A.pick_samples(committed, baselines, list(cfg.conditions))
    same, lines = A.check_samples(committed, samples)
    against_record.update(samples_equal=same, samples=lines)
    if progress:
        print("bench --against: " + "\n  ".join(["committed baselines re-run here:", *lines]), file=sys.stderr)
    if same:
        return cfg, notes, baselines
    notes = [
        *notes,
        f"--against {against_record['scorecard']}: a committed baseline episode differs on this machine (see "
        "bench.json); the baselines were run again here",
    ]
    return replace(cfg, policies=(*cfg.policies, *baselines)), notes, []


def _check_cells(cfg: BenchConfig, progress: bool) -> None:
    """Build every controller on every cell before any episode runs (`check_cells`), saying so: an sb3: agent
    loads torch and is built on each of ~100 cells, seconds that should not be silent."""
    assert cfg.conditions is not None and cfg.policies is not None
    if progress:
        n_cells = sum(len(cfg.env_ids(name)) for name in cfg.conditions)
        print(f"bench: building {len(cfg.policies)} controller(s) on each of {n_cells} cells ...", file=sys.stderr)
    for line in check_cells(cfg):
        if progress:
            print(f"bench: {line}", file=sys.stderr)


def _announce(cfg: BenchConfig, notes: list[str], n_tasks: int, out: Path) -> None:
    """The bench's notes and what it runs, on stderr."""
    assert cfg.policies is not None
    for n in notes:
        print(f"bench: {n}", file=sys.stderr)
    print(
        f"bench: track {cfg.track}, {len(cfg.conditions or ())} conditions x {len(cfg.policies)} controllers "
        f"({cfg.seeds} kinematic and {cfg.physics_seeds} physics seeds per cell) = {n_tasks} episodes in {out}",
        file=sys.stderr,
    )


def _episode_config(
    cfg: BenchConfig, out: Path, backend: str, address: str | None, workers: int, batch_size: int
) -> EvalConfig:
    """The `EvalConfig` every episode of the bench runs under (each task brings its condition and seed)."""
    assert cfg.policies is not None and cfg.conditions is not None
    return Execution(backend, address, workers, batch_size).episode_config(
        out,
        "bench",
        envs=tuple(dict.fromkeys(e for name in cfg.conditions for e in cfg.env_ids(name))),
        policies=cfg.policies,
        episodes=cfg.seeds,
        seed=cfg.seed_start,
        dynamics=tuple(dict.fromkeys(CONDITIONS[name].dynamics for name in cfg.conditions)),
        env_kwargs=dict(cfg.env_kwargs),
        tolerance=cfg.tolerance,
        settle_time=cfg.settle_time,
    )


def write_scorecard(out: Path, sc: dict, plots: bool = True) -> list[Path]:
    """scorecard.json, (with `plots`) the PNGs, and scorecard.md showing them, each written atomically."""
    atomic_write_text(out / "scorecard.json", scorecard_json_text(sc))
    written = [out / "scorecard.json"]
    stems = []
    if plots and sc["pooled"]:
        import matplotlib.pyplot as plt

        for stem, fig in scorecard_figures(sc):
            path = out / "plots" / f"{stem}.png"
            atomic_save_figure(fig, path)
            plt.close(fig)
            written.append(path)
            stems.append(stem)
    atomic_write_text(out / "scorecard.md", scorecard_markdown(sc, stems))
    return [*written, out / "scorecard.md"]


def _ray_session(backend: str, address: str | None, workers: int):
    """One Ray instance for all the conditions (each sweep would otherwise start and stop its own)."""
    if backend != "ray":
        return nullcontext()
    from eval.execution.ray_backend import ray_session

    return ray_session(EvalConfig(backend="ray", address=address, workers=workers))


def _check_out_dir(out: Path, protocol: dict) -> bool:
    """True if `out` holds a bench to resume, False if it is new or empty; EvalError if it holds something else,
    a bench with other fixed settings (naming the difference) or a bench of mobman < 0.4 (one folder per
    condition)."""
    if not out.is_dir() or not any(out.iterdir()):
        check_out(out, overwrite=False)
        return False
    old = read_folder_record(out, "bench.json", "bench")
    if (out / "conditions").is_dir() and not (out / JOURNAL).exists():
        raise EvalError(
            f"--out {str(out)!r} holds a bench of mobman < 0.4 (one folder per condition under conditions/), which "
            f"this version neither resumes nor mixes with its own (one results file for the whole bench): use "
            f"another --out"
        )
    changed = [k for k in FIXED_KEYS if old.get(k) != protocol[k]]
    if changed:
        diff = "; ".join(f"{k}: {old.get(k)!r} there, {protocol[k]!r} now" for k in changed)
        raise EvalError(
            f"--out {str(out)!r} holds a bench with other settings ({diff}); its episodes would not be "
            f"comparable: use another --out, or delete that directory to start over"
        )
    return True

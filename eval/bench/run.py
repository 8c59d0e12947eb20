"""`run_bench`: run the episodes of a bench not yet done (one sweep per condition), then write the scorecard.

Output directory (default `runs/bench`; running the same command again resumes):

| file | content |
|---|---|
| `bench.json` | the resolved bench (protocol, notes) and how it last ran |
| `conditions/<name>/` | a complete `mobman-eval sweep` directory per condition: journal, results.json, tables |
| `scorecard.json` | schema 2 statistics per (condition, task, controller) and pooled over tasks |
| `scorecard.md` | the same as Markdown, errors in mm |
| `plots/success_<condition>.png`, `plots/error_vs_wear.png` | success vs tolerance; max error vs wear |

Resuming follows the sweep's rules per condition (`eval.sweep`): episodes in a journal are skipped, more seeds,
controllers or conditions may be added later; the tolerance, settle time and extra env arguments may not change
(start a new --out), nor the code (a journal of other code is refused before anything is written; `--rerun-changed`
runs its episodes again: `eval.grid.same_code`). `max_episodes` bounds the new episodes of the whole bench, conditions in order.
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
from eval.config import EvalConfig
from eval.errors import EvalError
from eval.output.files import atomic_save_figure, atomic_write_json, atomic_write_text, check_out, read_folder_record
from eval.output.journal import FolderLock
from eval.sweep.config import SweepConfig
from eval.sweep.run import check_sweep, run_sweep
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


def sweep_for(cfg: BenchConfig, condition: str) -> SweepConfig:
    """The sweep grid of one condition of a resolved bench: its robots x tasks, the controllers, its seeds."""
    c = CONDITIONS[condition]
    return SweepConfig(
        envs=cfg.env_ids(condition),
        policies=tuple(cfg.policies or ()),
        seeds=cfg.seed_list(condition),
        dynamics=(c.dynamics,),
        model_error=(c.model_error,),
        obs_noise=(c.obs_noise,),
        env_kwargs={**dict(cfg.env_kwargs), **dict(c.env_kwargs)},
        tolerance=cfg.tolerance,
        settle_time=cfg.settle_time,
    )


def protocol_dict(cfg: BenchConfig) -> dict:
    """The resolved protocol as recorded in bench.json and scorecard.json."""
    assert cfg.conditions is not None and cfg.policies is not None
    envs = list(dict.fromkeys(e for name in cfg.conditions for e in cfg.env_ids(name)))
    return {
        "version": PROTOCOL_VERSION,
        "track": cfg.track,
        "heldout_sha256": HELDOUT_SHA256,
        "heldout_commit": HELDOUT_COMMIT,
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
) -> BenchResult:
    """Run what is left of the bench in `out`, then write scorecard.json, scorecard.md and the plots.

    `rerun_changed`: run again the episodes a condition's journal holds from other code (without it such a
    journal is refused before anything is written: `eval.grid.same_code`). `against`: a committed bench (folder or scorecard.json) whose baselines' rows are reused after a sample of
    them is run again bit for bit (`eval.bench.against`); then only `config.policies` run."""
    committed: dict | None = None
    against_record: dict[str, Any] | None = None
    if against is not None:
        if config.policies is None:
            raise EvalError(
                "--against runs only your controllers beside the committed scorecard's: name them with --policy "
                "(e.g. --policy mymod:Ctrl)"
            )
        committed, sha = A.load_against(against, typed=config.policies)
        against_record = {"scorecard": str(against), "sha256": sha}
    cfg, notes = config.resolved()
    out = Path(out) if out is not None else DEFAULT_OUT
    if max_episodes is not None and (
        isinstance(max_episodes, bool) or not isinstance(max_episodes, int) or max_episodes < 0
    ):
        raise EvalError(f"max_episodes must be an integer >= 0, got {max_episodes!r}")
    EvalConfig(workers=workers, backend=backend, address=address).validate_backend()
    integer("batch_size", batch_size, low=1, hint="e.g. --batch-size 64", error=EvalError)
    assert cfg.conditions is not None and cfg.policies is not None
    preflown = cfg.policies  # every cell of every spec given, built before any episode (the --against samples too)
    if progress:  # an sb3: agent loads torch and is built on each of ~100 cells: seconds, not silent
        n_cells = sum(len(cfg.env_ids(name)) for name in cfg.conditions)
        print(f"bench: building {len(cfg.policies)} controller(s) on each of {n_cells} cells ...", file=sys.stderr)
    for line in check_cells(cfg, {name: sweep_for(cfg, name) for name in cfg.conditions}):
        if progress:
            print(f"bench: {line}", file=sys.stderr)
    protocol = protocol_dict(cfg)
    baselines: list[str] = []
    if committed is not None:
        A.check_protocol(committed, protocol)
        assert cfg.policies is not None and cfg.conditions is not None and against_record is not None
        baselines = [q for q in committed["protocol"]["policies"] if q not in cfg.policies]
        samples = A.pick_samples(committed, baselines, list(cfg.conditions))
        same, lines = A.check_samples(committed, samples)
        against_record.update(samples_equal=same, samples=lines)
        if progress:
            print("bench --against: " + "\n  ".join(["committed baselines re-run here:", *lines]), file=sys.stderr)
        if not same:
            notes = [
                *notes,
                f"--against {against}: a committed baseline episode differs on this machine (see bench.json); the "
                "baselines were run again here",
            ]
            cfg = replace(cfg, policies=(*cfg.policies, *baselines))
            protocol = protocol_dict(cfg)
            baselines = []
    _check_out_dir(out, protocol)
    sweeps = {name: sweep_for(cfg, name) for name in protocol["conditions"]}
    checked = {  # every condition's envs, policies and folder, before bench.json changes
        name: check_sweep(
            sweep,
            out / "conditions" / name,
            backend,
            address,
            workers,
            batch_size,
            None,
            rerun_changed,
            checked=preflown,
        )
        for name, sweep in sweeps.items()
    }
    out.mkdir(parents=True, exist_ok=True)
    with FolderLock(out, "bench"):  # a second bench on this --out stops here, before anything is written
        atomic_write_json(
            out / "bench.json",
            {
                "command": "bench",
                **protocol,
                "notes": notes,
                "out": str(out),
                "backend": backend,
                "address": address,
                "workers": workers,
                "batch_size": batch_size,
                "against": against_record,
            },
        )
        n_expected = sum(s.n_episodes for s in sweeps.values())
        if progress:
            for n in notes:
                print(f"bench: {n}", file=sys.stderr)
            print(
                f"bench: track {cfg.track}, {len(sweeps)} conditions x {len(cfg.policies or ())} controllers "
                f"({cfg.seeds} kinematic and {cfg.physics_seeds} physics seeds per cell) = {n_expected} episodes in "
                f"{out}",
                file=sys.stderr,
            )
        results: dict[str, dict] = {}
        n_run = n_skipped = n_left = 0
        budget = max_episodes
        t0 = time.perf_counter()
        session = _ray_session(backend, address, workers)
        with session:
            for name, sweep in sweeps.items():
                if progress:
                    print(f"bench: condition {name}: {CONDITIONS[name].description}", file=sys.stderr)
                res = run_sweep(
                    sweep,
                    out / "conditions" / name,
                    backend=backend,
                    address=address,
                    workers=workers,
                    batch_size=batch_size,
                    max_episodes=budget,
                    retry_failed=retry_failed,
                    rerun_changed=rerun_changed,
                    plots=False,
                    progress=progress,
                    checked=checked[name],
                )
                results[name] = res.results
                n_run += res.n_run
                n_skipped += res.n_skipped
                n_left += res.n_left
                if budget is not None:
                    budget = max(0, budget - res.n_run)
        sc = build_scorecard(protocol, notes, results, n_expected=n_expected, wall_s=time.perf_counter() - t0)
        if committed is not None and baselines:
            sc = A.merge(committed, sc, baselines, track_episodes(protocol, results))
            sc["notes"] = [
                *sc["notes"],
                f"the rows of {', '.join(baselines)} are those of {against} (samples re-run here bit for bit)",
            ]
        write_scorecard(out, sc, plots)
        return BenchResult(out=out, scorecard=sc, n_run=n_run, n_skipped=n_skipped, n_left=n_left)


def write_scorecard(out: Path, sc: dict, plots: bool = True) -> list[Path]:
    """scorecard.json, scorecard.md and (with `plots`) the PNGs, each written atomically."""
    atomic_write_text(out / "scorecard.json", scorecard_json_text(sc))
    atomic_write_text(out / "scorecard.md", scorecard_markdown(sc))
    written = [out / "scorecard.json", out / "scorecard.md"]
    if plots and sc["pooled"]:
        import matplotlib.pyplot as plt

        for stem, fig in scorecard_figures(sc):
            path = out / "plots" / f"{stem}.png"
            atomic_save_figure(fig, path)
            plt.close(fig)
            written.append(path)
    return written


def _ray_session(backend: str, address: str | None, workers: int):
    """One Ray instance for all the conditions (each sweep would otherwise start and stop its own)."""
    if backend != "ray":
        return nullcontext()
    from eval.execution.ray_backend import ray_session

    return ray_session(EvalConfig(backend="ray", address=address, workers=workers))


def _check_out_dir(out: Path, protocol: dict) -> None:
    """`out` is new, empty, or a bench with the same fixed settings; else EvalError naming the difference."""
    if not out.is_dir() or not any(out.iterdir()):
        check_out(out, overwrite=False)
        return
    old = read_folder_record(out, "bench.json", "bench")
    changed = [k for k in FIXED_KEYS if old.get(k) != protocol[k]]
    if changed:
        diff = "; ".join(f"{k}: {old.get(k)!r} there, {protocol[k]!r} now" for k in changed)
        raise EvalError(
            f"--out {str(out)!r} holds a bench with other settings ({diff}); its episodes would not be "
            f"comparable: use another --out, or delete that directory to start over"
        )

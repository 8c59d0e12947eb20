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
(start a new --out). `max_episodes` bounds the new episodes of the whole bench, conditions in order.
"""

from __future__ import annotations

import json
import sys
import time
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path

from eval.bench.config import CONDITIONS, BenchConfig
from eval.bench.scorecard import build_scorecard, scorecard_figures, scorecard_json_text, scorecard_markdown
from eval.config import EvalConfig
from eval.errors import EvalError
from eval.output.files import atomic_save_figure, atomic_write_json, atomic_write_text, check_out
from eval.sweep.config import SweepConfig
from eval.sweep.run import run_sweep
from mobman_env.validation import integer

#: bench settings that must not change within one output directory
FIXED_KEYS = ("tolerance", "settle_time", "env_kwargs")

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
    """The sweep grid of one condition of a resolved bench."""
    c = CONDITIONS[condition]
    return SweepConfig(
        envs=cfg.env_ids(),
        policies=tuple(cfg.policies or ()),
        seeds=cfg.seed_list,
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
    return {
        "version": 1,
        "robots": list(cfg.robots),
        "tasks": list(cfg.tasks),
        "envs": list(cfg.env_ids()),
        "conditions": {name: CONDITIONS[name].to_dict() for name in cfg.conditions},
        "policies": list(cfg.policies),
        "seeds": list(cfg.seed_list),
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
    plots: bool = True,
    progress: bool = True,
) -> BenchResult:
    """Run what is left of the bench in `out`, then write scorecard.json, scorecard.md and the plots."""
    cfg, notes = config.resolved()
    out = Path(out) if out is not None else DEFAULT_OUT
    if max_episodes is not None and (
        isinstance(max_episodes, bool) or not isinstance(max_episodes, int) or max_episodes < 0
    ):
        raise EvalError(f"max_episodes must be an integer >= 0, got {max_episodes!r}")
    EvalConfig(workers=workers, backend=backend, address=address).validate_backend()
    integer("batch_size", batch_size, low=1, hint="e.g. --batch-size 64", error=EvalError)
    protocol = protocol_dict(cfg)
    _check_out_dir(out, protocol)
    sweeps = {name: sweep_for(cfg, name) for name in protocol["conditions"]}
    out.mkdir(parents=True, exist_ok=True)
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
        },
    )
    n_expected = sum(s.n_episodes for s in sweeps.values())
    if progress:
        for n in notes:
            print(f"bench: {n}", file=sys.stderr)
        print(
            f"bench: {len(protocol['envs'])} tasks x {len(sweeps)} conditions x {len(cfg.policies or ())} "
            f"controllers x {cfg.seeds} seeds = {n_expected} episodes in {out}",
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
                plots=False,
                progress=progress,
            )
            results[name] = res.results
            n_run += res.n_run
            n_skipped += res.n_skipped
            n_left += res.n_left
            if budget is not None:
                budget = max(0, budget - res.n_run)
    sc = build_scorecard(protocol, notes, results, n_expected=n_expected, wall_s=time.perf_counter() - t0)
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
    try:
        old = json.loads((out / "bench.json").read_text())
    except (OSError, ValueError):
        old = None
    if not isinstance(old, dict) or old.get("command") != "bench":
        raise EvalError(f"--out {str(out)!r} exists and does not hold a bench (no bench.json); choose another --out")
    changed = [k for k in FIXED_KEYS if old.get(k) != protocol[k]]
    if changed:
        diff = "; ".join(f"{k}: {old.get(k)!r} there, {protocol[k]!r} now" for k in changed)
        raise EvalError(
            f"--out {str(out)!r} holds a bench with other settings ({diff}); its episodes would not be "
            f"comparable: use another --out, or delete that directory to start over"
        )

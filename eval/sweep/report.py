"""Sweep tables: aggregate.csv, summary.md and the console summary, rebuilt from the journal after every run."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval.output.files import atomic_save_figure, atomic_write_json, atomic_write_text
from eval.output.results import csv_text
from eval.output.tables import _mm, failed_episode_lines, markdown_table

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
        _mm(me["median"]),
        "-" if me["mean"] is None else f"{me['mean'] * 1e3:.2f} ± {me['std'] * 1e3:.2f}",
        _mm(a["rms_error_m"]["median"]),
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
        lines += [f"## {env} — {dyn}", "", markdown_table(SUMMARY_HEADER, [_summary_row(a) for a in rows]), ""]
    lines += failed_episode_lines(
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
    atomic_write_json(out / "results.json", results)
    atomic_write_text(out / "results.csv", csv_text(results["episodes"]))
    atomic_write_text(out / "aggregate.csv", aggregate_csv_text(results["aggregate"]))
    atomic_write_text(out / "summary.md", summary_markdown(results))
    written = []
    if plots and results["aggregate"]:
        import matplotlib.pyplot as plt

        from eval.sweep.plots import sweep_figures

        for name, fig in sweep_figures(results["aggregate"], tolerance):
            path = out / "plots" / f"{name}.png"
            atomic_save_figure(fig, path)
            plt.close(fig)
            written.append(path)
    return written


def print_summary(result: Any) -> None:
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
                _mm(a["max_error_m"]["median"], 1),
            )
        console.print(table)

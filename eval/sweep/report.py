"""Sweep tables: aggregate.csv, summary.md and the console summary, rebuilt from the journal after every run."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval.output.files import atomic_save_figure, atomic_write_json, atomic_write_text
from eval.output.precision import format_mm
from eval.output.results import csv_text
from eval.output.tables import chaotic_note, failed_episode_lines, iqm_text, markdown_table, seed_text, success_text
from eval.output.tables import console as tables_console

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
    """One tidy row per condition: success_rate with success_ci95_low / _high; each summarised metric m gives
    columns m_median, m_mean, m_std, m_min, m_max, and those of `IQM_METRICS` also m_iqm, m_iqm_ci95_low, _high.
    (The success curve is in results.json.)"""
    stats = ("median", "mean", "std", "min", "max")
    columns = list(AGGREGATE_COLUMNS) + ["success_ci95_low", "success_ci95_high"]
    for m in M.SUMMARY_METRICS:
        columns += [f"{m}_{s}" for s in stats]
        if m in M.IQM_METRICS:
            columns += [f"{m}_iqm", f"{m}_iqm_ci95_low", f"{m}_iqm_ci95_high"]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    w.writeheader()
    for a in aggregate:
        row = {k: a.get(k) for k in AGGREGATE_COLUMNS}
        ci = a.get("success_rate_ci95") or [None, None]
        row["success_ci95_low"], row["success_ci95_high"] = ci
        for m in M.SUMMARY_METRICS:
            st = a.get(m) or {}
            for s in stats:
                row[f"{m}_{s}"] = st.get(s)
            if m in M.IQM_METRICS:
                low, high = st.get("iqm_ci95") or (None, None)
                row[f"{m}_iqm"], row[f"{m}_iqm_ci95_low"], row[f"{m}_iqm_ci95_high"] = st.get("iqm"), low, high
        w.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return buf.getvalue()


SUMMARY_HEADER = (
    "policy",
    "model_error",
    "obs_noise (mm)",
    "n",
    "failed",
    "success [95% CI]",
    "max err IQM [95% CI] (mm)",
    "max err median (mm)",
    "max err mean ± std (mm)",
    "rms median (mm)",
)


def _summary_row(a: dict) -> list[str]:
    me = a["max_error_m"]
    pol = str(a["policy"])
    return [
        pol,
        f"{a['model_error']:g}",
        f"{a['obs_noise'] * 1e3:g}",
        str(a["n"]),
        str(a["n_failed"]),
        success_text(a),
        iqm_text(a),
        format_mm(me["median"], pol),
        "-" if me["mean"] is None else f"{format_mm(me['mean'], pol)} ± {format_mm(me['std'], pol).lstrip('~')}",
        format_mm(a["rms_error_m"]["median"], pol),
    ]


def summary_markdown(results: dict) -> str:
    cfg = results["config"]
    eps = results["episodes"]
    lines = [
        "# mobman-eval sweep",
        "",
        f"{len(eps)} of {cfg['n_episodes']} episodes of the grid; seeds {seed_text(cfg['seeds'])}; success = max "
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
    lines += chaotic_note(results["aggregate"])
    lines += failed_episode_lines(
        eps,
        lambda r: (
            f"{r['env']} / {r['dynamics']} / {r['policy']} / model_error {r['model_error']} / "
            f"obs_noise {r['obs_noise']} / seed {r['seed']}"
        ),
    )
    return "\n".join(lines)


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
    from rich.table import Table

    console = tables_console()
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
                format_mm(a["max_error_m"]["median"], str(a["policy"]), 1),
            )
        console.print(table)

"""Tables: aggregate rows -> Markdown (summary.md) and the console table (rich); errors in mm.

Errors of a policy are printed with the precision its results have (`eval.output.precision`): chaotic ones
with one significant digit and a "~", with a footnote. Success rates carry their Wilson 95% interval and max
errors their IQM with its bootstrap interval (schema 2; "-" where a schema-1 row lacks them).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from eval.output.precision import CHAOTIC_NOTE, format_mm, is_chaotic


def _mm(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x * 1e3:.{digits}f}"


def success_text(a: dict) -> str:
    """ "80% [49-94]": the success rate with its 95% interval (in %), or just the rate for schema-1 rows."""
    rate = f"{a['success_rate'] * 100:.0f}%"
    ci = a.get("success_rate_ci95")
    return rate if not ci else f"{rate} [{ci[0] * 100:.0f}-{ci[1] * 100:.0f}]"


def iqm_text(a: dict, metric: str = "max_error_m", decimals: int = 2) -> str:
    """ "0.40 [0.39-0.45]": the IQM of `metric` in mm with its 95% interval, at the policy's precision."""
    stats = a.get(metric) or {}
    pol = str(a["policy"])
    value = format_mm(stats.get("iqm"), pol, decimals)
    ci = stats.get("iqm_ci95")
    if value == "-" or not ci:
        return value
    return f"{value} [{format_mm(ci[0], pol, decimals).lstrip('~')}-{format_mm(ci[1], pol, decimals).lstrip('~')}]"


def chaotic_note(rows: list[dict]) -> list[str]:
    """The footnote lines when any row is a chaotic policy ([] otherwise)."""
    return [CHAOTIC_NOTE + ".", ""] if any(is_chaotic(str(a["policy"])) for a in rows) else []


def seed_text(seeds) -> str:
    """Seeds as "first..last" when consecutive (one seed: itself), else a comma-separated list."""
    seeds = list(seeds)
    if seeds and seeds == list(range(seeds[0], seeds[0] + len(seeds))):
        return f"{seeds[0]}..{seeds[-1]}" if len(seeds) > 1 else str(seeds[0])
    return ", ".join(map(str, seeds))


def _num(x: float | None, fmt: str = "{:.2f}") -> str:
    return "-" if x is None else fmt.format(x)


SUMMARY_HEADER = (
    "policy",
    "n",
    "failed",
    "tipped over",
    "success [95% CI]",
    "max err IQM [95% CI] (mm)",
    "max err median (mm)",
    "max err mean ± std (mm)",
    "steady max IQM (mm)",
    "rms median (mm)",
    "final median (mm)",
    "effort median (s)",
    "peak joint (rad/s)",
    "peak wheel (rad/s)",
    "predict median / p99 (µs)",
)


def summary_row(a: dict) -> list[str]:
    me = a["max_error_m"]
    pol = str(a["policy"])
    return [
        pol,
        str(a["n"]),
        str(a["n_failed"]),
        str(a.get("n_tipped_over", 0)),
        success_text(a),
        iqm_text(a),
        format_mm(me["median"], pol),
        "-" if me["mean"] is None else f"{format_mm(me['mean'], pol)} ± {format_mm(me['std'], pol).lstrip('~')}",
        format_mm((a.get("steady_max_error_m") or {}).get("iqm"), pol),
        format_mm(a["rms_error_m"]["median"], pol),
        format_mm(a["final_error_m"]["median"], pol),
        _num(a["effort"]["median"]),
        _num(a["peak_joint_speed"]["median"]),
        _num(a["peak_wheel_speed"]["median"]),
        f"{_num(a['predict_us_median']['median'], '{:.0f}')} / {_num(a['predict_us_p99']['median'], '{:.0f}')}",
    ]


def _conditions(aggregate: list[dict]) -> dict[tuple, list[dict]]:
    groups: dict[tuple, list[dict]] = {}
    for a in aggregate:
        groups.setdefault((a["env"], a["dynamics"], a["model_error"], a["obs_noise"]), []).append(a)
    return groups


def markdown_table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def summary_markdown(results: dict) -> str:
    cfg = results["config"]
    lines = [
        "# mobman-eval summary",
        "",
        f"{cfg['episodes']} episode(s) per policy and condition, seeds {cfg['seed']}..{cfg['seed'] + cfg['episodes'] - 1}; "
        f"success = max tracking error <= {cfg['tolerance'] * 1e3:g} mm over the whole episode (failed or tipped-over "
        f"episodes are not successes). Errors in mm, statistics over the episodes that ran (status ok). "
        f"git {results['git']}.",
        "",
    ]
    for (env, dyn, me, on), rows in _conditions(results["aggregate"]).items():
        lines += [
            f"## {env} — {dyn} (model_error {me}, obs_noise {on} m)",
            "",
            markdown_table(SUMMARY_HEADER, [summary_row(a) for a in rows]),
            "",
        ]
    lines += chaotic_note(results["aggregate"])
    lines += failed_episode_lines(
        results["episodes"],
        lambda r: f"{r['env']} / {r['dynamics']} / {r['policy']} / seed {r['seed']}",
        " (traceback in results.json)",
    )
    return "\n".join(lines)


def failed_episode_lines(episodes: list[dict], describe, suffix: str = "") -> list[str]:
    """A Markdown section listing the failed episodes (last line of each traceback); [] when none failed.
    `describe(record)` names the episode's condition."""
    failed = [r for r in episodes if r["status"] != "ok"]
    if not failed:
        return []
    lines = [f"## Failed episodes ({len(failed)})", ""]
    for r in failed:
        last = (r.get("error") or "").strip().splitlines()
        lines.append(f"* {describe(r)}: `{last[-1] if last else 'unknown error'}`{suffix}")
    return lines + [""]


CONSOLE_HEADER = (
    "policy",
    "n",
    "failed\n/tipped",
    "succ",
    "max\nIQM",
    "max\nmed",
    "max\nmean",
    "rms\nmed",
    "final\nmed",
    "pred\nµs",
)


def console_row(a: dict) -> list[str]:
    me = a["max_error_m"]
    pol = str(a["policy"])
    return [
        pol,
        str(a["n"]),
        f"{a['n_failed']}/{a.get('n_tipped_over', 0)}",
        f"{a['success_rate'] * 100:.0f}%",
        format_mm(me.get("iqm"), pol, 1),
        format_mm(me["median"], pol, 1),
        format_mm(me["mean"], pol, 1),
        format_mm(a["rms_error_m"]["median"], pol, 1),
        format_mm(a["final_error_m"]["median"], pol, 1),
        _num(a["predict_us_median"]["median"], "{:.0f}"),
    ]


#: The console width off a terminal (a pipe, a log file): wide enough that no table is clipped or folded; a
#: table takes only the width its columns need.
OFF_TERMINAL_WIDTH = 1000


def console() -> Any:
    """The rich Console of the console tables: the terminal's width on a terminal; off one (stdout a pipe or
    a file, where rich would assume 80 columns and clip the last ones, e.g. the timing) `OFF_TERMINAL_WIDTH`,
    so every column is printed."""
    import sys

    from rich.console import Console

    return Console(width=None if sys.stdout.isatty() else OFF_TERMINAL_WIDTH)


def print_table(results: dict, out: Path | None = None) -> None:
    """A compact table per condition on stdout (errors in mm; summary.md has every column)."""
    from rich import box
    from rich.table import Table

    out_console = console()
    for (env, dyn, me, on), rows in _conditions(results["aggregate"]).items():
        table = Table(
            title=f"{env} — {dyn} (model_error {me}, obs_noise {on} m)",
            box=box.SIMPLE_HEAD,
            caption="errors in mm: max over each episode, then IQM/median/mean over episodes; pred: median "
            "predict call; summary.md has all columns and intervals"
            + ("; ~: chaotic, one significant digit" if any(is_chaotic(str(a["policy"])) for a in rows) else ""),
            padding=(0, 1),
        )
        for h in CONSOLE_HEADER:
            if h == "policy":
                longest = max(len(str(a["policy"])) for a in rows)
                table.add_column(h, justify="left", overflow="fold", min_width=min(max(longest, 6), 16))
            else:
                table.add_column(h, justify="right", no_wrap=True)
        for a in rows:
            table.add_row(*console_row(a))
        out_console.print(table)
    if out is not None:
        out_console.print(f"results in {out}")

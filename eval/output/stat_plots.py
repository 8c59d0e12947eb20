"""Plots of aggregate statistics (results.json schema 2 rows; matplotlib, Agg backend; each returns a Figure).

* `plot_success_curves`: success rate vs tolerance (log axis, 0.1-100 mm: the row's `success_curve` at the
  tolerances of `eval.metrics.SUCCESS_CURVE_TOLERANCES`), one line per policy, one panel per env (rows without
  an env, e.g. pooled over tasks, form one "all tasks" panel; with a single task that panel would repeat it
  and is left out, so one task is one panel). A curve that rises further left is better at every tolerance;
  where curves cross, the ranking depends on the tolerance.
* `success_figures_by_robot`: the same, one figure per robot (a bench of several robots in one figure is a
  column of 17 panels no reader compares).
* Rows with a `success_curve_ci95` (schema 3) get their Wilson band, shaded in the line's colour.
* `plot_ladder`: the difficulty ladder of a scorecard: success rate vs the path's duration (log axis, fastest on
  the right), one line per controller.
* `plot_error_vs_wear`: max-error IQM (mm, log axis) with its 95% bootstrap interval as a band, vs model_error
  (the relative std of the robot's lengths, "wear"), one line per policy, one panel per env. Give it rows that
  differ only in model_error (same dynamics, no noise).

A controller has one colour in every plot and a line style per knowledge class (`eval.output.styles`); the
success tolerance is a labelled line.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.artist import Artist
from matplotlib.figure import Figure
from matplotlib.ticker import NullLocator

from eval.metrics import SUCCESS_CURVE_TOLERANCES
from eval.output.styles import record_style, style_of, tolerance_line

#: The title of the panel of the rows without an env (pooled over tasks).
ALL_TASKS = "all tasks"
#: `success_figures_by_robot`'s key of the figure of the rows pooled over every robot (a file-name stem part).
ALL_ROBOTS = "all-robots"


def _panels(rows: Sequence[dict]) -> dict[str, list[dict]]:
    """env -> its rows; rows without an env form the ALL_TASKS panel, left out when there is one task only
    (it pools that task's episodes: the same curve again)."""
    panels: dict[str, list[dict]] = {}
    for r in rows:
        panels.setdefault(str(r.get("env") or ALL_TASKS), []).append(r)
    if len(panels) == 2 and ALL_TASKS in panels:
        del panels[ALL_TASKS]
    return panels


def _axes(fig: Figure, n: int):
    cols = min(n, 2)
    rows = math.ceil(n / cols)
    return fig.subplots(rows, cols, squeeze=False).ravel()


def plot_success_curves(
    rows: Sequence[dict],
    tolerances: Sequence[float] = SUCCESS_CURVE_TOLERANCES,
    *,
    title: str = "",
    mark: float | None = None,
) -> Figure:
    """Success rate (%) vs tolerance (mm) of every row (one line per policy, one panel per env); `mark` (m)
    draws a labelled vertical line at that tolerance (e.g. the 6 mm success threshold)."""
    panels = _panels([r for r in rows if r.get("success_curve")])
    n = max(len(panels), 1)
    fig = Figure(figsize=(5.2 * min(n, 2) + 0.4, 3.8 * math.ceil(n / 2) + 0.4), layout="constrained")
    axes = _axes(fig, n)
    tol_mm = np.asarray(tolerances, float) * 1e3
    for ax, (env, prow) in zip(axes, panels.items()):
        for r in prow:
            curve = np.asarray(r["success_curve"], float)
            if curve.shape != tol_mm.shape:
                raise ValueError(
                    f"row {r['policy']!r} of {env!r} has a success curve of {curve.size} points for "
                    f"{tol_mm.size} tolerances; pass the tolerances the rows were made with"
                )
            style = record_style(r)
            ax.plot(tol_mm, 100.0 * curve, lw=1.5, label=str(r["policy"]), **style)
            band = r.get("success_curve_ci95")
            if band and len(band) == tol_mm.size and all(b is not None for b in band):
                lo, hi = np.asarray(band, float).T
                ax.fill_between(tol_mm, 100.0 * lo, 100.0 * hi, color=style["color"], alpha=0.12, lw=0)
        if mark is not None:
            tolerance_line(ax, mark, vertical=True)
        ax.set_xscale("log")
        ax.set_ylim(-3, 103)
        ax.set_xlabel("tolerance on the max tracking error (mm)")
        ax.set_ylabel("success rate (%)")
        ax.set_title(env, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    return _finish(fig, axes, len(panels), title)


def plot_error_vs_wear(rows: Sequence[dict], *, title: str = "", tolerance: float | None = None) -> Figure:
    """Max-error IQM (mm) with its 95% interval vs model_error, one line per policy, one panel per env;
    `tolerance` (m) draws the success threshold, labelled."""
    panels = _panels([r for r in rows if (r.get("max_error_m") or {}).get("iqm") is not None])
    n = max(len(panels), 1)
    fig = Figure(figsize=(5.2 * min(n, 2) + 0.4, 3.8 * math.ceil(n / 2) + 0.4), layout="constrained")
    axes = _axes(fig, n)
    policies = list(dict.fromkeys(str(r["policy"]) for rs in panels.values() for r in rs))
    for ax, (env, prow) in zip(axes, panels.items()):
        for pol in policies:
            pts = sorted((r for r in prow if str(r["policy"]) == pol), key=lambda r: r["model_error"])
            if not pts:
                continue
            x = np.array([r["model_error"] for r in pts], float)
            y = np.array([r["max_error_m"]["iqm"] for r in pts], float) * 1e3
            ci = np.array([r["max_error_m"].get("iqm_ci95") or [np.nan, np.nan] for r in pts], float) * 1e3
            st = style_of(pol, pts[0].get("knowledge"))
            ax.plot(x, y, marker="o", ms=3.5, lw=1.5, label=pol, **st)
            ax.fill_between(x, ci[:, 0], ci[:, 1], color=st["color"], alpha=0.15, lw=0)
        if tolerance is not None:
            tolerance_line(ax, tolerance)
        ax.set_yscale("log")
        ax.set_xlabel("model error (relative std of the robot's lengths)")
        ax.set_ylabel("max tracking error, IQM (mm)")
        ax.set_title(env, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    return _finish(fig, axes, len(panels), title)


def success_figures_by_robot(
    rows: Sequence[dict],
    tolerances: Sequence[float] = SUCCESS_CURVE_TOLERANCES,
    *,
    robot_of: Callable[[str], str] = lambda env: env.split("-", 1)[0],
    title: str = "",
    mark: float | None = None,
) -> dict[str, Figure]:
    """`plot_success_curves` split into one figure per robot: robot -> Figure, in the order the robots appear.

    A row's robot is its `robot` field (a scorecard's `by_robot` rows: pooled over that robot's tasks, its
    "all tasks" panel) or `robot_of(env)` (default: the env id's prefix, "WheeledUR5" of
    "WheeledUR5-Circle-v0"). Rows with neither (pooled over every robot) join the robot's figure when there
    is one robot, and form their own figure, `ALL_ROBOTS`, when there are several."""
    groups: dict[str, list[dict]] = {}
    pooled: list[dict] = []
    for r in rows:
        robot = r.get("robot") or (robot_of(str(r["env"])) if r.get("env") else None)
        if robot is None:
            pooled.append(r)
        else:
            groups.setdefault(str(robot), []).append(r)
    if len(groups) == 1:
        groups[next(iter(groups))] += pooled
    elif pooled or not groups:
        groups[ALL_ROBOTS] = pooled
    head = f"{title} · " if title else ""
    return {
        robot: plot_success_curves(
            robot_rows, tolerances, title=head + ("all robots" if robot == ALL_ROBOTS else robot), mark=mark
        )
        for robot, robot_rows in groups.items()
    }


def _finish(fig: Figure, axes, n_panels: int, title: str) -> Figure:
    """Hide the unused panels, put one legend (every label of the panels once) beside the grid, and the title
    above it."""
    for ax in axes[n_panels:]:
        ax.set_visible(False)
    if n_panels:
        entries: dict[str, Artist] = {}
        for ax in axes[:n_panels]:
            for handle, label in zip(*ax.get_legend_handles_labels()):
                entries.setdefault(label, handle)
        fig.legend(list(entries.values()), list(entries), loc="outside right center", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=11)
    return fig


def plot_ladder(entries: Sequence[dict], *, success: float = 0.9, title: str = "") -> Figure:
    """The difficulty ladder (a scorecard's `ladder` entries): success rate (%) on each rung vs the rung's path
    duration (s, log axis, shorter = faster to the right), one line per controller; `success` draws the rung's
    "tracked" threshold, labelled."""
    fig = Figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
    for e in entries:
        if not e["rungs"]:
            continue
        d = [s["duration"] for s in e["rungs"]]
        rate = [100.0 * s["success_rate"] for s in e["rungs"]]
        ax.plot(d, rate, marker="o", ms=3, lw=1.5, label=str(e["policy"]), **record_style(e))
    ax.axhline(100.0 * success, color="black", lw=0.8, label=f"tracked: >= {success * 100:.0f}% success")
    ax.set_xscale("log")
    rungs = sorted({s["duration"] for e in entries for s in e["rungs"]})
    ax.set_xticks(rungs, [f"{d:g}" for d in rungs])  # the rungs themselves, not log-axis decades
    ax.xaxis.set_minor_locator(NullLocator())
    ax.invert_xaxis()
    ax.set_ylim(-3, 103)
    ax.set_xlabel("path duration (s): faster to the right")
    ax.set_ylabel("success rate (%)")
    ax.grid(True, which="both", alpha=0.3)
    return _finish(fig, [ax], 1, title)

"""Plots of aggregate statistics (results.json schema 2 rows; matplotlib, Agg backend; each returns a Figure).

* `plot_success_curves`: success rate vs tolerance (log axis, 0.1-100 mm: the row's `success_curve` at the
  tolerances of `eval.metrics.SUCCESS_CURVE_TOLERANCES`), one line per policy, one panel per env (rows without
  an env, e.g. pooled over tasks, form one "all tasks" panel). A curve that rises further left is better at
  every tolerance; where curves cross, the ranking depends on the tolerance.
* `plot_error_vs_wear`: max-error IQM (mm, log axis) with its 95% bootstrap interval as a band, vs model_error
  (the relative std of the robot's lengths, "wear"), one line per policy, one panel per env. Give it rows that
  differ only in model_error (same dynamics, no noise).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.figure import Figure

from eval.metrics import SUCCESS_CURVE_TOLERANCES
from eval.output.plots import _COLORS

#: Line styles cycled after the colours, so up to 32 policies stay distinguishable.
_STYLES = ("-", "--", "-.", ":")


def _style(i: int) -> dict:
    return {"color": _COLORS[i % len(_COLORS)], "ls": _STYLES[(i // len(_COLORS)) % len(_STYLES)]}


def _panels(rows: Sequence[dict]) -> dict[str, list[dict]]:
    panels: dict[str, list[dict]] = {}
    for r in rows:
        panels.setdefault(str(r.get("env") or "all tasks"), []).append(r)
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
    draws a vertical line at that tolerance (e.g. the 6 mm success threshold)."""
    panels = _panels([r for r in rows if r.get("success_curve")])
    n = max(len(panels), 1)
    fig = Figure(figsize=(5.2 * min(n, 2) + 0.4, 3.8 * math.ceil(n / 2) + 0.4), layout="constrained")
    axes = _axes(fig, n)
    policies = list(dict.fromkeys(str(r["policy"]) for rs in panels.values() for r in rs))
    tol_mm = np.asarray(tolerances, float) * 1e3
    for ax, (env, prow) in zip(axes, panels.items()):
        for r in prow:
            curve = np.asarray(r["success_curve"], float)
            if curve.shape != tol_mm.shape:
                raise ValueError(
                    f"row {r['policy']!r} of {env!r} has a success curve of {curve.size} points for "
                    f"{tol_mm.size} tolerances; pass the tolerances the rows were made with"
                )
            ax.plot(tol_mm, 100.0 * curve, lw=1.5, label=str(r["policy"]), **_style(policies.index(str(r["policy"]))))
        if mark is not None:
            ax.axvline(mark * 1e3, color="k", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_ylim(-3, 103)
        ax.set_xlabel("tolerance on the max tracking error (mm)")
        ax.set_ylabel("success rate (%)")
        ax.set_title(env, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    return _finish(fig, axes, len(panels), title)


def plot_error_vs_wear(rows: Sequence[dict], *, title: str = "", tolerance: float | None = None) -> Figure:
    """Max-error IQM (mm) with its 95% interval vs model_error, one line per policy, one panel per env;
    `tolerance` (m) draws the success threshold."""
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
            st = _style(policies.index(pol))
            ax.plot(x, y, marker="o", ms=3.5, lw=1.5, label=pol, **st)
            ax.fill_between(x, ci[:, 0], ci[:, 1], color=st["color"], alpha=0.15, lw=0)
        if tolerance is not None:
            ax.axhline(tolerance * 1e3, color="k", lw=0.8, ls=":")
        ax.set_yscale("log")
        ax.set_xlabel("model error (relative std of the robot's lengths)")
        ax.set_ylabel("max tracking error, IQM (mm)")
        ax.set_title(env, fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    return _finish(fig, axes, len(panels), title)


def _finish(fig: Figure, axes, n_panels: int, title: str) -> Figure:
    """Hide the unused panels, put one legend (the first panel's) beside the grid, and the title above it."""
    for ax in axes[n_panels:]:
        ax.set_visible(False)
    if n_panels:
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside right center", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=11)
    return fig

"""Summary plots of a sweep: success rate and max tracking error vs model error or sensor noise, per policy.

Each function takes aggregate rows (`eval.metrics.aggregate`: one per env, policy, dynamics, model_error,
obs_noise) and returns a Figure (Agg backend). For one (env, dynamics) and a swept variable x (`model_error` or
`obs_noise`): a column per value of the other variable; top row the success rate (%), bottom row the median
of the per-episode max error (mm, log scale) with its min-max range over the episodes as a band and the
tolerance as a labelled line; one line per policy, in its colour and the line style of its knowledge class
(`eval.output.styles`).
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.figure import Figure

from eval.output.styles import style_of, tolerance_line

#: the swept variables and their axis labels
VARIABLES = {
    "model_error": ("model error (relative std of the robot's lengths)", 1.0),
    "obs_noise": ("position sensor noise std (mm)", 1e3),
}


def _other(x: str) -> str:
    return "obs_noise" if x == "model_error" else "model_error"


def plot_vs(rows: Sequence[dict], x: str, tolerance: float | None = None) -> Figure:
    """Success rate and max error vs `x` ("model_error" or "obs_noise") for the rows of one (env, dynamics)."""
    if x not in VARIABLES:
        raise ValueError(f"x must be one of {', '.join(VARIABLES)}, got {x!r}")
    other = _other(x)
    xlabel, xscale = VARIABLES[x]
    olabel, oscale = VARIABLES[other]
    columns = sorted({r[other] for r in rows})
    policies = list(dict.fromkeys(r["policy"] for r in rows))
    fig = Figure(figsize=(4.4 * len(columns) + 0.6, 6.2), layout="constrained")
    axes = fig.subplots(2, len(columns), squeeze=False, sharex=True)
    for j, ov in enumerate(columns):
        top, bottom = axes[0, j], axes[1, j]
        for pol in policies:
            pts = sorted((r for r in rows if r["policy"] == pol and r[other] == ov), key=lambda r: r[x])
            if not pts:
                continue
            st = style_of(str(pol), pts[0].get("knowledge"))
            color = st["color"]
            xs = np.array([r[x] for r in pts]) * xscale
            top.plot(xs, [100.0 * r["success_rate"] for r in pts], marker="o", lw=1.4, ms=4, label=pol, **st)
            med = np.array([_mm(r["max_error_m"]["median"]) for r in pts])
            lo = np.array([_mm(r["max_error_m"]["min"]) for r in pts])
            hi = np.array([_mm(r["max_error_m"]["max"]) for r in pts])
            bottom.plot(xs, med, marker="o", lw=1.4, ms=4, label=pol, **st)
            bottom.fill_between(xs, lo, hi, color=color, alpha=0.15, lw=0)
        if tolerance is not None:
            tolerance_line(bottom, tolerance)
        top.set_ylim(-5, 105)
        top.set_ylabel("success rate (%)")
        top.set_title(f"{other} = {ov * oscale:g}" + (" mm" if other == "obs_noise" else ""), fontsize=10)
        top.grid(True, alpha=0.3)
        if np.any(np.isfinite([_mm(r["max_error_m"]["median"]) for r in rows])):
            bottom.set_yscale("log")
        bottom.set_ylabel("max tracking error (mm)")
        bottom.set_xlabel(xlabel)
        bottom.grid(True, which="both", alpha=0.3)
    axes[1, 0].legend(fontsize=7)
    if rows:
        fig.suptitle(
            f"{rows[0]['env']} · {rows[0]['dynamics']}: success and max error (median, min-max band) vs {x}",
            fontsize=11,
        )
    return fig


def _mm(v: float | None) -> float:
    return np.nan if v is None else v * 1e3


def sweep_figures(aggregate: Sequence[dict], tolerance: float | None = None) -> list[tuple[str, Figure]]:
    """(file stem, Figure) for every (env, dynamics) and every swept variable with at least two values."""
    from eval.output.files import slug

    groups: dict[tuple, list[dict]] = {}
    for a in aggregate:
        groups.setdefault((a["env"], a["dynamics"]), []).append(a)
    figures = []
    for (env, dyn), rows in groups.items():
        for x in VARIABLES:
            if len({r[x] for r in rows}) >= 2:
                figures.append((f"{slug(env)}_{dyn}_vs_{x}", plot_vs(rows, x, tolerance)))
    return figures

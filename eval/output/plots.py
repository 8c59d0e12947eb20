"""Plots of tracked paths and errors (matplotlib, Agg backend). Each function takes records and returns a Figure.

A record here is an episode record (env, policy, seed, ...) with its per-step arrays merged in (t, r_d, r_a,
p_c, error, action; see `eval.rollout`), one per policy, all of the same episode (same seed).

* `plot_paths_3d`: desired vs actual end-effector path and the platform trace p_c (on the ground), one 3-D
  panel per policy (the paper's Fig. 2a and Fig. 3).
* `plot_axis_errors`: E_x, E_y, E_z = r_d - r_a over time, one panel per policy (the paper's Fig. 2b).
* `plot_error_norm`: ||r_d - r_a|| over time of every policy on one log axis, with the tolerance.

A controller has one colour in every plot and a line style per knowledge class (`eval.output.styles`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import matplotlib

matplotlib.use("Agg")  # no display needed; set before pyplot is imported anywhere in this process

import numpy as np
from matplotlib.figure import Figure

from eval.output.styles import color_of, record_style, tolerance_line


def _title(rec: dict) -> str:
    return f"{rec.get('env', '')} · {rec.get('dynamics', '')} · seed {rec.get('seed', '')}"


def _label(rec: dict) -> str:
    status = "" if rec.get("status", "ok") == "ok" else " (failed)"
    m = rec.get("max_error_m")
    return f"{rec['policy']}" + (f" (max {m * 1e3:.1f} mm)" if m is not None else "") + status


def _grid(n: int) -> tuple[int, int]:
    cols = min(n, 3)
    return int(math.ceil(n / cols)), cols


def plot_paths_3d(records: Sequence[dict]) -> Figure:
    """Desired (dashed black) vs actual end-effector path (the policy's colour and line style) and the platform
    trace p_c at z = 0 (grey), one panel per policy."""
    n = max(1, len(records))
    rows, cols = _grid(n)
    fig = Figure(figsize=(4.6 * cols, 4.2 * rows))
    for i, rec in enumerate(records):
        ax = fig.add_subplot(rows, cols, i + 1, projection="3d")
        r_d, r_a, p_c = (np.asarray(rec[k]) for k in ("r_d", "r_a", "p_c"))
        ax.plot(r_d[:, 0], r_d[:, 1], r_d[:, 2], "k--", lw=1.2, label="desired r_d")
        ax.plot(r_a[:, 0], r_a[:, 1], r_a[:, 2], lw=1.4, label="actual r_a", **record_style(rec))
        ax.plot(p_c[:, 0], p_c[:, 1], np.zeros(len(p_c)), color="0.55", lw=1.4, label="platform p_c")
        if len(r_a):
            ax.scatter(*r_a[0], color="k", s=12)
            ax.plot([p_c[0, 0], r_a[0, 0]], [p_c[0, 1], r_a[0, 1]], [0.0, r_a[0, 2]], color="0.6", lw=0.8)
            ax.plot([p_c[-1, 0], r_a[-1, 0]], [p_c[-1, 1], r_a[-1, 1]], [0.0, r_a[-1, 2]], color="0.3", lw=0.8)
        _equal_3d(ax, np.vstack([r_d, r_a, np.c_[p_c, np.zeros(len(p_c))]]))
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_zlabel("z (m)")
        ax.set_title(_label(rec), fontsize=10)
        if i == 0:
            ax.legend(fontsize=7, loc="upper left")
    if records:
        fig.suptitle("End-effector path and platform trace — " + _title(records[0]), fontsize=11)
    return fig


def _equal_3d(ax, pts: np.ndarray) -> None:
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        return
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * max(float(np.max(hi - lo)), 1e-3)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(max(0.0, centre[2] - half), max(0.0, centre[2] - half) + 2 * half)


def plot_axis_errors(records: Sequence[dict]) -> Figure:
    """E_x, E_y, E_z = r_d - r_a (mm) over time, one panel per policy (the paper's Fig. 2b), in the policy's
    colour: E_x solid, E_y dashed, E_z dotted."""
    n = max(1, len(records))
    rows, cols = _grid(n)
    fig = Figure(figsize=(4.6 * cols, 3.2 * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[len(records) :]:
        ax.set_visible(False)
    for ax, rec in zip(axes, records):
        e = (np.asarray(rec["r_d"]) - np.asarray(rec["r_a"])) * 1e3
        t = np.asarray(rec["t"])
        color = color_of(str(rec["policy"]))
        for j, (name, ls) in enumerate(zip("xyz", ("-", "--", ":"))):
            ax.plot(t, e[:, j], color=color, ls=ls, lw=1.1, label=f"E_{name}", gid=f"policy:{rec['policy']}")
        ax.axhline(0.0, color="0.7", lw=0.6)
        ax.set_xlabel("t (s)")
        ax.set_ylabel("error (mm)")
        ax.set_title(_label(rec), fontsize=10)
        ax.legend(fontsize=7)
    if records:
        fig.suptitle("Tracking error per axis — " + _title(records[0]), fontsize=11)
    return fig


def plot_error_norm(records: Sequence[dict], tolerance: float | None = None) -> Figure:
    """||r_d - r_a|| (mm, log scale) over time for every policy, with the success tolerance (m) labelled."""
    fig = Figure(figsize=(7.5, 4.0), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    for rec in records:
        t = np.asarray(rec["t"])
        e = np.asarray(rec["error"]) * 1e3
        ax.plot(t[1:], np.maximum(e[1:], 1e-6), lw=1.2, label=_label(rec), **record_style(rec))
    if tolerance is not None:
        tolerance_line(ax, tolerance)
    ax.set_yscale("log")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("||r_d - r_a|| (mm)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    if records:
        ax.set_title("Tracking error — " + _title(records[0]), fontsize=11)
    return fig

"""SB3 callbacks of a training run: checkpoints and the periodic evaluation / learning curve."""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback

from eval.output.files import atomic_write_bytes, atomic_write_text
from train.curve import CURVE_FIELDS, read_curve, write_curve

log = logging.getLogger("train")


class CheckpointSaver(BaseCallback):
    """Every `freq` env steps call `save(model)` (which writes model, normaliser and replay buffer)."""

    def __init__(self, freq: int, save: Callable[[Any], object]):
        super().__init__()
        self.freq = freq
        self.save = save
        self._last = 0

    def _on_training_start(self) -> None:
        self._last = self.model.num_timesteps

    def _on_step(self) -> bool:
        if self.freq and self.model.num_timesteps - self._last >= self.freq:
            self._last = self.model.num_timesteps
            self.save(self.model)
        return True


class ProgressLog(BaseCallback):
    """A line every `every_s` seconds of wall clock to the run's log (train.log, and stderr: it shows off a
    terminal too, unlike a progress bar): env steps, steps/s of this session (learner included), and over the
    training episodes that ended since the previous line their mean return (VecMonitor's, as trained: learning
    reward weights and alive bonus, not normalised), mean length and success (the episode ran to its end with a max tracking error <=
    `tolerance`; noise-free error, `infos[i]["tracking_error"]`)."""

    def __init__(self, every_s: float, tolerance: float):
        super().__init__()
        self.every_s = float(every_s)
        self.tolerance = float(tolerance)
        self._max_err: Any = None
        self._ended: list[tuple[float, int, bool]] = []  # (return, length, success) since the last line

    def _on_training_start(self) -> None:
        import numpy as np

        self._t0 = self._last = time.time()
        self._steps0 = self.model.num_timesteps
        self._max_err = np.zeros(self.training_env.num_envs)

    def _on_step(self) -> bool:
        import numpy as np

        infos, dones = self.locals["infos"], self.locals["dones"]
        err = np.fromiter((i.get("tracking_error", np.nan) for i in infos), float, len(infos))
        np.maximum(self._max_err, err, out=self._max_err)
        for i in np.flatnonzero(dones):
            episode = infos[i].get("episode", {"r": np.nan, "l": 0})  # VecMonitor's, before any normalisation
            full = bool(infos[i].get("TimeLimit.truncated", False))
            self._ended.append((float(episode["r"]), int(episode["l"]), full and self._max_err[i] <= self.tolerance))
            self._max_err[i] = 0.0
        now = time.time()
        if now - self._last >= self.every_s:
            self._last = now
            log.info("%s", self.line(now))
            self._ended = []
        return True

    def line(self, now: float) -> str:
        """The progress line (also what the tests read)."""
        steps = self.model.num_timesteps
        rate = (steps - self._steps0) / max(now - self._t0, 1e-9)
        text = f"{steps:,} steps, {rate:,.0f} steps/s"
        if self._ended:
            r, n, ok = zip(*self._ended)
            text += (
                f"; {len(r)} episodes ended: mean return {sum(r) / len(r):.1f}, mean length {sum(n) / len(n):.0f}, "
                f"success {100 * sum(ok) / len(ok):.0f}%"
            )
        else:
            text += "; no episode ended since the last line"
        return text


class PeriodicEval(BaseCallback):
    """Every `freq` env steps: `evaluate(model) -> summary dict`; append a row to `curve_csv`, redraw the PNG.

    The first evaluation runs at the start of training (step 0, or the resumed step), so the curve starts from
    the untrained agent."""

    def __init__(
        self,
        freq: int,
        evaluate: Callable[[Any], dict],
        curve_csv: Path,
        curve_png: Path,
        reference: dict | None,
        t0: float,
        wall_offset: float = 0.0,
        on_result: Callable[[Any, dict], object] | None = None,
    ):
        super().__init__()
        self.on_result = on_result
        self.freq = freq
        self.evaluate = evaluate
        self.curve_csv = Path(curve_csv)
        self.curve_png = Path(curve_png)
        self.reference = reference
        self.t0 = t0
        self.wall_offset = wall_offset
        self._last = -1

    def _on_training_start(self) -> None:
        if self.freq:
            self._run()

    def _on_step(self) -> bool:
        if self.freq and self.model.num_timesteps - self._last >= self.freq:
            self._run()
        return True

    def _run(self) -> None:
        self._last = self.model.num_timesteps
        summary = self.evaluate(self.model)
        row = {
            "timesteps": self.model.num_timesteps,
            "wall_s": round(self.wall_offset + time.time() - self.t0, 1),
            **{k: summary[k] for k in CURVE_FIELDS[2:]},
        }
        append_curve_row(self.curve_csv, row)
        log.info(
            "eval @ %d steps: median RMS %.1f mm, median max %.1f mm, success %.0f%%",
            row["timesteps"],
            1e3 * row["median_rms_error_m"],
            1e3 * row["median_max_error_m"],
            100 * row["success_rate"],
        )
        if self.logger is not None:
            self.logger.record("eval/median_rms_error_m", row["median_rms_error_m"])
            self.logger.record("eval/median_max_error_m", row["median_max_error_m"])
            self.logger.record("eval/success_rate", row["success_rate"])
        write_curve_png(self.curve_csv, self.curve_png, self.reference)
        if self.on_result is not None:
            self.on_result(self.model, row)


def append_curve_row(path: Path, row: dict) -> None:
    write_curve(path, read_curve(path) + [row])


def truncate_curve(path: Path, max_timesteps: int) -> None:
    """Drop rows from `max_timesteps` on (a resumed run continues from its last checkpoint and evaluates the
    checkpoint's model again: an evaluation at that step during the first session may have preceded the
    last gradient update)."""
    rows = [r for r in read_curve(path) if r["timesteps"] < max_timesteps]
    if Path(path).exists():
        write_curve(path, rows)


def curve_figure(rows: list[dict], reference: dict | None = None, title: str = ""):
    """Tracking error (mm, log scale) vs env steps: median RMS and median max error over the evaluation seeds,
    the band between median and worst RMS, and the stand-still (`zero`) RMS as a reference."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4.2), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    x = [r["timesteps"] for r in rows]
    ax.plot(x, [1e3 * r["median_rms_error_m"] for r in rows], "o-", label="median RMS error")
    ax.fill_between(
        x,
        [1e3 * r["median_rms_error_m"] for r in rows],
        [1e3 * r["max_rms_error_m"] for r in rows],
        alpha=0.2,
        label="median..worst RMS",
    )
    ax.plot(x, [1e3 * r["median_max_error_m"] for r in rows], "s--", label="median max error")
    if reference:
        ax.axhline(1e3 * reference["median_rms_error_m"], color="k", ls=":", label="zero policy RMS")
        ax.axhline(1e3 * reference["median_rms_error_m"] / 4, color="r", ls=":", label='zero / 4 ("learns")')
    ax.set_yscale("log")
    ax.set_xlabel("env steps")
    ax.set_ylabel("tracking error (mm)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def write_curve_png(curve_csv: Path, png: Path, reference: dict | None, title: str = "") -> None:
    import io

    rows = read_curve(curve_csv)
    if not rows:
        return
    buf = io.BytesIO()
    curve_figure(rows, reference, title or Path(curve_csv).parent.name).savefig(buf, format="png")
    atomic_write_bytes(png, buf.getvalue())


def write_json(path: Path, data: dict) -> None:
    """A run-folder JSON file (keys sorted), written atomically with eval's writer."""
    atomic_write_text(path, json.dumps(data, indent=2, sort_keys=True) + "\n")

"""Known-answer tests of eval's outputs that an earlier mutation pass showed missing (issue 10): the axis
columns of results.csv, the sign of the per-axis error plot (the paper's Fig. 2b), the frame count of a video.

Each test here failed with its mutation applied by hand (see tests/mutation/mutants.py) and passes without it.
"""

from __future__ import annotations

import csv
import json
from types import SimpleNamespace

import numpy as np
import pytest
from test_eval_helpers import short_config

from eval import run
from eval.output import plots
from eval.output.results import csv_rows, csv_text


# --- results.csv: axis_max_error_x/y/z_m are the x, y, z components, in that order -----------------------
def test_csv_axis_columns_are_x_y_z_in_order():
    rec = {"index": 0, "policy": "p", "axis_max_error_m": [0.001, 0.002, 0.003], "path": None, "error": None}
    (row,) = csv_rows([rec])
    assert (row["axis_max_error_x_m"], row["axis_max_error_y_m"], row["axis_max_error_z_m"]) == (0.001, 0.002, 0.003)
    (parsed,) = csv.DictReader(csv_text([rec]).splitlines())
    assert [float(parsed[f"axis_max_error_{a}_m"]) for a in "xyz"] == [0.001, 0.002, 0.003]


def test_results_csv_axis_columns_match_results_json(tmp_path):
    """A real run: each row's x/y/z columns equal the episode's axis_max_error_m (which differ per axis)."""
    result = run(short_config(tmp_path, policies=("random", "zero"), episodes=1))
    episodes = json.loads((result.out / "results.json").read_text())["episodes"]
    rows = list(csv.DictReader((result.out / "results.csv").open()))
    assert len(rows) == len(episodes) == 2
    for row, ep in zip(rows, episodes):
        axis = ep["axis_max_error_m"]
        assert len(set(axis)) == 3, axis  # the three axes differ, so a swap would show
        assert [float(row[f"axis_max_error_{a}_m"]) for a in "xyz"] == pytest.approx(axis, rel=1e-12)


# --- Fig. 2b: E = r_d - r_a, the paper's sign ---------------------------------------------------------------
def test_axis_error_plot_shows_r_d_minus_r_a_in_mm():
    t = np.linspace(0.0, 1.0, 11)
    r_d = np.c_[np.sin(t), np.cos(t), 0.5 + t]
    offset = np.array([0.001, -0.002, 0.004])  # m: r_a = r_d + offset, so E = r_d - r_a = -offset
    records = [{"policy": "p", "t": t, "r_d": r_d, "r_a": r_d + offset, "env": "E", "dynamics": "kinematic"}]
    fig = plots.plot_axis_errors(records)
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines() if ln.get_label().startswith("E_")}
    assert sorted(lines) == ["E_x", "E_y", "E_z"]
    for j, name in enumerate(("E_x", "E_y", "E_z")):
        np.testing.assert_allclose(lines[name].get_xdata(), t)
        np.testing.assert_allclose(lines[name].get_ydata(), np.full(len(t), -offset[j] * 1e3), rtol=1e-9)


# --- a video of an episode has about duration * fps frames ---------------------------------------------------
def _count_frames(path) -> int:
    import imageio.v2 as imageio

    if path.suffix == ".gif":
        return len(imageio.mimread(path))
    with imageio.get_reader(path) as reader:
        return reader.count_frames()


def test_video_holds_one_frame_per_frame_period_of_the_episode(tmp_path):
    from eval.output.video import write_videos

    duration = 0.48  # s: 48 control steps at 100 Hz, a frame every 4 steps at 25 fps
    config = short_config(
        tmp_path,
        policies=("random",),
        episodes=1,
        env_kwargs={"path": {"type": "circle", "radius": 0.1, "duration": duration}},
    )
    (path,) = write_videos(SimpleNamespace(out=tmp_path), config, {})
    n = _count_frames(path)
    fps = 25  # WheeledPumaEnv.metadata["render_fps"]
    # the frame at t = 0 plus one per 1/fps s: 13 here; a one-frame (or half-length) video fails
    assert round(duration * fps) <= n <= round(duration * fps) + 1, n

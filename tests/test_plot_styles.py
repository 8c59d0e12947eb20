"""Plots a reader can compare (`eval.output.styles`): a controller has the same colour in every plot function's
figure whatever the order of its rows, its knowledge class sets the line style, the tolerance line is labelled,
one task is one panel, and a bench of several robots gives one figure per robot."""

from __future__ import annotations

import json
import zlib
from pathlib import Path

import numpy as np
import pytest
from matplotlib.colors import to_hex, to_rgb

from eval.output import plots, stat_plots, styles
from eval.output.compact import stored_bytes
from eval.sweep import plots as sweep_plots

ROOT = Path(__file__).resolve().parents[1]
SPECS = ("nnbc-plus", "clik", "qp-oracle", "nnbc", "sb3:my_agent/model.zip", "mine")
TOL = 0.006


def _trace(policy: str, k: int) -> dict:
    t = np.linspace(0.0, 1.0, 21)
    r_d = np.c_[np.cos(t), np.sin(t), 0.5 + 0 * t]
    r_a = r_d + 1e-3 * (k + 1)
    e = np.linalg.norm(r_d - r_a, axis=1)
    return {"policy": policy, "env": "E", "dynamics": "kinematic", "seed": 1, "t": t, "r_d": r_d, "r_a": r_a}, e


def _traces(order) -> list[dict]:
    out = []
    for k, p in enumerate(order):
        rec, e = _trace(p, k)
        out.append({**rec, "p_c": rec["r_d"][:, :2] * 0.5, "error": e, "max_error_m": float(e.max())})
    return out


def _agg(order, envs=("WheeledPuma-Circle-v0",), pooled=False) -> list[dict]:
    rows = []
    for env in [*envs, *([None] if pooled else [])]:
        for k, p in enumerate(order):
            for me in (0.05, 0.2):
                for noise in (0.0, 0.002):
                    m = 1e-3 * (k + 1) * (1 + me)
                    rows.append(
                        {
                            "env": env,
                            "policy": p,
                            "dynamics": "kinematic",
                            "model_error": me,
                            "obs_noise": noise,
                            "success_rate": 0.5,
                            "success_curve": [min(1.0, i / (10 + k)) for i in range(31)],
                            "max_error_m": {"iqm": m, "iqm_ci95": [0.9 * m, 1.1 * m], "median": m, "min": m, "max": m},
                        }
                    )
    return rows


def _figures(order):
    rows = _agg(order)
    return {
        "paths_3d": plots.plot_paths_3d(_traces(order)),
        "axis_errors": plots.plot_axis_errors(_traces(order)),
        "error_norm": plots.plot_error_norm(_traces(order), tolerance=TOL),
        "success_curves": stat_plots.plot_success_curves([r for r in rows if r["obs_noise"] == 0], mark=TOL),
        "error_vs_wear": stat_plots.plot_error_vs_wear([r for r in rows if r["obs_noise"] == 0], tolerance=TOL),
        "sweep_vs": sweep_plots.plot_vs(rows, "model_error", tolerance=TOL),
    }


def _policy_lines(fig) -> dict[str, list]:
    lines: dict[str, list] = {}
    for ax in fig.axes:
        for ln in ax.get_lines():
            gid = ln.get_gid() or ""
            if gid.startswith("policy:"):
                lines.setdefault(gid.removeprefix("policy:"), []).append(ln)
    return lines


def test_a_spec_has_one_colour_in_every_plot_whatever_the_order():
    seen: dict[str, set[str]] = {}
    for order in (SPECS, tuple(reversed(SPECS)), SPECS[2:]):
        for name, fig in _figures(order).items():
            lines = _policy_lines(fig)
            assert set(lines) == set(order), name
            for spec, lns in lines.items():
                seen.setdefault(spec, set()).update(to_hex(ln.get_color()) for ln in lns)
    assert all(len(colours) == 1 for colours in seen.values()), seen
    assert seen["nnbc-plus"] == {"#ff7f0e"} and seen["clik"] == {"#d62728"}
    assert len({next(iter(c)) for c in seen.values()}) == len(SPECS)  # six controllers, six colours


def _lab(color: str) -> np.ndarray:
    """CIELAB (D65 white) of a matplotlib colour: sRGB -> linear -> XYZ -> L*a*b*."""
    rgb = np.array(to_rgb(color))
    lin = np.where(rgb > 0.04045, ((rgb + 0.055) / 1.055) ** 2.4, rgb / 12.92)
    to_xyz = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
    xyz = to_xyz @ lin / np.array([0.95047, 1.0, 1.08883])
    f = np.where(xyz > 0.008856, np.cbrt(xyz), 7.787 * xyz + 16 / 116)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def test_other_specs_hash_stably_to_colours_unlike_the_built_ins():
    spec = "sb3:my_agent/model.zip"
    assert styles.color_of(spec) == styles.OTHER_COLORS[zlib.crc32(spec.encode()) % len(styles.OTHER_COLORS)]
    assert styles.color_of("nnbc-plus:formulation=whole_body") in styles.OTHER_COLORS  # an option makes another line
    others = [_lab(c) for c in styles.OTHER_COLORS]
    fixed = [_lab(c) for c in [*styles.BUILTIN_COLORS.values(), styles.TOLERANCE_COLOR]]
    for i, c in enumerate(others):  # Delta E >= 25: a reader tells them apart from the built-ins and each other
        nearest = min(np.linalg.norm(c - d) for d in fixed + others[:i] + others[i + 1 :])
        assert nearest >= 25, (styles.OTHER_COLORS[i], nearest)


def _reference_lines():
    """A figure with one line per knowledge class, drawn with matplotlib's names of the styles."""
    from matplotlib.figure import Figure

    fig = Figure()
    ax = fig.add_subplot()
    for kind, ls in {"none": "-", "structure": "-.", "nominal": "--", "true": ":"}.items():
        ax.plot([0, 1], [0, 1], ls=ls, gid=f"policy:{kind}")
    ax.plot([0, 1], [0, 1], ls=(0, (3, 1, 1, 1, 1, 1)), gid="policy:unknown")
    return fig


def test_the_line_style_is_the_knowledge_class():
    fig = plots.plot_error_norm(_traces(SPECS), tolerance=TOL)
    # get_linestyle() names a custom dash pattern "--": compare the patterns themselves
    style = {spec: lns[0]._unscaled_dash_pattern for spec, lns in _policy_lines(fig).items()}
    ref = {k: lns[0]._unscaled_dash_pattern for k, lns in _policy_lines(_reference_lines()).items()}
    assert style["nnbc"] == style["sb3:my_agent/model.zip"] == ref["none"]
    assert style["nnbc-plus"] == ref["structure"]
    assert style["clik"] == ref["nominal"]
    assert style["qp-oracle"] == ref["true"]
    assert style["mine"] == ref["unknown"]  # a label that names no policy
    assert len(set(ref.values())) == 5
    row = {"policy": "mine", "knowledge": "true"}  # a record's own class wins (results schema 3)
    assert styles.record_style(row)["ls"] == styles.LINESTYLES["true"]
    with pytest.raises(ValueError, match="knowledge class 'partial'.*accepted: none, structure, nominal, true"):
        styles.style_of("mine", "partial")


@pytest.mark.parametrize("name", ["error_norm", "success_curves", "error_vs_wear", "sweep_vs"])
def test_the_tolerance_line_is_labelled(name):
    fig = _figures(SPECS[:2])[name]
    labelled = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_label() == "tolerance 6 mm"]
    assert labelled
    if name in ("success_curves", "error_vs_wear"):  # one figure legend: the tolerance is in it
        assert "tolerance 6 mm" in [t.get_text() for t in fig.legends[0].get_texts()]


@pytest.mark.parametrize("plot", [stat_plots.plot_success_curves, stat_plots.plot_error_vs_wear])
def test_one_task_is_one_panel(plot):
    one = _agg(SPECS[:3], pooled=True)  # a task and the rows pooled over it: the same episodes
    one = [r for r in one if r["obs_noise"] == 0]
    assert len([ax for ax in plot(one).axes if ax.get_visible()]) == 1
    two = [r for r in _agg(SPECS[:3], envs=("A", "B"), pooled=True) if r["obs_noise"] == 0]
    assert len([ax for ax in plot(two).axes if ax.get_visible()]) == 3  # two tasks and all tasks


def test_several_robots_give_one_figure_per_robot():
    sc = json.loads(stored_bytes(ROOT / "docs/results/robots-v1/kinematic/scorecard.json"))
    prefix = {"WheeledPuma": "puma", "WheeledUR5": "ur5", "WheeledPanda": "panda", "WheeledRandomArm": "random-arm"}
    rows = sc["rows"] + sc["pooled"] + sc["by_robot"]
    figs = stat_plots.success_figures_by_robot(
        rows, sc["statistics"]["success_curve_tolerances_m"], robot_of=lambda e: prefix[e.split("-")[0]], mark=TOL
    )
    assert list(figs) == ["puma", "ur5", "panda", "random-arm", "all-robots"]
    for robot, fig in figs.items():
        titles = [ax.get_title() for ax in fig.axes if ax.get_visible()]
        if robot == "all-robots":
            assert titles == ["all tasks"]
        else:
            assert len(titles) == 5 and titles[-1] == "all tasks"  # four tasks and the robot's pool
            assert all(t.startswith(("Wheeled", "all")) for t in titles)
        assert fig.get_size_inches()[1] * fig.dpi < 1400  # not a column of 17 panels
    # a bench of one robot: its task rows and the rows pooled over its tasks (no robot field)
    one = [r for r in sc["rows"] if r["env"].startswith("WheeledPuma")]
    one += [{k: v for k, v in r.items() if k != "robot"} for r in sc["by_robot"] if r["robot"] == "puma"]
    figs = stat_plots.success_figures_by_robot(one, sc["statistics"]["success_curve_tolerances_m"])
    assert list(figs) == ["WheeledPuma"] and len([ax for ax in figs["WheeledPuma"].axes if ax.get_visible()]) == 5


@pytest.mark.parametrize("name", ["paths_3d", "error_vs_wear"])
def test_a_saved_plot_is_a_palette_png_that_draws_what_matplotlib_drew(name):
    """`eval.output.files.png_bytes`: a palette PNG of the figure's size, every pixel within 19 of 255 per channel of
    matplotlib's own render (the bound measured on the committed plots), white kept white, and smaller."""
    import io

    from PIL import Image

    from eval.output.files import PNG_COLOURS, png_bytes

    fig = _figures(SPECS)[name]
    fig.savefig(io.BytesIO(), format="png", dpi=110, bbox_inches="tight")  # a constrained layout settles in one draw
    data = png_bytes(fig)
    raw = io.BytesIO()
    fig.savefig(raw, format="png", dpi=110, bbox_inches="tight")
    with Image.open(io.BytesIO(data)) as img, Image.open(raw) as ref:
        assert img.format == "PNG" and img.mode == "P" and len(img.getcolors(PNG_COLOURS) or ()) <= PNG_COLOURS
        drawn, rendered = (np.asarray(i.convert("RGB"), dtype=int) for i in (img, ref))
    assert drawn.shape == rendered.shape
    assert np.abs(drawn - rendered).max() <= 19
    white = (rendered == 255).all(axis=2)
    assert white.mean() > 0.5 and (drawn[white] == 255).all()
    assert len(data) < len(raw.getvalue()) / 2


def test_a_figure_with_transparent_pixels_keeps_them():
    import io

    from PIL import Image

    from eval.output.files import png_bytes

    fig = _figures(SPECS)["error_norm"]
    fig.patch.set_alpha(0.0)
    with Image.open(io.BytesIO(png_bytes(fig))) as img:
        assert img.mode == "RGBA" and img.getchannel("A").getextrema()[0] < 255

"""`mobman-eval plots DIR...`: draw the plots of a results folder again from the results files it holds, running
no episode, so that a change in how plots are drawn or written (`eval.output.files.png_bytes`) reaches the
committed folders through a command, never by editing an image.

| folder | read | drawn again |
|---|---|---|
| a bench (`mobman-eval bench`; scorecard schema 3 or 4) | `scorecard.json` (or its `.xz` twin) | `plots/*.png` of `eval.bench.scorecard.scorecard_figures` |
| a bench of protocol v1 (release 0.2; scorecard schema 2, read for its plots only) | the same | `plots/success_<condition>.png` (a panel per task and one pooled: the condition's `rows` and `pooled`) and `plots/error_vs_wear.png` (the wear conditions' `pooled`), release 0.2's rule |
| a run (`mobman-eval run`) | `results.json` (or its twin) and `episodes.npz` | `plots/*.png` of `eval.output.results.write_plots` (episode 0 of each env and mode) |
| the paper (`mobman-eval paper`) | the same | the run's plots and `fig2a_`, `fig2b_`, `fig3_<dynamics>.png` (`eval.paper.write_figures`) |

A run draws its plots from the per-step arrays in memory (float64); episodes.npz keeps them as float32, so a
line drawn again from the file may move by a fraction of a pixel: on the committed paper folder 13,626 of the
1.6 million pixels of its largest plot differ from the first drawing (anti-aliasing), none visibly. Plots are
drawn by today's code: protocol v1's take today's colours and line styles (`eval.output.styles`). A
`mobman-train report` folder's curves.png is drawn again by `mobman-train report --redraw` (eval never imports
train).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from eval.bench.scorecard import KIND, load_scorecard, scorecard_figures
from eval.errors import EvalError
from eval.metrics import DEFAULT_TOLERANCE
from eval.output.files import atomic_save_figure
from eval.output.results import load_arrays, load_results, write_plots
from eval.paper import write_figures
from eval.runner import RunResult
from eval.schemas import MAX_SCORECARD_BYTES, SCORECARD_V1, check_shape, read_eval_json
from policies.agents.untrusted_json import stored_path

#: The scorecard schema of protocol v1 (release 0.2), which `load_scorecard` no longer reads.
V1_SCHEMA = 2


def redraw(folder: str | Path) -> list[Path]:
    """Draw the plots of `folder` again (see the module docstring) and return the files written; EvalError naming
    the folder when it holds neither a scorecard nor a results file with its arrays."""
    folder = Path(folder)
    if not folder.is_dir():
        raise EvalError(f"{str(folder)!r} is not a folder; give a bench's or a run's output folder")
    if stored_path(folder / "scorecard.json").exists():
        return _write(folder / "plots", _bench_figures(folder / "scorecard.json"))
    if stored_path(folder / "results.json").exists():
        return _redraw_run(folder)
    raise EvalError(
        f"{str(folder)!r} holds neither scorecard.json nor results.json (nor their .xz twins): give the folder of a "
        "`mobman-eval bench`, `run` or `paper`"
    )


def _write(plot_dir: Path, figures: Iterable[tuple[str, Any]]) -> list[Path]:
    import matplotlib.pyplot as plt

    written = []
    for stem, fig in figures:
        path = plot_dir / f"{stem}.png"
        atomic_save_figure(fig, path)
        plt.close(fig)
        written.append(path)
    return written


def _bench_figures(path: Path) -> list[tuple[str, Any]]:
    """The figures of a scorecard: today's (`scorecard_figures`) for schemas 3 and 4, release 0.2's for schema 2."""
    data = read_eval_json(path, MAX_SCORECARD_BYTES, "scorecard")
    if isinstance(data, dict) and data.get("kind") == KIND and data.get("schema") == V1_SCHEMA:
        check_shape(data, SCORECARD_V1, str(path))
        return v1_figures(data)
    return scorecard_figures(load_scorecard(path))


def v1_figures(sc: dict) -> list[tuple[str, Any]]:
    """(file stem, Figure) pairs of a protocol-v1 scorecard (schema 2), by release 0.2's rule: per condition the
    success-vs-tolerance curves of its `rows` (a panel per task) and `pooled` rows (one panel), and max error vs
    wear over the pooled rows of the kinematic conditions without noise or extra env arguments, if they hold two
    wear levels."""
    from eval.output.stat_plots import plot_error_vs_wear, plot_success_curves

    tolerances = sc["statistics"]["success_curve_tolerances_m"]
    tol = sc["protocol"]["tolerance"]
    names = list(dict.fromkeys(r["condition"] for r in sc["pooled"]))
    figs = []
    for name in names:
        rows = [r for r in (*sc["rows"], *sc["pooled"]) if r["condition"] == name]
        figs.append(
            (f"success_{name}", plot_success_curves(rows, tolerances, title=f"success vs tolerance: {name}", mark=tol))
        )
    conds = sc["protocol"]["conditions"]
    wear = [
        n
        for n in names
        if conds[n]["dynamics"] == "kinematic" and not conds[n]["obs_noise"] and not conds[n]["env_kwargs"]
    ]
    if len({conds[n]["model_error"] for n in wear}) >= 2:
        rows = [r for r in sc["pooled"] if r["condition"] in wear]
        figs.append(
            ("error_vs_wear", plot_error_vs_wear(rows, title="max error vs wear (kinematic, all tasks)", tolerance=tol))
        )
    return figs


def _redraw_run(folder: Path) -> list[Path]:
    """A run's (or the paper's) plots from its results.json and episodes.npz."""
    results = load_results(folder / "results.json")
    arrays = load_arrays(folder / "episodes.npz")
    keys = [(rec.get("index"), rec.get("arrays_key")) for rec in results["episodes"]]
    kept = {index: arrays[key] for index, key in keys if isinstance(key, str) and key in arrays}
    result = RunResult(out=folder, results=results, arrays=kept)
    written = write_plots(result, folder / "plots", results["config"].get("tolerance", DEFAULT_TOLERANCE))
    if results["config"].get("command") == "paper":
        written += [folder / name for names in write_figures(result, folder).values() for name in names]
    return written

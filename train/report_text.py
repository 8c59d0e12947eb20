"""The text and figure of `mobman-train report`: results dict (`train.report.build_report`) -> summary.md and
curves.png. Errors in mm; every figure printed here is read from the results dict, so `summary.md` can be
regenerated from `results.json` alone (`summary_markdown(json.load(...))`).

Imports: the standard library, `eval.output` (tables, precision) and, inside `curves_figure`, matplotlib.
"""

from __future__ import annotations

from typing import Any

from eval.output.precision import CHAOTIC_NOTE, format_mm, is_chaotic
from eval.output.tables import markdown_table, seed_text

#: Algorithm names as printed.
ALGO_TITLES = {"ppo": "PPO", "sac": "SAC", "td3": "TD3"}

FINAL_HEADER = (
    "policy",
    "training seeds x episodes",
    "failed",
    "tipped over",
    "success [95% CI]",
    "max err IQM [95% CI] (mm)",
    "max err median (mm)",
    "interval over",
)


def family_title(family: str) -> str:
    """ "ppo-kinematic" -> "PPO (kinematic-trained)"."""
    algo, _, dyn = family.partition("-")
    return f"{ALGO_TITLES.get(algo, algo)} ({dyn}-trained)"


def _pct(rate: float, ci: list[float] | None) -> str:
    text = f"{rate * 100:.0f}%"
    return text if not ci else f"{text} [{ci[0] * 100:.0f}-{ci[1] * 100:.0f}]"


def _mm_ci(stats: dict, spec: str) -> str:
    value = format_mm(stats.get("iqm"), spec)
    ci = stats.get("iqm_ci95")
    if value == "-" or not ci:
        return value
    return f"{value} [{format_mm(ci[0], spec).lstrip('~')}-{format_mm(ci[1], spec).lstrip('~')}]"


def _steps(n: int) -> str:
    return f"{n:,}"


def _row(label: str, size: str, stats: dict, spec: str, over: str) -> list[str]:
    """A row of `FINAL_HEADER` from an aggregate-shaped dict (a family row, a run's or a controller's)."""
    return [
        label,
        size,
        str(stats["n_failed"]),
        str(stats["n_tipped_over"]),
        _pct(stats["success_rate"], stats["success_rate_ci95"]),
        _mm_ci(stats["max_error_m"], spec),
        format_mm(stats["max_error_m"]["median"], spec),
        over,
    ]


def _family_row(f: dict, label: str) -> list[str]:
    return _row(label, f"{f['n_seeds']} x {f['n_episodes'] // f['n_seeds']}", f, "agent", "training seeds")


def _controller_rows(results: dict, dynamics: str) -> tuple[list[list[str]], list[str]]:
    """The controllers' rows of one mode and the chaotic-controller footnote lines ([] if none is chaotic)."""
    rows = results["controllers"].get(dynamics, {}).get("rows", [])
    lines = [_row(f"`{a['policy']}`", f"- x {a['n']}", a, a["policy"], "episodes") for a in rows]
    return lines, ([CHAOTIC_NOTE + ".", ""] if any(is_chaotic(a["policy"]) for a in rows) else [])


def final_table(results: dict, dynamics: str) -> str:
    """The final-evaluation table of one dynamics mode: the agent families trained in it, then the controllers
    (and the chaotic-controller footnote)."""
    lines = [
        _family_row(f, f"{family_title(f['family'])}, {'/'.join(_steps(s) for s in f['steps_per_run'])} steps")
        for f in results["families"]
        if f["dynamics"] == dynamics
    ]
    ctrl, note = _controller_rows(results, dynamics)
    return "\n".join([markdown_table(FINAL_HEADER, lines + ctrl), *([""] + note[:1] if note else [])])


def runs_table(results: dict) -> str:
    medians = {m["run"] for m in results["median_seed_models"].values()}
    header = ("run", "family", "seed", "steps", "wall (min)", "steps/s", "status", "max err IQM (mm)", "success")
    lines = []
    for r in results["runs"]:
        final = r.get("final")
        name = f"`{r['name']}`" + (" (median seed)" if r["name"] in medians else "")
        lines.append(
            [
                name,
                r["family"],
                str(r["seed"]),
                _steps(r["steps"]),
                f"{r['wall_s'] / 60:.1f}",
                f"{r['steps'] / r['wall_s']:.0f}" if r["wall_s"] else "-",
                "finished" if r["status"] == "done" else f"training (target {_steps(r['target_steps'])})",
                format_mm(final["max_error_m"]["iqm"], "agent") if final else "-",
                f"{final['success_rate'] * 100:.0f}%" if final else "-",
            ]
        )
    return markdown_table(header, lines)


def compute_table(results: dict) -> str:
    header = ("family", "runs finished", "steps per run", "wall per run (min)", "wall, all runs (h)")
    lines = []
    for fam in dict.fromkeys(r["family"] for r in results["runs"]):
        runs = [r for r in results["runs"] if r["family"] == fam]
        done = [r for r in runs if r["status"] == "done"]
        walls = sorted(r["wall_s"] / 60 for r in done)
        lines.append(
            [
                fam,
                f"{len(done)} of {len(runs)}",
                "/".join(_steps(s) for s in sorted({r["steps"] for r in done})) or "-",
                f"{walls[0]:.1f}-{walls[-1]:.1f}" if walls else "-",
                f"{sum(r['wall_s'] for r in runs) / 3600:.2f}",
            ]
        )
    runs, done = results["runs"], [r for r in results["runs"] if r["status"] == "done"]
    lines.append(
        [
            "all",
            f"{len(done)} of {len(runs)}",
            f"{_steps(sum(r['steps'] for r in runs))} in all",
            "",
            f"{sum(r['wall_s'] for r in runs) / 3600:.2f}",
        ]
    )
    note = (
        "Wall clock of each training process (its summary.json: all sessions, periodic evaluations included); "
        "unfinished runs count up to their last periodic evaluation; the report's final evaluations are not "
        f"included. {_machine(results)}"
    )
    return markdown_table(header, lines) + "\n\n" + note


def curves_table(results: dict) -> str:
    """Steps x families: the IQM over seeds of the periodic evaluation's median max error [95% interval] (mm)
    and how many seeds it is over."""
    fams = list(dict.fromkeys(c["family"] for c in results["curves"]))
    metric = results["curve_metric"]
    cells: dict[int, dict[str, str]] = {}
    for c in results["curves"]:
        value = format_mm(c[f"{metric}_iqm"], "agent", 1)
        if c[f"{metric}_ci95_low"] is not None:
            value += (
                f" [{format_mm(c[f'{metric}_ci95_low'], 'agent', 1)}-{format_mm(c[f'{metric}_ci95_high'], 'agent', 1)}]"
            )
        cells.setdefault(c["timesteps"], {})[c["family"]] = f"{value} (n={c['n_seeds']})"
    lines = [[_steps(step)] + [cells[step].get(f, "") for f in fams] for step in sorted(cells)]
    return markdown_table(("env steps", *fams), lines)


def summary_markdown(results: dict) -> str:
    cfg = results["config"]
    seeds = seed_text(range(cfg["seed"], cfg["seed"] + cfg["episodes"]))
    modes = list(results["bench_condition"])
    parts = [
        "# mobman-train report",
        "",
        f"`{results['env_id']}`; final evaluation of every finished run's last `model.zip` and of the controllers "
        f"on the same reported episodes (seeds {seeds}), with the env arguments of the bench condition of each "
        f"dynamics mode ({', '.join(f'{m}: `{c}`' for m, c in results['bench_condition'].items())}); success = "
        f"max tracking error <= {cfg['tolerance'] * 1e3:g} mm over the whole episode. Agents: IQM over training "
        "seeds x episodes, 95% stratified-bootstrap intervals over training seeds (episodes as strata); "
        "controllers: IQM over episodes, bootstrap interval over episodes, Wilson interval of the success rate. "
        f"Training code: {training_code(results)}; report: git {results['report_git']}.",
        "",
    ]
    for m in modes:
        parts += [f"## Final evaluation: {m}", "", final_table(results, m), ""]
    parts += ["## Runs", "", runs_table(results), ""]
    if results["median_seed_models"]:
        parts += [
            "Median-seed model of each family (the median of its seeds' IQM max error on these episodes): "
            + "; ".join(f"{f}: `{m['run']}` (seed {m['seed']})" for f, m in results["median_seed_models"].items())
            + ".",
            "",
        ]
    parts += ["## Compute", "", compute_table(results), ""]
    parts += [
        "## Learning curves",
        "",
        "IQM over the training seeds of each seed's median max error over its periodic evaluation (development "
        "seeds, never reported ones), with the 95% bootstrap interval over the seeds and the number of seeds "
        "evaluated at that step (curves.png draws the same numbers, and every seed's curve):",
        "",
        curves_table(results),
        "",
        "## Commands",
        "",
        *[
            f"* `{r['name']}`: trained by `{r['train_command']}`"
            + (f"; evaluated by `{r['command']}`" if r.get("command") else " (still training)")
            for r in results["runs"]
        ],
        *[f"* controllers, {m}: `{c['command']}`" for m, c in results["controllers"].items()],
        "",
    ]
    return "\n".join(parts)


def curves_figure(results: dict, run_curves: dict[str, list[dict]]) -> Any:
    """One panel per family: every seed's periodic-evaluation median max error (thin), the IQM over seeds
    (thick) and its 95% interval (band) vs env steps; log scale, the success tolerance dotted."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    metric = results["curve_metric"]
    fams = list(dict.fromkeys(c["family"] for c in results["curves"]))
    from matplotlib.ticker import FuncFormatter

    fig = Figure(figsize=(4.6 * max(len(fams), 1), 4.0), dpi=110)
    axes = fig.subplots(1, max(len(fams), 1), sharey=True, squeeze=False)[0]
    for i, (fam, ax) in enumerate(zip(fams, axes)):
        for r in (r for r in results["runs"] if r["family"] == fam):
            rows = run_curves.get(r["name"], [])
            ax.plot(
                [p["timesteps"] for p in rows],
                [1e3 * p[metric] for p in rows],
                lw=0.8,
                alpha=0.5,
                label=f"seed {r['seed']}",
            )
        cs = [c for c in results["curves"] if c["family"] == fam]
        x = [c["timesteps"] for c in cs]
        ax.plot(x, [1e3 * c[f"{metric}_iqm"] for c in cs], "k-", lw=2, label="IQM over seeds")
        band = [c for c in cs if c[f"{metric}_ci95_low"] is not None]
        ax.fill_between(
            [c["timesteps"] for c in band],
            [1e3 * c[f"{metric}_ci95_low"] for c in band],
            [1e3 * c[f"{metric}_ci95_high"] for c in band],
            color="k",
            alpha=0.15,
            label="95% interval",
        )
        ax.axhline(1e3 * results["config"]["tolerance"], color="g", ls=":", label="success tolerance")
        ax.set_yscale("log")
        ax.set_xlabel("env steps")
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v / 1e3:g}k" if v else "0"))
        if i == 0:
            ax.set_ylabel("median max error, development seeds (mm)")
        ax.set_title(family_title(fam))
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def training_code(results: dict) -> str:
    """Which commit trained which runs ("git X" when one did them all); carried-over runs say from where."""
    commits = results.get("train_commits") or {results["train_commit"] or "not recorded": []}
    if len(commits) == 1:
        text = f"git {next(iter(commits))}"
    else:
        text = "; ".join(f"git {c} ({', '.join(f'`{n}`' for n in names)})" for c, names in commits.items())
    sources = sorted({r["archived_from"] for r in results["runs"] if r.get("archived_from")})
    if sources:
        text += f" (runs carried over from {', '.join(f'`{s}`' for s in sources)}, as they were measured there)"
    return text


def _machine(results: dict) -> str:
    prov = results.get("provenance") or {}
    return f"Machine of the report: {prov.get('cpu') or 'unknown CPU'}, {prov.get('cpu_count') or '?'} cores."


def _median_note(n: int) -> str:
    if n >= 3:
        return "A typical run, not the best one."
    if n == 2:
        return "With two finished seeds the lower median is the better of the two."
    return "Only this seed had finished when the report was written, so it is the median by default."


def _training_section(results: dict, family: str, run: dict, algo: str) -> list[str]:
    """A shipped model's README: its "Training" section (command, hyperparameters, code, budget)."""
    hp_note = (
        f"the defaults of `mobman-train --algo {algo}` (`train/algos.py`; the same in rl-baselines3-zoo's format: "
        f"`train/hyperparams/{algo}.yml`)"
        if not run["hyperparams_overrides"]
        else f"overrides {run['hyperparams_overrides']} of the defaults of `train/algos.py`"
    )
    walls = [r["wall_s"] for r in results["runs"] if r["family"] == family and r["status"] == "done"]
    return [
        "## Training",
        "",
        "```",
        run["train_command"],
        "```",
        "",
        f"Hyperparameters: {hp_note}. Training code: git {run.get('train_commit') or results['train_commit'] or 'not recorded'}; "
        f"versions: {', '.join(f'{k} {v}' for k, v in run['versions'].items() if v)}. Periodic evaluation on "
        "development seeds only (900-904); the reported seeds were never seen in training or selection.",
        "",
        f"Budget of this run: {_steps(run['steps'])} env steps in {run['wall_s'] / 60:.1f} min wall clock "
        f"({run['steps'] / run['wall_s']:.0f} steps/s; {run['config']['n_envs']} env(s), torch "
        f"{run['config']['torch_threads']} thread(s)). {_machine(results)} The family's finished runs: "
        f"{len(walls)}, {sum(walls) / 3600:.2f} h in all.",
        "",
    ]


def model_readme(results: dict, family: str, alias: str, results_file: str) -> str:
    """README.md of a shipped model: what it is, how it was chosen and trained, and its results beside its
    family and the controllers, every figure read from `results` (the report's results.json)."""
    cfg = results["config"]
    fam = next(f for f in results["families"] if f["family"] == family)
    median = results["median_seed_models"][family]
    run = next(r for r in results["runs"] if r["name"] == median["run"])
    algo, dyn = run["config"]["algo"], run["config"]["dynamics"]
    title = ALGO_TITLES.get(algo, algo)
    seeds = seed_text(range(cfg["seed"], cfg["seed"] + cfg["episodes"]))
    cond = results["bench_condition"][dyn]
    ck = results["condition_kwargs"][dyn]
    final = run["final"]
    rows = [
        _row(f"`sb3:{alias}` (seed {run['seed']})", f"1 x {final['n']}", final, "agent", "episodes"),
        _family_row(fam, f"{family}, {fam['n_seeds']} finished seed(s)"),
    ]
    ctrl, note = _controller_rows(results, dyn)
    per_seed = "; ".join(
        f"seed {r['seed']}: {format_mm(r['final']['max_error_m']['iqm'], 'agent')} mm, "
        f"{r['final']['success_rate'] * 100:.0f}%"
        for r in results["runs"]
        if r["family"] == family and r.get("final")
    )
    eval_cmd = (
        f"mobman-eval run --env {results['env_id']} --policy sb3:{alias} --policy nnbc-plus --seeds "
        f"{cfg['episodes']} --seed {cfg['seed']} --dynamics {dyn} --model-error {ck['model_error']!r}"
    )
    lines = [
        f"# `sb3:{alias}` — the shipped {title} baseline ({dyn})",
        "",
        f"Generated by `mobman-train report` from `{results_file}` (rerun the report to change it; a test keeps "
        "this file and the results equal).",
        "",
        f"A Stable-Baselines3 {title} agent trained by `mobman-train` on `{results['env_id']}` in **{dyn}** mode "
        f"(the paper's circle, 20 s; every episode a different robot, 5% wear). It is the **median-seed model** "
        f"of the `{family}` family: of its finished training seeds ({', '.join(map(str, fam['seeds']))}), the run "
        f"whose IQM max error on the reported episodes (seeds {seeds}) is the median of the seeds' (the lower "
        f"median for an even count): `{run['name']}`, seed {run['seed']}. {_median_note(fam['n_seeds'])}",
        "",
        "Files: `model.zip` (the run's final model), `vecnormalize.pkl` (observation statistics), `config.json` "
        "(the run's resolved `TrainConfig`, which `policies.agents.sb3.SB3Policy` reads: algorithm, observation keys, "
        "wrappers).",
        "",
        "```",
        eval_cmd,
        "```",
        "",
        *_training_section(results, family, run, algo),
        f"## Results (reported seeds {seeds}, {dyn}, bench condition `{cond}`, success = max error <= "
        f"{cfg['tolerance'] * 1e3:g} mm)",
        "",
        markdown_table(FINAL_HEADER, rows + ctrl),
        "",
        *note,
        f"Per training seed (IQM max error, success): {per_seed}.",
        "",
        f"The same evaluation: `{run['command']}`.",
        "",
    ]
    return "\n".join(lines)

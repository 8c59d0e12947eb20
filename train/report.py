"""`mobman-train report`: several training runs -> one committed results folder (curves, final tables).

```
mobman-train report /work/rl-runs/ppo-kin-s* /work/rl-runs/sac-kin-s* --out docs/results/rl-v2 \
    --train-commit e52e574
```

What it does, in order (`build_report(ReportConfig)`):

1. Reads every run folder written by `mobman-train` (`config.json`, `summary.json`, `learning_curve.csv`):
   its family `<algo>-<dynamics>` (e.g. `ppo-kinematic`), training seed, steps and wall-clock time. The runs
   of one family must differ only in their seed (same env, hyperparameters, observation, target steps): a
   family is one setting trained several times. A run without a finished `summary.json` is still training:
   its curve is drawn, it is listed, and it gets no final evaluation.
2. Evaluates every finished run's final `model.zip` with `eval.run` (exactly `mobman-eval run --policy
   sb3:RUN/model.zip`) on the reported episodes (seeds `seed` .. `seed + episodes - 1`) in its dynamics mode,
   with the env arguments of the bench condition of that mode (`BENCH_CONDITION`: `default` for kinematic,
   `physics` for physics: 5% wear, no noise), and the controllers on the same episodes, one `eval.run` per
   mode. Each evaluation's report goes to `OUT/evals/<name>/` and is reused when its inputs did not change
   (the model's SHA-256, the episodes, the env arguments): rerunning the report after more runs finished
   evaluates only the new ones.
3. Aggregates (`train.report_stats`): per family the IQM of the max error over seeds x episodes with the
   stratified-bootstrap interval over training seeds, the success rate with its interval, the median-seed run;
   per evaluation step the IQM over seeds of the periodic evaluation (learning curves).
4. Writes `OUT/results.json` (config, provenance, runs, family rows, controller rows, curves, and every
   reported episode under "episodes"), `curves.csv` (per run), `curves_iqm.csv` (per family), `curves.png`,
   `summary.md` (the Markdown tables that `mobman-eval readme` copies into docs/rl/index.md) and `config.json`.

The training code's commit is not in a run folder (`config.json` records versions only): pass it as
`--train-commit`; it is recorded as given.

Imports: the standard library, numpy, `eval` (run, config, metrics, output) and `train.report_stats` /
`train.report_text`; torch and SB3 only through `eval.run` of `sb3:` policies.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import MISSING, Field, asdict, dataclass, field, fields
from pathlib import Path

from eval.metrics import DEFAULT_TOLERANCE
from eval.output.provenance import code_hash
from mobman_env.validation import folder_name, integer
from policies.agents.untrusted import file_sha256
from policies.agents.untrusted_json import stored_path
from train.curve import read_curve
from train.evaluation import eval_command
from train.report_archive import read_json as _json
from train.report_stats import CURVE_METRIC, curve_rows, family_row, median_run

#: Bench condition (`eval.bench.config.CONDITIONS`) whose env arguments the final evaluation uses, per mode.
BENCH_CONDITION = {"kinematic": "default", "physics": "physics"}

#: The controllers evaluated beside the agents (the model-free one, the known-model ceiling, the nominal-model
#: closed loop, the paper's open-loop baseline, the paper's method, the floor).
DEFAULT_CONTROLLERS = ("nnbc-plus", "qp-oracle", "clik", "jmpi", "nnbc", "zero")

#: Episode fields kept in results.json (the per-run reports in evals/ keep everything).
EPISODE_KEYS = (
    "seed",
    "status",
    "max_error_m",
    "rms_error_m",
    "final_error_m",
    "steady_max_error_m",
    "success",
    "tipped_over",
    "n_steps",
)

#: Files of OUT written by the report (besides evals/).
REPORT_FILES = ("results.json", "summary.md", "curves.csv", "curves_iqm.csv", "curves.png", "config.json")


@dataclass(frozen=True)
class ReportConfig:
    runs: tuple[str, ...] = ()
    """Run folders of `mobman-train` (any number of families, each with its seeds)."""
    out: str = "docs/results/rl-v2"
    """Results folder (written; evaluations cached in `out/evals/`)."""
    episodes: int = 20
    """Reported episodes of the final evaluation (seeds `seed` .. `seed + episodes - 1`)."""
    seed: int = 10_000
    """First reported seed (>= 10,000: never a training or tuning seed)."""
    controllers: tuple[str, ...] = DEFAULT_CONTROLLERS
    """Controller specs evaluated on the same episodes, in every dynamics mode of the runs."""
    tolerance: float = DEFAULT_TOLERANCE
    """Success threshold on the max tracking error, m (the paper's 6 mm)."""
    env_kwargs: dict = field(default_factory=dict)
    """Env arguments of every evaluation on top of the bench condition's (e.g. a `path`); a run trained on a
    task-defining argument (its config.json's `eval_env_kwargs`) must find it here with the same value."""
    train_commit: str | None = None
    """Git commit of the code that trained the runs (recorded as given; a run folder does not hold it)."""
    workers: int = 1
    """Parallel episodes of each evaluation (`eval.run`'s workers)."""
    plots: bool = True
    """Write curves.png (matplotlib)."""
    ship: tuple[tuple[str, str], ...] = ()
    """(alias, family) pairs: copy the family's median-seed model to `models_dir/alias/` with a generated
    README.md (e.g. ("ppo-circle", "ppo-kinematic")); `policies.agents.sb3.ALIASES` must name it to be `sb3:alias`."""
    models_dir: str = "policies/models"
    """Where `ship` puts the models (the folder of the shipped `sb3:` aliases)."""
    include: tuple[str, ...] = ()
    """Folders of earlier reports whose finished runs are carried over as they were measured (`train.report_archive`:
    their curves, budgets and cached final evaluations; their models need not be on disk). A run folder in `runs`
    wins over an archived run of the same name."""
    redraw: bool = False
    """Instead of a report: draw curves.png of the report in `out` again from its results.json and curves.csv
    (`redraw_curves`), evaluating nothing; no other option may be given."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "runs", tuple(str(r) for r in self.runs))
        object.__setattr__(self, "controllers", tuple(self.controllers))
        object.__setattr__(self, "env_kwargs", dict(self.env_kwargs))
        object.__setattr__(self, "ship", tuple((str(a), str(f)) for a, f in self.ship))
        for alias, _ in self.ship:
            folder_name(
                "--ship ALIAS", alias, hint="the alias is a folder of models_dir, e.g. --ship ppo-circle=ppo-kinematic"
            )
        object.__setattr__(self, "include", tuple(str(p) for p in self.include))
        integer("episodes", self.episodes, low=1, hint="the number of seeds, e.g. --seeds 20")
        integer("seed", self.seed, low=10_000, hint="reported seeds start at 10000; tune on 0-999")
        integer("workers", self.workers, low=1, hint="e.g. --workers 1")
        if self.redraw:
            others = [f.name for f in fields(self) if f.name not in ("out", "redraw") and _given(self, f)]
            if others:
                raise ValueError(f"--redraw takes only --out DIR, not {', '.join(others)}")
            return
        if not self.runs and not self.include:
            raise ValueError(
                "no run folder given; e.g. mobman-train report runs/ppo-s0 runs/ppo-s1 --out DIR "
                "(or --include an earlier report's folder)"
            )

    def to_dict(self) -> dict:
        d = asdict(self)
        del d["redraw"]  # a report's config.json: redrawing writes none
        d["runs"] = list(self.runs)
        d["controllers"] = list(self.controllers)
        d["ship"] = [list(pair) for pair in self.ship]
        d["include"] = list(self.include)
        return json.loads(json.dumps(d))


def _given(config: ReportConfig, f: Field) -> bool:
    """Whether `config`'s field `f` differs from its default."""
    return getattr(config, f.name) != (f.default_factory() if f.default_factory is not MISSING else f.default)


# --- reading run folders ---------------------------------------------------------------------------------


#: The SHA-256 of a file (hex): the model identity the report caches its evaluations under.
sha256 = file_sha256


#: config.json entries that must agree between the seeds of one family.
FAMILY_KEYS = (
    "env_id",
    "algo",
    "dynamics",
    "timesteps",
    "env_kwargs",
    "alive_bonus",
    "obs_keys",
    "wrappers",
    "n_envs",
    "torch_threads",
)


def read_run(path: str | Path) -> dict:
    """One run folder: name, path, family, seed, config entries, status ("done" or "training"), steps,
    wall-clock seconds, the learning curve and (finished) the model's SHA-256."""
    d = Path(path)
    if not (d / "config.json").is_file():
        raise ValueError(f"{d} is not a mobman-train run folder (no config.json); give the folders of the runs")
    name = folder_name(
        f"run folder {str(path)!r}: its name",
        d.resolve().name,
        hint="give the run folder by a path that ends in its name",
    )
    cfg = _json(d / "config.json")
    _require(d / "config.json", cfg, {"algo": str, "dynamics": str, "env_id": str, "seed": int, "timesteps": int})
    curve = read_curve(d / "learning_curve.csv")
    summary = _json(d / "summary.json") if (d / "summary.json").exists() else {}
    done = summary.get("status") == "done" and (d / "model.zip").is_file()
    if done:
        _require(d / "summary.json", summary, {"timesteps": int, "wall_s": float})
    run = {
        "name": name,
        "path": str(d.resolve()),
        "family": f"{cfg['algo']}-{cfg['dynamics']}",
        "seed": int(cfg["seed"]),
        "status": "done" if done else "training",
        "steps": int(summary["timesteps"]) if done else int(curve[-1]["timesteps"]) if curve else 0,
        "target_steps": int(cfg["timesteps"]),
        "wall_s": float(summary["wall_s"]) if done else float(curve[-1]["wall_s"]) if curve else 0.0,
        "config": {k: cfg.get(k) for k in FAMILY_KEYS},
        "eval_env_kwargs": {k: v for k, v in cfg.get("eval_env_kwargs", {}).items() if k != "dynamics"},
        "hyperparams": cfg.get("hyperparams_resolved", cfg.get("hyperparams", {})),
        "hyperparams_overrides": cfg.get("hyperparams", {}),
        "train_command": train_command(cfg, f"runs/{name}"),
        "versions": cfg.get("versions", {}),
        "curve": curve,
    }
    if done:
        run["model_sha256"] = sha256(d / "model.zip")
    return run


def _require(path: Path, data: dict, types: dict[str, type]) -> None:
    """ValueError naming the file, the key and what it must be when `data` lacks a key of `types` or holds a
    value of another type (an int is a float; a bool is neither)."""
    for key, kind in types.items():
        value = data.get(key)
        accepted = (int, float) if kind is float else (kind,)
        if value is None or isinstance(value, bool) or not isinstance(value, accepted):
            shown = "missing" if key not in data else f"{value!r}"
            raise ValueError(
                f"{path}: {key!r} must be {'a number' if kind is float else 'an integer' if kind is int else 'a text'}"
                f", got {shown}; this file is not what mobman-train writes: copy it again from the run"
            )


def train_command(cfg: dict, out: str) -> str:
    """The `mobman-train` command line that trains a run of this config.json into `out` (hyperparameters other
    than the defaults: `--hyperparams HP.json` with the run's `hyperparams` entry as that file)."""
    import shlex

    from train.config import LEARNING_ENV_KWARGS, TrainConfig

    d = TrainConfig()
    parts = ["mobman-train", "--algo", cfg["algo"], "--env", cfg["env_id"], "--dynamics", cfg["dynamics"]]
    parts += ["--timesteps", str(cfg["timesteps"]), "--seed", str(cfg["seed"])]
    for key in ("n_envs", "eval_freq", "eval_episodes", "final_eval_episodes", "checkpoint_freq", "alive_bonus"):
        if key in cfg and cfg[key] != getattr(d, key):
            parts += ["--" + key.replace("_", "-"), str(cfg[key])]
    if cfg.get("env_kwargs", LEARNING_ENV_KWARGS) != LEARNING_ENV_KWARGS:
        parts += ["--env-kwargs", json.dumps(cfg["env_kwargs"], sort_keys=True)]
    if cfg.get("hyperparams"):
        parts += ["--hyperparams", "HP.json"]
    return " ".join(shlex.quote(p) for p in [*parts, "--out", out])


def group_families(runs: list[dict]) -> dict[str, list[dict]]:
    """Runs by family (in first-seen order, each sorted by seed); ValueError when seeds repeat or the runs of a
    family differ in anything but their seed."""
    families: dict[str, list[dict]] = {}
    for r in runs:
        families.setdefault(r["family"], []).append(r)
    for fam, members in families.items():
        members.sort(key=lambda r: r["seed"])
        seeds = [r["seed"] for r in members]
        if len(set(seeds)) != len(seeds):
            raise ValueError(f"{fam}: training seeds repeat ({seeds}, runs {[r['name'] for r in members]})")
        ref = members[0]
        for r in members[1:]:
            for key, a, b in [(k, ref["config"][k], r["config"][k]) for k in FAMILY_KEYS] + [
                ("hyperparams", ref["hyperparams"], r["hyperparams"])
            ]:
                if a != b:
                    raise ValueError(
                        f"{fam}: {r['name']} has {key} {b!r}, {ref['name']} {a!r}; the runs of a family may differ "
                        f"only in their seed (report different settings as different families)"
                    )
    return families


# --- evaluations ---------------------------------------------------------------------------------------------


def condition_kwargs(dynamics: str, extra: dict | None = None) -> dict:
    """`EvalConfig` fields of the bench condition of `dynamics` (`BENCH_CONDITION`), plus env arguments `extra`."""
    from eval.bench.config import CONDITIONS

    c = CONDITIONS[BENCH_CONDITION[dynamics]]
    return {
        "dynamics": (c.dynamics,),
        "model_error": c.model_error,
        "obs_noise": c.obs_noise,
        "env_kwargs": {**c.extra_kwargs, **(extra or {})},
    }


def check_task(config: ReportConfig, run: dict) -> None:
    """A run trained on task-defining env arguments is evaluated on that task or refused (never silently
    evaluated on another one)."""
    cond = condition_kwargs(run["config"]["dynamics"], config.env_kwargs)
    flat = {"model_error": cond["model_error"], "obs_noise": cond["obs_noise"], **cond["env_kwargs"]}
    differ = {k: v for k, v in run["eval_env_kwargs"].items() if k not in flat or flat[k] != v}
    if differ:
        raise ValueError(
            f"{run['name']} was trained on env arguments {differ}, which the report's evaluation "
            f"({flat}) does not use; pass them with --env-kwargs, or leave the run out"
        )


def _eval_config(config: ReportConfig, env_id: str, policies: tuple[str, ...], dynamics: str, out: Path):
    from eval import EvalConfig

    return EvalConfig(
        envs=(env_id,),
        policies=policies,
        episodes=config.episodes,
        seed=config.seed,
        out=str(out),
        overwrite=True,
        workers=config.workers,
        tolerance=config.tolerance,
        plots=False,
        save_arrays="none",
        progress=False,
        **condition_kwargs(dynamics, config.env_kwargs),
    )


#: `EvalConfig` fields that say where and how an evaluation runs, not what it measures: a cached evaluation made
#: with other values is reused (their records are the same).
NOT_INPUTS = ("out", "workers", "progress", "batch_size")


def _inputs(cfg, extra: dict) -> dict:
    d = cfg.to_dict()
    return {"eval_config": {k: d[k] for k in sorted(d) if k not in NOT_INPUTS}, **extra}


def cached_evaluation(cfg, extra: dict) -> list[dict]:
    """The episode records of `eval.run(cfg)`, read from `cfg.out` when an earlier run there had the same
    inputs (`inputs.json`: the EvalConfig without its output settings, plus `extra`, e.g. the model's
    SHA-256); otherwise run it (progress on stderr) and record the inputs."""
    import sys

    from eval import run as eval_run
    from eval.output.files import atomic_write_json

    out = Path(cfg.out)
    inputs = _inputs(cfg, extra)
    same = (out / "inputs.json").is_file() and _json(out / "inputs.json") == json.loads(json.dumps(inputs))
    if same and stored_path(out / "results.json").is_file():  # results.json or its compacted twin
        return list(_json(out / "results.json")["episodes"])
    print(f"mobman-train report: evaluating {', '.join(cfg.policies)} ({cfg.dynamics[0]}) -> {out}", file=sys.stderr)
    result = eval_run(cfg)
    atomic_write_json(out / "inputs.json", inputs)
    return list(result.results["episodes"])


def _slim(rec: dict) -> dict:
    return {k: rec.get(k) for k in EPISODE_KEYS}


def evaluate_run(config: ReportConfig, run: dict, out: Path) -> dict:
    """Final evaluation of one finished run (cached): its slim episode records and the command."""
    model = Path(run["path"]) / "model.zip"
    cfg = _eval_config(config, run["config"]["env_id"], (f"sb3:{model}",), run["config"]["dynamics"], out)
    records = cached_evaluation(cfg, {"model_sha256": run["model_sha256"]})
    return {"episodes": [_slim(r) for r in records], "command": eval_command(cfg)}


def evaluate_controllers(config: ReportConfig, env_id: str, dynamics: str, out: Path) -> dict:
    """The controllers on the reported episodes in one mode (cached while `code_hash()` is the same):
    aggregate rows and slim records.

    The cache key holds the hash of the code (`eval.output.provenance.code_hash`, the one hash of "the code
    that ran", over all four packages), so a changed controller, env or metric is evaluated again instead of
    being read from an earlier report's cache (the key was the configuration alone before `nnbc-plus` v4 moved
    its actions, and `mobman-train report` then carried v3's rows over; it hashed `mobman_env` and `policies`
    alone until the code hash became one function: eval's metrics make these rows too)."""
    from eval import metrics as M

    cfg = _eval_config(config, env_id, config.controllers, dynamics, out)
    records = cached_evaluation(cfg, {"source_sha256": code_hash()})
    rows = M.aggregate(records, group_keys=("policy",))
    for row in rows:
        row.pop("success_curve", None)
    return {
        "rows": rows,
        "episodes": [{**_slim(r), "policy": r["policy"]} for r in records],
        "command": eval_command(cfg),
    }


# --- the report ---------------------------------------------------------------------------------------------


def _families(families: dict[str, list[dict]]) -> tuple[list[dict], dict[str, dict]]:
    """Per family: its row over its finished runs (each run's final figures set on it) and its median run."""
    family_rows, medians = [], {}
    for fam, members in families.items():
        finished = [r for r in members if r["status"] == "done"]
        for r in finished:
            r["final"] = run_final(r["episodes"])
        if finished:
            family_rows.append(
                {**family_row(fam, finished), "dynamics": finished[0]["config"]["dynamics"], **_budget(finished)}
            )
            m = median_run(finished, key=_final_iqm)
            medians[fam] = {"run": m["name"], "seed": m["seed"], "path": m["path"]}
    return family_rows, medians


def _episodes(runs: list[dict], controllers: dict[str, dict]) -> list[dict]:
    """Every evaluated episode of the runs (named by family, run and `sb3:` policy) and of the controllers."""
    return [
        {
            **e,
            "family": r["family"],
            "run": r["name"],
            "policy": f"sb3:{r['name']}",
            "dynamics": r["config"]["dynamics"],
        }
        for r in runs
        for e in r.get("episodes", [])
    ] + [{**e, "dynamics": m} for m, c in controllers.items() for e in c["episodes"]]


def _write(config: ReportConfig, out: Path, results: dict, runs: list[dict]) -> None:
    """The report's files: results.json, config.json, the curves' CSVs, summary.md and (with plots) curves.png."""
    from eval.output.files import atomic_write_json, atomic_write_text
    from train.report_text import curves_figure, summary_markdown

    atomic_write_json(out / "results.json", results)
    atomic_write_json(out / "config.json", config.to_dict())
    atomic_write_text(out / "curves.csv", _csv(_run_curve_rows(runs)))
    atomic_write_text(out / "curves_iqm.csv", _csv(results["curves"]))
    atomic_write_text(out / "summary.md", summary_markdown(results))
    if config.plots:
        from eval.output.files import atomic_save_figure

        atomic_save_figure(curves_figure(results, {r["name"]: r["curve"] for r in runs}), out / "curves.png")


def redraw_curves(folder: str | Path) -> Path:
    """Draw curves.png of the report in `folder` again from its results.json and curves.csv (read as `--include`
    reads them: `train.report_archive`), evaluating and writing nothing else, so that a change in how plots are
    written reaches a committed report through a command; returns the file written. ValueError naming the folder
    when it is not a report's."""
    from eval.output.files import atomic_save_figure
    from train.report_archive import REPORT_SCHEMA, archived_curves
    from train.report_text import curves_figure

    folder = Path(folder)
    results = _json(folder / "results.json")
    if results.get("schema") != REPORT_SCHEMA:
        raise ValueError(
            f"{folder}/results.json has schema {results.get('schema')!r}, not a report's ({REPORT_SCHEMA!r})"
        )
    atomic_save_figure(curves_figure(results, archived_curves(folder)), folder / "curves.png")
    return folder / "curves.png"


def build_report(config: ReportConfig) -> dict:
    """Read, evaluate, aggregate and write the report (see the module docstring); the results dict."""
    from eval.output.provenance import git_rev, provenance
    from train.report_archive import Evaluation, archived_runs, copy_cached_eval

    live = [{**read_run(p), "train_commit": config.train_commit} for p in config.runs]
    names = {r["name"] for r in live}
    archived = [
        r
        for folder in config.include
        for r in archived_runs(folder, config, Evaluation(_eval_config, _inputs, _slim))
        if r["name"] not in names
    ]
    runs = sorted(live + archived, key=lambda r: (r["family"], r["seed"]))
    env_ids = sorted({r["config"]["env_id"] for r in runs})
    if len(env_ids) != 1:
        raise ValueError(f"the runs were trained on several envs {env_ids}; report one env at a time")
    env_id = env_ids[0]
    families = group_families(runs)
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)

    for r in runs:
        check_task(config, r)
    for r in runs:
        if "archived_from" in r:
            copy_cached_eval(r, out)
        elif r["status"] == "done":
            r.update(evaluate_run(config, r, out / "evals" / r["name"]))
    modes = sorted({r["config"]["dynamics"] for r in runs}, key=list(BENCH_CONDITION).index)
    controllers = {
        m: evaluate_controllers(config, env_id, m, out / "evals" / f"controllers-{m}")
        for m in (modes if config.controllers else [])
    }

    family_rows, medians = _families(families)
    curves = [row for fam, members in families.items() for row in curve_rows(fam, members)]
    episodes = _episodes(runs, controllers)
    results = {
        "schema": "mobman-rl-report-1",
        "config": config.to_dict(),
        "env_id": env_id,
        "bench_condition": {m: BENCH_CONDITION[m] for m in modes},
        "condition_kwargs": {m: condition_kwargs(m, config.env_kwargs) for m in modes},
        "train_commit": config.train_commit,
        "train_commits": _train_commits(runs),
        "report_git": git_rev(),
        "provenance": provenance(),
        "runs": [{k: v for k, v in r.items() if k not in ("curve", "episodes")} for r in runs],
        "families": family_rows,
        "median_seed_models": medians,
        "controllers": {m: {"rows": c["rows"], "command": c["command"]} for m, c in controllers.items()},
        "curve_metric": CURVE_METRIC,
        "curves": curves,
        "episodes": episodes,
    }
    _write(config, out, results, runs)
    for alias, family in config.ship:
        ship_model(results, family, alias, Path(config.models_dir), out / "results.json")
    return results


#: Files of a run folder that a shipped model keeps (vecnormalize.pkl when the run normalised observations).
SHIPPED_FILES = ("model.zip", "vecnormalize.pkl", "config.json")


def ship_model(results: dict, family: str, alias: str, models_dir: Path, results_file: Path) -> Path:
    """Copy `family`'s median-seed model into `models_dir/alias/` and write its README.md (generated from
    `results`, which `results_file` holds); the copied model.zip must have the SHA-256 the report evaluated."""
    import shutil

    from eval.output.files import atomic_write_text
    from train.report_text import model_readme

    medians = results["median_seed_models"]
    if family not in medians:
        raise ValueError(f"--ship {alias}={family}: no finished run of family {family!r}; families: {sorted(medians)}")
    run = next(r for r in results["runs"] if r["name"] == medians[family]["run"])
    src, dest = Path(run["path"]), models_dir / alias
    shipped = (dest / "model.zip").is_file() and sha256(dest / "model.zip") == run["model_sha256"]
    if not (src / "model.zip").is_file() and not shipped:
        raise ValueError(
            f"--ship {alias}={family}: the median-seed run {run['name']} has no model at {src} (an archived run) and "
            f"{dest / 'model.zip'} is not that model (SHA-256 {run['model_sha256'][:12]}...); give its run folder"
        )
    dest.mkdir(parents=True, exist_ok=True)
    if not shipped:  # an archived run's model already shipped under this alias keeps its files
        for name in SHIPPED_FILES:
            if (src / name).is_file():
                shutil.copyfile(src / name, dest / name)
    if sha256(dest / "model.zip") != run["model_sha256"]:
        raise ValueError(f"{src / 'model.zip'} changed since the report evaluated it; rerun the report")
    atomic_write_text(dest / "README.md", model_readme(results, family, alias, str(results_file)))
    return dest


def _train_commits(runs: list[dict]) -> dict[str, list[str]]:
    """{training commit: the runs it trained} ("not recorded" where a run has none)."""
    out: dict[str, list[str]] = {}
    for r in runs:
        out.setdefault(r.get("train_commit") or "not recorded", []).append(r["name"])
    return out


def run_final(episodes: list[dict]) -> dict:
    """One run's final figures over its reported episodes, as `eval.metrics.aggregate` gives a controller's:
    IQM max error with its bootstrap interval over the episodes, median, success rate with its Wilson
    interval, failed and tipped-over episodes."""
    from eval import metrics as M

    row = M.aggregate(episodes, group_keys=(), metrics=("max_error_m",))[0]
    keys = ("n", "n_failed", "n_tipped_over", "success_rate", "success_rate_ci95", "max_error_m")
    return {k: row[k] for k in keys}


def _final_iqm(run: dict) -> float:
    """A run's IQM max error on the reported episodes (infinite when none of them ran)."""
    value = run["final"]["max_error_m"]["iqm"]
    return math.inf if value is None else float(value)


def _budget(runs: list[dict]) -> dict:
    """Training budget of a family: steps and wall-clock seconds per run and in total."""
    return {
        "steps_per_run": sorted({r["steps"] for r in runs}),
        "wall_s_per_run": [r["wall_s"] for r in runs],
        "wall_s_total": float(sum(r["wall_s"] for r in runs)),
        "steps_total": int(sum(r["steps"] for r in runs)),
    }


def _run_curve_rows(runs: list[dict]) -> list[dict]:
    return [
        {"family": r["family"], "run": r["name"], "seed": r["seed"], **{k: row[k] for k in row}}
        for r in runs
        for row in r["curve"]
    ]


def _csv(rows: list[dict]) -> str:
    if not rows:
        return ""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    return buf.getvalue()

"""Runs carried over from an earlier report: `mobman-train report NEW_RUN... --include OLD_REPORT_DIR`.

Training runs outlive the machine that trained them only through what a report committed: `results.json`
(each run's config, hyperparameters, versions, budget, model SHA-256, training commit), `curves.csv` (each
run's learning curve) and `evals/<run>/` (its final evaluation: `results.json` and the `inputs.json` it was
cached under). `archived_runs(folder, config)` turns those back into the run entries that `train.report`
builds from a live run folder, so that a family can grow by seeds trained in a later session (the five PPO
seeds of one machine and the new SAC seeds of another in one table) without retraining what is already
measured and without a model file that is no longer on disk.

What is carried over is exactly what was measured: an archived run is never re-evaluated. Its cached final
evaluation must have been made with the evaluation this report makes (the cache key the report itself uses:
the `EvalConfig` without the settings of where and how it runs, `train.report.NOT_INPUTS`; and the same model
SHA-256), else the run is refused with the difference named: a model that is not on disk cannot be evaluated again. Runs still training when the
old report was written are not carried over (their curves stop where that report stopped). A run folder given
on the command line wins over an archived run of the same name.

Every carried run says where it came from (`archived_from`) and which code trained it (`train_commit`, from
the old report's record).

Run names become folder names (`evals/<name>/`), so each must be one plain path component
(`mobman_env.validation.folder_name`): a results.json naming a run `../x` is refused, never written outside.

Every file is read as a regular file with a size cap (`read_json`, `train.curve.read_curve`): a curves.csv
symlinked to /dev/zero or a FIFO is refused, never read.

Imports: the standard library, `mobman_env.validation`, `policies.agents.untrusted`, `train.curve` and
`train.evaluation`; what it needs of `train.report` (which imports this
module) is handed in as an `Evaluation`.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any, NamedTuple

from mobman_env.validation import folder_name
from policies.agents.untrusted import FileRefused
from policies.agents.untrusted_json import read_json as read_json_checked
from policies.agents.untrusted_json import stored_path
from train.curve import read_curve

#: The schema of the report results this module reads (`train.report.build_report` writes it).
REPORT_SCHEMA = "mobman-rl-report-1"


class Evaluation(NamedTuple):
    """How a report evaluates a run: `config(report_config, env_id, policies, dynamics, out)` the `EvalConfig`,
    `inputs(eval_config, extra)` the cache key of `inputs.json`, `slim(record)` the episode fields it keeps."""

    config: Any
    inputs: Any
    slim: Any


#: Columns of curves.csv that name the run rather than hold its curve.
RUN_COLUMNS = ("family", "run", "seed")


#: Cap on a JSON file a report reads (a report's results.json with every episode: about 0.3 MB).
MAX_JSON_BYTES = 64 * 2**20


def read_json(path: Path) -> dict:
    """The JSON object in `path`; ValueError naming the file when it is not a regular file of at most
    `MAX_JSON_BYTES`, not UTF-8 JSON or nested too deep (`policies.agents.untrusted_json.read_json`), or not an object."""
    try:  # the one JSON reader (`policies.agents.untrusted_json`): regular file, cap, UTF-8, bounded nesting
        data = read_json_checked(path, MAX_JSON_BYTES, "JSON file")
    except FileRefused:
        raise
    except OSError as exc:
        raise ValueError(f"{path} is not a readable JSON file ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} holds {type(data).__name__}, expected a JSON object")
    return data


def archived_curves(folder: Path) -> dict[str, list[dict]]:
    """Each run's learning-curve rows from `folder/curves.csv` (the columns of its `learning_curve.csv`, as
    `train.curve.read_curve` reads them: floats), by run name."""
    path = folder / "curves.csv"
    if not path.is_file():
        raise ValueError(f"{folder} holds no curves.csv; --include takes a folder written by mobman-train report")
    curves: dict[str, list[dict]] = {}
    for row in read_curve(path, run_columns=RUN_COLUMNS):
        curves.setdefault(str(row.get("run")), []).append({k: v for k, v in row.items() if k not in RUN_COLUMNS})
    return curves


def archived_runs(folder: str | Path, config: Any, evaluation: Evaluation) -> list[dict]:
    """The finished runs of the report in `folder` as `train.report` run entries (see the module docstring);
    ValueError naming the run and the difference when one cannot be carried over as measured. `evaluation`:
    how the report makes (and caches) a run's final evaluation (`train.report` passes its own functions)."""
    from train.evaluation import eval_command

    _eval_config, _inputs, _slim = evaluation.config, evaluation.inputs, evaluation.slim

    folder = Path(folder)
    res_path = folder / "results.json"
    if not stored_path(res_path).is_file():  # results.json, or its compacted twin (`mobman-eval compact`)
        raise ValueError(f"--include {folder}: no results.json; give a folder written by mobman-train report")
    old = read_json(res_path)
    if old.get("schema") != REPORT_SCHEMA:
        raise ValueError(
            f"--include {folder}: results.json has schema {old.get('schema')!r}, expected {REPORT_SCHEMA!r}"
        )
    curves = archived_curves(folder)
    runs = []
    for entry in old["runs"]:
        if entry.get("status") != "done":
            continue
        name = folder_name(
            f"--include {folder}: results.json's run name",
            entry.get("name"),
            hint="a report names each run by its folder's name, and writes evals/<name>/; restore the file",
        )
        cached = folder / "evals" / name
        if not (cached / "inputs.json").is_file() or not stored_path(cached / "results.json").is_file():
            raise ValueError(f"--include {folder}: run {name} has no cached evaluation in {cached}")
        policy = f"sb3:{entry['path']}/model.zip"
        cfg = _eval_config(config, entry["config"]["env_id"], (policy,), entry["config"]["dynamics"], cached)
        wanted = json.loads(json.dumps(_inputs(cfg, {"model_sha256": entry["model_sha256"]})))
        have = read_json(cached / "inputs.json")
        had = have.get("eval_config", {})
        # the report's own cache key (`train.report.NOT_INPUTS` says what it ignores): an archived evaluation is
        # carried over exactly when the report would have reused it from its cache
        want = wanted["eval_config"]
        differ = sorted(k for k in set(want) | set(had) if k not in had or k not in want or want[k] != had[k])
        if have.get("model_sha256") != entry["model_sha256"]:
            differ.append("model_sha256")
        if differ:
            raise ValueError(
                f"--include {folder}: run {name} was evaluated with other settings ({', '.join(differ)} differ from "
                "this report's); its model is not here to evaluate again: report with the earlier settings, or give "
                "the run folder instead"
            )
        records = read_json(cached / "results.json")["episodes"]
        run = {k: v for k, v in entry.items() if k not in ("final", "command")}
        run.update(
            curve=curves.get(name, []),
            episodes=[_slim(r) for r in records],
            command=eval_command(cfg),
            archived_from=str(entry.get("archived_from") or folder),
            train_commit=entry.get("train_commit") or old.get("train_commit"),
            _cached_eval=str(cached),
        )
        runs.append(run)
    return runs


def copy_cached_eval(run: dict, out: Path) -> None:
    """Keep the archived run's evaluation in the new report's `out/evals/<name>/` (when it is another folder),
    so that a report folder always holds the evaluations behind its tables."""
    src, dest = Path(run.pop("_cached_eval")), out / "evals" / run["name"]
    if src.resolve() == dest.resolve():
        return
    dest.mkdir(parents=True, exist_ok=True)
    for name in ("inputs.json", "results.json", "results.csv", "summary.md", "config.json"):
        stored = stored_path(src / name)  # the file, or its compacted twin (NAME.xz), copied as it is
        if stored.is_file():
            shutil.copyfile(stored, dest / stored.name)

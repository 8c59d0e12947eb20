"""The scorecard of a bench: per-condition sweep results -> scorecard.json (schema 2), scorecard.md, plots, and
the README block.

scorecard.json:

```
{"schema": 2, "kind": "mobman-bench-scorecard", "protocol": {"version": 1, "robots", "tasks", "envs",
   "conditions": {name: {dynamics, model_error, obs_noise, env_kwargs, description}}, "policies", "seeds",
   "tolerance", "settle_time", "env_kwargs"},
 "notes": [...],                     # e.g. conditions this mobman_env cannot build, non-reported seeds
 "provenance": {...}, "statistics": {...}, "versions": {...}, "git": "...",   # as results.json schema 2
 "precision": {"significant_digits": {policy: digits}, "chaotic": [policy, ...]},
 "n_episodes", "n_expected", "n_failed", "wall_s",
 "rows": [ results.json aggregate rows (one per condition, env, policy) with "condition" ],
 "pooled": [ one row per (condition, policy) over every task of the bench: the same statistics, the IQM
             interval bootstrapped within each task (strata = envs), "env": null ],
 "by_robot": [ only for a bench of several robots: one row per (condition, robot, policy) over that robot's
               tasks, as "pooled" ]}
```

A bench of several robots (`--robots all`) adds the portability table to its README block: per robot and
controller, the success rate [Wilson 95%] and the median max error over the robot's tasks, per condition.

The episodes stay in the bench directory (`conditions/<name>/results.json`, one sweep per condition);
the scorecard holds the statistics only, so a committed scorecard stays small.

`readme_markdown(scorecard)` is the block the README shows between `<!-- bench:begin PATH -->` and
`<!-- bench:end -->`; `render_readme(text, root)` regenerates every such block from the scorecard file it
names, and a test fails when the README and the committed scorecards disagree.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval.bench.config import ROBOTS
from eval.errors import EvalError
from eval.output.files import to_jsonable
from eval.output.precision import CHAOTIC, CHAOTIC_NOTE, SIGNIFICANT_DIGITS, format_mm, is_chaotic
from eval.output.provenance import git_rev, provenance, versions
from eval.output.results import statistics_block
from eval.output.tables import iqm_text, markdown_table, seed_text, success_text

KIND = "mobman-bench-scorecard"
SCHEMA = 2


def build_scorecard(
    protocol: dict,
    notes: Sequence[str],
    condition_results: dict[str, dict],
    *,
    n_expected: int,
    wall_s: float | None = None,
) -> dict:
    """The scorecard dict from {condition name: that condition's results.json dict} (in scorecard order)."""
    rows: list[dict] = []
    pooled: list[dict] = []
    by_robot: list[dict] = []
    n_episodes = n_failed = 0
    several = len(protocol.get("robots") or ()) > 1
    for name, res in condition_results.items():
        eps = res["episodes"]
        n_episodes += len(eps)
        n_failed += sum(r.get("status") != "ok" for r in eps)
        for a in res["aggregate"]:
            rows.append({"condition": name, **a})
        keys = ("policy", "dynamics", "model_error", "obs_noise")
        for a in M.aggregate(eps, group_keys=keys, strata_key="env"):
            pooled.append({"condition": name, "env": None, **a})
        if several:
            tagged = [{**r, "robot": robot_of(str(r["env"]))} for r in eps]
            for a in M.aggregate(tagged, group_keys=("robot", *keys), strata_key="env"):
                by_robot.append({"condition": name, "env": None, **a})
    extra = {"by_robot": by_robot} if several else {}
    return to_jsonable(
        {
            "schema": SCHEMA,
            "kind": KIND,
            "protocol": protocol,
            "notes": list(notes),
            "provenance": provenance(),
            "statistics": statistics_block(protocol.get("settle_time")),
            "versions": versions(),
            "git": git_rev(),
            "precision": {"significant_digits": dict(SIGNIFICANT_DIGITS), "chaotic": sorted(CHAOTIC)},
            "n_episodes": n_episodes,
            "n_expected": n_expected,
            "n_failed": n_failed,
            "wall_s": wall_s,
            "rows": rows,
            "pooled": pooled,
            **extra,
        }
    )


def robot_of(env_id: str) -> str:
    """The `--robots` name of an env id: "ur5" for "WheeledUR5-Circle-v0" (the id itself if it is none of
    `ROBOTS`)."""
    prefix = env_id.split("-", 1)[0]
    return {v: k for k, v in ROBOTS.items()}.get(prefix, env_id)


def scorecard_json_text(sc: dict) -> str:
    """scorecard.json's text: the header indented, each row of `rows` and `pooled` on one line (a 20-seed
    bench has a few hundred rows: one line each keeps the file small and its diffs readable)."""
    data = to_jsonable(sc)
    lists = [k for k in ("rows", "pooled", "by_robot") if k in data]
    head = {k: v for k, v in data.items() if k not in lists}
    text = json.dumps(head, indent=2, allow_nan=False)[:-2]  # without the closing "\n}"
    for key in lists:
        lines = ",\n".join("    " + json.dumps(r, allow_nan=False, separators=(",", ":")) for r in data[key])
        text += f',\n  "{key}": [\n{lines}\n  ]'
    return text + "\n}\n"


def load_scorecard(path: str | Path) -> dict:
    """Read a scorecard.json; EvalError when it is missing or not a scorecard."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise EvalError(f"scorecard {str(path)!r} not found (a bench writes DIR/scorecard.json)") from None
    except (OSError, ValueError) as exc:
        raise EvalError(f"cannot read scorecard {str(path)!r}: {exc}") from None
    if not isinstance(data, dict) or data.get("kind") != KIND:
        raise EvalError(f"{str(path)!r} is not a bench scorecard (its 'kind' is not {KIND!r})")
    if data.get("schema") != SCHEMA:
        raise EvalError(f"{str(path)!r} has scorecard schema {data.get('schema')!r}; this mobman reads {SCHEMA}")
    return data


# --- Markdown ---------------------------------------------------------------------------------------------


def _policies(sc: dict) -> list[str]:
    return list(dict.fromkeys(str(r["policy"]) for r in sc["pooled"]))


def _conditions(sc: dict) -> list[str]:
    return list(dict.fromkeys(str(r["condition"]) for r in sc["pooled"]))


def _blas_text(sc: dict) -> str:
    prov = sc.get("provenance") or {}
    libs = [b for b in prov.get("blas") or [] if b.get("user_api") == "blas"]
    kernel = ", ".join(f"{b.get('internal_api')} {b.get('version')} ({b.get('architecture')})" for b in libs) or "?"
    core = (prov.get("env") or {}).get("OPENBLAS_CORETYPE")
    return kernel + (f", OPENBLAS_CORETYPE={core}" if core else "")


def headline_tables(sc: dict) -> list[str]:
    """Two tables, controllers x conditions, pooled over the bench's tasks: success rate [Wilson 95%] and the
    max-error IQM [bootstrap 95%] in mm."""
    conds = _conditions(sc)
    cell = {(r["condition"], str(r["policy"])): r for r in sc["pooled"]}
    pols = _policies(sc)
    tol_mm = sc["protocol"]["tolerance"] * 1e3
    succ = [[p] + [success_text(cell[(c, p)]) if (c, p) in cell else "" for c in conds] for p in pols]
    err = [[p] + [iqm_text(cell[(c, p)]) if (c, p) in cell else "" for c in conds] for p in pols]
    lines = [
        f"Success rate, % [Wilson 95% interval] (max tracking error <= {tol_mm:g} mm), all tasks pooled:",
        "",
        markdown_table(["controller", *conds], succ),
        "",
        "Max tracking error, IQM in mm [stratified bootstrap 95% interval], all tasks pooled:",
        "",
        markdown_table(["controller", *conds], err),
        "",
    ]
    if any(is_chaotic(p) for p in pols):
        lines += [CHAOTIC_NOTE + ".", ""]
    return lines


def portability_table(sc: dict) -> list[str]:
    """The portability table of a bench of several robots: one row per robot and controller, per condition the
    success rate [Wilson 95%] and the median max tracking error (mm) over the robot's tasks."""
    conds = _conditions(sc)
    cell = {(r["condition"], str(r["robot"]), str(r["policy"])): r for r in sc["by_robot"]}
    robots = list(dict.fromkeys(str(r["robot"]) for r in sc["by_robot"]))
    tol_mm = sc["protocol"]["tolerance"] * 1e3
    body = []
    for robot in robots:
        for pol in _policies(sc):
            row = [robot, pol]
            for c in conds:
                r = cell.get((c, robot, pol))
                row += ["", ""] if r is None else [success_text(r), format_mm(r["max_error_m"]["median"], pol)]
            body.append(row)
    header = ["robot", "controller"]
    for c in conds:
        header += [f"{c}: success", f"{c}: median max error (mm)"]
    return [
        f"Portability: success rate, % [Wilson 95% interval] (max tracking error <= {tol_mm:g} mm) and median "
        f"max tracking error per robot and controller, the robot's tasks ({', '.join(sc['protocol']['tasks'])}) "
        "pooled:",
        "",
        markdown_table(header, body),
        "",
    ]


def readme_markdown(sc: dict) -> str:
    """The README block of a scorecard: what ran, on what, and the two headline tables (a bench of several
    robots: the portability table instead, since pooling robots would hide what it compares)."""
    p = sc["protocol"]
    seeds = p["seeds"]
    prov = sc.get("provenance") or {}
    if "by_robot" in sc:
        what = f"{len(p['robots'])} robots ({', '.join(p['robots'])}) x {len(p['tasks'])} tasks"
        tables = portability_table(sc)
        if any(is_chaotic(q) for q in _policies(sc)):
            tables += [CHAOTIC_NOTE + ".", ""]
    else:
        what = f"{len(p['envs'])} tasks"
        tables = headline_tables(sc)
    lines = [
        f"`mobman-eval bench` (protocol v{p['version']}): {what} ({', '.join(p['tasks'])}) x "
        f"{len(_conditions(sc))} conditions x {len(_policies(sc))} controllers x {len(seeds)} seeds "
        f"({seed_text(seeds)}); {sc['n_episodes']} episodes, {sc['n_failed']} failed. git {str(sc['git'])[:12]}, "
        f"{prov.get('cpu') or '?'}, {_blas_text(sc)}.",
        "",
        *tables,
    ]
    return "\n".join(lines).rstrip() + "\n"


def condition_table(sc: dict, condition: str) -> str:
    """Controllers x tasks for one condition: success and max-error IQM per task, then pooled with intervals
    and the steady-state (t >= settle time) max-error IQM."""
    rows = [r for r in sc["rows"] if r["condition"] == condition]
    envs = list(dict.fromkeys(r["env"] for r in rows))
    cell = {(r["env"], str(r["policy"])): r for r in rows}
    pooled = {str(r["policy"]): r for r in sc["pooled"] if r["condition"] == condition}
    header = ["controller"] + [e.split("-")[1] if e.count("-") >= 2 else e for e in envs]
    header += ["all: success [95% CI]", "all: max IQM [95% CI] (mm)", "all: steady max IQM (mm)"]
    body = []
    for pol in _policies(sc):
        if pol not in pooled:
            continue
        cells = [pol]
        for e in envs:
            r = cell.get((e, pol))
            cells.append(
                "" if r is None else f"{r['success_rate'] * 100:.0f}% · {format_mm(r['max_error_m']['iqm'], pol)}"
            )
        a = pooled[pol]
        cells += [success_text(a), iqm_text(a), format_mm((a.get("steady_max_error_m") or {}).get("iqm"), pol)]
        body.append(cells)
    return markdown_table(header, body)


def scorecard_markdown(sc: dict) -> str:
    """scorecard.md: what ran and where, the headline tables, then one table per condition."""
    p = sc["protocol"]
    prov = sc.get("provenance") or {}
    lines = [
        "# mobman-eval bench: scorecard",
        "",
        f"Protocol v{p['version']}; seeds {seed_text(p['seeds'])}; success = max tracking error <= "
        f"{p['tolerance'] * 1e3:g} mm over the whole episode (failed or tipped-over episodes are not successes); "
        f"steady-state errors over t >= {p['settle_time']:g} s. {sc['n_episodes']} of {sc['n_expected']} episodes, "
        f"{sc['n_failed']} failed. IQM = interquartile mean (rliable's); intervals: Wilson 95% for success, "
        f"stratified bootstrap 95% for the IQM (strata = tasks when pooled). Errors in mm.",
        "",
        f"Machine: {prov.get('cpu') or '?'} ({prov.get('cpu_count')} CPUs), {prov.get('platform')}, "
        f"{prov.get('python')}, numpy {prov.get('numpy')}, BLAS {_blas_text(sc)}; git {sc['git']}.",
        "",
    ]
    lines += [f"* {n}" for n in sc["notes"]] + ([""] if sc["notes"] else [])
    lines += ["## Conditions", ""]
    lines.append(
        markdown_table(
            ["condition", "dynamics", "model_error", "obs_noise (mm)", "further env arguments", "what"],
            [
                [
                    name,
                    c["dynamics"],
                    f"{c['model_error']:g}",
                    f"{c['obs_noise'] * 1e3:g}",
                    ", ".join(f"{k}={v}" for k, v in c["env_kwargs"].items()) or "-",
                    c["description"],
                ]
                for name, c in p["conditions"].items()
            ],
        )
    )
    lines += ["", "## All tasks pooled", "", *headline_tables(sc)]
    for name in _conditions(sc):
        c = p["conditions"][name]
        lines += [f"## {name}: {c['description']}", "", condition_table(sc, name), ""]
    lines += [
        "Per-task cells: success rate · max-error IQM (mm). Plots: `plots/success_<condition>.png` (success vs "
        "tolerance), `plots/error_vs_wear.png`. Episodes: `conditions/<name>/results.json`.",
        "",
    ]
    return "\n".join(lines)


# --- plots -----------------------------------------------------------------------------------------------


def scorecard_figures(sc: dict) -> list[tuple[str, Any]]:
    """(file stem, Figure) pairs: success-vs-tolerance per condition (a panel per task and one pooled) and
    error-vs-wear over the kinematic conditions without noise or drift (if there are two wear levels)."""
    from eval.output.stat_plots import plot_error_vs_wear, plot_success_curves

    tolerances = sc["statistics"]["success_curve_tolerances_m"]
    tol = sc["protocol"]["tolerance"]
    figs = []
    for name in _conditions(sc):
        rows = [r for r in sc["rows"] if r["condition"] == name]
        rows += [r for r in sc["pooled"] if r["condition"] == name]
        figs.append(
            (f"success_{name}", plot_success_curves(rows, tolerances, title=f"success vs tolerance: {name}", mark=tol))
        )
    conds = sc["protocol"]["conditions"]
    wear = [
        n
        for n in _conditions(sc)
        if conds[n]["dynamics"] == "kinematic" and not conds[n]["obs_noise"] and not conds[n]["env_kwargs"]
    ]
    if len({conds[n]["model_error"] for n in wear}) >= 2:
        rows = [r for r in sc["pooled"] if r["condition"] in wear]
        figs.append(
            ("error_vs_wear", plot_error_vs_wear(rows, title="max error vs wear (kinematic, all tasks)", tolerance=tol))
        )
    return figs


# --- the README ------------------------------------------------------------------------------------------

#: `<!-- bench:begin docs/results/x/scorecard.json -->` ... `<!-- bench:end -->` (path relative to the README)
README_BLOCK = re.compile(r"(<!-- bench:begin (?P<path>\S+) -->\n)(?P<body>.*?)(<!-- bench:end -->)", re.S)


def render_readme(text: str, root: str | Path) -> tuple[str, list[str]]:
    """`text` with every bench block regenerated from the scorecard it names (relative to `root`), and the
    paths of those scorecards. EvalError when a block names a missing file or no block exists."""
    root = Path(root)
    found: list[str] = []

    def sub(m: re.Match) -> str:
        found.append(m.group("path"))
        body = readme_markdown(load_scorecard(root / m.group("path")))
        return m.group(1) + body + m.group(4)

    new = README_BLOCK.sub(sub, text)
    if not found:
        raise EvalError(
            "no bench block in the README; add '<!-- bench:begin PATH/scorecard.json -->' and "
            "'<!-- bench:end -->' lines where the table goes"
        )
    return new, found

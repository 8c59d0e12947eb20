"""The scorecard of a bench: the bench's one results file -> scorecard.json (schema 4), scorecard.md, plots, and
the README block.

scorecard.json:

```
{"schema": 4, "kind": "mobman-bench-scorecard", "protocol": {"version": 3, "track", "heldout_sha256",
   "heldout_commit" (protocol v2's held-out conditions, retired into dev), "heldout_release": {"release",
   "seed_sha256", "seed_commit", "revealed"} (protocol v3's draw), "robots", "tasks", "envs",
   "conditions": {name: {track, env_kwargs (dynamics, model_error, obs_noise included), robots, tasks,
   description, retired, envs, seeds}}, "policies", "seeds", "seed_start", "kinematic_seeds", "physics_seeds",
   "tolerance", "settle_time", "env_kwargs"},
 "notes": [...],                     # e.g. conditions this mobman_env cannot build, non-reported seeds
 "provenance": {...}, "statistics": {...}, "versions": {...}, "git": "...",   # as results.json
 "precision": {"significant_digits": {policy: digits}, "chaotic": [policy, ...]},
 "n_episodes", "n_expected", "n_failed", "wall_s",
 "rows": [ aggregate rows (one per condition, env, policy) with "condition", "track", "knowledge", "feasible" ],
 "pooled": [ one row per (condition, policy) over the condition's robots and tasks (strata = envs) ],
 "by_robot": [ one row per (condition, robot, policy) for the conditions of several robots, as "pooled" ],
 "tracks": [ one row per (track, policy) over every condition of the track (strata = condition x env) ],
 "ladder": [ per policy: {"policy", "knowledge", "rungs": [{"condition", "duration", "success_rate",
             "success_rate_ci95"}], "fastest": duration of the fastest rung with >= 90% success | null} ],
 "prob_improvement": [ {"track", "policy", "reference", "p", "ci95"}: P(policy's max error < reference's) ],
 "entries": [ the leaderboard entry of each policy: {"spec", "knowledge", "artefacts": [{path, sha256}]} ],
 "reference_episodes": {reference: {condition: {env: [max_error_m per seed]}}},   # for `--against`
 "samples": [ {"condition", "env", "policy", "seed", "fields": {...}} ]}           # re-run bit for bit by `--against`
```

"feasible" (rows, pooled, tracks; protocol v3): `eval.metrics.feasible_success` of the row's episodes, the success
rates at 1, 2 and 6 mm over the episodes whose path the true robot can follow, with their Wilson intervals, and the
counts of infeasible episodes (counted, not scored) and of episodes of unknown feasibility. Schema 3 (protocol v2)
lacks it and reads as before; its rows' conditions have the v2 form (axes as fields of their own).

The scorecard leads with the held-out track when it has one (`scorecard.md`, the README block): its conditions
were fixed before any tuning (`protocol.heldout_commit`), so they are the figures to trust.

The episodes stay in the bench directory (`results.json`, one grid, each episode naming its condition); the
scorecard holds the statistics, each reference controller's max errors (the probability of improvement of a
new controller against them needs its episodes) and one sample episode per (condition, controller).

`readme_markdown(scorecard)` is the block the README shows between `<!-- bench:begin PATH -->` and
`<!-- bench:end -->`; `render_readme(text, root)` regenerates every such block from the scorecard file it
names, and a test fails when the README and the committed scorecards disagree.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Collection, Iterable, Sequence
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval.bench.config import ROBOTS, Condition, conditions_markdown
from eval.errors import EvalError
from eval.output.blocks import escape_copied, replace_blocks
from eval.output.files import to_jsonable
from eval.output.precision import CHAOTIC, CHAOTIC_NOTE, SIGNIFICANT_DIGITS, format_mm, is_chaotic
from eval.output.provenance import git_rev, provenance, versions
from eval.output.readme import source_path
from eval.output.results import statistics_block
from eval.output.tables import iqm_text, markdown_table, success_text

KIND = "mobman-bench-scorecard"
SCHEMA = 4
#: The scorecard schemas `load_scorecard` reads (3: protocol v2's, without the feasibility blocks).
READABLE_SCHEMAS = (3, 4)
#: the controllers every other one is compared with (probability of improvement), when they ran: the known-model
#: ceiling, the nominal-model law and the structure-aware adaptive baseline
REFERENCES = ("mpc-oracle", "qp-oracle", "qp", "calib-qp")
#: the per-episode fields `--against` compares bit for bit on its re-run samples
SAMPLE_FIELDS = ("max_error_m", "rms_error_m", "final_error_m", "effort", "cmd_accel_rms", "n_steps", "success")


def _max_error(rec: dict) -> float:
    """An episode's max error for the probability of improvement: +inf when it failed or tipped over."""
    v = rec.get("max_error_m")
    if v is None or rec.get("status") != "ok" or rec.get("tipped_over"):
        return math.inf
    return float(v)


def _first(values: Iterable[Any]) -> Any:
    return next((v for v in values if v is not None), None)


def _feasible(eps: Sequence[dict], **match: Any) -> dict:
    """Protocol v3's block of the episodes of `eps` whose fields equal `match` (`eval.metrics.feasible_success`)."""
    return M.feasible_success([r for r in eps if all(r.get(k) == v for k, v in match.items())])


def by_condition(protocol: dict, results: dict) -> dict[str, list[dict]]:
    """The episodes of a bench's results (results.json's dict) grouped by the condition each record names, in
    the protocol's order (a condition without an episode yet has an empty list)."""
    out: dict[str, list[dict]] = {name: [] for name in protocol["conditions"]}
    for r in results["episodes"]:
        if r.get("condition") in out:
            out[r["condition"]].append(r)
    return out


def build_scorecard(
    protocol: dict,
    notes: Sequence[str],
    results: dict,
    *,
    n_expected: int,
    wall_s: float | None = None,
) -> dict:
    """The scorecard dict from the bench's one results file (its dict): every record names its condition."""
    conds = protocol["conditions"]
    condition_eps = by_condition(protocol, results)
    rows: list[dict] = []
    pooled: list[dict] = []
    by_robot: list[dict] = []
    n_episodes = n_failed = 0
    track_eps = track_episodes(protocol, results)
    knowledge: dict[str, str] = {}
    artefacts: dict[str, dict[str, dict]] = {}
    samples: list[dict] = []
    references: dict[str, dict[str, dict[str, list]]] = {}
    for name, eps in condition_eps.items():
        track = conds[name].get("track", "dev")
        n_episodes += len(eps)
        n_failed += sum(r.get("status") != "ok" for r in eps)
        for r in eps:
            pol = str(r["policy"])
            knowledge.setdefault(pol, r.get("knowledge") or "unknown")
            for art in r.get("artefacts") or []:
                artefacts.setdefault(pol, {})[art["sha256"]] = dict(art)
        cell_rows, cell_pooled, cell_by_robot = _condition_rows(name, track, eps, protocol["policies"])
        rows += cell_rows
        pooled += cell_pooled
        by_robot += cell_by_robot
        _samples_and_references(name, eps, samples, references)
    tracks = []
    for track, eps in track_eps.items():
        for a in M.aggregate(eps, group_keys=("policy",), strata_key="cell"):
            row = {"track": track, "knowledge": knowledge.get(a["policy"]), **a}
            tracks.append({**row, "feasible": _feasible(eps, policy=a["policy"])})
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
            "by_robot": by_robot,
            "tracks": tracks,
            "ladder": ladder(pooled, protocol),
            "prob_improvement": prob_improvement(track_eps),
            "entries": [
                {"spec": p, "knowledge": knowledge.get(p, "unknown"), "artefacts": list(artefacts.get(p, {}).values())}
                for p in protocol["policies"]
            ],
            "reference_episodes": references,
            "samples": samples,
        }
    )


def _condition_rows(
    name: str, track: str, eps: list[dict], policies: Sequence[str]
) -> tuple[list[dict], list[dict], list[dict]]:
    """One condition's aggregate rows: per env (`rows`), pooled over its envs (`pooled`, stratified by env) and
    per robot where it runs on several (`by_robot`)."""
    keys = ("policy", "dynamics", "model_error", "obs_noise")
    policy_kind = {p: _first(r.get("knowledge") for r in eps if r["policy"] == p) for p in policies}
    rows, pooled, by_robot = [], [], []
    for a in M.aggregate(eps):
        row = {"condition": name, "track": track, "knowledge": policy_kind.get(a["policy"]), **a}
        rows.append({**row, "feasible": _feasible(eps, env=a["env"], policy=a["policy"])})
    for a in M.aggregate(eps, group_keys=keys, strata_key="env"):
        row = {"condition": name, "track": track, "env": None, "knowledge": policy_kind.get(a["policy"]), **a}
        pooled.append({**row, "feasible": _feasible(eps, policy=a["policy"])})
    robots = {robot_of(str(r["env"])) for r in eps}
    if len(robots) > 1:
        tagged = [{**r, "robot": robot_of(str(r["env"]))} for r in eps]
        for a in M.aggregate(tagged, group_keys=("robot", *keys), strata_key="env"):
            by_robot.append({"condition": name, "track": track, "env": None, **a})
    return rows, pooled, by_robot


def _samples_and_references(name: str, eps: list[dict], samples: list[dict], references: dict) -> None:
    """Append one condition's samples (each controller's first finished episode, by env and seed: what
    `--against` runs again) and the reference laws' max errors per env."""
    seen: set[str] = set()
    for r in sorted(eps, key=lambda r: (str(r["env"]), r["seed"])):
        if r["policy"] not in seen and r.get("status") == "ok":
            seen.add(r["policy"])
            samples.append(
                {
                    "condition": name,
                    "env": r["env"],
                    "policy": r["policy"],
                    "seed": r["seed"],
                    "fields": {k: r.get(k) for k in SAMPLE_FIELDS},
                }
            )
        if r["policy"] in REFERENCES:
            references.setdefault(r["policy"], {}).setdefault(name, {}).setdefault(str(r["env"]), []).append(
                _max_error(r)
            )


def track_episodes(protocol: dict, results: dict) -> dict[str, list[dict]]:
    """The episodes of each track, each tagged with its `cell` (condition:env), the tasks of the probability of
    improvement."""
    out: dict[str, list[dict]] = {}
    for name, eps in by_condition(protocol, results).items():
        track = protocol["conditions"][name].get("track", "dev")
        out.setdefault(track, []).extend({**r, "cell": f"{name}:{r['env']}"} for r in eps)
    return out


def ladder(pooled: Sequence[dict], protocol: dict) -> list[dict]:
    """Per policy, the ladder's rungs (the conditions `ladder-*`, in the protocol's order) and the duration of
    the fastest rung it tracks in at least `LADDER_SUCCESS` of its episodes (None: not even the slowest)."""
    from eval.bench.config import LADDER_SUCCESS

    conds = protocol["conditions"]
    rungs = [n for n in conds if n.startswith("ladder-")]
    if not rungs:
        return []
    cell = {(r["condition"], r["policy"]): r for r in pooled}
    out = []
    for pol in protocol["policies"]:
        steps = []
        for n in rungs:
            r = cell.get((n, pol))
            if r is None:
                continue
            duration = float(conds[n]["env_kwargs"]["path"]["duration"])
            steps.append(
                {
                    "condition": n,
                    "duration": duration,
                    "success_rate": r["success_rate"],
                    "success_rate_ci95": r["success_rate_ci95"],
                }
            )
        tracked = [s["duration"] for s in steps if s["success_rate"] >= LADDER_SUCCESS]
        kind = _first(r.get("knowledge") for r in pooled if r["policy"] == pol)
        out.append({"policy": pol, "knowledge": kind, "rungs": steps, "fastest": min(tracked) if tracked else None})
    return out


def prob_improvement(track_eps: dict[str, list[dict]]) -> list[dict]:
    """Per track, every controller against each of `REFERENCES` that ran: P(its max error < the reference's)
    over the track's cells (condition x env) as tasks, with the bootstrap interval (`eval.metrics`)."""
    out = []
    for track, eps in track_eps.items():
        cells: dict[str, dict[str, list[float]]] = {}
        for r in eps:
            cells.setdefault(str(r["policy"]), {}).setdefault(r["cell"], []).append(_max_error(r))
        for ref in REFERENCES:
            if ref not in cells:
                continue
            for pol, by_cell in cells.items():
                if pol == ref:
                    continue
                common = [c for c in by_cell if c in cells[ref]]
                res = M.probability_of_improvement([by_cell[c] for c in common], [cells[ref][c] for c in common])
                if res is not None:
                    out.append({"track": track, "policy": pol, "reference": ref, "p": res[0], "ci95": res[1]})
    return out


def robot_of(env_id: str) -> str:
    """The `--robots` name of an env id: "ur5" for "WheeledUR5-Circle-v0" (the id itself if it is none of
    `ROBOTS`)."""
    prefix = env_id.split("-", 1)[0]
    return {v: k for k, v in ROBOTS.items()}.get(prefix, env_id)


def scorecard_json_text(sc: dict) -> str:
    """scorecard.json's text: the header indented, each row of `rows` and `pooled` on one line (a 20-seed
    bench has a few hundred rows: one line each keeps the file small and its diffs readable)."""
    data = to_jsonable(sc)
    lists = [k for k in ("rows", "pooled", "by_robot", "tracks", "ladder", "prob_improvement", "samples") if k in data]
    head = {k: v for k, v in data.items() if k not in lists}
    text = json.dumps(head, indent=2, allow_nan=False)[:-2]  # without the closing "\n}"
    for key in lists:
        lines = ",\n".join("    " + json.dumps(r, allow_nan=False, separators=(",", ":")) for r in data[key])
        text += f',\n  "{key}": [\n{lines}\n  ]'
    return text + "\n}\n"


def load_scorecard(path: str | Path) -> dict:
    """Read a scorecard.json through the one JSON reader (`eval.schemas`: a regular file of at most
    `MAX_SCORECARD_BYTES`, UTF-8, bounded nesting) and check its kind, schema number and shape (`SCORECARD`)
    before anything uses it; EvalError naming the file, the field and the fix otherwise."""
    from eval.schemas import MAX_SCORECARD_BYTES, SCORECARD, check_shape, read_eval_json

    path = Path(path)
    try:
        data = read_eval_json(path, MAX_SCORECARD_BYTES, "scorecard")
    except FileNotFoundError:
        raise EvalError(f"scorecard {str(path)!r} not found (a bench writes DIR/scorecard.json)") from None
    if not isinstance(data, dict) or data.get("kind") != KIND:
        raise EvalError(f"{str(path)!r} is not a bench scorecard (its 'kind' is not {KIND!r})")
    if data.get("schema") not in READABLE_SCHEMAS:
        raise EvalError(
            f"{str(path)!r} has scorecard schema {data.get('schema')!r}; this mobman reads "
            f"{', '.join(map(str, READABLE_SCHEMAS))} (protocols v2 and v3). A schema-2 scorecard is protocol v1's "
            "(release 0.2): read its scorecard.md, or run the bench again"
        )
    check_shape(data, SCORECARD, str(path))
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


def _tracks(sc: dict) -> list[str]:
    """The scorecard's tracks, held-out first (the figures to trust lead)."""
    present = {r["track"] for r in sc.get("tracks", [])}
    return [t for t in ("heldout", "dev") if t in present]


def _num_mm(x: float | None, pol: str) -> str:
    return format_mm(x, pol)


def feasible_text(block: dict | None) -> str:
    """ "12% · 40% · 91% [86-94]": protocol v3's success at its tolerances over feasible episodes (the last with
    its Wilson 95% interval), "-" for a scorecard without feasibility (protocol v2) or no feasible episode."""
    if not block or not block.get("n_feasible"):
        return "-"
    rates = " · ".join(f"{r * 100:.0f}%" for r in block["success"])
    ci = block["success_ci95"][-1]
    return rates + (f" [{ci[0] * 100:.0f}-{ci[1] * 100:.0f}]" if ci else "")


def _feasible_note(rows: list[dict]) -> list[str]:
    """The line under a v3 table: which tolerances, and how many episodes were infeasible (counted apart)."""
    blocks = [r["feasible"] for r in rows if r.get("feasible")]
    if not blocks:
        return []
    tol = " / ".join(f"{t * 1e3:g}" for t in blocks[0]["tolerances_m"])
    n_inf = max(b["n_infeasible"] for b in blocks)
    n_all = max(b["n_feasible"] + b["n_infeasible"] + b["n_unknown"] for b in blocks)
    return [
        f"Success at {tol} mm is over the feasible episodes only: {n_inf} of each controller's {n_all} episodes "
        "ask for more speed than the true robot has (a reference law that knows everything peaks above 90% of the "
        "actuator limits, `mobman_env.feasibility`); they are counted here, not scored.",
        "",
    ]


def track_table(sc: dict, track: str) -> list[str]:
    """Controllers over every condition of `track` pooled: knowledge class, protocol v3's success at 1 / 2 / 6 mm
    over feasible episodes, success and clean success over every episode [Wilson 95%], the max error's IQM
    [bootstrap 95%], p90 and worst (mm), and the commands' smoothness."""
    body = []
    track_rows = [r for r in sc["tracks"] if r["track"] == track]
    v3 = any(r.get("feasible") for r in track_rows)
    for r in track_rows:
        pol = str(r["policy"])
        me = r["max_error_m"]
        clean = r.get("clean_success_rate")
        ci = r.get("clean_success_rate_ci95")
        clean_text = (
            "-" if clean is None else f"{clean * 100:.0f}%" + (f" [{ci[0] * 100:.0f}-{ci[1] * 100:.0f}]" if ci else "")
        )
        accel = (r.get("cmd_accel_rms") or {}).get("median")
        body.append(
            [
                pol,
                str(r.get("knowledge") or "unknown"),
                *([feasible_text(r.get("feasible"))] if v3 else []),
                success_text(r),
                clean_text,
                iqm_text(r),
                _num_mm(me.get("p90"), pol),
                _num_mm(me.get("worst"), pol),
                "-" if accel is None else f"{accel:.3g}",
            ]
        )
    conds = [n for n, c in sc["protocol"]["conditions"].items() if c.get("track", "dev") == track]
    n = len({(r["condition"], r["env"]) for r in sc["rows"] if r["track"] == track})
    return [
        f"**{track} track** ({len(conds)} conditions: {', '.join(conds)}; {n} cells), every condition, robot and "
        f"task pooled:",
        "",
        markdown_table(
            [
                "controller",
                "knowledge",
                *(["success at 1 · 2 · 6 mm, feasible [95% CI at 6 mm]"] if v3 else []),
                "success, all [95% CI]" if v3 else "success [95% CI]",
                "clean success [95% CI]",
                "max error IQM [95% CI] (mm)",
                "p90 (mm)",
                "worst (mm)",
                "cmd accel RMS, median (rad/s^2)",
            ],
            body,
        ),
        "",
        *_feasible_note(track_rows),
    ]


def condition_success_table(sc: dict, track: str) -> list[str]:
    """Controllers x the track's conditions: success rate [Wilson 95%] over each condition's robots and tasks."""
    conds = [n for n in _conditions(sc) if sc["protocol"]["conditions"][n].get("track", "dev") == track]
    cell = {(r["condition"], str(r["policy"])): r for r in sc["pooled"]}
    tol_mm = sc["protocol"]["tolerance"] * 1e3
    if any(r.get("feasible") for r in sc["pooled"]):  # protocol v3: over the feasible episodes, infeasible counted
        body = [
            [p]
            + [
                _feasible_at(cell[(c, p)]["feasible"], sc["protocol"]["tolerance"]) if (c, p) in cell else ""
                for c in conds
            ]
            for p in _policies(sc)
        ]
        n_inf = {
            c: max((r["feasible"]["n_infeasible"] for r in sc["pooled"] if r["condition"] == c), default=0)
            for c in conds
        }
        heads = [c + (f" ({n_inf[c]} infeasible)" if n_inf[c] else "") for c in conds]
        return [
            f"Success rate per {track} condition over its feasible episodes, % [Wilson 95%] (max tracking error <= "
            f"{tol_mm:g} mm), its robots and tasks pooled; the heading counts each controller's infeasible episodes:",
            "",
            markdown_table(["controller", *heads], body),
            "",
        ]
    body = [[p] + [success_text(cell[(c, p)]) if (c, p) in cell else "" for c in conds] for p in _policies(sc)]
    return [
        f"Success rate per {track} condition, % [Wilson 95%] (max tracking error <= {tol_mm:g} mm), its robots and "
        "tasks pooled:",
        "",
        markdown_table(["controller", *conds], body),
        "",
    ]


def _feasible_at(block: dict, tolerance: float) -> str:
    """The success over feasible episodes at `tolerance` (one of the block's) with its interval; "-" if none."""
    if not block.get("n_feasible") or tolerance not in block["tolerances_m"]:
        return "-"
    k = block["tolerances_m"].index(tolerance)
    rate, ci = block["success"][k], block["success_ci95"][k]
    return f"{rate * 100:.0f}%" + (f" [{ci[0] * 100:.0f}-{ci[1] * 100:.0f}]" if ci else "")


def ladder_table(sc: dict) -> list[str]:
    """The difficulty ladder: per controller the success rate on each rung and the fastest rung it tracks."""
    from eval.bench.config import LADDER_CEILINGS, LADDER_SUCCESS

    entries = sc.get("ladder") or []
    if not entries:
        return []
    durations = [s["duration"] for s in entries[0]["rungs"]]
    body = []
    for e in entries:
        by = {s["duration"]: s for s in e["rungs"]}
        body.append(
            [e["policy"], str(e.get("knowledge") or "unknown")]
            + [f"{by[d]['success_rate'] * 100:.0f}%" if d in by else "" for d in durations]
            + ["-" if e["fastest"] is None else f"{e['fastest']:g} s"]
        )
    known = [e for e in entries if e["policy"] in LADDER_CEILINGS and e["fastest"] is not None]
    ceiling = min(known, key=lambda e: (e["fastest"], LADDER_CEILINGS.index(e["policy"])), default=None)
    ceil_text = (
        ""
        if ceiling is None or ceiling["fastest"] is None
        else f" (the ceiling, the best known-model law, {ceiling['policy']}: {ceiling['fastest']:g} s)"
    )
    return [
        f"Difficulty ladder: success on a 5-harmonic 0.3 m random path (PUMA, kinematic) in each duration, and the "
        f"fastest one tracked in >= {LADDER_SUCCESS * 100:.0f}% of the episodes{ceil_text}:",
        "",
        markdown_table(["controller", "knowledge", *[f"{d:g} s" for d in durations], "fastest tracked"], body),
        "",
    ]


def prob_table(sc: dict, track: str) -> list[str]:
    """P(controller's max error < reference's) [bootstrap 95%] over the track's cells, per reference."""
    rows = [r for r in sc.get("prob_improvement", []) if r["track"] == track]
    refs = list(dict.fromkeys(r["reference"] for r in rows))
    if not refs:
        return []
    cell = {(r["policy"], r["reference"]): r for r in rows}
    body = []
    for pol in _policies(sc):
        cells = []
        for ref in refs:
            r = cell.get((pol, ref))
            cells.append("" if r is None else f"{r['p']:.2f} [{r['ci95'][0]:.2f}-{r['ci95'][1]:.2f}]")
        body.append([pol, *cells])
    return [
        f"Probability of improvement on the {track} track: P(the controller's max error < the reference's) "
        "[stratified bootstrap 95%], the track's condition x task cells as tasks (0.5: neither is better):",
        "",
        markdown_table(["controller", *[f"vs {r}" for r in refs]], body),
        "",
    ]


def headline_tables(sc: dict, pooled_only: bool = False) -> list[str]:
    """Per track, held-out first: the pooled table and (unless `pooled_only`) the success per condition; then
    (unless `pooled_only`) the ladder."""
    lines: list[str] = []
    for track in _tracks(sc):
        lines += track_table(sc, track) + ([] if pooled_only else condition_success_table(sc, track))
    if not pooled_only:
        lines += ladder_table(sc)
    if any(is_chaotic(p) for p in _policies(sc)):
        lines += [CHAOTIC_NOTE + ".", ""]
    return lines


def _heldout_text(p: dict, short: bool = False) -> str:
    """Where the protocol's held-out conditions come from: v2's fixed commit; v3's release draw (its seed's hash
    and commit, revealed or not) with v2's conditions retired into dev."""
    v2 = (
        f"{str(p['heldout_commit'])[:7]}"
        if short
        else f"{p['heldout_commit']} (sha256 {str(p['heldout_sha256'])[:12]})"
    )
    rel = p.get("heldout_release")
    if not rel:
        return f"held-out track fixed at {v2}" if short else f"held-out conditions fixed at commit {v2}"
    state = "revealed and run" if rel["revealed"] else "not revealed yet"
    return (
        f"held-out draw of release {rel['release']}: seed hash committed at {str(rel['seed_commit'])[:7]}, {state}; "
        f"protocol v2's held-out conditions (fixed at {v2}) retired into dev"
    )


def readme_markdown(sc: dict, pooled_only: bool = False) -> str:
    """The README block of a scorecard: what ran, on what, then the headline tables (held-out first; with
    `pooled_only`, each track's pooled table alone)."""
    p = sc["protocol"]
    prov = sc.get("provenance") or {}
    heldout = f", {_heldout_text(p, short=True)}" if "heldout" in _tracks(sc) or p.get("heldout_release") else ""
    lines = [
        f"`mobman-eval bench` (protocol v{p['version']}, track {p['track']}{heldout}): {len(_conditions(sc))} "
        f"conditions x {len(p['robots'])} robots x {len(p['tasks'])} tasks x {len(_policies(sc))} controllers; "
        f"seeds {p['seed_start']}.. ({p['kinematic_seeds']} per kinematic cell, {p['physics_seeds']} per physics "
        f"cell); {sc['n_episodes']} episodes, {sc['n_failed']} failed. git {str(sc['git'])[:12]}, "
        f"{prov.get('cpu') or '?'}.",
        "",
        *headline_tables(sc, pooled_only),
    ]
    return "\n".join(lines).rstrip() + "\n"


def condition_table(sc: dict, condition: str) -> str:
    """Controllers x robots for one condition: success and max-error IQM per robot (its tasks pooled), then over
    every robot and task with intervals, the tail and the smoothness."""
    pooled = {str(r["policy"]): r for r in sc["pooled"] if r["condition"] == condition}
    robots = list(dict.fromkeys(str(r["robot"]) for r in sc.get("by_robot", []) if r["condition"] == condition))
    cell = {(str(r["robot"]), str(r["policy"])): r for r in sc.get("by_robot", []) if r["condition"] == condition}
    header = ["controller", *robots]
    header += ["all: success [95% CI]", "all: clean success", "all: max IQM [95% CI] (mm)", "p90 (mm)", "worst (mm)"]
    body = []
    for pol in _policies(sc):
        if pol not in pooled:
            continue
        cells = [pol]
        for rb in robots:
            r = cell.get((rb, pol))
            cells.append(
                "" if r is None else f"{r['success_rate'] * 100:.0f}% · {format_mm(r['max_error_m']['iqm'], pol)}"
            )
        a = pooled[pol]
        clean = a.get("clean_success_rate")
        cells += [
            success_text(a),
            "-" if clean is None else f"{clean * 100:.0f}%",
            iqm_text(a),
            _num_mm(a["max_error_m"].get("p90"), pol),
            _num_mm(a["max_error_m"].get("worst"), pol),
        ]
        body.append(cells)
    return markdown_table(header, body)


def scorecard_markdown(sc: dict, figures: Collection[str] = ()) -> str:
    """scorecard.md: what ran and where, the tracks (held-out first), the ladder, the probability of improvement,
    the conditions and one table per condition; each of `figures` (the stems of the PNGs written beside it in
    plots/, `scorecard_figures`) is shown under the table it pictures."""

    def figure(stem: str, alt: str) -> list[str]:
        return [f"![{escape_copied(alt)}](plots/{stem}.png)", ""] if stem in figures else []

    p = sc["protocol"]
    prov = sc.get("provenance") or {}
    lines = [
        "# mobman-eval bench: scorecard",
        "",
        f"Protocol v{p['version']}, track {p['track']}; {_heldout_text(p)}; seeds from {p['seed_start']} ({p['kinematic_seeds']} per "
        f"kinematic cell, {p['physics_seeds']} per physics cell); success = max tracking error <= "
        f"{p['tolerance'] * 1e3:g} mm over the whole episode (failed or tipped-over episodes are not successes); "
        f"clean success = success without a joint-limit hit; steady-state errors over t >= {p['settle_time']:g} s. "
        f"{sc['n_episodes']} of {sc['n_expected']} episodes, {sc['n_failed']} failed. IQM = interquartile mean "
        f"(rliable's); intervals: Wilson 95% for rates, stratified bootstrap 95% for the IQM and the probability "
        f"of improvement. Errors in mm; knowledge: what a controller knows of the robot (none, structure, nominal, "
        f"true).",
        "",
        f"Machine: {prov.get('cpu') or '?'} ({prov.get('cpu_count')} CPUs), {prov.get('platform')}, "
        f"{prov.get('python')}, numpy {prov.get('numpy')}, BLAS {_blas_text(sc)}; git {sc['git']}.",
        "",
    ]
    lines += [f"* {n}" for n in sc["notes"]] + ([""] if sc["notes"] else [])
    for track in _tracks(sc):
        lines += [f"## The {track} track", ""]
        lines += track_table(sc, track) + condition_success_table(sc, track) + prob_table(sc, track)
    if sc.get("ladder"):
        lines += ["## The difficulty ladder", "", *ladder_table(sc), *figure("ladder", "success per ladder rung")]
    lines += ["## Conditions", "", conditions_markdown(p["conditions"])]
    lines.append("")
    lines += figure("error_vs_wear", "max error vs wear, kinematic, every robot and task pooled")
    for name in _conditions(sc):
        c = p["conditions"][name]
        lines += [f"## {name} ({c.get('track', 'dev')}): {c['description']}", "", condition_table(sc, name), ""]
        lines += figure(f"success_{name}", f"success vs tolerance: {name}, every robot and task pooled")
    lines += [
        "Per-robot cells: success rate · max-error IQM (mm), the robot's tasks pooled. Plots: "
        "`plots/success_<condition>.png` (success vs tolerance, with its band), `plots/ladder.png`, "
        "`plots/error_vs_wear.png`. Episodes: `results.json` (each names its condition).",
        "",
    ]
    if any(is_chaotic(q) for q in _policies(sc)):
        lines += [CHAOTIC_NOTE + ".", ""]
    return "\n".join(lines)


# --- plots -----------------------------------------------------------------------------------------------


def scorecard_figures(sc: dict) -> list[tuple[str, Any]]:
    """(file stem, Figure) pairs: success-vs-tolerance per condition (its robots and tasks pooled, with the Wilson
    band), the difficulty ladder, and error-vs-wear over the kinematic conditions without noise, drift or lag
    (if there are two wear levels)."""
    from eval.bench.config import LADDER_SUCCESS
    from eval.output.stat_plots import plot_error_vs_wear, plot_ladder, plot_success_curves

    tolerances = sc["statistics"]["success_curve_tolerances_m"]
    tol = sc["protocol"]["tolerance"]
    figs = []
    for name in _conditions(sc):
        rows = [r for r in sc["pooled"] if r["condition"] == name]
        figs.append(
            (f"success_{name}", plot_success_curves(rows, tolerances, title=f"success vs tolerance: {name}", mark=tol))
        )
    if sc.get("ladder"):
        figs.append(("ladder", plot_ladder(sc["ladder"], success=LADDER_SUCCESS, title="difficulty ladder")))
    conds = {n: Condition.from_dict({**c, "name": n}) for n, c in sc["protocol"]["conditions"].items()}
    wear = [
        n
        for n in _conditions(sc)
        if conds[n].dynamics == "kinematic" and not conds[n].obs_noise and not conds[n].extra_kwargs
    ]
    if len({conds[n].model_error for n in wear}) >= 2:
        rows = [r for r in sc["pooled"] if r["condition"] in wear]
        figs.append(
            ("error_vs_wear", plot_error_vs_wear(rows, title="max error vs wear (kinematic, all tasks)", tolerance=tol))
        )
    return figs


# --- the README ------------------------------------------------------------------------------------------

#: `<!-- bench:begin docs/results/x/scorecard.json -->` ... `<!-- bench:end -->` (path relative to the README; for
#: reading a committed page: rendering finds the blocks in one pass, `eval.output.blocks.replace_blocks`)
README_BLOCK = re.compile(r"(<!-- bench:begin (?P<path>\S+) -->\n)(?P<body>.*?)(<!-- bench:end -->)", re.S)


def render_readme(text: str, root: str | Path, repo: Path | None = None) -> tuple[str, list[str]]:
    """`text` with every bench block regenerated from the scorecard it names (relative to `root`, inside the
    page's repository `repo`: `eval.output.readme.source_path`), and the paths of those scorecards. EvalError
    when a block names a missing file or one outside the repository or one it cannot render, or no block
    exists. The scorecard's names are escaped on their way into the page (`eval.output.blocks`)."""
    root = Path(root)
    found: list[str] = []

    def rebuild(args: str) -> str:
        rel, _, form = args.partition(" ")
        if form.strip() not in ("", "pooled"):
            raise EvalError(
                f"a bench block names {args!r}; write '<!-- bench:begin PATH/scorecard.json -->', or with "
                "'pooled' after the path for each track's pooled table alone"
            )
        found.append(rel)
        path = source_path(root, rel, repo)
        sc = load_scorecard(path)
        try:
            return readme_markdown(sc, pooled_only=form.strip() == "pooled")
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
            raise EvalError(
                f"{rel}: a scorecard whose rows this mobman cannot render ({type(exc).__name__}: {exc}); write it "
                f"again with `mobman-eval bench` (or restore the committed file)"
            ) from None

    new = replace_blocks(text, "bench", rebuild)[0]
    if not found:
        raise EvalError(
            "no bench block in the README; add '<!-- bench:begin PATH/scorecard.json -->' and "
            "'<!-- bench:end -->' lines where the table goes"
        )
    return new, found

"""`mobman-eval bench --against DIR`: benchmark only your own controller against a committed scorecard.

A researcher wants their controller's row beside the built-in ones, not hours of re-running baselines that were
run already. So:

1. the committed scorecard (`DIR/scorecard.json`) names its protocol; the bench asked for must be the same
   protocol (version, track, seeds, tolerance, settle time, env arguments); its conditions, robots and tasks may
   be any subset of the committed ones (`--conditions`, `--robots`, `--tasks`). The file is
   data from someone else: it is read through the one JSON reader and its shape checked (`eval.schemas`), and
   the controllers and env ids it names must be built-in controllers, `sb3:` agents and registered env ids
   (`eval.schemas.check_scorecard_names`), all before anything runs;
2. a fixed sample of the committed baseline episodes (`SAMPLE_SIZE`, spread over the conditions and controllers:
   `samples`) is run again here; their metric fields must equal the committed ones **bit for bit** (the engine
   and the compiled laws do not depend on the BLAS kernel: `mobman_env.engine`). If they do, the committed rows
   of the baselines are reused as they are; if one does not, the baselines are run again too, and the bench says
   which sample differed, by how much, and the kernel hashes of both sides (`provenance.kernels`);
3. only the new controllers run the protocol's grid; the scorecard joins their rows to the baselines' (the
   probability of improvement against the references uses the committed references' episodes). With a subset,
   the baselines' rows are those of the committed cells this bench ran; their rows pooled over more cells than
   ran here (a condition's other robots or tasks, the track, the ladder's other rungs) are left out, and a note
   says so: they would not compare with the new controller's.

The output folder holds the new controllers' episodes (`results.json`) and the joined scorecard; bench.json
records the committed scorecard it was run against (path and sha256) and the sample check.

Imports `eval.bench.*`, `eval.metrics`, `eval.rollout`, `eval.output`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from eval import metrics as M
from eval.bench import scorecard as S
from eval.bench.config import CONDITIONS, Condition
from eval.errors import EvalError

#: committed episodes re-run to check that this machine reproduces them
SAMPLE_SIZE = 8
#: `BenchConfig` field -> its protocol key, for the fields that must equal the committed scorecard's
CONFIG_KEYS = {
    "track": "track",
    "seed_start": "seed_start",
    "seeds": "kinematic_seeds",
    "physics_seeds": "physics_seeds",
    "tolerance": "tolerance",
    "settle_time": "settle_time",
    "env_kwargs": "env_kwargs",
}
#: protocol fields that must equal the committed scorecard's
SAME = ("version", *CONFIG_KEYS.values())


def load_against(path: str | Path, typed: Iterable[str] = ()) -> tuple[dict, str]:
    """The committed scorecard of `path` (a bench folder or its scorecard.json, either stored plain or compacted as
    scorecard.json.xz) and the SHA-256 of its JSON bytes (the same for both forms), read through the one JSON
    reader and checked before anything runs: its shape (`eval.schemas.SCORECARD`) and its names,
    since its baselines and samples are built and run here (`eval.schemas.check_scorecard_names`: built-in
    controllers, `sb3:` agents, registered env ids; `typed`, the controllers of --policy, are the user's own)."""
    import hashlib

    from eval.output.compact import stored_bytes
    from eval.schemas import MAX_SCORECARD_BYTES, check_scorecard_names
    from policies.agents.untrusted import FileRefused

    path = Path(path)
    file = path / "scorecard.json" if path.is_dir() else path
    sc = S.load_scorecard(file)
    check_scorecard_names(sc, str(file), typed)
    try:
        return sc, hashlib.sha256(stored_bytes(file, MAX_SCORECARD_BYTES)).hexdigest()
    except FileRefused as exc:
        raise EvalError(str(exc)) from None


def committed_settings(path: str | Path, given: Iterable[str]) -> dict[str, Any]:
    """The committed scorecard's value of every `CONFIG_KEYS` field not in `given` (the fields the command line
    set): `--against DIR` alone runs the committed protocol, and a value given that differs is refused by
    `check_protocol`, naming it."""
    protocol = S.load_scorecard(Path(path) / "scorecard.json" if Path(path).is_dir() else path)["protocol"]
    given = set(given)
    return {f: protocol[k] for f, k in CONFIG_KEYS.items() if f not in given and k in protocol}


def check_protocol(committed: dict, protocol: dict) -> None:
    """EvalError naming every difference that makes the committed rows incomparable with this bench's."""
    old = committed["protocol"]
    diff = [f"{k}: {old.get(k)!r} there, {protocol.get(k)!r} here" for k in SAME if old.get(k) != protocol.get(k)]
    missing = [c for c in protocol["conditions"] if c not in old["conditions"]]
    if missing:
        diff.append(f"conditions {missing} are not in the committed scorecard")
    for c in protocol["conditions"]:
        if c in old["conditions"] and not set(protocol["conditions"][c]["envs"]) <= set(
            old["conditions"][c].get("envs") or []
        ):
            diff.append(f"condition {c!r} runs robots or tasks here that the committed scorecard has not")
    if diff:
        raise EvalError(
            "--against: this bench is not the committed scorecard's protocol (" + "; ".join(diff) + "); run the "
            "bench with the same --track, --seeds, --physics-seeds, --seed, --tolerance and --settle-time "
            "as the scorecard (bench.json there lists them)"
        )


def pick_samples(committed: dict, baselines: list[str], conditions: list[str]) -> list[dict]:
    """`SAMPLE_SIZE` committed episodes of the baselines, spread evenly over the (condition, controller) pairs in
    a fixed order (kinematic first: they cost less), so every machine checks the same ones."""
    pool = [s for s in committed["samples"] if s["policy"] in baselines and s["condition"] in conditions]
    pool.sort(key=lambda s: (CONDITIONS[s["condition"]].dynamics != "kinematic", s["condition"], s["policy"]))
    if len(pool) <= SAMPLE_SIZE:
        return pool
    step = len(pool) / SAMPLE_SIZE
    return [pool[int(i * step)] for i in range(SAMPLE_SIZE)]


def rerun_sample(
    sample: dict, tolerance: float, settle_time: float, env_kwargs: dict, condition: dict | None = None
) -> dict:
    """The metric fields of one committed episode run again here (its condition's env with the bench's extra
    `env_kwargs`, the spec, the seed). `condition`: the condition as the committed scorecard's protocol defines
    it (either protocol's form); None: the table's of that name."""
    import policies
    from eval.rollout import make_env, rollout

    name = sample["condition"]
    c = CONDITIONS[name] if condition is None else Condition.from_dict({**condition, "name": name})
    env = make_env(sample["env"], c.dynamics, c.model_error, c.obs_noise, {**env_kwargs, **c.extra_kwargs})
    try:
        pol = policies.make(sample["policy"], env, seed=None)
        rec, _ = rollout(env, pol, int(sample["seed"]), tolerance=tolerance, settle_time=settle_time)
    finally:
        env.close()
    return {k: rec.get(k) for k in S.SAMPLE_FIELDS}


def _same(a: Any, b: Any) -> bool:
    """Equal after the JSON round trip the committed file went through (floats bit for bit)."""
    return json.loads(json.dumps(a)) == json.loads(json.dumps(b))


def check_samples(committed: dict, samples: list[dict]) -> tuple[bool, list[str]]:
    """(all equal, one line per sample: what matched or how it differed), each sample run under the committed
    protocol's tolerance, settle time and extra env arguments."""
    p = committed["protocol"]
    lines = []
    ok = True
    for s in samples:
        got = rerun_sample(
            s, p["tolerance"], p["settle_time"], dict(p.get("env_kwargs") or {}), p["conditions"].get(s["condition"])
        )
        diff = [k for k in S.SAMPLE_FIELDS if not _same(got.get(k), s["fields"].get(k))]
        where = f"{s['policy']} on {s['env']} ({s['condition']}), seed {s['seed']}"
        if diff:
            ok = False
            lines.append(
                f"{where}: differs in "
                + ", ".join(f"{k} {s['fields'].get(k)!r} committed, {got.get(k)!r} here" for k in diff)
            )
        else:
            lines.append(f"{where}: equal bit for bit")
    if not ok:
        from eval.output.provenance import kernels

        lines.append(
            f"kernels committed {(committed.get('provenance') or {}).get('kernels')}, here {kernels()}; git "
            f"committed {committed.get('git')}"
        )
    return ok, lines


def subset_of(committed: dict, protocol: dict) -> tuple[set, set, bool]:
    """(the (condition, env) cells this bench runs, the conditions it runs whole, whether it runs every committed
    cell): what of the committed baselines' rows compare with its own."""
    cells = {(c, e) for c, d in protocol["conditions"].items() for e in d["envs"]}
    old = committed["protocol"]["conditions"]
    whole = {c for c, d in protocol["conditions"].items() if set(d["envs"]) == set(old[c].get("envs") or [])}
    every = cells == {(c, e) for c, d in old.items() for e in d.get("envs") or []}
    return cells, whole, every


def merge(committed: dict, new: dict, baselines: list[str], track_eps: dict[str, list[dict]]) -> dict:
    """The scorecard of the new controllers (`new`, built from their episodes) joined with the committed rows of
    `baselines`; the probability of improvement of every new controller against the committed references' episodes
    (`track_eps`: the new controllers' episodes of each track, each with its `cell`)."""
    out = dict(new)
    ran, whole, every = subset_of(committed, new["protocol"])
    inside = {  # which committed rows of the baselines compare with this bench's (see the module docstring)
        "rows": lambda r: (r["condition"], r["env"]) in ran,
        "samples": lambda r: (r["condition"], r["env"]) in ran,
        "pooled": lambda r: r["condition"] in whole,
        "by_robot": lambda r: r["condition"] in whole,
        "tracks": lambda r: every,
        "ladder": lambda r: every,
        "entries": lambda r: True,
    }
    for key, keep_row in inside.items():
        keep = [r for r in committed.get(key, []) if r.get("policy", r.get("spec")) in baselines and keep_row(r)]
        out[key] = keep + list(new.get(key, []))
    if not every:
        out["notes"] = [
            *new.get("notes", []),
            f"--against with a subset of the committed cells ({len(ran)} of them ran): the baselines' rows pooled "
            "over cells that did not run here (their tracks, the ladder, conditions run in part, their probabilities "
            "of improvement) are left out",
        ]
    refs = committed.get("reference_episodes", {})
    # the committed probabilities are over every cell of their track: comparable only when every cell ran here
    prob = [r for r in committed.get("prob_improvement", []) if r["policy"] in baselines and every]
    for track, eps in track_eps.items():
        mine: dict[str, dict[str, list[float]]] = {}
        for r in eps:
            mine.setdefault(str(r["policy"]), {}).setdefault(r["cell"], []).append(S._max_error(r))
        for ref, by_cond in refs.items():
            ref_cells = {f"{c}:{env}": v for c, envs in by_cond.items() for env, v in envs.items()}
            for pol, cells in mine.items():
                common = [c for c in cells if c in ref_cells]
                res = M.probability_of_improvement(
                    [cells[c] for c in common],
                    [[v if v is not None else math.inf for v in ref_cells[c]] for c in common],
                )
                if res is not None:
                    prob.append({"track": track, "policy": pol, "reference": ref, "p": res[0], "ci95": res[1]})
    out["prob_improvement"] = prob
    out["reference_episodes"] = refs
    out["protocol"] = {**new["protocol"], "policies": list(dict.fromkeys([*baselines, *new["protocol"]["policies"]]))}
    base_rows = [r for r in committed.get("rows", []) if r["policy"] in baselines and (r["condition"], r["env"]) in ran]
    out["n_episodes"] = new["n_episodes"] + sum(int(r["n"]) for r in base_rows)
    out["n_expected"] = new["n_expected"] + sum(int(r["n"]) for r in base_rows)
    out["n_failed"] = new["n_failed"] + sum(int(r["n_failed"]) for r in base_rows)
    return out

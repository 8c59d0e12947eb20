"""The JSON files eval reads, each through the one reader (`policies.agents.untrusted_json.read_json`) with its shape.

A scorecard or a results file may come from a stranger (a leaderboard entry, a colleague's run). Each kind has
a size cap and a schema that is checked before anything runs, so that a malformed file is refused naming the
field (`scorecard.json: rows[0].n is the string 'abc'; expected an integer`) instead of a traceback after the new
episodes ran. The schemas name what eval indexes; other keys are allowed (a newer writer may add some).

What a file may *name* is a second rule (`check_scorecard_names`): the specs and env ids a committed scorecard
gives to `bench --against` are built and run here, so they must be data: built-in controllers, `sb3:` agents
and env ids already registered with gymnasium (never `module:attr`, never `module:EnvId`, which imports
`module`). A results file's specs and env ids are labels: no command builds or runs them.

`read_eval_json` turns every refusal into `EvalError` (exit 2 on the command line, no traceback).
Imports `policies.agents.untrusted_json`, `policies.registry` and (to list the registered env ids) gymnasium and
mobman_env.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from eval.errors import EvalError
from policies.agents.untrusted import FileRefused
from policies.agents.untrusted_json import (
    AnyJSON,
    Bool,
    Int,
    ListOf,
    MapOf,
    Nullable,
    Num,
    Obj,
    Schema,
    SchemaError,
    Str,
    read_json,
)

#: Caps on the files eval reads (the committed dev scorecard is 10 MB; a results file with 100,000 episodes is
#: about 300 MB; a folder record's cap is `eval.output.files.MAX_RECORD_BYTES`).
MAX_SCORECARD_BYTES = 256 * 2**20
MAX_RESULTS_BYTES = 1024 * 2**20

_STATS = Nullable(MapOf(AnyJSON))
_INTERVAL = Nullable(ListOf(Nullable(Num)))

#: The rows of a scorecard's tables: who, how many; statistics are objects or null. `rows`, `pooled` and
#: `by_robot` are per condition (`tracks` pools the conditions of a track).
_ROW_FIELDS = {"policy": Str, "track": Str, "n": Int, "n_failed": Int}
_ROW_OPTIONAL = {
    "env": Nullable(Str),
    "robot": Nullable(Str),
    "knowledge": Nullable(Str),
    "success_rate": Nullable(Num),
    "success_rate_ci95": _INTERVAL,
    "max_error_m": _STATS,
}
_TRACK_ROW = Obj(_ROW_FIELDS, _ROW_OPTIONAL)
_ROW = Obj({**_ROW_FIELDS, "condition": Str}, _ROW_OPTIONAL)

#: A committed episode that `bench --against` runs again.
_SAMPLE = Obj({"condition": Str, "env": Str, "policy": Str, "seed": Int, "fields": MapOf(AnyJSON)})

_PROTOCOL = Obj(
    {
        "version": Int,
        "track": Str,
        "conditions": MapOf(Obj({}, {"envs": ListOf(Str), "track": Str, "env_kwargs": MapOf(AnyJSON)})),
        "policies": ListOf(Str),
        "tolerance": Num,
        "settle_time": Num,
    },
    {
        "envs": ListOf(Str),
        "env_kwargs": MapOf(AnyJSON),
        "seeds": ListOf(Int),
        "seed_start": Int,
        "kinematic_seeds": Int,
        "physics_seeds": Int,
    },
)

#: scorecard.json (schema 3; `eval.bench.scorecard`).
SCORECARD: Schema = Obj(
    {
        "schema": Int,
        "kind": Str,
        "protocol": _PROTOCOL,
        "notes": ListOf(Str),
        "rows": ListOf(_ROW),
        "pooled": ListOf(_ROW),
        "tracks": ListOf(_TRACK_ROW),
        "samples": ListOf(_SAMPLE),
    },
    {
        "n_episodes": Int,
        "n_expected": Int,
        "n_failed": Int,
        "by_robot": ListOf(_ROW),
        "ladder": ListOf(Obj({"policy": Str, "rungs": ListOf(Obj({"condition": Str, "duration": Num}))})),
        "entries": ListOf(Obj({"spec": Str})),
        "prob_improvement": ListOf(Obj({"track": Str, "policy": Str, "reference": Str})),
        "reference_episodes": MapOf(MapOf(MapOf(ListOf(Nullable(Num))))),
        "provenance": Nullable(MapOf(AnyJSON)),
        "statistics": Nullable(MapOf(AnyJSON)),
    },
)

#: scorecard.json of protocol v1 (schema 2, release 0.2): read only to draw its plots again (`eval.redraw`).
SCORECARD_V1: Schema = Obj(
    {
        "schema": Int,
        "kind": Str,
        "protocol": Obj(
            {
                "tolerance": Num,
                "conditions": MapOf(
                    Obj({"dynamics": Str, "model_error": Num, "obs_noise": Num, "env_kwargs": MapOf(AnyJSON)})
                ),
            }
        ),
        "statistics": Obj({"success_curve_tolerances_m": ListOf(Num)}),
        "rows": ListOf(Obj({"condition": Str, "policy": Str}, _ROW_OPTIONAL)),
        "pooled": ListOf(Obj({"condition": Str, "policy": Str}, _ROW_OPTIONAL)),
    }
)

#: results.json (schemas 1 to 4; `eval.output.results`): its episodes and aggregate rows.
RESULTS: Schema = Obj(
    {
        "schema": Int,
        "episodes": ListOf(
            Obj(
                {"env": Str, "policy": Str},
                {"seed": Nullable(Int), "status": Str, "condition": Nullable(Str), "feasible": Nullable(Bool)},
            )
        ),
    },
    {
        "config": MapOf(AnyJSON),
        "aggregate": ListOf(Obj({"env": Str, "policy": Str}, {"n": Int, "n_failed": Int})),
        "provenance": Nullable(MapOf(AnyJSON)),
        "statistics": Nullable(MapOf(AnyJSON)),
    },
)


def read_eval_json(path: str | Path, max_bytes: int, what: str, schema: Schema | None = None) -> Any:
    """`read_json` with eval's errors: FileNotFoundError passes through (callers say how to make the file);
    every refusal (not a regular file, too large, not UTF-8 JSON, too deep, the wrong shape) is `EvalError`."""
    try:
        return read_json(path, max_bytes, what, schema)
    except FileNotFoundError:
        raise
    except (FileRefused, OSError) as exc:
        raise EvalError(f"cannot read the {what}: {exc}") from None


def check_shape(data: Any, schema: Schema, where: str) -> None:
    """EvalError naming `where`, the field path, what was found and what is expected, if `data` (read by
    `read_eval_json` without a schema, e.g. to check its kind and version first) does not have `schema`'s shape."""
    try:
        schema.check(data, "")
    except SchemaError as exc:
        raise EvalError(f"{where}: {exc}") from None


def registered_env_problem(env_id: object) -> str | None:
    """Why `env_id`, read from a file, may not be made here (None: it may): it must be an id gymnasium's
    registry holds after `import mobman_env`, without a `module:` prefix (which would import that module)."""
    import gymnasium as gym

    import mobman_env

    if not isinstance(env_id, str) or ":" in env_id or env_id not in gym.registry:
        return (
            f"{env_id!r} is not a registered env id (a file may name only ids registered with gymnasium, never "
            f"module:id; mobman's: {', '.join(mobman_env.ENV_IDS[:4])}, ...)"
        )
    return None


def check_scorecard_names(sc: dict, where: str, typed: Iterable[str] = ()) -> None:
    """EvalError naming the first spec or env id of the scorecard `sc` that names code (`where`: the file, for
    the message). Specs in `typed` (the controllers the command line names with --policy) are the user's own and
    are never taken from the file (`bench --against` runs them itself), so the file may name them too."""
    from policies.registry import KNOWN_POLICIES, data_spec_problem

    typed = set(typed)
    specs = [(f"protocol.policies[{i}]", s) for i, s in enumerate(sc["protocol"]["policies"])]
    for key in ("rows", "pooled", "tracks", "by_robot", "samples", "prob_improvement", "ladder"):
        specs += [(f"{key}[{i}].policy", r["policy"]) for i, r in enumerate(sc.get(key) or [])]
    specs += [(f"entries[{i}].spec", r["spec"]) for i, r in enumerate(sc.get("entries") or [])]
    for field, spec in specs:
        if spec not in typed and data_spec_problem(spec) is not None:
            raise EvalError(
                f"{where}: {field} = {spec!r} names code; a scorecard may name only built-in controllers "
                f"(known: {', '.join(KNOWN_POLICIES)}) and sb3: agents; run your own controller with --policy on "
                f"the command line"
            )
    envs = [(f"samples[{i}].env", s["env"]) for i, s in enumerate(sc["samples"])]
    envs += [(f"protocol.envs[{i}]", e) for i, e in enumerate(sc["protocol"].get("envs") or [])]
    for name, c in sc["protocol"]["conditions"].items():
        envs += [(f"protocol.conditions[{name!r}].envs[{i}]", e) for i, e in enumerate(c.get("envs") or [])]
    for field, env_id in envs:
        problem = registered_env_problem(env_id)
        if problem is not None:
            raise EvalError(f"{where}: {field} = {problem}")

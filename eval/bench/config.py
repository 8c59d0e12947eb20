"""The benchmark protocol as data: `BenchConfig` (what one `mobman-eval bench` runs) over the one conditions table.

A bench is one grid (`eval.grid`): for each condition of its track(s) (`eval.conditions.CONDITIONS`, the one
table), that condition's robots x tasks x controllers x seeds with its env arguments. Every episode record names
its condition, and the bench's one results file holds them all. The tracks:

* **dev**: the conditions a controller may be tuned on (development seeds 0-999 only; reported seeds >= 10,000
  are run, never tuned on);
* **heldout**: conditions no controller may be tuned on, run on reported seeds and reported as they come
  (`eval.conditions` says which; `HELDOUT_SHA256` keeps protocol v2's unchanged).

"dev robots" = puma, ur5, panda, random-arm. Not in a default bench, selectable with `--conditions`: `wear0`,
`wear10`, `wear30` (the error-vs-wear curve) and the research conditions.

This module imports the standard library, `eval.errors`, `eval.metrics`, `eval.conditions` and, inside
functions, gymnasium, `mobman_env` and `policies`.
"""

from __future__ import annotations

import difflib
import inspect
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from eval.conditions import (
    CONDITIONS,
    DEV_ROBOTS,
    HELDOUT_COMMIT,
    HELDOUT_SHA256,
    LADDER_DURATIONS,
    ROBOTS,
    TASKS,
    Condition,
    conditions_markdown,
    env_id,
    heldout_digest,
)
from eval.errors import EvalError
from eval.metrics import DEFAULT_SETTLE_TIME, DEFAULT_TOLERANCE

__all__ = [  # the table's names, as this module exported them before the table had a module of its own
    "CONDITIONS",
    "DEV_ROBOTS",
    "HELDOUT_COMMIT",
    "HELDOUT_SHA256",
    "LADDER_DURATIONS",
    "ROBOTS",
    "TASKS",
    "BenchConfig",
    "Condition",
    "conditions_markdown",
    "env_id",
    "heldout_digest",
]

#: First reported seed: bench episodes use seeds REPORTED_SEED_START, +1, ... (tune on 0-999, never on these).
REPORTED_SEED_START = 10_000

#: Default number of seeds per kinematic (condition, robot, task, controller) cell.
DEFAULT_SEEDS = 5

#: The tracks of `--track`.
TRACKS = ("dev", "heldout", "all")
#: Protocol version (recorded in bench.json and the scorecard).
PROTOCOL_VERSION = 3

#: Policy names never in the default controller list (none today; the `sb3:` and `module:` spec forms are not
#: registry names, so they never appear in it either).
EXCLUDED_POLICIES: frozenset[str] = frozenset()


#: The known-model laws the ladder is read against: its ceiling is the one of them that tracks the fastest rung
#: (protocol v3's reference of a cell is the best known-model law).
LADDER_CEILINGS = ("mpc-oracle", "qp-oracle")
#: A rung counts as tracked by a controller when at least this share of its episodes succeed.
LADDER_SUCCESS = 0.9


#: The conditions of a default bench per track, in order (`wear0`, `wear10`, `wear30` only on request): the dev
#: track's (retired held-out conditions included) and the revealed held-out draw of the newest release (empty
#: until its seed is revealed, `eval.heldout`).
DEFAULT_CONDITIONS: dict[str, tuple[str, ...]] = {
    "dev": tuple(n for n, c in CONDITIONS.items() if c.track == "dev" and n not in ("wear0", "wear10", "wear30")),
    "heldout": tuple(n for n, c in CONDITIONS.items() if c.track == "heldout"),
}
DEFAULT_CONDITIONS["all"] = DEFAULT_CONDITIONS["dev"] + DEFAULT_CONDITIONS["heldout"]


def env_arguments(env_id_: str) -> set[str] | None:
    """Names of the env constructor's arguments (None if they cannot be read: then nothing is filtered)."""
    import gymnasium as gym

    import mobman_env  # noqa: F401  (registers the ids)

    try:
        entry = gym.spec(env_id_).entry_point
        if isinstance(entry, str):
            module, _, attr = entry.partition(":")
            import importlib

            entry = getattr(importlib.import_module(module), attr)
        if entry is None:
            return None
        params = inspect.signature(entry).parameters
    except Exception:
        return None
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return None
    return set(params)


def missing_arguments(condition: Condition, env_id_: str) -> list[str]:
    """The env arguments `condition` needs that the env `env_id_` does not take ([] if it can run)."""
    names = env_arguments(env_id_)
    if names is None:
        return []
    return [k for k in condition.env_kwargs if k not in names]


def default_policies() -> tuple[str, ...]:
    """Every built-in controller of the registry (`policies.KNOWN_POLICIES`), in registry order; it grows when
    controllers are added. `zero` and `random` are the floors."""
    from policies.registry import KNOWN_POLICIES

    return tuple(name for name in KNOWN_POLICIES if name not in EXCLUDED_POLICIES)


#: Default seeds per (condition, task, robot, controller): kinematic and physics episodes. Chosen so that the
#: default dev bench (every built-in controller) runs in about 10 minutes of CPU on one core; a physics episode
#: costs about 30x a kinematic one (`docs/protocol.md` says how the sizes were decided). Reported scorecards use
#: more (`--seeds`, `--physics-seeds`).
DEFAULT_PHYSICS_SEEDS = 2


@dataclass(frozen=True)
class BenchConfig:
    """What one `mobman-eval bench` runs: for each condition of its track(s), the condition's robots x tasks x
    controllers x seeds."""

    track: str = "dev"
    """"dev", "heldout" or "all": which conditions a default bench runs (`DEFAULT_CONDITIONS`)."""
    robots: tuple[str, ...] | None = None
    """Robot names (`ROBOTS`) to restrict every condition to, or ("all",); None: each condition's own robots."""
    tasks: tuple[str, ...] = tuple(TASKS)
    """Task names (`TASKS`); a condition with its own tasks runs those of them that are here."""
    conditions: tuple[str, ...] | None = None
    """Condition names (`CONDITIONS`, any track); None: the track's `DEFAULT_CONDITIONS` minus those this
    mobman_env cannot build."""
    policies: tuple[str, ...] | None = None
    """Policy specs; None: `default_policies()` (every built-in controller)."""
    seeds: int = DEFAULT_SEEDS
    """Seeds per kinematic cell: seed_start, +1, ..."""
    physics_seeds: int = DEFAULT_PHYSICS_SEEDS
    """Seeds per physics cell: seed_start, +1, ... (fewer: a physics episode costs about 30 kinematic ones)."""
    seed_start: int = REPORTED_SEED_START
    """First seed (reported results: >= 10,000)."""
    tolerance: float = DEFAULT_TOLERANCE
    """Success threshold on the max tracking error, m (the paper's 6 mm)."""
    settle_time: float = DEFAULT_SETTLE_TIME
    """Start of the steady-state window of `steady_*_error_m`, s."""
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Env arguments added to every condition (e.g. a shorter `path` for a quick check); may not set what a
    condition sets."""

    def __post_init__(self) -> None:
        for name in ("robots", "tasks", "conditions", "policies"):
            value = getattr(self, name)
            if isinstance(value, str):
                value = (value,)
            if value is not None:
                object.__setattr__(self, name, tuple(value))
        if self.robots == ("all",):  # `--robots all`: every robot of ROBOTS, in its order
            object.__setattr__(self, "robots", tuple(ROBOTS))
        object.__setattr__(self, "env_kwargs", dict(self.env_kwargs or {}))

    def seed_list(self, condition: str) -> tuple[int, ...]:
        """The seeds of `condition`'s cells (physics conditions get `physics_seeds`)."""
        n = self.physics_seeds if CONDITIONS[condition].dynamics == "physics" else self.seeds
        return tuple(range(self.seed_start, self.seed_start + n))

    def condition_robots(self, condition: str) -> tuple[str, ...]:
        c = CONDITIONS[condition]
        return c.robots if self.robots is None else tuple(r for r in c.robots if r in self.robots)

    def condition_tasks(self, condition: str) -> tuple[str, ...]:
        c = CONDITIONS[condition]
        return self.tasks if c.tasks is None else tuple(t for t in c.tasks if t in self.tasks)

    def condition_kwargs(self, condition: str) -> dict[str, Any]:
        """The further env arguments of `condition`'s episodes (beyond the three axes): the bench's and the
        condition's."""
        return {**dict(self.env_kwargs), **CONDITIONS[condition].extra_kwargs}

    def tasks_of(self, policies: Sequence[str]) -> list[Any]:
        """Every episode of the bench as one grid (`eval.execution.tasks.Task`, each naming its condition): per
        condition in order, its env ids (robot-major), `policies`, its seeds."""
        from eval.execution.tasks import Task

        tasks: list[Task] = []
        for name in self.conditions or ():
            c = CONDITIONS[name]
            kwargs = self.condition_kwargs(name)
            for env in self.env_ids(name):
                for pol in policies:
                    for k, seed in enumerate(self.seed_list(name)):
                        tasks.append(
                            Task(len(tasks), env, c.dynamics, pol, k, seed, c.model_error, c.obs_noise, name, kwargs)
                        )
        return tasks

    def env_ids(self, condition: str) -> tuple[str, ...]:
        """The env ids of `condition`'s cells: its robots x its tasks, robot-major."""
        return tuple(env_id(r, t) for r in self.condition_robots(condition) for t in self.condition_tasks(condition))

    def resolved(self) -> tuple[BenchConfig, list[str]]:
        """(a copy with conditions and policies filled in and every value checked, notes for the scorecard).
        EvalError names the bad value, the accepted ones and the fix."""
        notes: list[str] = []
        missing_robots = self._check_values(notes)
        conditions = self._resolve_conditions(missing_robots, notes)
        clash = sorted(
            set(self.env_kwargs) & ({"render_mode"} | {k for c in conditions for k in CONDITIONS[c].env_kwargs})
        )
        if clash:
            raise EvalError(f"env_kwargs sets {clash}, which the bench conditions set; remove them")
        pols = default_policies() if self.policies is None else self.policies
        if not pols:
            raise EvalError("no policy given; name some with --policy or leave it out for every built-in one")
        dup = sorted({p for p in pols if list(pols).count(p) > 1})
        if dup:
            raise EvalError(f"policies lists {', '.join(dup)} more than once; give each once")
        cfg = BenchConfig(
            track=self.track,
            robots=self.robots,
            tasks=self.tasks,
            conditions=tuple(conditions),
            policies=tuple(pols),
            seeds=int(self.seeds),
            physics_seeds=int(self.physics_seeds),
            seed_start=int(self.seed_start),
            tolerance=float(self.tolerance),
            settle_time=float(self.settle_time),
            env_kwargs=self.env_kwargs,
        )
        return cfg, notes

    def _check_values(self, notes: list[str]) -> list[str]:
        """Check the track, robots, tasks, seeds, tolerance and settle time (a note for development seeds); return
        the robots this version of mobman_env lacks (an error when they were asked for by name)."""
        import gymnasium as gym

        import mobman_env  # noqa: F401  (registers the ids)
        from mobman_env.validation import integer, number

        if self.track not in TRACKS:
            raise EvalError(f"unknown track {self.track!r}; accepted: {', '.join(TRACKS)} (e.g. --track dev)")
        _names("robots", self.robots, ROBOTS)
        wanted = self.robots if self.robots is not None else tuple(ROBOTS)
        missing_robots = [r for r in wanted if not all(env_id(r, t) in gym.registry for t in TASKS)]
        if missing_robots and self.robots is not None:
            have = [r for r in ROBOTS if all(env_id(r, t) in gym.registry for t in TASKS)]
            raise EvalError(
                f"robot(s) {', '.join(missing_robots)} are not in this version of mobman_env (no env ids "
                f"{env_id(missing_robots[0], 'circle')}, ...); available: {', '.join(have)}"
            )
        _names("tasks", self.tasks, TASKS)
        for name in ("seeds", "physics_seeds"):
            integer(name, getattr(self, name), low=1, hint="the number of seeds per cell, e.g. 20", error=EvalError)
        integer("seed_start", self.seed_start, low=0, error=EvalError)
        if self.seed_start < REPORTED_SEED_START:
            notes.append(
                f"seeds start at {self.seed_start}, below the reported range (>= {REPORTED_SEED_START}): "
                f"development results, not for reporting"
            )
        number("tolerance", self.tolerance, low=0.0, open_low=True, hint="m, e.g. 0.006", error=EvalError)
        number("settle_time", self.settle_time, low=0.0, hint="s, e.g. 0.5", error=EvalError)
        return missing_robots

    def _resolve_conditions(self, missing_robots: list[str], notes: list[str]) -> list[str]:
        """The conditions to run: the track's defaults (those that cannot run here left out with a note) or the
        named ones (one that cannot run is an error)."""
        conditions: list[str] = []
        if self.conditions is None and self.track == "heldout" and not DEFAULT_CONDITIONS["heldout"]:
            from eval import heldout as H

            release = max(H.RELEASE_SEED_SHA256, key=lambda r: tuple(int(x) for x in r.split(".")))
            raise EvalError(
                f"the held-out track has no condition yet: release {release}'s held-out draw is made from a seed "
                f"committed as a hash (commit {H.RELEASE_SEED_COMMIT[release][:7]}) and revealed once, when the "
                "release's controllers are fixed (docs/protocol.md); run --track dev, or name conditions with "
                "--conditions"
            )
        if self.conditions is None:
            for name in DEFAULT_CONDITIONS[self.track]:
                why = self._cannot_run(name, missing_robots)
                if why:
                    notes.append(f"condition {name!r} left out: {why}")
                else:
                    conditions.append(name)
        else:
            _names("conditions", self.conditions, CONDITIONS)
            for name in self.conditions:
                why = self._cannot_run(name, missing_robots)
                if why:
                    raise EvalError(f"condition {name!r} cannot run: {why}; leave it out of --conditions")
            conditions = list(self.conditions)
        if not conditions:
            raise EvalError("no condition left to run; name some with --conditions (or other --robots, --tasks)")
        return conditions

    def _cannot_run(self, name: str, missing_robots: Sequence[str]) -> str | None:
        """Why condition `name` cannot run in this bench (no robot or task left, an env argument or a robot this
        mobman_env lacks), or None."""
        robots = [r for r in self.condition_robots(name) if r not in missing_robots]
        if not robots:
            return f"none of its robots ({', '.join(CONDITIONS[name].robots)}) is in this bench or this mobman_env"
        tasks = self.condition_tasks(name)
        if not tasks:
            return f"none of its tasks ({', '.join(CONDITIONS[name].tasks or ())}) is in this bench"
        miss = missing_arguments(CONDITIONS[name], env_id(robots[0], tasks[0]))
        if miss:
            return f"this mobman_env has no env argument {', '.join(miss)}"
        return None

    def to_dict(self) -> dict[str, Any]:
        d = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}
        d["env_kwargs"] = dict(self.env_kwargs)
        return d


def _names(what: str, values: Sequence[str] | None, known: Mapping[str, Any]) -> None:
    if values is None:
        return
    if not values:
        raise EvalError(f"{what} is empty; give at least one of {', '.join(known)}")
    for v in values:
        if v not in known:
            close = difflib.get_close_matches(str(v), list(known), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise EvalError(f"unknown {what[:-1]} {v!r}{hint}; known: {', '.join(known)}")
    dup = sorted({v for v in values if list(values).count(v) > 1})
    if dup:
        raise EvalError(f"{what} lists {', '.join(dup)} more than once; give each once")

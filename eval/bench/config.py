"""The benchmark protocol v1 as data: robots, tasks, conditions, the default controllers and `BenchConfig`.

A bench is a set of sweeps (`eval.sweep`) with a fixed grid: for every condition of `CONDITIONS` one sweep over
tasks x controllers x seeds, with that condition's dynamics mode, model error, sensor noise and further env
arguments. The conditions are a table, so a new one is one entry:

| name | dynamics | model_error | obs_noise (m) | further env arguments | what it separates |
|---|---|---|---|---|---|
| `default` | kinematic | 0.05 | 0 | - | the catalogue task (the paper's setting: 5% wear) |
| `wear20` | kinematic | 0.2 | 0 | - | a robot far from its catalogue: "knows the model" vs "learns it" |
| `noise` | kinematic | 0.05 | 0.001 | `obs_noise_vel` 0.01 m/s | 1 mm position and 0.01 m/s velocity sensor noise |
| `drift` | kinematic | 0.05 | 0 | `wear_rate` 0.005 1/s | the robot changes while it works (the paper's motivation) |
| `physics` | physics | 0.05 | 0 | - | contact dynamics, torque limits, wheel slip |

Not in the default set, selectable with `--conditions` (the error-vs-wear curve uses every kinematic condition
without noise or drift): `wear0` (0.0), `wear10` (0.1), `wear30` (0.3).

Why `wear_rate` = 0.005 per second: over a 20 s task the true lengths move by 10% (relative), twice the default
5% offset and half of `wear20`'s, so a controller that identifies the robot once and then trusts it ends the
episode on a robot as far from its estimate as the catalogue is from the default robot, while the change per
control step (5e-5 at 100 Hz) stays far below what one step of the paper's estimator sees. Larger rates make the
length drift exceed `wear20`'s spread within the episode and mix the two conditions.

A condition may need an env argument that this version of `mobman_env` does not have (`wear_rate` and
`obs_noise_joint_vel` come with the env hardening of release 0.2): the default set leaves such a condition out
(the scorecard says so); naming it with `--conditions` is an error saying which argument is missing.

This module imports the standard library, `eval.errors`, `eval.metrics` and, inside functions, gymnasium,
`mobman_env` and `policies`.
"""

from __future__ import annotations

import difflib
import inspect
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from eval.errors import EvalError
from eval.metrics import DEFAULT_SETTLE_TIME, DEFAULT_TOLERANCE

#: First reported seed: bench episodes use seeds REPORTED_SEED_START, +1, ... (tune on 0-999, never on these).
REPORTED_SEED_START = 10_000

#: Default number of seeds per (task, condition, controller).
DEFAULT_SEEDS = 20

#: Robot names of `--robots` -> the prefix of their env ids (`<prefix>-<Task>-v0`). An entry whose ids are not
#: registered (the robot is not in this version of mobman_env) is refused naming the robots that exist.
ROBOTS: dict[str, str] = {
    "puma": "WheeledPuma",
    "ur5": "WheeledUR5",
    "panda": "WheeledPanda",
    "random-arm": "WheeledRandomArm",
}

#: Task names of `--tasks` -> the middle part of the env id.
TASKS: dict[str, str] = {"circle": "Circle", "line": "Line", "lemniscate": "Lemniscate", "random": "Random"}

#: Policy names never in the default controller list (none today; the `sb3:` and `module:` spec forms are not
#: registry names, so they never appear in it either).
EXCLUDED_POLICIES: frozenset[str] = frozenset()


@dataclass(frozen=True)
class Condition:
    """One experimental condition: the env arguments every episode of it gets."""

    name: str
    """Short name (`--conditions`, scorecard headings, output sub-directory)."""
    description: str
    """One line for the scorecard."""
    dynamics: str = "kinematic"
    """Dynamics mode ("kinematic": the paper's idealised model; "physics": PyBullet contact dynamics)."""
    model_error: float = 0.05
    """Relative std of the true robot's lengths vs the catalogue ("wear")."""
    obs_noise: float = 0.0
    """Std of the position sensor noise, m."""
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Further env constructor arguments (e.g. `obs_noise_vel`, `wear_rate`)."""

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["env_kwargs"] = dict(self.env_kwargs)
        return d


#: Every condition the bench knows, in scorecard order (see the module docstring's table).
CONDITIONS: dict[str, Condition] = {
    c.name: c
    for c in (
        Condition("default", "catalogue task, 5% wear (the paper's setting)"),
        Condition("wear20", "20% wear: the robot is far from its catalogue", model_error=0.2),
        Condition(
            "noise",
            "sensor noise: 1 mm on positions, 0.01 m/s on velocities",
            obs_noise=0.001,
            env_kwargs={"obs_noise_vel": 0.01},
        ),
        Condition(
            "drift", "wear drift: lengths change by 0.5% per second (10% over 20 s)", env_kwargs={"wear_rate": 0.005}
        ),
        Condition("physics", "PyBullet contact dynamics, 5% wear", dynamics="physics"),
        Condition("wear0", "the catalogue robot itself (no wear)", model_error=0.0),
        Condition("wear10", "10% wear", model_error=0.1),
        Condition("wear30", "30% wear", model_error=0.3),
    )
}

#: The conditions of a default bench (the protocol v1 set), in order.
DEFAULT_CONDITIONS = ("default", "wear20", "noise", "drift", "physics")


def env_id(robot: str, task: str) -> str:
    """`WheeledPuma-Circle-v0` from ("puma", "circle")."""
    return f"{ROBOTS[robot]}-{TASKS[task]}-v0"


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
    needed = ["dynamics", "model_error", "obs_noise", *condition.env_kwargs]
    return [k for k in needed if k not in names]


def default_policies() -> tuple[str, ...]:
    """Every built-in controller of the registry (`policies.KNOWN_POLICIES`), in registry order; it grows when
    controllers are added. `zero` and `random` are the floors."""
    from policies.registry import KNOWN_POLICIES

    return tuple(name for name in KNOWN_POLICIES if name not in EXCLUDED_POLICIES)


@dataclass(frozen=True)
class BenchConfig:
    """What one `mobman-eval bench` runs: robots x tasks x conditions x controllers x seeds."""

    robots: tuple[str, ...] = ("puma",)
    """Robot names (`ROBOTS`), or ("all",) for every one; only those whose env ids are registered."""
    tasks: tuple[str, ...] = tuple(TASKS)
    """Task names (`TASKS`)."""
    conditions: tuple[str, ...] | None = None
    """Condition names (`CONDITIONS`); None: `DEFAULT_CONDITIONS` minus those this mobman_env cannot build."""
    policies: tuple[str, ...] | None = None
    """Policy specs; None: `default_policies()` (every built-in controller)."""
    seeds: int = DEFAULT_SEEDS
    """Seeds per cell: REPORTED_SEED_START, +1, ..."""
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

    @property
    def seed_list(self) -> tuple[int, ...]:
        return tuple(range(self.seed_start, self.seed_start + self.seeds))

    def env_ids(self) -> tuple[str, ...]:
        return tuple(env_id(r, t) for r in self.robots for t in self.tasks)

    def resolved(self) -> tuple[BenchConfig, list[str]]:
        """(a copy with conditions and policies filled in and every value checked, notes for the scorecard).
        EvalError names the bad value, the accepted ones and the fix."""
        import gymnasium as gym

        import mobman_env  # noqa: F401  (registers the ids)
        from mobman_env.validation import integer, number

        notes: list[str] = []
        _names("robots", self.robots, ROBOTS)
        missing_robots = [r for r in self.robots if not all(env_id(r, t) in gym.registry for t in TASKS)]
        if missing_robots:
            have = [r for r in ROBOTS if all(env_id(r, t) in gym.registry for t in TASKS)]
            raise EvalError(
                f"robot(s) {', '.join(missing_robots)} are not in this version of mobman_env (no env ids "
                f"{env_id(missing_robots[0], 'circle')}, ...); available: {', '.join(have)}"
            )
        _names("tasks", self.tasks, TASKS)
        integer("seeds", self.seeds, low=1, hint="the number of seeds per cell, e.g. 20", error=EvalError)
        integer("seed_start", self.seed_start, low=0, error=EvalError)
        if self.seed_start < REPORTED_SEED_START:
            notes.append(
                f"seeds start at {self.seed_start}, below the reported range (>= {REPORTED_SEED_START}): "
                f"development results, not for reporting"
            )
        number("tolerance", self.tolerance, low=0.0, open_low=True, hint="m, e.g. 0.006", error=EvalError)
        number("settle_time", self.settle_time, low=0.0, hint="s, e.g. 0.5", error=EvalError)
        ids = self.env_ids()
        if self.conditions is None:
            conditions = []
            for name in DEFAULT_CONDITIONS:
                miss = missing_arguments(CONDITIONS[name], ids[0])
                if miss:
                    notes.append(f"condition {name!r} left out: this mobman_env has no env argument {', '.join(miss)}")
                else:
                    conditions.append(name)
        else:
            _names("conditions", self.conditions, CONDITIONS)
            for name in self.conditions:
                miss = missing_arguments(CONDITIONS[name], ids[0])
                if miss:
                    raise EvalError(
                        f"condition {name!r} needs the env argument(s) {', '.join(miss)}, which this "
                        f"version of mobman_env does not have; leave it out of --conditions"
                    )
            conditions = list(self.conditions)
        if not conditions:
            raise EvalError("no condition left to run; name some with --conditions")
        clash = sorted(
            set(self.env_kwargs)
            & (
                {"dynamics", "model_error", "obs_noise", "render_mode"}
                | {k for c in conditions for k in CONDITIONS[c].env_kwargs}
            )
        )
        if clash:
            raise EvalError(f"env_kwargs sets {clash}, which the bench conditions set; remove them")
        pols = default_policies() if self.policies is None else self.policies
        if not pols:
            raise EvalError("no policy given; name some with --policies or leave it out for every built-in one")
        dup = sorted({p for p in pols if list(pols).count(p) > 1})
        if dup:
            raise EvalError(f"policies lists {', '.join(dup)} more than once; give each once")
        cfg = BenchConfig(
            robots=self.robots,
            tasks=self.tasks,
            conditions=tuple(conditions),
            policies=tuple(pols),
            seeds=int(self.seeds),
            seed_start=int(self.seed_start),
            tolerance=float(self.tolerance),
            settle_time=float(self.settle_time),
            env_kwargs=self.env_kwargs,
        )
        return cfg, notes

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

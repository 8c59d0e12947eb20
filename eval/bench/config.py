"""The benchmark protocol v2 as data: robots, tasks, the one conditions table (two tracks), `BenchConfig`.

A bench is a set of sweeps (`eval.sweep`), one per condition, each over that condition's robots x tasks x
controllers x seeds with its dynamics mode, model error, sensor noise and further env arguments. Every
condition belongs to one of two tracks:

* **dev**: the conditions a controller may be tuned on (development seeds 0-999 only; reported seeds >= 10,000
  are run, never tuned on);
* **heldout**: conditions no controller may be tuned on, fixed here before any controller was tuned against
  protocol v2 (`HELDOUT_COMMIT` introduced them; `HELDOUT_SHA256` is the hash of their definitions, and a test
  fails if any of them changes: a changed held-out condition is a new protocol version). They are run on
  reported seeds and reported as they come.

The table (`conditions_markdown`, in the docs' protocol page, `mobman-eval bench --list`, and each scorecard):
the dev track holds `default` (kinematic, 5% wear), `wear20`, `noise` (1 mm, 0.01 m/s), `drift`
(`wear_rate` 0.005), `lag` (`actuator_tau` 0.05 s), `yaw-noise` (`obs_noise_yaw` 1 mrad) on the dev robots,
`physics` and `physics-lag` on the PUMA, and the difficulty ladder; the held-out track `fast-rich`, `rate50`,
`lag100`, `noise-heavy`, `combined`, `scaled-arms`, `physics-robots` and `physics-combined`.

"dev robots" = puma, ur5, panda, random-arm. Not in a default bench, selectable with `--conditions` (the
error-vs-wear curve uses every kinematic condition without noise, drift or lag): `wear0` (0.0), `wear10` (0.1),
`wear30` (0.3) (dev).

**The difficulty ladder.** A success rate of 100% ranks nothing, and the scorecard of release 0.2 saturated at
the top. The ladder runs one path family (5 harmonics per axis, 0.3 m, PUMA, kinematic, 5% wear) at durations
20, 10, 5 and 2.5 s; for every controller the scorecard reports the fastest rung it still tracks in >= 90% of
its episodes, beside the ceiling's (`qp-oracle`), so the top of the table keeps headroom.

Why `wear_rate` = 0.005 per second: over a 20 s task the true lengths move by 10% (relative), twice the default
5% offset and half of `wear20`'s, so a controller that identifies the robot once and then trusts it ends the
episode on a robot as far from its estimate as the catalogue is from the default robot, while the change per
control step (5e-5 at 100 Hz) stays far below what one step of the paper's estimator sees.

Why the dev track's lag (50 ms) and heading noise (1 mrad): a 50 ms time constant is a slow but real velocity
loop (a 3 Hz bandwidth; electric drives reach 5-30 Hz, a heavy base with its wheel drives less), and 1 mrad is a
good odometry-plus-gyro heading (see `mobman_env.env.WheeledPumaEnv`'s "Actuators" and "Observation Space"). The
held-out track doubles both and combines them with wear and noise.

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

#: Default number of seeds per kinematic (condition, robot, task, controller) cell.
DEFAULT_SEEDS = 5

#: Robot names of `--robots` -> the prefix of their env ids (`<prefix>-<Task>-v0`). An entry whose ids are not
#: registered (the robot is not in this version of mobman_env) is refused naming the robots that exist.
ROBOTS: dict[str, str] = {
    "puma": "WheeledPuma",
    "ur5": "WheeledUR5",
    "panda": "WheeledPanda",
    "random-arm": "WheeledRandomArm",
    "scaled-arm": "WheeledScaledArm",
}
#: The robots of the dev track (and of every condition that does not name its own).
DEV_ROBOTS = ("puma", "ur5", "panda", "random-arm")
#: The tracks of `--track`.
TRACKS = ("dev", "heldout", "all")
#: Protocol version (recorded in bench.json and the scorecard).
PROTOCOL_VERSION = 2

#: Task names of `--tasks` -> the middle part of the env id.
TASKS: dict[str, str] = {"circle": "Circle", "line": "Line", "lemniscate": "Lemniscate", "random": "Random"}

#: Policy names never in the default controller list (none today; the `sb3:` and `module:` spec forms are not
#: registry names, so they never appear in it either).
EXCLUDED_POLICIES: frozenset[str] = frozenset()


@dataclass(frozen=True)
class Condition:
    """One experimental condition: its track, where it runs (robots, tasks) and the env arguments every episode of
    it gets."""

    name: str
    """Short name (`--conditions`, scorecard headings, output sub-directory)."""
    description: str
    """One line for the scorecard."""
    track: str = "dev"
    """"dev" (may be tuned on) or "heldout" (never tuned on: reported as it comes)."""
    dynamics: str = "kinematic"
    """Dynamics mode ("kinematic": the paper's idealised model; "physics": PyBullet contact dynamics)."""
    model_error: float = 0.05
    """Relative std of the true robot's lengths vs the catalogue ("wear")."""
    obs_noise: float = 0.0
    """Std of the position sensor noise, m."""
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """Further env constructor arguments (e.g. `obs_noise_vel`, `wear_rate`, `actuator_tau`, a `path`)."""
    robots: tuple[str, ...] = DEV_ROBOTS
    """The robots (`ROBOTS`) the condition runs on."""
    tasks: tuple[str, ...] | None = None
    """The tasks (`TASKS`) it runs on; None: every task of the bench."""

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["env_kwargs"] = dict(self.env_kwargs)
        d["robots"] = list(self.robots)
        d["tasks"] = None if self.tasks is None else list(self.tasks)
        return d


def _ladder_path(duration: float) -> dict[str, Any]:
    return {"type": "random", "size": 0.3, "n_terms": 5, "duration": duration}


#: The rungs of the difficulty ladder: path duration, s (the module docstring).
LADDER_DURATIONS = (20.0, 10.0, 5.0, 2.5)
#: The ceiling the ladder is read against.
LADDER_CEILING = "qp-oracle"
#: A rung counts as tracked by a controller when at least this share of its episodes succeed.
LADDER_SUCCESS = 0.9
_NOISE = {"obs_noise_vel": 0.01}

#: Every condition the bench knows, in scorecard order (see the module docstring's table).
CONDITIONS: dict[str, Condition] = {
    c.name: c
    for c in (
        Condition("default", "catalogue task, 5% wear (the paper's setting)"),
        Condition("wear20", "20% wear: the robot is far from its catalogue", model_error=0.2),
        Condition(
            "noise", "sensor noise: 1 mm on positions, 0.01 m/s on velocities", obs_noise=0.001, env_kwargs=_NOISE
        ),
        Condition(
            "drift", "wear drift: lengths change by 0.5% per second (10% over 20 s)", env_kwargs={"wear_rate": 0.005}
        ),
        Condition(
            "lag",
            "actuator lag: every actuator follows its command with tau = 50 ms",
            env_kwargs={"actuator_tau": 0.05},
        ),
        Condition("yaw-noise", "heading noise: 1 mrad on base_yaw", env_kwargs={"obs_noise_yaw": 0.001}),
        Condition("physics", "PyBullet contact dynamics, 5% wear", dynamics="physics", robots=("puma",)),
        Condition(
            "physics-lag",
            "PyBullet contact dynamics with a 50 ms actuator lag",
            dynamics="physics",
            env_kwargs={"actuator_tau": 0.05},
            robots=("puma",),
        ),
        *(
            Condition(
                f"ladder-{d:g}s",
                f"difficulty ladder: a 5-harmonic random path of 0.3 m in {d:g} s",
                env_kwargs={"path": _ladder_path(d)},
                robots=("puma",),
                tasks=("random",),
            )
            for d in LADDER_DURATIONS
        ),
        Condition("wear0", "the catalogue robot itself (no wear)", model_error=0.0),
        Condition("wear10", "10% wear", model_error=0.1),
        Condition("wear30", "30% wear", model_error=0.3),
        # --- the held-out track: fixed before any tuning against protocol v2; never tuned on ---------------------
        Condition(
            "fast-rich",
            "held out: a 6-harmonic random path of 0.4 m in 8 s",
            track="heldout",
            env_kwargs={"path": {"type": "random", "size": 0.4, "n_terms": 6, "duration": 8.0}},
            tasks=("random",),
        ),
        Condition("rate50", "held out: 50 Hz control", track="heldout", env_kwargs={"control_freq": 50.0}),
        Condition("lag100", "held out: actuator lag tau = 100 ms", track="heldout", env_kwargs={"actuator_tau": 0.1}),
        Condition(
            "noise-heavy",
            "held out: 2 mm, 0.02 m/s and 3 mrad heading noise",
            track="heldout",
            obs_noise=0.002,
            env_kwargs={"obs_noise_vel": 0.02, "obs_noise_yaw": 0.003},
        ),
        Condition(
            "combined",
            "held out: 15% wear, drift 0.3%/s, lag 30 ms, 1 mm + 0.01 m/s + 2 mrad noise",
            track="heldout",
            model_error=0.15,
            obs_noise=0.001,
            env_kwargs={"obs_noise_vel": 0.01, "obs_noise_yaw": 0.002, "actuator_tau": 0.03, "wear_rate": 0.003},
        ),
        Condition("scaled-arms", "held out: random arms scaled 0.7-1.4x", track="heldout", robots=("scaled-arm",)),
        Condition(
            "physics-robots",
            "held out: contact dynamics on the UR5, the Panda and random arms",
            track="heldout",
            dynamics="physics",
            robots=("ur5", "panda", "random-arm"),
        ),
        Condition(
            "physics-combined",
            "held out: contact dynamics, 10% wear, lag 30 ms, 1 mm + 0.01 m/s + 2 mrad noise",
            track="heldout",
            dynamics="physics",
            model_error=0.1,
            obs_noise=0.001,
            env_kwargs={"obs_noise_vel": 0.01, "obs_noise_yaw": 0.002, "actuator_tau": 0.03},
            robots=("puma",),
        ),
    )
}

#: The conditions of a default bench per track, in order (`wear0`, `wear10`, `wear30` only on request).
DEFAULT_CONDITIONS: dict[str, tuple[str, ...]] = {
    "dev": tuple(n for n, c in CONDITIONS.items() if c.track == "dev" and n not in ("wear0", "wear10", "wear30")),
    "heldout": tuple(n for n, c in CONDITIONS.items() if c.track == "heldout"),
}
DEFAULT_CONDITIONS["all"] = DEFAULT_CONDITIONS["dev"] + DEFAULT_CONDITIONS["heldout"]


#: SHA-256 of the held-out conditions as fixed before any tuning against protocol v2 (`heldout_digest()`); a test
#: keeps the table equal to it
HELDOUT_SHA256 = "5f62ef3b88f2dd28a2842a44e35bc6b654f5cc823d277ec586509820630bbaf3"
#: The commit that fixed the held-out track (scorecards cite it), before any controller was tuned against
#: protocol v2 (`git show 0a07529 -- eval/bench/config.py`)
HELDOUT_COMMIT = "0a0752963d633337486a25e2ee13d44386d8e7ef"


def conditions_markdown(conditions: Mapping[str, Mapping[str, Any]]) -> str:
    """The conditions table (Markdown) of {name: `Condition.to_dict()`}: the one rendering of `CONDITIONS`
    (the docs' protocol page, `bench --list --markdown`, each scorecard)."""
    rows = [
        "| condition | track | robots | tasks | dynamics | model_error | obs_noise (mm) | further env arguments | what |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, c in conditions.items():
        extra = ", ".join(f"`{k}` {v}" for k, v in c["env_kwargs"].items()) or "-"
        tasks = ", ".join(c.get("tasks") or []) or "all"
        rows.append(
            f"| `{name}` | {c.get('track', 'dev')} | {', '.join(c.get('robots') or [])} | {tasks} | {c['dynamics']} "
            f"| {c['model_error']:g} | {c['obs_noise'] * 1e3:g} | {extra} | {c['description']} |"
        )
    return "\n".join(rows)


def heldout_digest() -> str:
    """SHA-256 of the held-out conditions' definitions (canonical JSON): `HELDOUT_SHA256` must equal it."""
    import hashlib
    import json

    table = [c.to_dict() for c in CONDITIONS.values() if c.track == "heldout"]
    return hashlib.sha256(json.dumps(table, sort_keys=True).encode()).hexdigest()


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
    needed = ["dynamics", "model_error", "obs_noise", *condition.env_kwargs]
    return [k for k in needed if k not in names]


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

    def env_ids(self, condition: str) -> tuple[str, ...]:
        """The env ids of `condition`'s cells: its robots x its tasks, robot-major."""
        return tuple(env_id(r, t) for r in self.condition_robots(condition) for t in self.condition_tasks(condition))

    def resolved(self) -> tuple[BenchConfig, list[str]]:
        """(a copy with conditions and policies filled in and every value checked, notes for the scorecard).
        EvalError names the bad value, the accepted ones and the fix."""
        import gymnasium as gym

        import mobman_env  # noqa: F401  (registers the ids)
        from mobman_env.validation import integer, number

        notes: list[str] = []
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
        conditions: list[str] = []
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

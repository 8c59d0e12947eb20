"""The one conditions table: every named experimental condition of the project, and the name of any other.

A **condition** is what an episode runs under besides its robot, task, controller and seed: the env arguments
(`dynamics`, `model_error` and `obs_noise` are plain env arguments like `actuator_tau` or `path`), where it runs
(`robots`, `tasks`) and its track. Every episode record names its condition (results schema 4, `condition`), so a
results file, a scorecard or a plot groups episodes by that name and nothing re-joins folders.

Tracks (protocol v3): **dev** (public: a controller may be tuned on it, on development seeds 0-999; it holds every
retired held-out condition, `retired` naming the held-out track it came from: protocol v2's, fixed in code before
the tuning of release 0.3, whose definitions `HELDOUT_SHA256` keeps as they were), **heldout** (the newest
release's held-out draw once its seed is revealed, `eval.heldout`: never tuned on, run once on reported seeds and
published as it comes; until then the track is empty) and **research** (conditions the result pages under
docs/results ran: named here so that a page and the bench mean the same thing by the same name; not in any bench
by default).

An episode run outside the table (`mobman-eval run --model-error 0.1`, a sweep's axes) gets the name of the table
entry whose env arguments are exactly its own, else a name made from those arguments (`condition_name`), e.g.
`kinematic, model_error=0.1, obs_noise=0.002`: within one results file a name always means one set of env
arguments.

The table (`conditions_markdown`, in the docs' protocol page, `mobman-eval bench --list`, and each scorecard):
the dev track holds `default` (kinematic, 5% wear), `wear20`, `noise` (1 mm, 0.01 m/s), `drift` (`wear_rate`
0.005), `lag` (`actuator_tau` 0.05 s), `yaw-noise` (`obs_noise_yaw` 1 mrad) on the dev robots, `physics` and
`physics-lag` on the PUMA, the difficulty ladder and protocol v2's held-out conditions (`fast-rich`, `rate50`,
`lag100`, `noise-heavy`, `combined`, `scaled-arms`, `physics-robots`, `physics-combined`); not in a default
bench, selectable with `--conditions`: `wear0`, `wear10`, `wear30` (the error-vs-wear curve) and the research
conditions.

**The difficulty ladder.** A success rate of 100% ranks nothing, and the scorecard of release 0.2 saturated at
the top. The ladder runs one path family (5 harmonics per axis, 0.3 m, PUMA, kinematic, 5% wear) at durations
20, 10, 5 and 2.5 s; for every controller the scorecard reports the fastest rung it still tracks in >= 90% of
its episodes, beside the ceiling's, so the top of the table keeps headroom. Protocol v3 draws every rung's paths
feasible (`max_peak` 0.9 in the path spec: redrawn from the episode's generator until a law that knows everything
stays within 90% of the true robot's speed limits; `mobman_env.feasibility`): in protocol v2 nobody tracked the
2.5 s rung, and on development seeds 0-59 only 14 of its 60 paths (5 s: 49, 10 and 20 s: all) were feasible, so
the rung measured path luck as much as control.

Why `wear_rate` = 0.005 per second: over a 20 s task the true lengths move by 10% (relative), twice the default
5% offset and half of `wear20`'s, so a controller that identifies the robot once and then trusts it ends the
episode on a robot as far from its estimate as the catalogue is from the default robot, while the change per
control step (5e-5 at 100 Hz) stays far below what one step of the paper's estimator sees.

Why the dev track's lag (50 ms) and heading noise (1 mrad): a 50 ms time constant is a slow but real velocity
loop (a 3 Hz bandwidth; electric drives reach 5-30 Hz, a heavy base with its wheel drives less), and 1 mrad is a
good odometry-plus-gyro heading (see `mobman_env.env.WheeledPumaEnv`'s "Actuators" and "Observation Space").
Protocol v2's held-out track doubles both and combines them with wear and noise.

This module imports the standard library, `eval.errors` and `eval.heldout`.
"""

from __future__ import annotations

import difflib
import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from eval.errors import EvalError

#: Robot names of `--robots` -> the prefix of their env ids (`<prefix>-<Task>-v0`).
ROBOTS: dict[str, str] = {
    "puma": "WheeledPuma",
    "ur5": "WheeledUR5",
    "panda": "WheeledPanda",
    "random-arm": "WheeledRandomArm",
    "scaled-arm": "WheeledScaledArm",
}
#: The robots of the dev track (and of every condition that does not name its own).
DEV_ROBOTS = ("puma", "ur5", "panda", "random-arm")
#: Task names of `--tasks` -> the middle part of the env id.
TASKS: dict[str, str] = {"circle": "Circle", "line": "Line", "lemniscate": "Lemniscate", "random": "Random"}
#: The tracks a table entry may belong to.
TABLE_TRACKS = ("dev", "heldout", "research")
#: The env arguments every condition states (the old privileged axes), with the value a condition that does not
#: name one has: the benchmark's kinematic world and the envs' own defaults of wear and noise (a test keeps the
#: latter equal to `WheeledPumaEnv`'s).
AXES: dict[str, Any] = {"dynamics": "kinematic", "model_error": 0.05, "obs_noise": 0.0}


def env_id(robot: str, task: str) -> str:
    """`WheeledPuma-Circle-v0` from ("puma", "circle")."""
    return f"{ROBOTS[robot]}-{TASKS[task]}-v0"


@dataclass(frozen=True)
class Condition:
    """One experimental condition: its name, track, env arguments and where it runs (robots, tasks)."""

    name: str
    """Short name (`--conditions`, scorecard headings, every episode record's `condition`)."""
    description: str
    """One line for the scorecard."""
    track: str = "dev"
    """"dev", "heldout" or "research" (see the module docstring)."""
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    """The env constructor arguments of every episode of it; `dynamics`, `model_error` and `obs_noise` are always
    present (`AXES` fills the ones a definition leaves out)."""
    robots: tuple[str, ...] = DEV_ROBOTS
    """The robots (`ROBOTS`) it runs on."""
    tasks: tuple[str, ...] | None = None
    """The tasks (`TASKS`) it runs on; None: every task of the bench."""
    retired: str | None = None
    """The held-out track it was run on before it became public ("v2": protocol v2's, fixed in code; "0.4": a
    release's drawn one), None for a condition that was never held out. A retired condition is on the dev track."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "env_kwargs", {**AXES, **dict(self.env_kwargs)})
        object.__setattr__(self, "robots", tuple(self.robots))
        if self.tasks is not None:
            object.__setattr__(self, "tasks", tuple(self.tasks))

    @property
    def dynamics(self) -> str:
        return str(self.env_kwargs["dynamics"])

    @property
    def model_error(self) -> float:
        return float(self.env_kwargs["model_error"])

    @property
    def obs_noise(self) -> float:
        return float(self.env_kwargs["obs_noise"])

    @property
    def extra_kwargs(self) -> dict[str, Any]:
        """The env arguments beyond the three axes."""
        return {k: v for k, v in self.env_kwargs.items() if k not in AXES}

    def to_dict(self) -> dict[str, Any]:
        """Plain data: `{name, description, track, env_kwargs, robots, tasks}` (the form `from_dict` reads, a
        scorecard's protocol records and `eval.heldout.draw` makes)."""
        return {
            "name": self.name,
            "description": self.description,
            "track": self.track,
            "env_kwargs": dict(self.env_kwargs),
            "robots": list(self.robots),
            "tasks": None if self.tasks is None else list(self.tasks),
            "retired": self.retired,
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Condition:
        """The condition of `to_dict`'s form (or of protocol v2's, whose axes were fields of their own)."""
        kw = dict(d.get("env_kwargs") or {})
        for k in AXES:
            if k in d:
                kw[k] = d[k]
        return cls(
            name=str(d["name"]),
            description=str(d.get("description", "")),
            track=str(d.get("track", "dev")),
            env_kwargs=kw,
            robots=tuple(d.get("robots") or DEV_ROBOTS),
            tasks=None if d.get("tasks") is None else tuple(d["tasks"]),
            retired=d.get("retired"),
        )

    def v2_dict(self) -> dict[str, Any]:
        """The condition as protocol v2 wrote it (the axes as fields of their own; its held-out conditions on the
        "heldout" track): what `HELDOUT_SHA256` hashes."""
        return {
            "name": self.name,
            "description": self.description,
            "track": "heldout" if self.retired == "v2" else self.track,
            "dynamics": self.dynamics,
            "model_error": self.model_error,
            "obs_noise": self.obs_noise,
            "env_kwargs": self.extra_kwargs,
            "robots": list(self.robots),
            "tasks": None if self.tasks is None else list(self.tasks),
        }


def _ladder_path(duration: float) -> dict[str, Any]:
    return {"type": "random", "size": 0.3, "n_terms": 5, "duration": duration, "max_peak": LADDER_MAX_PEAK}


#: The rungs of the difficulty ladder: path duration, s (the module docstring).
LADDER_DURATIONS = (20.0, 10.0, 5.0, 2.5)
#: A rung's paths are drawn feasible: the reference law of `mobman_env.feasibility` within 90% of every speed
#: limit of the episode's true robot (= 1 - its `FEASIBILITY_MARGIN`, the records' `feasible` flag).
LADDER_MAX_PEAK = 0.9
_NOISE = {"obs_noise": 0.001, "obs_noise_vel": 0.01}
_PHYSICS = {"dynamics": "physics"}
_PUMA = ("puma",)

#: Every named condition, in scorecard order (see the module docstring).
CONDITIONS: dict[str, Condition] = {
    c.name: c
    for c in (
        Condition("default", "catalogue task, 5% wear (the paper's setting)"),
        Condition("wear20", "20% wear: the robot is far from its catalogue", env_kwargs={"model_error": 0.2}),
        Condition("noise", "sensor noise: 1 mm on positions, 0.01 m/s on velocities", env_kwargs=_NOISE),
        Condition(
            "drift", "wear drift: lengths change by 0.5% per second (10% over 20 s)", env_kwargs={"wear_rate": 0.005}
        ),
        Condition(
            "lag",
            "actuator lag: every actuator follows its command with tau = 50 ms",
            env_kwargs={"actuator_tau": 0.05},
        ),
        Condition("yaw-noise", "heading noise: 1 mrad on base_yaw", env_kwargs={"obs_noise_yaw": 0.001}),
        Condition("physics", "PyBullet contact dynamics, 5% wear", env_kwargs=_PHYSICS, robots=_PUMA),
        Condition(
            "physics-lag",
            "PyBullet contact dynamics with a 50 ms actuator lag",
            env_kwargs={**_PHYSICS, "actuator_tau": 0.05},
            robots=_PUMA,
        ),
        *(
            Condition(
                f"ladder-{d:g}s",
                f"difficulty ladder: a 5-harmonic random path of 0.3 m in {d:g} s, drawn feasible",
                env_kwargs={"path": _ladder_path(d)},
                robots=_PUMA,
                tasks=("random",),
            )
            for d in LADDER_DURATIONS
        ),
        Condition("wear0", "the catalogue robot itself (no wear)", env_kwargs={"model_error": 0.0}),
        Condition("wear10", "10% wear", env_kwargs={"model_error": 0.1}),
        Condition("wear30", "30% wear", env_kwargs={"model_error": 0.3}),
        # --- protocol v2's held-out track (HELDOUT_SHA256), retired into the dev track by protocol v3 ------------
        Condition(
            "fast-rich",
            "held out: a 6-harmonic random path of 0.4 m in 8 s",
            track="dev",
            retired="v2",
            env_kwargs={"path": {"type": "random", "size": 0.4, "n_terms": 6, "duration": 8.0}},
            tasks=("random",),
        ),
        Condition("rate50", "held out: 50 Hz control", track="dev", retired="v2", env_kwargs={"control_freq": 50.0}),
        Condition(
            "lag100", "held out: actuator lag tau = 100 ms", track="dev", retired="v2", env_kwargs={"actuator_tau": 0.1}
        ),
        Condition(
            "noise-heavy",
            "held out: 2 mm, 0.02 m/s and 3 mrad heading noise",
            track="dev",
            retired="v2",
            env_kwargs={"obs_noise": 0.002, "obs_noise_vel": 0.02, "obs_noise_yaw": 0.003},
        ),
        Condition(
            "combined",
            "held out: 15% wear, drift 0.3%/s, lag 30 ms, 1 mm + 0.01 m/s + 2 mrad noise",
            track="dev",
            retired="v2",
            env_kwargs={
                "model_error": 0.15,
                "obs_noise": 0.001,
                "obs_noise_vel": 0.01,
                "obs_noise_yaw": 0.002,
                "actuator_tau": 0.03,
                "wear_rate": 0.003,
            },
        ),
        Condition(
            "scaled-arms", "held out: random arms scaled 0.7-1.4x", track="dev", retired="v2", robots=("scaled-arm",)
        ),
        Condition(
            "physics-robots",
            "held out: contact dynamics on the UR5, the Panda and random arms",
            track="dev",
            retired="v2",
            env_kwargs=_PHYSICS,
            robots=("ur5", "panda", "random-arm"),
        ),
        Condition(
            "physics-combined",
            "held out: contact dynamics, 10% wear, lag 30 ms, 1 mm + 0.01 m/s + 2 mrad noise",
            track="dev",
            retired="v2",
            env_kwargs={
                **_PHYSICS,
                "model_error": 0.1,
                "obs_noise": 0.001,
                "obs_noise_vel": 0.01,
                "obs_noise_yaw": 0.002,
                "actuator_tau": 0.03,
            },
            robots=_PUMA,
        ),
        # --- research: the conditions of the result pages (docs/results/*), by the names those pages use --------
        Condition(
            "joint-vel-noise",
            "research: 0.01 rad/s joint-speed noise",
            track="research",
            env_kwargs={"obs_noise_joint_vel": 0.01},
        ),
        Condition(
            "jv05", "research: 0.05 rad/s joint-speed noise", track="research", env_kwargs={"obs_noise_joint_vel": 0.05}
        ),
        Condition(
            "heavy15",
            "research: 3 mm, 0.03 m/s and 4.5 mrad heading noise (1.5x protocol v2's noise-heavy)",
            track="research",
            env_kwargs={"obs_noise": 0.003, "obs_noise_vel": 0.03, "obs_noise_yaw": 0.0045},
        ),
        Condition("lag150", "research: actuator lag tau = 150 ms", track="research", env_kwargs={"actuator_tau": 0.15}),
        Condition("delay1", "research: observations 1 control step old", track="research", env_kwargs={"obs_delay": 1}),
        Condition(
            "delay2", "research: observations 2 control steps old", track="research", env_kwargs={"obs_delay": 2}
        ),
        Condition(
            "noise20",
            "research: 20% wear with 1 mm and 0.01 m/s noise",
            track="research",
            env_kwargs={**_NOISE, "model_error": 0.2},
        ),
        Condition(
            "yaw-noise20",
            "research: 20% wear with 5 mrad heading noise",
            track="research",
            env_kwargs={"model_error": 0.2, "obs_noise_yaw": 0.005},
        ),
        Condition(
            "joint-vel-noise20",
            "research: 20% wear with 0.05 rad/s joint-speed noise",
            track="research",
            env_kwargs={"model_error": 0.2, "obs_noise_joint_vel": 0.05},
        ),
        Condition(
            "delay20",
            "research: 20% wear, observations 2 control steps old",
            track="research",
            env_kwargs={"model_error": 0.2, "obs_delay": 2},
        ),
        Condition(
            "lag20",
            "research: 20% wear, actuator lag tau = 20 ms",
            track="research",
            env_kwargs={"model_error": 0.2, "actuator_tau": 0.02},
        ),
    )
}


def _revealed_draws() -> list[Condition]:
    """The conditions of every release's held-out draw whose seed is revealed (`eval.heldout.REVEALED_SEEDS`):
    the newest release's on the heldout track, older ones retired into dev."""
    from eval import heldout as H

    out: list[Condition] = []
    newest = max(H.REVEALED_SEEDS, key=lambda r: tuple(int(x) for x in r.split(".")), default=None)
    for release in H.REVEALED_SEEDS:
        for d in H.revealed_draw(release):
            c = Condition.from_dict({**d, "name": f"{d['name']}-{release}"})
            if release != newest:
                c = Condition.from_dict({**c.to_dict(), "track": "dev", "retired": release})
            out.append(c)
    return out


CONDITIONS.update({c.name: c for c in _revealed_draws()})

#: SHA-256 of protocol v2's held-out conditions as fixed before any tuning against it (`heldout_digest()`, over
#: their v2 form); a test keeps the table equal to it
HELDOUT_SHA256 = "5f62ef3b88f2dd28a2842a44e35bc6b654f5cc823d277ec586509820630bbaf3"
#: The commit that fixed protocol v2's held-out track (scorecards cite it): `git show 0a07529 -- eval/bench/config.py`
HELDOUT_COMMIT = "0a0752963d633337486a25e2ee13d44386d8e7ef"


def heldout_digest() -> str:
    """SHA-256 of protocol v2's held-out conditions (canonical JSON of their v2 form): equals `HELDOUT_SHA256`."""
    table = [c.v2_dict() for c in CONDITIONS.values() if c.retired == "v2"]
    return hashlib.sha256(json.dumps(table, sort_keys=True).encode()).hexdigest()


def get(name: str) -> Condition:
    """The table's condition `name`; EvalError naming the close names and the whole table."""
    if name in CONDITIONS:
        return CONDITIONS[name]
    close = difflib.get_close_matches(str(name), list(CONDITIONS), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise EvalError(
        f"unknown condition {name!r}{hint}; known: {', '.join(CONDITIONS)} (`mobman-eval bench --list` shows them)"
    )


def _text(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (dict, list)):
        return json.dumps(value, sort_keys=True, separators=(",", ":"))
    return str(value)


def condition_name(env_kwargs: Mapping[str, Any]) -> str:
    """The name of the condition of an episode whose env arguments are `env_kwargs` (the axes left out take
    `AXES`'s values): the table entry's with exactly these arguments (never-held-out entries first, the table's
    order), else `dynamics, key=value, ...` over the axes and then the other arguments, sorted."""
    full = {**AXES, **{k: v for k, v in env_kwargs.items() if v is not None}}
    for c in sorted(CONDITIONS.values(), key=lambda c: c.retired is not None):
        if dict(c.env_kwargs) == full:
            return c.name
    parts = [str(full["dynamics"])]
    parts += [f"{k}={_text(full[k])}" for k in ("model_error", "obs_noise")]
    parts += [f"{k}={_text(v)}" for k, v in sorted(full.items()) if k not in AXES]
    return ", ".join(parts)


def conditions_markdown(conditions: Mapping[str, Mapping[str, Any]]) -> str:
    """The conditions table (Markdown) of {name: `Condition.to_dict()`} (protocol v2's form is read too): the
    one rendering of the table (the docs' protocol page, `bench --list --markdown`, each scorecard)."""
    rows = [
        "| condition | track | robots | tasks | dynamics | model_error | obs_noise (mm) | further env arguments | what |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, d in conditions.items():
        c = Condition.from_dict({**d, "name": name})
        extra = ", ".join(f"`{k}` {v}" for k, v in c.extra_kwargs.items()) or "-"
        tasks = ", ".join(c.tasks or []) or "all"
        track = c.track + (f" (held out in {c.retired})" if c.retired else "")
        rows.append(
            f"| `{name}` | {track} | {', '.join(c.robots)} | {tasks} | {c.dynamics} "
            f"| {c.model_error:g} | {c.obs_noise * 1e3:g} | {extra} | {c.description} |"
        )
    return "\n".join(rows)


def on_track(track: str, names: Sequence[str] | None = None) -> list[str]:
    """The table's condition names of `track` (in table order), or those of `names` on it."""
    pool = CONDITIONS if names is None else {n: CONDITIONS[n] for n in names}
    return [n for n, c in pool.items() if c.track == track]

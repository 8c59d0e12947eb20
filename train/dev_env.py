"""`MobMan-DevTrack-v0`: one training env whose episodes are the dev track's kinematic cells, for agents that must
run every robot, task and condition of the scorecard with one network.

```python
import gymnasium as gym, train                        # importing train registers the id
venv = gym.make_vec("MobMan-DevTrack-v0", num_envs=255, autoreset_mode="SameStep")   # training: N robots
env = gym.make("MobMan-DevTrack-v0")                   # one robot, e.g. for a look or a check_env
```

**What an episode is.** Each episode draws, from the robot's own generator: a dev condition (uniformly over the
conditions of the protocol's dev track, `eval.conditions`, that are kinematic and hold the robot), then one of the
condition's tasks (its own path for the ladder and `fast-rich`, else Circle, Line, Lemniscate or Random), and
runs it as the dev track's cell does (the condition's env arguments as the episode's reset options: wear,
sensor noise, drift, actuator lag, heading noise, path). The single env's reset `info` names the draw (`robot`,
`condition`, `task_name`).

**Which robots.** The fixed arms of the dev track: PUMA 560, UR5, Panda (`ROBOTS`). The single env draws the robot
per episode too; the vector env gives each robot an equal block of rows (the first third PUMA, then UR5, then
Panda; `robot_index`), whose rows draw their conditions and tasks per episode: the same distribution,
stratified. Left out, and so unseen in training: the random and the scaled arm
families (a random arm's draw and kinematic check cost about 0.2 s per candidate at every reset, as much as
a few hundred steps of training) and the conditions that change the control rate (`rate50`: the control period
is one per vector env) or need physics. The scorecard's rows on those cells measure how an agent generalises.

**Interface.** The agent's (`policies.agents.agent_interface`): observations in the heading frame, padded to the
Panda's 7 arm joints with a mask; 9 action slots, the padded ones ignored. The observation is already the
agent's, so `train`'s `agent` wrapper passes it through, and an agent trained here runs on every registered id
through `sb3:` (which applies the same interface to the env's raw observation).

**Seeds.** Robot i of the vector env is seeded S + i at `reset(seed=S)` as every vector env here; training seeds
are development seeds (`train` keeps them below 1,000). Every draw comes from the row's generator, so a seed
fixes every episode of a row.

Imports gymnasium, numpy, `mobman_env` and `eval.conditions`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.envs.registration import register, registry
from gymnasium.vector import AutoresetMode

import policies
from eval import conditions as C
from mobman_env.paths import TASK_SPECS
from policies.agents import agent_interface as interface

DEV_TRACK_ID = interface.DEV_TRACK_ID
#: the robots the training env draws (the dev track's fixed arms), by their conditions-table names
ROBOTS = ("puma", "ur5", "panda")
#: env arguments a condition may set that the training env cannot draw per episode (one per vector env)
PER_ENV = ("control_freq",)
#: what the training env refuses as its own argument: it draws them
DRAWN = ("robot", "path", "model_error", "obs_noise", "obs_noise_vel", "obs_noise_yaw", "actuator_tau", "wear_rate")


@dataclass(frozen=True)
class Draw:
    """One cell of the training distribution: a condition's name, a task's name and the reset options."""

    condition: str
    task: str
    options: Mapping[str, Any]

    def reset_options(self) -> dict:
        """The options as a fresh dict (a reset may keep what it is given; the draw stays as it was)."""
        return {k: (dict(v) if isinstance(v, Mapping) else v) for k, v in self.options.items()}


def robot_draws(robot: str, track: str = "dev") -> list[list[Draw]]:
    """The draws open to `robot` on `track`, grouped by condition (a list of its tasks' draws per condition): the
    kinematic conditions that hold the robot and keep the control rate."""
    groups = []
    for name in C.on_track(track):
        cond = C.get(name)
        kwargs = dict(cond.env_kwargs)
        if kwargs.pop("dynamics", "kinematic") != "kinematic" or robot not in cond.robots:
            continue
        if any(k in kwargs for k in PER_ENV):
            continue
        path = kwargs.pop("path", None)
        tasks = cond.tasks or tuple(TASK_SPECS)
        groups.append(
            [
                Draw(name, task, {**kwargs, "path": dict(path if path is not None else TASK_SPECS[task])})
                for task in tasks
            ]
        )
    if not groups:
        raise ValueError(f"no kinematic {track} condition holds the robot {robot!r}; training robots: {ROBOTS}")
    return groups


class EpisodeSampler:
    """`sampler(rng)` -> one episode's reset options for a robot: a condition uniformly, then one of its tasks
    uniformly (the `episode_sampler` of `mobman_env.vector.WheeledPumaVectorEnv`). `last` is the latest draw."""

    def __init__(self, robot: str):
        self.robot = robot
        self.groups = robot_draws(robot)
        self.last: Draw | None = None

    def draw(self, rng: np.random.Generator) -> Draw:
        group = self.groups[int(rng.integers(len(self.groups)))]
        self.last = group[int(rng.integers(len(group)))]
        return self.last

    def __call__(self, rng: np.random.Generator) -> dict:
        return self.draw(rng).reset_options()


def residual_settings(kwargs: dict) -> tuple[str | None, float]:
    """Pop (`residual_base`, `residual_scale`) from the env arguments, checked: the base is a built-in spec
    (`policies.KNOWN_POLICIES`, with options), the scale > 0 (the residual's share of the speed limits)."""
    from policies import KNOWN_POLICIES

    base = kwargs.pop(interface.RESIDUAL_BASE, None)
    scale = float(kwargs.pop(interface.RESIDUAL_SCALE, interface.DEFAULT_RESIDUAL_SCALE))
    if base is not None and (not isinstance(base, str) or base.partition(":")[0] not in KNOWN_POLICIES):
        raise ValueError(
            f"{interface.RESIDUAL_BASE}={base!r} is not a built-in controller; accepted: {', '.join(KNOWN_POLICIES)}"
        )
    if not scale > 0:
        raise ValueError(f"{interface.RESIDUAL_SCALE} must be > 0 (e.g. 0.05), got {scale!r}")
    return base, scale


def _check_kwargs(kwargs: Mapping[str, Any]) -> dict:
    given = sorted(k for k in kwargs if k in DRAWN)
    if given:
        raise ValueError(
            f"{DEV_TRACK_ID} draws {given} per episode from the dev track; pass the other env arguments only "
            f"(e.g. error_bound, reward_weights), or train on a fixed id such as WheeledPuma-Circle-v0 with them"
        )
    dynamics = kwargs.get("dynamics", "kinematic")
    if dynamics != "kinematic":
        raise ValueError(f"{DEV_TRACK_ID} is kinematic, got dynamics={dynamics!r}; leave dynamics unset")
    return {k: v for k, v in kwargs.items() if k not in ("dynamics", "max_episode_steps", "render_mode")}


def _stack(parts: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {k: np.concatenate([p[k] for p in parts], axis=0) for k in interface.AGENT_OBS_KEYS}


class DevTrackVectorEnv(gym.vector.VectorEnv):
    """N robots of the training distribution (module docstring): one native vector env per robot, an equal block
    of rows each, in the agent's interface. `info` holds `tracking_error` (N,) and, in `AutoresetMode.SAME_STEP`,
    `final_obs` (the agent's view) for the rows whose episode ended."""

    def __init__(self, num_envs: int = 3, autoreset_mode: Any = AutoresetMode.NEXT_STEP, **kwargs: Any):
        n = int(num_envs)
        if n < len(ROBOTS):
            raise ValueError(f"{DEV_TRACK_ID} needs num_envs >= {len(ROBOTS)} (one block per robot {ROBOTS}), got {n}")
        kwargs = dict(kwargs)
        self.residual_base, self.residual_scale = residual_settings(kwargs)
        kwargs = _check_kwargs(kwargs)
        sizes = [n // len(ROBOTS) + (1 if k < n % len(ROBOTS) else 0) for k in range(len(ROBOTS))]
        self.samplers = [EpisodeSampler(r) for r in ROBOTS]
        self.parts: list[Any] = [
            gym.make_vec(
                C.env_id(robot, "circle"),
                num_envs=size,
                vectorization_mode="vector_entry_point",
                dynamics="kinematic",
                autoreset_mode=autoreset_mode,
                episode_sampler=sampler,
                **kwargs,
            )
            for robot, size, sampler in zip(ROBOTS, sizes, self.samplers, strict=True)
        ]
        self._bounds = np.cumsum([0, *sizes])
        self._m = [int(p.single_action_space.shape[0]) for p in self.parts]
        self.num_envs = n
        self.metadata = {"autoreset_mode": self.parts[0].metadata["autoreset_mode"], "render_modes": []}
        self.render_mode = None
        self.single_observation_space = interface.observation_space(residual=self.residual_base is not None)
        self.single_action_space = interface.action_space()
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, n)
        self.bases = [] if self.residual_base is None else [policies.make(self.residual_base, p) for p in self.parts]
        self._base_actions: list[np.ndarray] = []  # each part's base action for the coming step (agent slots)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, n)
        #: the robot of each row (an index into `ROBOTS`)
        self.robot_index = np.repeat(np.arange(len(ROBOTS)), sizes)

    @property
    def dt(self) -> float:
        """The control period, s (one for every robot)."""
        return float(self.parts[0].dt)

    def _seeds(self, seed: Any) -> list[Any]:
        if seed is None:
            return [None] * len(self.parts)
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            return [int(seed) + int(a) for a in self._bounds[:-1]]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"reset(seed=...) got {len(seeds)} seeds for {self.num_envs} robots")
        return [seeds[a:b] for a, b in zip(self._bounds[:-1], self._bounds[1:], strict=True)]

    def reset(self, *, seed: Any = None, options: dict | None = None):
        if options:
            raise ValueError(f"{DEV_TRACK_ID} draws every episode's options itself; reset(options=...) is refused")
        seeds = self._seeds(seed)
        out = [p.reset(seed=s) for p, s in zip(self.parts, seeds, strict=True)]
        for base, (o, info), s in zip(self.bases, out, seeds, strict=False):
            base.reset(o, info, seed=s)
        starts = [np.ones(p.num_envs, bool) for p in self.parts]
        return self._observe([o for o, _ in out], starts), self._info([i for _, i in out])

    def _observe(self, raw: Sequence[dict[str, np.ndarray]], starts: Sequence[np.ndarray | None]) -> dict:
        """The agent's observation of every row; with a residual base, the base's next action joins it."""
        obs = _stack([interface.agent_observation(o) for o in raw])
        if self.bases:
            self._base_actions = [
                interface.base_action(base, o, s) for base, o, s in zip(self.bases, raw, starts, strict=True)
            ]
            obs[interface.BASE_ACTION] = np.concatenate(self._base_actions, axis=0)
        return obs

    def step(self, actions: Any):
        a = np.asarray(actions, dtype=np.float32)
        if a.shape != (self.num_envs, interface.N_ACTIONS):
            raise ValueError(f"actions must have shape ({self.num_envs}, {interface.N_ACTIONS}), got {a.shape}")
        results = []
        for k, (p, m, lo, hi) in enumerate(zip(self.parts, self._m, self._bounds[:-1], self._bounds[1:], strict=True)):
            act = a[lo:hi]
            if self.bases:
                act = interface.residual_action(self._base_actions[k], act, self.residual_scale)
            results.append(p.step(interface.env_action(act, m)))
        starts = [r[2] | r[3] if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP else None for r in results]
        applied = self._base_actions
        obs = self._observe([r[0] for r in results], starts)
        rewards, terminated, truncated = (np.concatenate([r[k] for r in results]) for k in (1, 2, 3))
        return obs, rewards, terminated, truncated, self._info([r[4] for r in results], applied)

    def _info(self, infos: Sequence[Mapping[str, Any]], applied: Sequence[np.ndarray] = ()) -> dict[str, Any]:
        """The merged info; a final observation of a residual agent carries the base action of the step that
        ended the episode (`applied`: the base is not asked about a state it will not act in)."""
        sizes = np.diff(self._bounds)
        err = np.concatenate([np.asarray(i.get("tracking_error", np.zeros(s)), float) for i, s in zip(infos, sizes)])
        out: dict[str, Any] = {"tracking_error": err, "_tracking_error": np.ones(self.num_envs, bool)}
        if not any("final_obs" in i for i in infos):
            return out
        final = np.full(self.num_envs, None, dtype=object)
        for k, (info, lo) in enumerate(zip(infos, self._bounds[:-1], strict=False)):
            if "final_obs" in info:
                for j in np.flatnonzero(info["_final_obs"]):
                    final[lo + j] = view = interface.agent_observation(info["final_obs"][j])
                    if applied:
                        view[interface.BASE_ACTION] = applied[k][j].copy()
        out["final_obs"], out["_final_obs"] = final, np.array([f is not None for f in final])
        return out

    def close_extras(self, **kwargs: Any) -> None:
        for p in self.parts:
            p.close()


class DevTrackEnv(gym.Env):
    """One robot of the training distribution: each reset draws a robot, then its condition and task (module
    docstring); observation and action in the agent's interface. `info` of a reset has `robot`, `condition`,
    `task_name` beside the env's own keys."""

    metadata = {"render_modes": []}  # noqa: RUF012  (gymnasium's attribute)

    def __init__(self, **kwargs: Any):
        kwargs = dict(kwargs)
        self.residual_base, self.residual_scale = residual_settings(kwargs)
        self._kwargs = _check_kwargs(kwargs)
        self.samplers = [EpisodeSampler(r) for r in ROBOTS]
        self._envs: dict[str, Any] = {}
        self._bases: dict[str, Any] = {}
        self._env: Any = None
        self._base: Any = None
        self._base_slots = np.zeros(interface.N_ACTIONS, np.float32)
        self._m = interface.N_ACTIONS
        self.observation_space = interface.observation_space(residual=self.residual_base is not None)
        self.action_space = interface.action_space()

    def _robot_env(self, robot: str) -> Any:
        if robot not in self._envs:
            env = gym.make(C.env_id(robot, "circle"), dynamics="kinematic", **self._kwargs).unwrapped
            self._envs[robot] = env
            if self.residual_base is not None:
                self._bases[robot] = policies.make(self.residual_base, env)
        return self._envs[robot]

    def _observe(self, obs: Any, start: bool) -> dict:
        view = interface.agent_observation(obs)
        if self._base is not None:
            self._base_slots = interface.base_action(self._base, obs, np.array([start]))
            view[interface.BASE_ACTION] = self._base_slots
        return view

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        if options:
            raise ValueError(f"{DEV_TRACK_ID} draws every episode's options itself; reset(options=...) is refused")
        super().reset(seed=seed)
        rng = self.np_random
        k = int(rng.integers(len(ROBOTS)))
        draw = self.samplers[k].draw(rng)
        self._env = env = self._robot_env(ROBOTS[k])
        self._base = self._bases.get(ROBOTS[k])
        self._m = int(env.action_space.shape[0])
        episode_seed = int(rng.integers(2**31))
        obs, info = env.reset(seed=episode_seed, options=draw.reset_options())
        if self._base is not None:
            self._base.reset(obs, info, seed=episode_seed)
        info = {**info, "robot": ROBOTS[k], "condition": draw.condition, "task_name": draw.task}
        return self._observe(obs, True), info

    def step(self, action: Any):
        if self._env is None:
            raise RuntimeError("call reset() before step()")
        if self._base is not None:
            action = interface.residual_action(self._base_slots, action, self.residual_scale)
        obs, reward, terminated, truncated, info = self._env.step(interface.env_action(action, self._m))
        return self._observe(obs, False), reward, terminated, truncated, info

    def close(self) -> None:
        for env in self._envs.values():
            env.close()
        self._envs.clear()


def register_dev_track() -> None:
    """Register `DEV_TRACK_ID` (silent when it is registered already)."""
    if DEV_TRACK_ID not in registry:
        register(
            id=DEV_TRACK_ID,
            entry_point="train.dev_env:DevTrackEnv",
            vector_entry_point="train.dev_env:DevTrackVectorEnv",
            max_episode_steps=None,
        )


register_dev_track()

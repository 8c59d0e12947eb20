"""The policy contract shared by every controller and agent: SB3's `predict`, plus `reset`.

```python
class Policy(Protocol):
    def reset(self, obs, info=None, *, seed=None) -> None: ...
    def predict(self, observation, state=None, episode_start=None, deterministic=True) -> tuple[np.ndarray, Any]: ...
```

* `predict` accepts an unbatched observation dict or one batched with a leading axis of length 1 (what a
  `DummyVecEnv` passes) and returns an action of the matching shape, in the env's normalised action space.
  Controllers are single-env: a longer batch raises `ValueError`.
* `episode_start[0] == True` re-initialises the controller from that observation exactly like `reset(obs)`
  (SB3's `evaluate_policy` never calls `reset`). A controller that was never reset initialises itself on its
  first `predict`.
* Model-free controllers are built from a frozen `EnvFacts` (control period, action scale, observation keys),
  never from the env, so they cannot read a model.
* The seed a policy's `reset(seed=...)` receives is `policy_seed(episode_seed)`, never the env's own episode
  seed (see `policy_seed`). Controllers that estimate the Jacobian expose the estimate as `jacobian_estimate`
  (see `ControllerPolicy.jacobian_estimate`), which eval compares with the true robot's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from mobman_env.validation import integer

#: Entropy word that separates the policy's random stream from the env's (ASCII "mobman-policy" folded into
#: 32 bits). Part of the documented seed rule of `policy_seed`; changing it changes every dithering result.
POLICY_STREAM_ID = 0x6D6F_706F


def policy_seed(episode_seed: int) -> int:
    """The seed a policy gets for the episode the env starts with `reset(seed=episode_seed)`.

    Rule (documented, fixed): ``int(np.random.SeedSequence([episode_seed, POLICY_STREAM_ID]).generate_state(1,
    np.uint64)[0])``, an integer in [0, 2**64). The env's Generator starts from ``SeedSequence(episode_seed)``,
    a different entropy pool, so a Generator seeded with this value shares no state with the env's: the policy
    cannot replay the env's draws (the true robot `RobotParams.nominal().perturbed(default_rng(seed), ...)`,
    the random path, the sensor noise) from its seed. The rule is public, so a policy that *searches* episode
    seeds for one whose image equals its own seed could still find it (seeds are small integers); that is
    deliberate cheating, like reading `true_params`, and no public deterministic rule can prevent it.

    A batched policy seeds robot i of a vector env reset with seed S from ``policy_seed(S + i)``: exactly the
    seed a single policy gets for a single env reset with S + i. `episode_seed` must be an integer >= 0.
    """
    seed = integer("episode_seed", episode_seed, low=0, hint="the seed given to env.reset(seed=...)")
    return int(np.random.SeedSequence([seed, POLICY_STREAM_ID]).generate_state(1, np.uint64)[0])


@runtime_checkable
class Policy(Protocol):
    def reset(self, obs: dict, info: dict | None = None, *, seed: int | None = None) -> None: ...

    def predict(
        self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[np.ndarray, Any]: ...


def unwrap_env(env: Any) -> Any:
    """The `WheeledPumaEnv` inside a gym.Env (wrappers) or an SB3 VecEnv with one sub-env of the same kind
    (attributes are read through `get_attr`, which works for subprocess envs too)."""
    if hasattr(env, "get_attr") and hasattr(env, "num_envs"):  # SB3 VecEnv
        return _VecEnvView(env)
    return getattr(env, "unwrapped", env)


class _VecEnvView:
    """Attribute access to the first sub-env of a VecEnv (`get_attr` works across processes)."""

    def __init__(self, venv: Any):
        self._venv = venv

    def __getattr__(self, name: str) -> Any:
        if name == "observation_space":
            return self._venv.observation_space
        return self._venv.get_attr(name, indices=[0])[0]


def current_model(model: Any) -> Any:
    """The robot model a model-based controller inverts this episode: `model` itself (a `RobotParams`) or, for a
    callable (the registry's provider of the env's nominal robot, which changes per reset for the random arm
    family), what it returns now. Called at every episode start."""
    return model() if callable(model) else model


@dataclass(frozen=True)
class EnvFacts:
    """What a model-free controller may know about the env: nothing about the robot's geometry.

    dt: control period, s. action_scale: speed limits of the n + 2 actuators (n arm joints, left, right wheel),
    rad/s (action = u / action_scale); its length is the actuator count `n_actuators` (8 for the PUMA, 9 for
    the Panda), so facts pickled by release 0.1 keep their meaning. obs_keys: the observation dict's keys.
    """

    dt: float
    action_scale: tuple[float, ...]
    obs_keys: tuple[str, ...]

    @classmethod
    def from_env(cls, env: Any) -> EnvFacts:
        """Read the facts from a gym.Env (any wrappers) or a VecEnv, touching no model attribute."""
        base = unwrap_env(env)
        try:
            dt = float(base.dt)
            scale = tuple(float(v) for v in np.asarray(base.action_scale, dtype=float))
        except AttributeError as exc:
            raise TypeError(
                f"{type(env).__name__} does not look like a mobman env (needs .dt and .action_scale): {exc}"
            ) from None
        keys = tuple(getattr(base.observation_space, "spaces", {}).keys())
        return cls(dt=dt, action_scale=scale, obs_keys=keys)

    @property
    def scale(self) -> np.ndarray:
        return np.asarray(self.action_scale, dtype=float)

    @property
    def n_actuators(self) -> int:
        """The number of actuators: n arm joints + 2 wheels, the action's length."""
        return len(self.action_scale)

    @property
    def n_arm(self) -> int:
        """The number of arm joints n (the actuators less the two wheels)."""
        return len(self.action_scale) - 2


def missing_keys_error(observation: dict, keys: Any) -> ValueError:
    """The error for an observation that lacks keys a policy reads: the missing ones, the ones it reads, the ones
    the observation holds and the fix (a bare KeyError named one key and nothing else)."""
    missing = [k for k in keys if k not in observation]
    return ValueError(
        f"the observation has no {', '.join(map(repr, missing))}: this policy reads {list(keys)}, the observation "
        f"holds {sorted(map(str, observation))}; pass the env's whole Dict observation (not a flattened or "
        f"filtered one)"
    )


def unbatch(observation: dict, keys: tuple[str, ...] | None = None) -> tuple[dict, bool]:
    """Return (single observation with 1-D float64 arrays, whether the input was a batch of one).

    `keys`: convert only these keys (a controller's hot path needs a few of the ten); None: all of them.
    """
    if not isinstance(observation, dict):
        raise ValueError(f"observation must be a dict (the env's Dict observation), got {type(observation).__name__}")
    first = observation.get("ee_pos")
    if first is None:
        first = next(iter(observation.values()))
    batched = (first.ndim if isinstance(first, np.ndarray) else np.ndim(first)) == 2
    if batched and first.shape[0] != 1:
        raise ValueError(
            f"controllers are single-env: got a batch of {first.shape[0]} observations; use one env (DummyVecEnv "
            f"with n_envs=1) or one controller per env"
        )
    if keys is None:
        keys = tuple(observation)
    try:
        if batched:
            return {k: np.asarray(observation[k], dtype=float)[0] for k in keys}, True
        return {k: np.asarray(observation[k], dtype=float) for k in keys}, False
    except KeyError:
        raise missing_keys_error(observation, keys) from None


def reject_extra(owner: object, extra: dict, accepted: str = "") -> None:
    """The constructors' check of their keyword arguments: TypeError naming the unexpected ones of `owner`'s class
    and, when there are any, the `accepted` ones."""
    if extra:
        tail = f"; accepted: {accepted}" if accepted else ""
        raise TypeError(f"{type(owner).__name__} got unexpected keyword argument(s) {sorted(extra)}{tail}")


def first_flag(episode_start: Any) -> bool:
    if episode_start is None:
        return False
    return bool(np.asarray(episode_start).reshape(-1)[0])


class ControllerPolicy:
    """Base class of the controllers: handles batching, `episode_start` and the per-controller RNG.

    Subclasses implement `_reset(obs)` (re-initialise all state from the first observation) and `_act(obs)`
    (return the actuator speeds u in rad/s for one unbatched observation). The base class clips u to the speed
    limits, records it as `self.last_u` (the command actually issued) and returns u / action_scale. A subclass
    that reads only some observation keys lists them in `uses_keys`, and only those are converted per call.
    """

    name = "controller"
    #: observation keys `_reset`/`_act` read (None: all); only these are converted on the hot path
    uses_keys: tuple[str, ...] | None = None
    #: which Jacobian `jacobian_estimate` estimates: "whole_body" (r_a_dot = J u, the platform's translation
    #: included; `mobman_env.kinematics.whole_body_jacobian`), "paper" (r_a_dot - [p_c_dot; 0] = J u, the J of
    #: the paper's eq. (6); `mobman_env.kinematics.paper_jacobian`), or None for a controller with no estimate
    jacobian_kind: str | None = None

    @property
    def jacobian_estimate(self) -> np.ndarray | None:
        """The controller's current estimate of the Jacobian, or None (no estimate, or none yet).

        A 3 x (n + 2) float array in the action's physical units: actuator speeds u (rad/s: n arm joints, left wheel,
        right wheel) to end-effector velocity (m/s), for the state of the last observation given to `predict`;
        `jacobian_kind` names the Jacobian. Eval compares it with the true robot's Jacobian (computed by eval,
        never by the policy) and records the relative error and the row-space angle. Model-based controllers
        and those that estimate nothing return None.
        """
        return None

    def __init__(self, facts: EnvFacts, seed: int | None = None):
        self.facts = facts
        self._scale = facts.scale
        self._neg_scale = -self._scale
        self._seed = seed
        self.rng = np.random.default_rng(seed)
        self._initialised = False
        self.last_u = np.zeros(len(self._scale))

    # --- contract --------------------------------------------------------------------------------------
    def reset(self, obs: dict, info: dict | None = None, *, seed: int | None = None) -> None:
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self._start(unbatch(obs, self.uses_keys)[0])

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        single, batched = unbatch(observation, self.uses_keys)
        if not self._initialised or (episode_start is not None and first_flag(episode_start)):
            self._start(single)
        # np.minimum(np.maximum(...)) is np.clip at a third of its cost for an 8-vector
        u = np.minimum(np.maximum(self._act(single), self._neg_scale), self._scale)
        self.last_u = u
        action = (u / self._scale).astype(np.float32)
        return (action[None] if batched else action), state

    def _start(self, single: dict) -> None:
        """Begin an episode from its first (unbatched) observation: what reset() and episode_start share."""
        self.last_u = np.zeros(len(self._scale))
        self._reset(single)
        self._initialised = True

    # --- to implement ----------------------------------------------------------------------------------
    def _reset(self, obs: dict) -> None:
        raise NotImplementedError

    def _act(self, obs: dict) -> np.ndarray:
        raise NotImplementedError

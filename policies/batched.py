"""`policies.make(spec, vector_env)`: one policy object for the N robots of a vector env, speaking SB3's batched
`predict` (one row per robot).

```python
venv = gym.make_vec("WheeledPuma-Circle-v0", num_envs=64, vectorization_mode="vector_entry_point",
                    dynamics="kinematic")
policy = policies.make("clik", venv)             # a BatchedPolicy (here a BatchedController: a vectorised law)
obs, info = venv.reset(seed=10_000)
policy.reset(obs, info, seed=10_000)             # row i: policy_seed(10_000 + i), as a single env's policy
actions, _ = policy.predict(obs)                 # (64, 8) float32
actions, _ = policy.predict(obs, episode_start=mask)   # re-initialise the rows of mask only
```

Two kinds behind one interface (`BatchedPolicy`):

* Vectorised laws (`BatchedController`): `zero`, `random`, `jmpi`, `jmpi-full`, `clik`, `clik-full`, `oracle`,
  `oracle-full`, `nnbc`, `nnbc-full`, `qp`, `qp-oracle`, `calib-qp`, `mpc`, `mpc-oracle` (batched up to the QP,
  which is solved row by row; `calib-qp`'s calibration is one per-row kernel; `mpc`'s QP is assembled per row by
  one kernel), and the model-free `nnbc-plus`, `nnbc-plus-wb`, `broyden`,
  `rls` (one per-row numba kernel, `policies.kernels.model_free`: each row draws its dither signs from its own
  Generator as the single controller does). The
  law's state is (N, ...) arrays and one `predict` advances every row with whole-array numpy operations
  (`policies.kernels.shared`: the damped pseudo-inverse of N Jacobians, the nominal or true robots' Jacobians batched by
  `mobman_env.vector_kinematics`). The single-env class of the spec (`NNBC`, `CLIK`, `Oracle`, ...) is a `LawView`:
  the same law with N = 1 (STYLE 14: one implementation per law). So robot i's actions are those of a single policy
  reset with `policy_seed(S + i)` on the same observations; bit for bit on our machines (products are numpy stacked
  `matmul`s, the same BLAS kernel per row whatever N; the 3 x 3 algebra is the same expressions on floats and on
  (N,) arrays), which `tests/test_batched_policies.py` checks to 1e-9 over 200 steps and finds exact. The oracle's
  true robot is robot i's (`venv.true_params(i)`), read at each of the row's episode starts; nnbc's rows probe,
  finish the probe and run the ZNN law each at its own step count. Cost per robot-step at N = 64 and 1,024: a few
  microseconds, against 25-85 us for one single `predict` (`mobman-eval speed`; `random` keeps one draw per row's
  Generator and step, so its cost stays that of N small draws).
* Every other spec (`sb3:`, `module:attr`): this class loops
  N single-env policies, row i built for robot i (`_RobotView`: the vector env's dt, action scale, single
  observation space and nominal robot; the true robot is robot i's, read at each of its episode starts) and
  fed row i of each batched observation (float32 rows, as a single env hands them out): bit for bit the single
  policy, at the cost of one single `predict` per robot-step. A vectorised kernel for a law replaces its loop
  without changing this interface (its single-env class gets a `batched` constructor, `policies.registry`).

Several controllers on one vector env: `policies.stacked.StackedPolicy` (one batched policy per block of rows).

`reset(obs, info=None, *, seed=None)`: `seed` is the vector env's reset seed S (row i gets `policy_seed(S + i)`,
the documented rule of `policies.base.policy_seed`), or a list of N policy seeds (None entries: no reseed).
`episode_start` (N,) re-initialises the rows where it is True from their observation, as a single policy's
`episode_start` does (its generator continues). `rows[i]` offers row i's `jacobian_kind` and `jacobian_estimate`
(the single policies of the loop; views of a vectorised law); `jacobian_estimates()` returns each row's estimate.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from policies.base import ControllerPolicy, EnvFacts, first_flag, policy_seed, unbatch
from policies.kernels.shared import obs_rows


def is_vector_env(env: Any) -> bool:
    """Whether `env` is a Gymnasium vector env (it has `num_envs` and `single_observation_space`)."""
    return hasattr(env, "num_envs") and hasattr(env, "single_observation_space")


class _VectorEnvPart:
    """What every view of part of a vector env passes through unchanged: dt, action scale, nominal robot."""

    _venv: Any

    @property
    def dt(self) -> float:
        return float(self._venv.dt)

    @property
    def action_scale(self) -> np.ndarray:
        return np.asarray(self._venv.action_scale, dtype=float)

    @property
    def nominal_params(self) -> Any:
        return self._venv.nominal_params


class _RobotView(_VectorEnvPart):
    """What a single-env policy may read of robot i of a vector env (the attributes `policies.make` reads)."""

    def __init__(self, venv: Any, i: int):
        self._venv = venv
        self._i = i
        self.observation_space = venv.single_observation_space
        self.action_space = venv.single_action_space
        self.unwrapped = self

    @property
    def true_params(self) -> Any:
        """Robot i's current true robot (the oracle's provider reads it at each episode start)."""
        return self._venv.true_params(self._i)

    @property
    def true_actuator_tau(self) -> float:
        """Robot i's actuator lag this episode, s (`mpc-oracle`'s provider reads it at each episode start)."""
        return float(self._venv.true_actuator_tau(self._i))

    @property
    def nominal_params(self) -> Any:
        """Robot i's nominal robot (for the random arm family its episode's drawn design)."""
        of = getattr(self._venv, "nominal_params_of", None)
        return self._venv.nominal_params if of is None else of(self._i)


class BatchedPolicy:
    """One policy for the N robots of a vector env (see the module docstring). This class is the interface and
    the row loop of the laws written only for one env; `BatchedController` runs a vectorised law."""

    def __init__(self, spec: str, rows: Sequence[Any]):
        self.spec = spec
        self.rows = list(rows)
        self.num_envs = len(self.rows)

    @classmethod
    def for_vector_env(cls, spec: str, venv: Any, build: Callable[[str, Any], Any]) -> BatchedPolicy:
        """Build row i with `build(spec, robot i)` (`policies.make` passes itself): robot i is a view of the
        native vector env (`_RobotView`), or the i-th single env of a `SyncVectorEnv` (`sync_envs`)."""
        check_vector_env(venv)
        robots = sync_envs(venv) or [_RobotView(venv, i) for i in range(venv.num_envs)]
        return cls(spec, [build(spec, robot) for robot in robots])

    def reset(self, obs: dict, info: dict | None = None, *, seed: int | Sequence[int | None] | None = None) -> None:
        self._check(obs, "reset")
        seeds = self._seeds(seed)
        for i, row in enumerate(self.rows):
            row.reset(_row(obs, i), None, seed=seeds[i])

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        self._check(observation)
        starts = self._starts(episode_start)
        if starts is None:
            starts = np.zeros(self.num_envs, dtype=bool)
        actions = [
            row.predict(_row(observation, i), None, starts[i : i + 1], deterministic)[0]
            for i, row in enumerate(self.rows)
        ]
        return np.stack([np.asarray(a, dtype=np.float32).reshape(-1) for a in actions]), state

    def jacobian_estimates(self) -> list[np.ndarray | None]:
        """Each row's current `jacobian_estimate` (None where a row has none)."""
        return [getattr(row, "jacobian_estimate", None) for row in self.rows]

    @property
    def artefacts(self) -> list[dict]:
        """The files the rows loaded (an `sb3:` agent's `SB3Policy.artefacts`), each once, in row order; []
        for policies that load none."""
        seen: dict[tuple, dict] = {}
        for row in self.rows:
            for item in getattr(row, "artefacts", None) or []:
                seen.setdefault((item["path"], item["sha256"]), item)
        return list(seen.values())

    # --- shared by the loop and the vectorised laws -------------------------------------------------------
    def _seeds(self, seed: int | Sequence[int | None] | None) -> list[int | None]:
        """The N policy seeds of `reset(seed=...)`: S -> policy_seed(S + i); a list as given; None: no reseed."""
        n = self.num_envs
        if seed is None:
            return [None] * n
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            return [policy_seed(int(seed) + i) for i in range(n)]
        seeds = list(seed)  # type: ignore[arg-type]
        if len(seeds) != n:
            raise ValueError(f"reset(seed=...) needs the vector reset seed S or a list of {n} seeds, got {len(seeds)}")
        return seeds

    def _check(self, observation: dict, call: str = "predict") -> None:
        """Refuse an observation that is not a dict of (N, k) arrays, naming the shapes."""
        n = self.num_envs
        if not isinstance(observation, dict) or not observation:
            raise ValueError(
                f"{call} of a batched policy of {n} rows needs the vector env's observation, a dict of ({n}, k) "
                f"arrays; got {type(observation).__name__}"
            )
        shapes = {k: np.shape(v) for k, v in observation.items()}
        if any(len(shape) != 2 or shape[0] != n for shape in shapes.values()):
            raise ValueError(
                f"{call} of a batched policy of {n} rows needs observations with a leading axis of {n} (one row "
                f"per robot), got shapes {shapes}; pass the vector env's whole observation"
            )

    def _starts(self, episode_start: Any) -> np.ndarray | None:
        """episode_start as an (N,) bool array, or None when no row starts."""
        if episode_start is None:
            return None
        starts = np.asarray(episode_start, dtype=bool).reshape(self.num_envs)
        return starts if starts.any() else None


class BatchedAgent(BatchedPolicy):
    """One `sb3:` agent for the N robots of the native vector env: one `predict` for N rows. Built only for an
    agent whose deterministic action is computed row by row (`policies.agents.sb3_actor`: the same bits for any N), so
    its episodes equal the single path's; a residual agent's base is the base's vectorised law. `rows` are the
    agent itself N times (its knowledge class and artefacts, for the records)."""

    def __init__(self, spec: str, agent: Any, n: int):
        super().__init__(spec, [agent] * n)
        self.agent = agent

    @property
    def knowledge(self) -> str:
        """The agent's knowledge class (a residual agent's is its base's)."""
        return str(self.agent.knowledge)

    def reset(self, obs: dict, info: dict | None = None, *, seed: int | Sequence[int | None] | None = None) -> None:
        self._check(obs, "reset")
        self.agent.reset(obs, info, seed=seed)

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        self._check(observation)
        starts = self._starts(episode_start)
        action, _ = self.agent.predict(observation, None, starts, deterministic)
        return np.asarray(action, dtype=np.float32).reshape(self.num_envs, -1), state


class BatchedController(BatchedPolicy):
    """Base of the vectorised laws: N rows whose state is (N, ...) arrays, advanced by one call per step.

    A subclass implements `_reset_rows(rows, obs)` (re-initialise the rows `rows`, an index array, from their
    observations: `obs` holds every row's, (N, k) float64, of the keys in `uses_keys`) and `_act(obs)` (the
    actuator speeds u of every row, (N, n + 2), rad/s). This class clips u to the speed limits, keeps it as
    `last_u` (the commands issued) and returns u / action_scale as float32, as `ControllerPolicy` does for one
    env; its single-env class is a `LawView` of an instance with N = 1. `rngs[i]` is row i's Generator
    (`reset(seed=S)` seeds it with policy_seed(S + i)); rows never reset start on their first `predict`.
    """

    name = "controller"
    #: observation keys `_reset_rows`/`_act` read
    uses_keys: tuple[str, ...] = ()
    #: see `ControllerPolicy.jacobian_kind`
    jacobian_kind: str | None = None

    def __init__(self, facts: Any, n: int, seed: int | None = None):
        self.spec = self.name
        self.num_envs = n
        self.facts = facts
        self._scale = facts.scale
        self._neg_scale = -self._scale
        self.rngs = [np.random.default_rng(seed) for _ in range(n)]
        self.initialised = np.zeros(n, dtype=bool)
        self._ready = False  # every row initialised
        self.last_u = np.zeros((n, len(self._scale)))

    @property
    def rows(self) -> list[Any]:  # type: ignore[override]
        """Per-row views (`jacobian_kind`, `jacobian_estimate`), as the loop's rows offer them."""
        return [_Row(self, i) for i in range(self.num_envs)]

    def reset(self, obs: dict, info: dict | None = None, *, seed: int | Sequence[int | None] | None = None) -> None:
        self._check(obs, "reset")
        for i, s in enumerate(self._seeds(seed)):
            if s is not None:
                self.rngs[i] = np.random.default_rng(s)
        self._start(np.arange(self.num_envs), obs_rows(obs, self.uses_keys))

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        self._check(observation)
        return self.step(obs_rows(observation, self.uses_keys), self._starts(episode_start)), state

    def jacobian_estimates(self) -> list[np.ndarray | None]:
        return [self.jacobian_estimate_row(i) for i in range(self.num_envs)]

    def jacobian_estimate_row(self, i: int) -> np.ndarray | None:
        """Row i's `jacobian_estimate` (see `ControllerPolicy.jacobian_estimate`); None by default."""
        return None

    def step(self, obs: dict[str, np.ndarray], starts: np.ndarray | None) -> np.ndarray:
        """One step of every row: (re)start the rows of `starts` (None: none) and those never started, then act.
        `obs`: the keys of `uses_keys` as (N, k) float64. Returns the actions (N, n + 2), float32."""
        if starts is not None or not self._ready:
            mask = ~self.initialised if starts is None else starts | ~self.initialised
            self._start(np.flatnonzero(mask), obs)
        # np.minimum(np.maximum(...)) is np.clip at a third of its cost for small arrays
        u = np.minimum(np.maximum(self._act(obs), self._neg_scale), self._scale)
        self.last_u = u
        return (u / self._scale).astype(np.float32)

    def _start(self, rows: np.ndarray, obs: dict[str, np.ndarray]) -> None:
        self.last_u[rows] = 0.0
        self._reset_rows(rows, obs)
        self.initialised[rows] = True
        self._ready = bool(self.initialised.all())

    # --- to implement ------------------------------------------------------------------------------------
    def _reset_rows(self, rows: np.ndarray, obs: dict[str, np.ndarray]) -> None:
        raise NotImplementedError

    def _act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        raise NotImplementedError


class _Row:
    """Row i of a `BatchedController`, as the loop's rows are read (eval's Jacobian recorder; eval's records read
    its knowledge class through `policies.knowledge_of`: the law's `knowledge` where it declares one, else its
    spec's)."""

    def __init__(self, law: BatchedController, i: int):
        self._law, self._i = law, i
        self.name = law.name
        self.knowledge = getattr(law, "knowledge", None)
        self.jacobian_kind = law.jacobian_kind

    @property
    def jacobian_estimate(self) -> np.ndarray | None:
        return self._law.jacobian_estimate_row(self._i)

    @property
    def spec(self) -> str | None:
        """The law's spec (what `policies.knowledge_of` reads a row's class from)."""
        return getattr(self._law, "spec", None)


_ROW0 = np.zeros(1, dtype=np.intp)
_START = np.ones(1, dtype=bool)


class LawView(ControllerPolicy):
    """The single-env controller of a vectorised law: its N = 1 case (STYLE 14).

    `self.law` is a `BatchedController` with one row; `predict` hands it the observation as a batch of one and
    returns its row (unbatched or batched of one, as given), `reset` and `episode_start` restart it. `last_u`,
    `rng` and `jacobian_estimate` are the row's. A subclass sets `self.law` before calling `LawView.__init__`.
    """

    law: BatchedController

    def __init__(self, facts: EnvFacts, seed: int | None = None):
        self.facts = facts
        self._scale = facts.scale
        self._seed = seed
        self.name = self.law.name
        self.jacobian_kind = self.law.jacobian_kind
        self.uses_keys = self.law.uses_keys

    @property
    def rng(self) -> np.random.Generator:
        return self.law.rngs[0]

    @rng.setter
    def rng(self, value: np.random.Generator) -> None:
        self.law.rngs[0] = value

    @property
    def last_u(self) -> np.ndarray:
        return self.law.last_u[0]

    @last_u.setter
    def last_u(self, value: np.ndarray) -> None:
        self.law.last_u[0] = value

    @property
    def _initialised(self) -> bool:
        return bool(self.law.initialised[0])

    @_initialised.setter
    def _initialised(self, value: bool) -> None:
        self.law.initialised[0] = value

    @property
    def jacobian_estimate(self) -> np.ndarray | None:
        return self.law.jacobian_estimate_row(0)

    def reset(self, obs: dict, info: dict | None = None, *, seed: int | None = None) -> None:
        if seed is not None:
            self.law.rngs[0] = np.random.default_rng(seed)
        self.law._start(_ROW0, _single_rows(obs, self.law.uses_keys)[0])

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        obs, batched = _single_rows(observation, self.law.uses_keys)
        action = self.law.step(obs, _START if first_flag(episode_start) else None)
        return (action if batched else action[0]), state

    def _start(self, single: dict) -> None:
        self.law._start(_ROW0, _single_rows(single, self.law.uses_keys)[0])


def _single_rows(observation: dict, keys: tuple[str, ...]) -> tuple[dict[str, np.ndarray], bool]:
    """A single env's observation (unbatched, or batched with one row) as (1, k) float64 arrays of `keys`, and
    whether it came batched; a longer batch raises as `policies.base.unbatch` does."""
    if not isinstance(observation, dict):
        raise ValueError(f"observation must be a dict (the env's Dict observation), got {type(observation).__name__}")
    first = np.asarray(observation.get("ee_pos", next(iter(observation.values()))))
    batched = first.ndim == 2
    if batched and first.shape[0] != 1:
        unbatch(observation, keys)  # raises, naming the fix
    return obs_rows(observation, keys), batched


def is_native_vector_env(venv: Any) -> bool:
    """Whether `venv` is mobman's native vector env (robot i's true robot is `venv.true_params(i)`)."""
    return is_vector_env(venv) and callable(getattr(venv, "true_params", None)) and hasattr(venv, "dt")


def sync_envs(venv: Any) -> list[Any] | None:
    """The single envs of a `SyncVectorEnv` (mobman's physics-mode and random-arm vector envs), else None."""
    if is_native_vector_env(venv):
        return None
    envs = getattr(venv, "envs", None)
    return list(envs) if isinstance(envs, (list, tuple)) and len(envs) == venv.num_envs else None


def check_vector_env(venv: Any) -> None:
    """Refuse a vector env whose robots a batched policy cannot see: neither mobman's native vector env nor a
    vector env holding its single envs (`SyncVectorEnv`); e.g. an `AsyncVectorEnv`, whose envs live in other
    processes."""
    if not is_vector_env(venv):
        raise TypeError(f"expected a gymnasium vector env (num_envs, single_observation_space), got {venv!r}")
    if not is_native_vector_env(venv) and sync_envs(venv) is None:
        raise TypeError(
            f"policies.make cannot build a batched policy for a {type(venv).__name__}: it needs mobman's native "
            f"vector env or a SyncVectorEnv of mobman envs (whose robots it can read); make it with "
            f'gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point") or vectorization_mode="sync"'
        )


def info_rows(info: Any, rows: slice) -> dict | None:
    """The rows `rows` of a vector env's info (Gymnasium's dict of per-row arrays and `_key` masks, nested dicts
    included), as the info of a vector env of those rows; None for no info. `StackedPolicy` hands each part its
    rows' reset info (the path a controller with preview reads, `policies.laws.mpc`)."""
    if not isinstance(info, dict):
        return None
    out: dict[str, Any] = {}
    for key, value in info.items():
        if isinstance(value, dict):
            out[key] = info_rows(value, rows)
        elif isinstance(value, np.ndarray) and value.ndim >= 1:
            out[key] = value[rows]
        else:
            out[key] = value
    return out


def _row(observation: dict, i: int) -> dict:
    return {k: v[i] for k, v in observation.items()}

"""One rollout loop for every policy and every env: controllers, SB3 agents and the user's own objects, one env
or N robots of a vector env.

```
obs, info = envs.reset(seed=[S_0, ..., S_N-1])          # robot i: the single env's episode of seed S_i
policy.reset(obs, info, seed=[policy_seed(S_i) ...])    # if the object has `reset` (SB3-only objects do not)
repeat: actions, state = policy.predict(obs, state)      # timed with perf_counter, whole call
        obs, reward, terminated, truncated, info = envs.step(actions)
```

`run_episodes` is the loop. `rollout(env, policy, seed)` runs it on one env and the policy object as it is (a
batch of one: the env's own observation dict goes to `predict`, the action comes back as the env takes it), which
is how physics episodes, SB3 agents, `module:attr` specs and the user's objects run; `rollout_batch(venv, policy,
seeds)` runs it on a vector env with a batched policy (`policies.make(spec, venv)`), which is how `eval` runs the
kinematic episodes of built-in controllers. Both return per robot the same (record, arrays), the same code
making them: the records of a batched episode equal the single path's, timing fields (`wall_s`,
`predict_us_*`) and `pid` excepted (`tests/test_batch_rollout.py`), because robot i of the vector env is the single
env and row i of a batched policy the single policy, by construction (`mobman_env.engine`, `policies.kernels.shared`).

Per step and robot it records (SI units, float64 unless noted):

| array | shape | meaning |
|---|---|---|
| t | (n+1,) | time of each sample, s (t_0 = 0 is the state after reset) |
| r_d | (n+1, 3) | desired position r_d(t) (`obs["target_pos"]`, float32 precision), m |
| r_a | (n+1, 3) | true end-effector position (`info["ee_pos_true"]`, noise-free), m |
| p_c | (n+1, 2) | arm mount position p_c as observed (`obs["arm_base_pos"]`), m |
| error | (n+1,) | tracking error `info["tracking_error"]` (noise-free), m |
| action | (n, m) | normalised action the env applied (after clipping to [-1, 1]) |
| predict_us | (n,) | wall time of each `predict` call (batched: the call's time / robots served), microseconds |
| q | (n+1, n_arm) | the arm's joint angles as observed (`obs["joint_pos"]`, float32 precision), rad |

Policies that expose a Jacobian estimate (a `jacobian_kind` other than None and `jacobian_estimate`: see
`policies.base.ControllerPolicy`) get two more per-step arrays, computed here from the true robot (the env's
`true_params` and `mobman_env.engine.jacobians`, the env's own chain, at the joint angles and heading of the
observation the policy was given), never by the policy; nan on steps without an estimate (during a probe):

| array | shape | meaning |
|---|---|---|
| jacobian_rel_error | (n,) | ||J_hat - J||_F / ||J||_F after each `predict` |
| jacobian_angle_rad | (n,) | largest principal angle between the row spaces of J_hat and J, rad |

and the record gets their median and max (`JACOBIAN_KEYS`; None for policies without an estimate).

The policy's seed is `policies.base.policy_seed(S_i)`, derived from the episode seed by a documented rule so
that it reveals nothing the env drew (the true robot, the path, the noise); it never is the env's seed itself.

A crash anywhere in the call (env or policy) is caught: every record of the call gets `status: "failed"` and the
traceback, its metrics None, and the caller goes on (`eval.execution.batches` runs a failed batch's episodes
again one by one, so only the episodes that really fail are recorded failed).
"""

from __future__ import annotations

import os
import time
import traceback
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from eval import metrics as M
from eval.errors import EvalError
from policies.base import policy_seed

#: Keys of the per-step arrays one rollout returns (see the module docstring).
ARRAY_KEYS = ("t", "r_d", "r_a", "p_c", "error", "action", "predict_us", "q")

#: Per-step arrays recorded only for policies that expose `jacobian_estimate` (see the module docstring).
JACOBIAN_ARRAY_KEYS = ("jacobian_rel_error", "jacobian_angle_rad")

#: Per-episode Jacobian-estimate fields and every field of an episode record, in order: one table with per-field
#: flags, `eval.metrics.RECORD_FIELDS` (see eval/README.md, "results.json").
JACOBIAN_KEYS = M.JACOBIAN_KEYS
RECORD_KEYS = M.RECORD_KEYS

#: Env constructor arguments that the eval flags set (--dynamics, --model-error, --obs-noise); --env-kwargs may
#: not set them too.
FLAG_KWARGS = ("dynamics", "model_error", "obs_noise")


def make_env(
    env_id: str,
    dynamics: str | None = None,
    model_error: float | None = None,
    obs_noise: float | None = None,
    env_kwargs: dict | None = None,
    render_mode: str | None = None,
):
    """`gym.make(env_id, **kwargs)` with the eval flags (None: the env's default) and extra constructor kwargs."""
    import mobman_env  # noqa: F401  (registers the ids)

    kwargs = dict(env_kwargs or {})
    for name, value in (("dynamics", dynamics), ("model_error", model_error), ("obs_noise", obs_noise)):
        if value is not None:
            kwargs[name] = value
    if render_mode is not None:
        kwargs["render_mode"] = render_mode
    return gym.make(env_id, **kwargs)


def make_vector_env(
    env_id: str,
    num_envs: int,
    dynamics: str | None = None,
    model_error: float | None = None,
    obs_noise: float | None = None,
    env_kwargs: dict | None = None,
) -> Any:
    """`gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point", **kwargs)` with the eval flags
    (None: the env's default) and extra constructor kwargs, as `make_env` builds a single env. Kinematic mode
    gives the native `mobman_env.vector.WheeledPumaVectorEnv`."""
    import mobman_env  # noqa: F401  (registers the ids)

    kwargs = dict(env_kwargs or {})
    for name, value in (("dynamics", dynamics), ("model_error", model_error), ("obs_noise", obs_noise)):
        if value is not None:
            kwargs[name] = value
    return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def _metrics_none() -> dict[str, Any]:
    return {
        "max_error_m": None,
        "rms_error_m": None,
        "final_error_m": None,
        "steady_max_error_m": None,
        "steady_rms_error_m": None,
        "axis_max_error_m": None,
        "effort": None,
        "peak_joint_speed": None,
        "peak_wheel_speed": None,
        "cmd_accel_rms": None,
        "cmd_jerk_rms": None,
        "limit_margin_min": None,
        "converge_time_s": None,
        "success": False,
        "clean_success": False,
    }


def _empty_record(base: Any, seed: int, meta: dict | None) -> dict[str, Any]:
    """The record of an episode before it runs: the caller's fields, the condition, every metric None."""
    rec: dict[str, Any] = dict(meta or {})
    rec.update(
        {
            "seed": int(seed),
            "robot": getattr(base, "robot", None),
            "knowledge": None,
            "artefacts": None,
            "dynamics": getattr(base, "dynamics", None),
            "model_error": getattr(base, "model_error", None),
            "obs_noise": getattr(base, "obs_noise", None),
            "control_freq": getattr(base, "control_freq", None),
            "path": None,
            "start": None,
            "true_params_hash": None,
            "feasible": None,
            "feasibility_peak": None,
            "status": "ok",
            "error": None,
        }
    )
    rec.setdefault("condition", None)
    rec.update(_metrics_none())
    rec.update(
        {
            "n_steps": 0,
            "joint_limit_hits": 0,
            "n_clipped": 0,
            "tipped_over": False,
            "terminated": False,
            "predict_us_median": None,
            "predict_us_p99": None,
            **dict.fromkeys(JACOBIAN_KEYS),
        }
    )
    return rec


def _finish(rec: dict, arrays: dict, info: dict, k: int, base: Any, tolerance: float, settle_time: float, jac) -> dict:
    """Fill `rec` with the episode's counters and metrics (and the Jacobian-estimate quality); returns the
    arrays, with the Jacobian-estimate arrays added."""
    rec["n_steps"] = k
    rec["joint_limit_hits"] = int(info.get("joint_limit_hits", 0))
    rec["n_clipped"] = int(info.get("n_clipped", 0))
    rec["tipped_over"] = bool(info.get("tipped_over", False))
    rec.update(
        M.episode_metrics(
            arrays["r_d"],
            arrays["r_a"],
            arrays["action"],
            float(base.dt),
            np.asarray(base.action_scale, float),
            tolerance,
            tipped_over=rec["tipped_over"],
            err=arrays["error"],
            settle_time=settle_time,
            q=arrays["q"],
            limits=base.limits,
            limit_hits=rec["joint_limit_hits"],
        )
    )
    rec["predict_us_median"], rec["predict_us_p99"] = M.timing_stats(arrays["predict_us"])
    if jac is not None:
        quality = jac.finish(k)
        arrays.update(quality.pop("arrays"))
        rec.update(quality)
    return arrays


def _known_policies_text() -> str:
    try:
        import policies

        known = getattr(policies, "KNOWN_POLICIES", {})
        names = ", ".join(known) if known else "see the policies package"
    except Exception as exc:  # pragma: no cover - policies broken: say so
        names = f"(the policies package failed to import: {exc})"
    return f"known: {names}; also sb3:PATH and module:attr"


def make_policy(spec: str, env, seed: int | None):
    """`policies.make(spec, env, seed)`; errors become `EvalError` naming the spec (and, from the registry, the
    known names when the name is unknown)."""
    try:
        import policies
    except Exception as exc:
        raise EvalError(f"cannot import the policies package to build {spec!r}: {exc}") from None
    try:
        return policies.make(spec, env, seed=seed)
    except FileNotFoundError as exc:
        raise EvalError(f"policy {spec!r}: model file not found: {exc}") from None
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # SystemExit from a user's constructor too: named, not a silent exit
        # no list of the known policies here: the registry adds it where the name is the problem; an env the
        # policy cannot run on or a bad option is not about the name, and a list there only hides the reason
        msg = str(exc) if isinstance(exc, Exception) else f"{type(exc).__name__}({exc}) raised while building it"
        raise EvalError(f"policy {spec!r}: {msg}") from None


class _JacobianRecorder:
    """Per-step Jacobian-estimate quality of a policy exposing `jacobian_estimate` (see the module docstring).

    Per step it stores the policy's estimate and the state (arm angles, heading) of the observation the policy
    acted on, and the true robot of that step; at the end the true robot's Jacobian of the same kind is computed
    at all those states in one call of `mobman_env.engine.jacobians` (the env's own chain) and the metrics batched
    (`eval.metrics.jacobian_relative_error`, `eval.metrics.row_space_angle`)."""

    def __init__(self, policy: Any, base: Any, n: int):
        kind = getattr(policy, "jacobian_kind", None)
        if kind not in ("paper", "whole_body"):
            raise ValueError(
                f"{type(policy).__name__} exposes jacobian_estimate but its jacobian_kind is {kind!r}; set it to "
                f"'paper' or 'whole_body' (see policies.base.ControllerPolicy.jacobian_estimate)"
            )
        self.kind = kind
        self._policy = policy
        self._base = base
        n_act = len(np.asarray(base.action_scale))
        self._J_hat = np.full((n, 3, n_act), np.nan)
        self._q = np.zeros((n, n_act))
        self._yaw = np.zeros(n)
        self._params: list[Any] = [None] * n  # the true robot at each step (it changes under wear drift)

    def record(self, k: int, joint_pos: np.ndarray, base_yaw: np.ndarray) -> None:
        J_hat = self._policy.jacobian_estimate
        if J_hat is None:
            return
        J_hat = np.asarray(J_hat, float)
        if J_hat.shape != self._J_hat.shape[1:]:
            raise ValueError(
                f"{type(self._policy).__name__}.jacobian_estimate has shape {J_hat.shape}, expected "
                f"{self._J_hat.shape[1:]} (3 x actuators)"
            )
        self._J_hat[k] = J_hat
        self._q[k] = joint_pos
        self._yaw[k] = base_yaw[0]
        self._params[k] = self._base.true_params

    def finish(self, k: int) -> dict[str, Any]:
        from mobman_env import engine

        J_hat = self._J_hat[:k]
        have = np.flatnonzero(np.isfinite(J_hat).all(axis=(1, 2)))
        rel = np.full(k, np.nan)
        angle = np.full(k, np.nan)
        if have.size:
            robots: dict[int, int] = {}  # the distinct true robots of the steps, packed once each
            index = np.array([robots.setdefault(id(self._params[s]), len(robots)) for s in have.tolist()])
            first = {v: have[j] for j, v in reversed(list(enumerate(index.tolist())))}
            arm, prm = engine.packed([self._params[first[r]] for r in range(len(robots))])
            J = np.empty((have.size, *J_hat.shape[1:]))
            engine.jacobians(arm, prm, index, self._q[have], self._yaw[have], self.kind == "whole_body", J)
            rel[have] = M.jacobian_relative_error(J_hat[have], J)
            angle[have] = M.row_space_angle(J_hat[have], J)
        return {
            "jacobian_kind": self.kind,
            **M.jacobian_quality(rel, angle),
            "arrays": {"jacobian_rel_error": rel, "jacobian_angle_rad": angle},
        }


# --- the loop -------------------------------------------------------------------------------------------------
class _RobotBase:
    """What the records read of robot i's env (`env.unwrapped` of a single env; robot i of a vector env): the
    condition, dt, the action scale and the door to its true robot."""

    def __init__(self, env: Any, i: int | None = None):
        self._env, self._i = env, i
        tpl = env if i is None else getattr(env, "_template", env)
        self.dt = float(tpl.dt)
        self.action_scale = np.asarray(tpl.action_scale, dtype=float)
        self.n_arm = len(self.action_scale) - 2
        for name in ("dynamics", "model_error", "obs_noise", "control_freq", "robot"):
            setattr(self, name, getattr(tpl, name, None))

    @property
    def true_params(self) -> Any:
        return self._env.true_params if self._i is None else self._env.true_params(self._i)

    @property
    def limits(self) -> tuple[Any, Any] | None:
        """The arm's joint limits (lower, upper) of this episode's robot (the nominal one's: wear leaves limits
        alone), rad; None for an env without mobman's `nominal_params`."""
        of = getattr(self._env, "nominal_params_of", None)
        p = of(self._i) if (of is not None and self._i is not None) else getattr(self._env, "nominal_params", None)
        return None if p is None else (p.joint_lower, p.joint_upper)


class _OneEnv:
    """A single env seen as a batch of one by the loop: the batched observation and info are views of the env's
    own (the policy gets the env's observation dict itself, unbatched)."""

    num_envs = 1

    def __init__(self, env: Any):
        self.env = env
        self.obs: dict = {}
        self.info: dict = {}

    def reset(self, seed: list[int]) -> tuple[dict, dict]:
        self.obs, self.info = self.env.reset(seed=seed[0])
        return _batch1(self.obs), _batch_info(self.info)

    def step(self, actions: np.ndarray) -> tuple[dict, Any, np.ndarray, np.ndarray, dict]:
        self.obs, reward, terminated, truncated, info = self.env.step(actions[0])
        return _batch1(self.obs), reward, np.array([terminated]), np.array([truncated]), _batch_info(info)


def _batch1(obs: dict) -> dict:
    return {k: v[None] for k, v in obs.items()}


def _batch_info(info: dict) -> dict:
    """A single env's info as the loop reads a vector env's: each entry an array of one row."""
    out: dict[str, Any] = {k: np.array([info.get(k, 0)]) for k in ("n_clipped", "joint_limit_hits")}
    out["ee_pos_true"] = np.asarray(info["ee_pos_true"], dtype=float)[None]
    out["tracking_error"] = np.array([info["tracking_error"]])
    out["tipped_over"] = np.array([bool(info.get("tipped_over", False))])
    if "task" in info:
        task = info["task"]
        out["task"] = {"n_steps": np.array([task["n_steps"]]), "start": [task["start"]], "path": [task["path"]]}
        out["true_params_hash"] = [info["true_params_hash"]]
    return out


class _OnePolicy:
    """The user's (or SB3's, or a built-in's) single-env policy object driven by the loop: it gets the env's own
    observation dict and may keep a recurrent `state`; its action comes back as a row of a batch of one."""

    def __init__(self, policy: Any, env: _OneEnv):
        self.policy, self._env = policy, env
        self.rows = [policy]
        self._state: Any = None

    def reset(self, obs: dict, info: dict, seed: list[int]) -> None:
        reset = getattr(self.policy, "reset", None)
        self._state = None
        if reset is not None:
            reset(self._env.obs, self._env.info, seed=seed[0])

    def predict(self, obs: dict, episode_start: Any = None, deterministic: bool = True) -> tuple[np.ndarray, Any]:
        action, self._state = self.policy.predict(
            self._env.obs, state=self._state, episode_start=None, deterministic=True
        )
        a = np.asarray(action, dtype=np.float32)
        return (a if a.ndim == 2 else a[None]), self._state


def rollout(
    env: Any,
    policy: Any,
    seed: int,
    *,
    tolerance: float = M.DEFAULT_TOLERANCE,
    settle_time: float = M.DEFAULT_SETTLE_TIME,
    meta: dict | None = None,
    on_step: Callable[[int], None] | None = None,
) -> tuple[dict, dict | None]:
    """Run one episode of `policy` (any object with SB3's `predict`; `reset` if it has one) on `env` from
    `env.reset(seed=seed)`: the loop's batch of one.

    Returns (record, arrays): the episode record of the `results.json` schema (without the fields only the
    caller knows, which it passes in `meta`: env, policy, episode) and the per-step arrays (None if the episode
    failed before its first step). `on_step(k)` is called after the reset (k = 0) and after each step k (used
    to grab video frames). `settle_time` (s) starts the window of the steady-state errors."""
    envs = _OneEnv(env)
    one = _OnePolicy(policy, envs)
    base = _RobotBase(env.unwrapped)
    return run_episodes(envs, one, [int(seed)], [base], [policy_seed(seed)], tolerance, settle_time, [meta], on_step)[0]


def rollout_batch(
    venv: Any,
    policy: Any,
    seed: int | Sequence[int],
    *,
    tolerance: float = M.DEFAULT_TOLERANCE,
    settle_time: float = M.DEFAULT_SETTLE_TIME,
    meta: dict | Sequence[dict] | None = None,
) -> list[tuple[dict, dict | None]]:
    """Run the N episodes of seeds `seed` .. `seed + N - 1` (or the N seeds of the list `seed`, in any order) of
    `policy` (a `policies.batched.BatchedPolicy` for `venv`) on the vector env `venv`; returns each robot's (record,
    arrays) as `rollout` returns them for that seed and the same policy spec. `meta`: the caller's record fields,
    one dict for all or one per robot."""
    n = venv.num_envs
    if isinstance(seed, (int, np.integer)):
        seeds = [int(seed) + i for i in range(n)]
        policy_seeds: Any = int(seed)  # the batched policy derives policy_seed(S + i) itself
    else:
        seeds = [int(s) for s in seed]
        policy_seeds = [policy_seed(s) for s in seeds]
    metas = list(meta) if isinstance(meta, Sequence) else [meta] * n
    if len(seeds) != n or len(metas) != n:
        raise ValueError(
            f"rollout_batch on {n} robots needs one seed (or a list of {n}) and one meta dict (or a list of {n}), "
            f"got {len(seeds)} seeds and {len(metas)} meta dicts"
        )
    bases = [_RobotBase(venv.unwrapped, i) for i in range(n)]
    return run_episodes(_VectorEnv(venv), policy, seeds, bases, policy_seeds, tolerance, settle_time, metas, None)


class _VectorEnv:
    """A vector env as the loop drives it: reset with a list of seeds."""

    def __init__(self, venv: Any):
        self.venv, self.num_envs = venv, venv.num_envs

    def reset(self, seed: list[int]) -> tuple[dict, dict]:
        return self.venv.reset(seed=seed)

    def step(self, actions: np.ndarray) -> tuple:
        return self.venv.step(actions)


def run_episodes(
    envs: Any,
    policy: Any,
    seeds: list[int],
    bases: list[_RobotBase],
    policy_seeds: Any,
    tolerance: float,
    settle_time: float,
    metas: Sequence[dict | None],
    on_step: Callable[[int], None] | None,
) -> list[tuple[dict, dict | None]]:
    """The loop (see the module docstring): N episodes of `envs` (N = `envs.num_envs`, a vector env or `_OneEnv`)
    under `policy` (batched; `_OnePolicy` for one env), robot i from seed `seeds[i]`; returns each robot's
    (record, arrays). `policy_seeds` is what `policy.reset` gets (the vector reset seed, or the list of the
    robots' policy seeds)."""
    n = envs.num_envs
    recs = [_empty_record(bases[i], seeds[i], metas[i]) for i in range(n)]
    wall0 = time.perf_counter()
    steps_run = np.zeros(n, dtype=int)
    arr: dict[str, np.ndarray] = {}  # the per-step arrays of all robots, step-major (filled by _begin)
    k = [0]  # the steps taken (a failure records its arrays up to here)
    try:
        obs, info, n_steps = _begin(envs, seeds, bases, recs, arr)
        reset = getattr(policy, "reset", None)
        if reset is not None:
            reset(obs, info, seed=policy_seeds)
        rows = getattr(policy, "rows", [policy] * n)
        _describe_policies(recs, rows)
        jacs = [
            _JacobianRecorder(rows[i], bases[i], int(n_steps[i]))
            if getattr(rows[i], "jacobian_kind", None) is not None
            else None
            for i in range(n)
        ]
        if on_step is not None:
            on_step(0)
        _loop(envs, policy, obs, n_steps, arr, recs, bases, jacs, steps_run, k, tolerance, settle_time, on_step)
        out = [(rec, rec.pop("_arrays")) for rec in recs]
    except KeyboardInterrupt:
        raise
    except BaseException:  # SystemExit from a user's policy too: a failed episode, not a stopped evaluation
        tb = traceback.format_exc()
        out = []
        for i, rec in enumerate(recs):
            rec.pop("_arrays", None)
            done = int(steps_run[i]) or k[0]
            rec.update(status="failed", error=tb, n_steps=done, **_metrics_none())
            out.append((rec, _arrays(arr, i, done, bases[i].dt) if arr else None))
    wall = (time.perf_counter() - wall0) / n
    for rec, _ in out:
        rec["wall_s"] = wall
        rec["pid"] = os.getpid()
    return out


def _begin(
    envs: Any, seeds: list[int], bases: list[_RobotBase], recs: list[dict], arr: dict[str, np.ndarray]
) -> tuple[Any, dict, np.ndarray]:
    """Reset the robots, allocate `arr` (step-major per-step arrays) with step 0 observed, and fill each record's
    path, start, robot hash and feasibility. Returns (obs, info, each robot's number of steps)."""
    n = envs.num_envs
    obs, info = envs.reset(seed=seeds)
    n_steps = np.asarray(info["task"]["n_steps"], dtype=int)
    m = int(n_steps.max())
    n_act = len(bases[0].action_scale)
    arr.update(
        r_d=np.empty((m + 1, n, 3)),
        r_a=np.empty((m + 1, n, 3)),
        p_c=np.empty((m + 1, n, 2)),
        error=np.empty((m + 1, n)),
        action=np.empty((m, n, n_act)),
        predict_us=np.empty((m, n)),
        q=np.empty((m + 1, n, n_act - 2)),
    )
    _observe(arr, 0, obs, info)
    task = info["task"]
    for i, (rec, (feasible, peak)) in enumerate(zip(recs, _feasibility(envs, n), strict=True)):
        rec.update(
            path=_path(task["path"], i),
            start=list(task["start"][i]),
            true_params_hash=info["true_params_hash"][i],
            feasible=feasible,
            feasibility_peak=peak,
        )
    return obs, info, n_steps


def _loop(
    envs: Any,
    policy: Any,
    obs: Any,
    n_steps: np.ndarray,
    arr: dict[str, np.ndarray],
    recs: list[dict],
    bases: list[_RobotBase],
    jacs: list[_JacobianRecorder | None],
    steps_run: np.ndarray,
    k: list[int],
    tolerance: float,
    settle_time: float,
    on_step: Callable[[int], None] | None,
) -> None:
    """Step every robot until its episode ends, timing each predict; an ended robot's record is finished there
    (its arrays kept in `rec["_arrays"]`). k[0] counts the steps taken."""
    n = envs.num_envs
    watched = [(i, jac) for i, jac in enumerate(jacs) if jac is not None]
    running = np.ones(n, dtype=bool)
    clock = time.perf_counter
    while running.any():
        t0 = clock()
        actions, _ = policy.predict(obs, episode_start=None, deterministic=True)
        row_us = getattr(policy, "row_us", None)  # a StackedPolicy times each of its parts
        arr["predict_us"][k[0]] = (clock() - t0) * 1e6 / running.sum() if row_us is None else row_us
        act = np.asarray(actions, dtype=np.float32)
        for i, jac in watched:
            if running[i]:
                jac.record(k[0], obs["joint_pos"][i], obs["base_yaw"][i])
        obs, _, term, trunc, info = envs.step(act)
        arr["action"][k[0]] = np.clip(act, -1.0, 1.0)
        k[0] += 1
        step = k[0]
        _observe(arr, step, obs, info)
        if on_step is not None:
            on_step(step)
        ended = running & (term | trunc | (step >= n_steps))
        for i in np.flatnonzero(ended).tolist():
            running[i] = False
            steps_run[i] = step
            arrays = _arrays(arr, i, step, bases[i].dt)
            recs[i]["_arrays"] = _finish(
                recs[i], arrays, _row_info(info, i), step, bases[i], tolerance, settle_time, jacs[i]
            )
            recs[i]["terminated"] = bool(term[i])


def _feasibility(envs: Any, n: int) -> list[tuple[bool | None, float | None]]:
    """(feasible, peak speed ratio) of each robot's episode just reset (`mobman_env.feasibility`: the path within
    the true robot's speed limits with `FEASIBILITY_MARGIN`); (None, None) for an env without mobman's engine
    batch (another package's env, a `SyncVectorEnv` fallback)."""
    env = envs.env if isinstance(envs, _OneEnv) else envs.venv
    batch = getattr(getattr(env, "unwrapped", None), "_batch", None)
    if batch is None or getattr(batch, "num", n) != n:
        return [(None, None)] * n
    from mobman_env.feasibility import FEASIBILITY_MARGIN, check_rows

    return [(bool(c.peak_ratio <= 1.0 - FEASIBILITY_MARGIN), c.peak_ratio) for c in check_rows(batch, np.arange(n))]


def _describe_policies(recs: list[dict], rows: Sequence[Any]) -> None:
    """Each record's `knowledge` (`policies.knowledge_of` its row's policy: none, structure, nominal, true or
    unknown) and `artefacts` (the files the policy loaded, with their SHA-256: an SB3 agent's; None for a
    controller)."""
    from policies import knowledge_of

    known: dict[Any, str] = {}
    for rec, row in zip(recs, rows):
        spec = getattr(row, "spec", None)
        key = spec if isinstance(spec, str) and getattr(row, "knowledge", None) is None else id(row)
        if key not in known:
            try:
                known[key] = knowledge_of(row)
            except Exception:  # a user's object that declares a value knowledge_of refuses: say so in the record
                known[key] = "unknown"
        rec["knowledge"] = known[key]
        artefacts = getattr(row, "artefacts", None)
        rec["artefacts"] = None if artefacts is None else [dict(a) for a in artefacts]


def _path(spec: Any, i: int) -> dict:
    """Row i of the batched `task["path"]` info (a nested dict of arrays, or a list of spec dicts for one env)
    as the single env's spec dict."""
    if isinstance(spec, list):
        return spec[i]
    row = {}
    for key, value in spec.items():
        if key.startswith("_") or not spec["_" + key][i]:
            continue
        v = value[i]
        row[key] = v.item() if isinstance(v, np.generic) else v
    return row


def _observe(arr: dict, k: int, obs: dict, info: dict) -> None:
    """The state after step k of every robot (k = 0: after the reset)."""
    arr["r_d"][k], arr["r_a"][k] = obs["target_pos"], info["ee_pos_true"]
    arr["p_c"][k], arr["error"][k] = obs["arm_base_pos"], info["tracking_error"]
    arr["q"][k] = obs["joint_pos"][:, : arr["q"].shape[2]]


def _row_info(info: dict, i: int) -> dict:
    return {
        "ee_pos_true": info["ee_pos_true"][i],
        "tracking_error": float(info["tracking_error"][i]),
        "joint_limit_hits": int(info["joint_limit_hits"][i]),
        "n_clipped": int(info["n_clipped"][i]),
        "tipped_over": bool(info["tipped_over"][i]) if "tipped_over" in info else False,
    }


def _arrays(arr: dict, i: int, k: int, dt: float) -> dict[str, np.ndarray]:
    """Robot i's arrays of its first k steps, contiguous (so the metrics reduce them in the same order whatever
    the batch)."""
    out = {"t": np.arange(k + 1) * dt}
    for key, value in arr.items():
        out[key] = np.ascontiguousarray(value[: k + (0 if key in ("action", "predict_us") else 1), i])
    return out

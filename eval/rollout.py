"""One rollout loop for every policy: controllers, SB3 agents and the user's own objects alike.

```
obs, info = env.reset(seed=S + k)
policy.reset(obs, info, seed=policy_seed(S + k))   # if the object has `reset` (SB3-only objects do not)
repeat: action, state = policy.predict(obs, state)   # timed with perf_counter, whole call
        obs, reward, terminated, truncated, info = env.step(action)
```

Per step it records (SI units, float64 unless noted):

| array | shape | meaning |
|---|---|---|
| t | (n+1,) | time of each sample, s (t_0 = 0 is the state after reset) |
| r_d | (n+1, 3) | desired position r_d(t) (`obs["target_pos"]`, float32 precision), m |
| r_a | (n+1, 3) | true end-effector position (`info["ee_pos_true"]`, noise-free), m |
| p_c | (n+1, 2) | arm mount position p_c as observed (`obs["arm_base_pos"]`), m |
| error | (n+1,) | tracking error `info["tracking_error"]` (noise-free), m |
| action | (n, 8) | normalised action the env applied (after clipping to [-1, 1]) |
| predict_us | (n,) | wall time of each `predict` call, microseconds |

Policies that expose a Jacobian estimate (a `jacobian_kind` other than None and `jacobian_estimate`: see
`policies.base.ControllerPolicy`) get two more per-step arrays, computed here from the true robot
(`env.unwrapped.true_params` and `mobman_env.kinematics`, at the joint angles and heading of the observation the
policy was given), never by the policy; nan on steps without an estimate (during a probe):

| array | shape | meaning |
|---|---|---|
| jacobian_rel_error | (n,) | ||J_hat - J||_F / ||J||_F after each `predict` |
| jacobian_angle_rad | (n,) | largest principal angle between the row spaces of J_hat and J, rad |

and the record gets their median and max (`JACOBIAN_KEYS`; None for policies without an estimate).

The policy's seed is `policies.base.policy_seed(S + k)`, derived from the episode seed by a documented rule so
that it reveals nothing the env drew (the true robot, the path, the noise); it never is the env's seed itself.

A crash anywhere in the episode (env or policy) is caught: the record gets `status: "failed"` and the
traceback, its metrics are None, and the caller goes on with the next episode.
"""

from __future__ import annotations

import itertools
import os
import time
import traceback
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from eval import metrics as M
from eval.errors import EvalError
from policies.base import policy_seed

#: Keys of the per-step arrays one rollout returns (see the module docstring).
ARRAY_KEYS = ("t", "r_d", "r_a", "p_c", "error", "action", "predict_us")

#: Per-step arrays recorded only for policies that expose `jacobian_estimate` (see the module docstring).
JACOBIAN_ARRAY_KEYS = ("jacobian_rel_error", "jacobian_angle_rad")

#: Per-episode Jacobian-estimate fields of a record (`eval.metrics.jacobian_quality`); None without an estimate.
JACOBIAN_KEYS = (
    "jacobian_kind",
    "jacobian_rel_error_median",
    "jacobian_rel_error_max",
    "jacobian_angle_median_rad",
    "jacobian_angle_max_rad",
)

#: Every field of an episode record, in order (see eval/README.md, "results.json").
RECORD_KEYS = (
    "env",
    "policy",
    "episode",
    "seed",
    "dynamics",
    "model_error",
    "obs_noise",
    "control_freq",
    "path",
    "start",
    "true_params_hash",
    "status",
    "error",
    "max_error_m",
    "rms_error_m",
    "final_error_m",
    "steady_max_error_m",
    "steady_rms_error_m",
    "axis_max_error_m",
    "effort",
    "peak_joint_speed",
    "peak_wheel_speed",
    "success",
    "n_steps",
    "joint_limit_hits",
    "n_clipped",
    "tipped_over",
    "terminated",
    "predict_us_median",
    "predict_us_p99",
    *JACOBIAN_KEYS,
    "wall_s",
    "pid",
)

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
        "success": False,
    }


def rollout(
    env,
    policy,
    seed: int,
    *,
    tolerance: float = M.DEFAULT_TOLERANCE,
    settle_time: float = M.DEFAULT_SETTLE_TIME,
    meta: dict | None = None,
    on_step: Callable[[int], None] | None = None,
) -> tuple[dict, dict | None]:
    """Run one episode of `policy` on `env` from `env.reset(seed=seed)`.

    Returns (record, arrays): the episode record of the `results.json` schema (without the fields only the
    caller knows, which it passes in `meta`: env, policy, episode) and the per-step arrays (None if the episode
    failed before its first step). `on_step(k)` is called after the reset (k = 0) and after each step k (used
    to grab video frames). `settle_time` (s) starts the window of the steady-state errors."""
    base = env.unwrapped
    rec = _empty_record(base, seed, meta)
    buf: _Buffers | None = None
    jac = None
    k = 0
    wall0 = time.perf_counter()
    try:
        obs, info = env.reset(seed=seed)
        task = info["task"]
        rec.update(path=task["path"], start=task["start"], true_params_hash=info["true_params_hash"])
        n = int(task["n_steps"])
        buf = _Buffers(n, float(base.dt), len(np.asarray(base.action_scale)))
        buf.observe(0, obs, info)
        reset = getattr(policy, "reset", None)
        if reset is not None:
            reset(obs, info, seed=policy_seed(seed))
        if getattr(policy, "jacobian_kind", None) is not None:
            jac = _JacobianRecorder(policy, base, n)
        if on_step is not None:
            on_step(0)
        k, info, rec["terminated"] = _run_steps(env, policy, obs, n, buf, jac, on_step)
        arrays: dict | None = _finish(rec, buf.arrays(k), info, k, base, tolerance, settle_time, jac)
    except KeyboardInterrupt:
        raise
    except BaseException:  # SystemExit from a user's policy too: a failed episode, not a stopped evaluation
        k = buf.k if buf is not None else 0
        rec["status"] = "failed"
        rec["error"] = traceback.format_exc()
        rec["n_steps"] = k
        rec.update(_metrics_none())
        arrays = buf.arrays(k) if buf is not None else None
    rec["wall_s"] = time.perf_counter() - wall0
    rec["pid"] = os.getpid()
    return rec, arrays


def _empty_record(base: Any, seed: int, meta: dict | None) -> dict[str, Any]:
    """The record of an episode before it runs: the caller's fields, the condition, every metric None."""
    rec: dict[str, Any] = dict(meta or {})
    rec.update(
        {
            "seed": int(seed),
            "dynamics": getattr(base, "dynamics", None),
            "model_error": getattr(base, "model_error", None),
            "obs_noise": getattr(base, "obs_noise", None),
            "control_freq": getattr(base, "control_freq", None),
            "path": None,
            "start": None,
            "true_params_hash": None,
            "status": "ok",
            "error": None,
        }
    )
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


class _Buffers:
    """The per-step arrays of one episode, allocated for its full length and cut to the steps that ran."""

    def __init__(self, n: int, dt: float, n_act: int):
        self.t = np.arange(n + 1) * dt
        self.r_d = np.empty((n + 1, 3))
        self.r_a = np.empty((n + 1, 3))
        self.p_c = np.empty((n + 1, 2))
        self.err = np.empty(n + 1)
        self.act = np.empty((n, n_act))
        self.us = np.empty(n)
        self.k = 0  # steps run so far: the index of the latest state observed

    def observe(self, k: int, obs: dict, info: dict) -> None:
        """The state after step k (k = 0: after the reset), from the observation and the noise-free info."""
        self.k = k
        self.r_d[k], self.r_a[k], self.p_c[k], self.err[k] = (
            obs["target_pos"],
            info["ee_pos_true"],
            obs["arm_base_pos"],
            info["tracking_error"],
        )

    def arrays(self, k: int) -> dict[str, np.ndarray]:
        """The arrays of the first k steps (states 0..k, actions and timings 0..k-1)."""
        return {
            "t": self.t[: k + 1],
            "r_d": self.r_d[: k + 1],
            "r_a": self.r_a[: k + 1],
            "p_c": self.p_c[: k + 1],
            "error": self.err[: k + 1],
            "action": self.act[:k],
            "predict_us": self.us[:k],
        }


def _run_steps(env, policy, obs: dict, n: int, buf: _Buffers, jac, on_step) -> tuple[int, dict, bool]:
    """Step until truncation, termination or n steps; returns (steps run, last info, terminated). Each
    `predict` call is timed whole; the action stored is the one the env applied (clipped to [-1, 1])."""
    predict = policy.predict
    clock = time.perf_counter
    n_act = buf.act.shape[1]
    state = None
    info: dict = {}
    k = 0
    while k < n:
        t0 = clock()
        action, state = predict(obs, state=state, episode_start=None, deterministic=True)
        buf.us[k] = (clock() - t0) * 1e6
        if jac is not None:
            jac.record(k, obs)
        a = np.asarray(action, dtype=np.float32)
        if a.shape == (1, n_act):  # a batch of one back from an SB3-style object
            a = a[0]
        obs, _, terminated, truncated, info = env.step(a)
        buf.act[k] = np.clip(a, -1.0, 1.0)
        k += 1
        buf.observe(k, obs, info)
        if on_step is not None:
            on_step(k)
        if terminated or truncated:
            return k, info, bool(terminated)
    return k, info, False


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
    """`policies.make(spec, env, seed)`; errors become `EvalError` naming the spec and the known names."""
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
        msg = str(exc) if isinstance(exc, Exception) else f"{type(exc).__name__}({exc}) raised while building it"
        if "known" not in msg:
            msg += f" ({_known_policies_text()})"
        raise EvalError(f"policy {spec!r}: {msg}") from None


class _JacobianRecorder:
    """Per-step Jacobian-estimate quality of a policy exposing `jacobian_estimate` (see the module docstring).

    Per step it stores the policy's estimate and the state (arm angles, heading) of the observation the policy
    acted on; at the end the true robot's Jacobian of the same kind is computed at all those states in one
    numpy pass (`mobman_env.vector_kinematics.robot_jacobians`, bit for bit the per-step
    `mobman_env.kinematics` function) and the metrics batched (`eval.metrics.jacobian_relative_error`,
    `eval.metrics.row_space_angle`)."""

    def __init__(self, policy: Any, base: Any, n: int):
        from mobman_env import kinematics as K

        kind = getattr(policy, "jacobian_kind", None)
        if kind not in ("paper", "whole_body"):
            raise ValueError(
                f"{type(policy).__name__} exposes jacobian_estimate but its jacobian_kind is {kind!r}; set it to "
                f"'paper' or 'whole_body' (see policies.base.ControllerPolicy.jacobian_estimate)"
            )
        self.kind = kind
        self._single = K.whole_body_jacobian if kind == "whole_body" else K.paper_jacobian
        self._policy = policy
        self._base = base
        n_act = len(np.asarray(base.action_scale))
        self._J_hat = np.full((n, 3, n_act), np.nan)
        self._q = np.zeros((n, n_act - 2))
        self._yaw = np.zeros(n)
        self._params: list[Any] = [None] * n  # the true robot at each step (it changes under wear drift)

    def record(self, k: int, obs: dict) -> None:
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
        self._q[k] = np.asarray(obs["joint_pos"], float)[:-2]  # the n arm angles (the last two are the wheels)
        self._yaw[k] = obs["base_yaw"][0]
        self._params[k] = self._base.true_params

    def finish(self, k: int) -> dict[str, Any]:
        from mobman_env.vector_kinematics import robot_jacobians

        J_hat = self._J_hat[:k]
        have = np.isfinite(J_hat).all(axis=(1, 2))
        rel = np.full(k, np.nan)
        angle = np.full(k, np.nan)
        if have.any():
            steps = np.flatnonzero(have).tolist()
            J = np.empty((len(steps),) + J_hat.shape[1:])
            start = 0  # runs of steps with the same true robot, one numpy pass each
            for _, group in itertools.groupby(steps, key=lambda step: id(self._params[step])):
                run = list(group)
                end = start + len(run)
                params = self._params[run[0]]
                if len(run) == 1:  # a robot that changes every step (wear drift): the cheaper single call
                    J[start] = self._single(params, self._q[run[0]], float(self._yaw[run[0]]))
                else:
                    J[start:end] = robot_jacobians(params, self._q[run], self._yaw[run], self.kind == "whole_body")
                start = end
            rel[have] = M.jacobian_relative_error(J_hat[have], J)
            angle[have] = M.row_space_angle(J_hat[have], J)
        return {
            "jacobian_kind": self.kind,
            **M.jacobian_quality(rel, angle),
            "arrays": {"jacobian_rel_error": rel, "jacobian_angle_rad": angle},
        }

"""Evaluations during and after training, through `eval` (its one rollout loop and its metrics).

* Periodic (`evaluate`): the live agent (`train.agent.Agent`), in this process, on the held-out development
  seeds, without writing files: `eval.rollout.rollout` per episode, `eval.metrics.aggregate` over them.
* Final (`final_evaluation`): `eval.run` on the saved run folder (`sb3:DIR/model.zip`, loaded by
  `policies.agents.sb3.SB3Policy` exactly as `mobman-eval run` loads it) and `zero`, with the benchmark's env settings
  (the learning-only env arguments dropped) on the reported seeds; its report goes to `DIR/final_eval/`, so
  the printed `mobman-eval run` command reproduces the same numbers.

Episode k uses `reset(seed=first_seed + k)`, as everywhere in the benchmark.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from eval.metrics import DEFAULT_TOLERANCE


def summarize(records: list[dict]) -> dict:
    """Median / worst RMS and max tracking error (m) and success rate of episode records (eval's schema)."""
    from eval import metrics as M

    agg = M.aggregate(records, group_keys=("policy",))[0]
    ok = [r for r in records if r.get("status") == "ok"]
    if not ok:
        raise RuntimeError("every evaluation episode failed: " + str(records[0].get("error")))
    return {
        "n": agg["n"],
        "n_failed": agg["n_failed"],
        "median_rms_error_m": agg["rms_error_m"]["median"],
        "max_rms_error_m": agg["rms_error_m"]["max"],
        "median_max_error_m": agg["max_error_m"]["median"],
        "max_max_error_m": agg["max_error_m"]["max"],
        "success_rate": agg["success_rate"],
    }


def evaluate(
    env_id: str, env_kwargs: dict, policy: Any, first_seed: int, episodes: int, tolerance: float, name: str = "agent"
) -> dict:
    """Roll `policy` out on seeds first_seed .. first_seed + episodes - 1 (in this process); the summary plus
    the per-episode records under "episodes"."""
    from eval.rollout import make_env, rollout

    env = make_env(env_id, env_kwargs=env_kwargs)
    bind = getattr(policy, "bind", None)
    if bind is not None:  # a residual agent builds its base controller for this env
        bind(env)
    try:
        records = [
            rollout(env, policy, first_seed + k, tolerance=tolerance, meta={"policy": name})[0] for k in range(episodes)
        ]
    finally:
        env.close()
    return {**summarize(records), "episodes": [_slim(r) for r in records]}


def _slim(rec: dict) -> dict:
    keys = ("seed", "status", "rms_error_m", "max_error_m", "final_error_m", "success", "n_steps", "terminated")
    return {k: rec.get(k) for k in keys}


def final_evaluation(
    env_id: str, eval_env_kwargs: dict, run_dir: Path, first_seed: int, episodes: int, tolerance: float
) -> dict:
    """`eval.run` on the saved agent (`agent`), the best one on the development seeds if saved (`best`) and
    `zero` (files in run_dir/final_eval); a summary per policy."""
    from eval import run as eval_run

    run_dir = Path(run_dir)
    agents = {"agent": run_dir / "model.zip"}
    if (run_dir / "best" / "model.zip").is_file():
        agents["best"] = run_dir / "best" / "model.zip"
    cfg = eval_config(
        env_id, eval_env_kwargs, list(agents.values()), run_dir / "final_eval", first_seed, episodes, tolerance
    )
    import contextlib
    import io
    import logging

    table = io.StringIO()
    with contextlib.redirect_stdout(table):  # eval prints its results table: into the run's log, not stdout
        result = eval_run(dataclasses.replace(cfg, progress=True))  # its progress bar: stderr, a line per 5 s off a TTY
    logging.getLogger("train").info("final evaluation results:\n%s", table.getvalue().rstrip())
    by_policy: dict[str, list[dict]] = {}
    for rec in result.episodes:
        by_policy.setdefault(rec["policy"], []).append(rec)
    names = dict(zip(cfg.policies, [*agents, "zero"]))
    out = {
        names[spec]: {**summarize(recs), "spec": spec, "episodes": [_slim(r) for r in recs]}
        for spec, recs in by_policy.items()
    }
    return {**out, "eval_out": str(cfg.out), "eval_config": cfg.to_dict(), "eval_command": eval_command(cfg)}


def eval_config(
    env_id: str, eval_env_kwargs: dict, models: list[Path], out: Path, first_seed: int, episodes: int, tolerance: float
):
    """The EvalConfig of `mobman-eval run` for these saved agents plus `zero`."""
    from eval import EvalConfig

    kw = dict(eval_env_kwargs)
    dynamics = kw.pop("dynamics", "physics")
    model_error = kw.pop("model_error", None)
    obs_noise = kw.pop("obs_noise", None)
    return EvalConfig(
        envs=(env_id,),
        policies=(*(f"sb3:{m}" for m in models), "zero"),
        episodes=episodes,
        seed=first_seed,
        out=str(out),
        overwrite=True,
        dynamics=(dynamics,),
        model_error=model_error,
        obs_noise=obs_noise,
        env_kwargs=kw,
        tolerance=tolerance,
        save_arrays="first",
        progress=False,
    )


def eval_command(cfg) -> str:
    """The `mobman-eval run` command line equivalent to an EvalConfig built by `eval_config`."""
    import json
    import shlex

    parts = ["mobman-eval", "run", "--env", cfg.envs[0]]
    for p in cfg.policies:
        parts += ["--policy", p]
    parts += ["--seeds", str(cfg.episodes), "--seed", str(cfg.seed), "--dynamics", cfg.dynamics[0]]
    if cfg.model_error is not None:
        parts += ["--model-error", repr(cfg.model_error)]
    if cfg.obs_noise is not None:
        parts += ["--obs-noise", repr(cfg.obs_noise)]
    if cfg.env_kwargs:
        parts += ["--env-kwargs", json.dumps(cfg.env_kwargs)]
    if cfg.tolerance != DEFAULT_TOLERANCE:
        parts += ["--tolerance", repr(cfg.tolerance)]
    return " ".join(shlex.quote(p) for p in parts)


class ZeroPolicy:
    """Stand-still reference for the learning curve (the benchmark's `zero` floor); the action has one entry per
    actuator, sized from the observation's `joint_pos` (n arm joints + 2 wheels), batched like it."""

    def reset(self, obs, info=None, *, seed=None):
        pass

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros(np.shape(observation["joint_pos"]), dtype=np.float32), state

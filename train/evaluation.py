"""Evaluations during and after training: tracking-error metrics of an agent on given seeds.

Episode k is run with `reset(seed=first_seed + k)`, as in `mobman-eval`, with the env's default settings for
everything the config does not name (the learning-only arguments are dropped), so the numbers compare with the
benchmark's.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np


def rollout_errors(env: gym.Env, policy: Any, seed: int) -> np.ndarray:
    """Run one episode with reset(seed=seed); return the noise-free tracking error after every step, m."""
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info, seed=seed)
    errors = []
    episode_start = True
    while True:
        action, _ = policy.predict(obs, episode_start=np.array([episode_start]), deterministic=True)
        episode_start = False
        obs, _, terminated, truncated, info = env.step(action)
        errors.append(info["tracking_error"])
        if terminated or truncated:
            return np.asarray(errors)


def episode_metrics(errors: np.ndarray, tolerance: float) -> dict:
    """RMS, max and final tracking error (m) and success (max <= tolerance) of one episode."""
    return {
        "rms_error_m": float(math.sqrt(float(np.mean(np.square(errors))))),
        "max_error_m": float(np.max(errors)),
        "final_error_m": float(errors[-1]),
        "success": bool(np.max(errors) <= tolerance),
        "n_steps": int(len(errors)),
    }


def evaluate(env_id: str, env_kwargs: dict, policy: Any, first_seed: int, episodes: int, tolerance: float) -> dict:
    """Per-episode metrics and their summary (median / max over episodes, success rate)."""
    env = gym.make(env_id, **env_kwargs)
    try:
        rows = [
            {"seed": first_seed + k, **episode_metrics(rollout_errors(env, policy, first_seed + k), tolerance)}
            for k in range(episodes)
        ]
    finally:
        env.close()
    return {"episodes": rows, **summarize(rows)}


def summarize(rows: list[dict]) -> dict:
    rms = np.array([r["rms_error_m"] for r in rows])
    mx = np.array([r["max_error_m"] for r in rows])
    return {
        "n": len(rows),
        "median_rms_error_m": float(np.median(rms)),
        "max_rms_error_m": float(np.max(rms)),
        "median_max_error_m": float(np.median(mx)),
        "max_max_error_m": float(np.max(mx)),
        "success_rate": float(np.mean([r["success"] for r in rows])),
    }


class ZeroPolicy:
    """Stand-still reference for the learning curve (the `zero` floor of the benchmark)."""

    def reset(self, obs, info=None, *, seed=None):
        pass

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros(8, dtype=np.float32), state

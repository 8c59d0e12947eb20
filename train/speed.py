"""`mobman-train speed`: how fast `mobman-train`'s default PPO recipe trains, learner included, beside the same SB3
settings on Gymnasium's MuJoCo `Reacher-v5` (measures, asserts nothing).

| figure | how |
|---|---|
| env-steps/s, mobman | `model.learn` of the default `TrainConfig` (PPO, `n_envs` robots of the native vector env through `SB3VecEnv`, the agent's view, the alive bonus, VecMonitor, VecNormalize) for `steps` env steps |
| env-steps/s, dev track | the same on `MobMan-DevTrack-v0` (three native vector envs, per-episode draws) |
| env-steps/s, Reacher-v5 | `model.learn` of PPO with the same hyperparameters, `n_envs` and VecNormalize on SB3's `DummyVecEnv` of `n_envs` `Reacher-v5` (MuJoCo, the `[bench]` extra) |

Each model is built once, then its `learn` is timed `repeats` times, the three interleaved (so a busy moment
of a shared machine hits all of them); the best repeat is reported, as CPU time of this process (torch runs
one thread) and wall time. The load average at the start and the core count are recorded. Writes
`train-speed.json` and `train-speed.md` into `--out`.
"""

from __future__ import annotations

import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

#: what is raced: label -> how its model is built
SUBJECTS = ("mobman", "dev-track", "Reacher-v5")


@dataclass(frozen=True)
class SpeedConfig:
    """`mobman-train speed`'s settings."""

    steps: int = 81_920
    """Env steps per timed `learn` (a whole number of the recipe's rollouts: 5 x 256 x 64)."""
    repeats: int = 3
    """Timed `learn` calls per subject, interleaved; the best is reported."""
    out: str = "runs/train-speed"
    """Folder of train-speed.json and train-speed.md."""


def _mobman_model(env_id: str) -> Any:
    from stable_baselines3.common.vec_env import VecMonitor

    from train.config import TrainConfig
    from train.run import _build_model, _wrap_normalize, make_vec_env

    config = TrainConfig(env_id=env_id, eval_freq=0, progress_bar=False)
    return config, _build_model(config, _wrap_normalize(config, VecMonitor(make_vec_env(config))), None)


def _reacher_model(config: Any) -> Any:
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor, VecNormalize

    from train import algos

    envs = DummyVecEnv([lambda: gym.make("Reacher-v5") for _ in range(config.num_envs)])
    venv = VecNormalize(VecMonitor(envs), gamma=float(config.resolved_hyperparams.get("gamma", 0.99)))
    kwargs = algos.build_kwargs("ppo", config.resolved_hyperparams, int(np.prod(venv.action_space.shape or (1,))))
    venv.seed(0)
    return PPO("MlpPolicy", venv, seed=0, device="cpu", **kwargs)


def _time_learn(model: Any, steps: int) -> tuple[float, float, int]:
    before = model.num_timesteps
    cpu0, wall0 = time.process_time(), time.perf_counter()
    model.learn(total_timesteps=steps, reset_num_timesteps=False, progress_bar=False)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    return cpu, wall, model.num_timesteps - before


def measure(config: SpeedConfig, progress: Any = print) -> dict:
    """Race the three subjects (module docstring); the results dict that `write` stores."""
    import stable_baselines3
    import torch

    torch.set_num_threads(1)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    recipe, mobman = _mobman_model("WheeledPuma-Circle-v0")
    models = {
        "mobman": mobman,
        "dev-track": _mobman_model("MobMan-DevTrack-v0")[1],
        "Reacher-v5": _reacher_model(recipe),
    }
    for model in models.values():  # the first rollout builds buffers and compiles nothing more afterwards
        model.learn(total_timesteps=1, reset_num_timesteps=False, progress_bar=False)
    best: dict[str, dict] = {}
    for r in range(config.repeats):
        for name, model in models.items():
            cpu, wall, steps = _time_learn(model, config.steps)
            progress(f"repeat {r + 1}/{config.repeats} {name}: {steps:,} steps, {steps / cpu:,.0f} steps/s of CPU")
            row = {
                "steps": steps,
                "cpu_s": cpu,
                "wall_s": wall,
                "steps_per_cpu_s": steps / cpu,
                "steps_per_s": steps / wall,
            }
            if name not in best or row["steps_per_cpu_s"] > best[name]["steps_per_cpu_s"]:
                best[name] = row
    ref = best["Reacher-v5"]["steps_per_cpu_s"]
    return {
        "what": "mobman-train's default PPO recipe, learner included (model.learn), best of interleaved repeats",
        "recipe": {"algo": "ppo", "n_envs": recipe.num_envs, "hyperparams": recipe.resolved_hyperparams},
        "steps_per_repeat": config.steps,
        "repeats": config.repeats,
        "results": {k: {**v, "ratio_to_reacher": v["steps_per_cpu_s"] / ref} for k, v in best.items()},
        "load_average_1min": load,
        "cores": os.cpu_count(),
        "torch_threads": 1,
        "versions": {
            "python": platform.python_version(),
            "torch": torch.__version__,
            "stable_baselines3": stable_baselines3.__version__,
        },
    }


def markdown(res: dict) -> str:
    """The results as a Markdown table (the source of the RL page's block)."""
    lines = [
        "| env | env-steps/s (CPU) | env-steps/s (wall) | vs Reacher-v5 |",
        "|---|---|---|---|",
    ]
    for name, row in res["results"].items():
        lines.append(
            f"| {name} | {row['steps_per_cpu_s']:,.0f} | {row['steps_per_s']:,.0f} | {row['ratio_to_reacher']:.2f}x |"
        )
    load = res["load_average_1min"]
    lines.append("")
    lines.append(
        f"PPO, {res['recipe']['n_envs']} envs, the default recipe for each; best of {res['repeats']} interleaved "
        f"repeats of {res['steps_per_repeat']:,} steps; {res['cores']} cores, load average "
        f"{'unknown' if load is None else f'{load:.2f}'} at the start; torch {res['versions']['torch']} on one thread."
    )
    return "\n".join(lines) + "\n"


def write(res: dict, out: str | Path) -> Path:
    from eval.output.files import atomic_write_json

    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_json(folder / "train-speed.json", res)
    (folder / "train-speed.md").write_text(markdown(res), encoding="utf-8")
    return folder

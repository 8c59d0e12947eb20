"""rl-baselines3-zoo trains on mobman from the shipped hyperparameter files, and `sb3:` evaluates what it saved.

`train/hyperparams/{ppo,sac}.yml` are in rl-zoo's format (env id -> hyperparameters, mobman's own wrappers as
`env_wrapper`). This runs `python -m rl_zoo3.train --gym-packages mobman_env` on each, cut to a few thousand
steps (the file's `n_timesteps` replaced; everything else as shipped), then `mobman-eval run --policy
sb3:<the zoo's run folder>` on one reported episode: the zoo's layout (`<ENV>.zip`, `<ENV>/vecnormalize.pkl`,
`config.yml`) must load and act.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ENV_ID = "WheeledPuma-Circle-v0"
#: steps per algorithm: one PPO rollout; SAC past its 2,000 warm-up steps (a few gradient steps)
STEPS = {"ppo": 2048, "sac": 2100}


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["ppo", "sac"])
def test_rl_zoo_trains_from_the_shipped_file_and_sb3_evaluates_its_folder(tmp_path, algo):
    pytest.importorskip("rl_zoo3")
    text = (ROOT / "train" / "hyperparams" / f"{algo}.yml").read_text()
    lines = [
        f"  n_timesteps: {STEPS[algo]}" if line.strip().startswith("n_timesteps:") else line
        for line in text.splitlines()
    ]
    conf = tmp_path / f"{algo}.yml"
    conf.write_text("\n".join(lines) + "\n")
    logs = tmp_path / "logs"
    cmd = [
        sys.executable, "-m", "rl_zoo3.train", "--algo", algo, "--env", ENV_ID, "--gym-packages", "mobman_env",
        "--conf-file", str(conf), "--env-kwargs", "dynamics:'kinematic'", "error_bound:0.1",
        "reward_weights:dict(tracking=20.0,effort=0.02)", "--seed", "3", "-f", str(logs), "--eval-freq", "-1",
        "--num-threads", "1", "--verbose", "0",
    ]  # fmt: skip
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}
    done = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    run = logs / algo / f"{ENV_ID}_1"
    assert (run / f"{ENV_ID}.zip").is_file() and (run / ENV_ID / "vecnormalize.pkl").is_file()

    from eval.cli import main

    out = tmp_path / "eval"
    argv = ["run", "--env", ENV_ID, "--policy", f"sb3:{run}", "--seeds", "1", "--seed", "10000"]
    assert main([*argv, "--dynamics", "kinematic", "--out", str(out), "--no-plots", "--quiet"]) == 0
    (episode,) = json.loads((out / "results.json").read_text())["episodes"]
    assert episode["status"] == "ok" and episode["n_steps"] == 2000

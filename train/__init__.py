"""train: Stable-Baselines3 baselines for the mobman tasks (`mobman-train`).

```python
from train import TrainConfig, run
summary = run(TrainConfig(algo="sac", env_id="WheeledPuma-Circle-v0", timesteps=100_000, out="runs/sac"))
```

```
mobman-train --algo sac --env WheeledPuma-Circle-v0 --timesteps 100000 --seed 0 --out runs/sac
mobman-train --resume runs/sac --timesteps 200000          # continue (also after Ctrl-C)
mobman-eval run --policy sb3:runs/sac/model.zip --policy nnbc --dynamics kinematic
mobman-train report runs/ppo-s0 runs/ppo-s1 runs/ppo-s2 --out docs/results/rl-v2   # several seeds, one report
```

Modules: `config` (`TrainConfig`, frozen, a docstring per field, JSON round trip), `algos` (name -> SB3 class
and default hyperparameters, rl-zoo style), `wrappers` (the agent's view of the observation), `run` (`run`,
`resume`, the run folder), `runfolder` (naming, config.json, checkpoints, best model), `callbacks` (checkpoints, learning curve), `evaluation` (through `eval`), `agent`
(the live model behind the `Policy` contract), `zoo` (rl-baselines3-zoo hyperparameter files), `report`,
`report_stats`, `report_text`, `report_cli` (`mobman-train report`: several seeds -> curves and tables with
intervals), `cli` (`main(argv)`). Importing `train` loads neither torch nor
SB3; `run` does.

## How the task is posed to the agent (the defaults)

* Env arguments for learning, written into the run's config (env arguments, not a forked env):
  `reward_weights = {"tracking": 20, "effort": 0.02}` (the error in units of 5 cm, the env's 1e-3
  effort/tracking ratio kept) and `error_bound = 0.1` m (an episode ends once the error passes 10 cm, so early
  experience stays near the path). A training-only wrapper adds `alive_bonus = 2` per step (= 20 x 0.1), so a
  step inside the bound earns >= 0 and ending early never pays. Evaluations drop these learning-only
  arguments and use the env's defaults.
* Observation: the `pos_error` wrapper adds target_pos - ee_pos; the agent sees `pos_error, target_vel, ee_vel,
  joint_pos, joint_vel, base_yaw, time`, normalised by VecNormalize (`vecnormalize.pkl`). `config.json` records
  `"wrappers"` and `"obs_keys"`, which `policies.sb3.SB3Policy` reproduces at inference.
* Actions: the env's normalised speeds. SAC/TD3 start with the actor's output layer scaled by 0.01, so the
  untrained agent commands about zero speed instead of random full-speed motions (PPO's orthogonal init does
  the same); SAC explores with gSDE.
* Seeds: training seed 0-999; periodic evaluation on development seeds 900-904 (held out: training envs are
  seeded once with the training seed); the final evaluation on reported seeds from 10,000 through `eval.run`,
  with the same env settings as `mobman-eval run` (the exact command is in `final_eval.json`).
* Torch runs with one thread (`torch_threads`).
"""

from mobman_env.packages import check_not_shadowed

# a user's eval.py or policies.py beside their script would hide mobman's: say so before importing them
check_not_shadowed(("policies", "eval"))

from train.config import TrainConfig  # noqa: E402

__all__ = ["TrainConfig", "resume", "run"]


def run(config: TrainConfig) -> dict:
    """Train one agent (see `train.run.run`)."""
    from train.run import run as _run

    return _run(config)


def resume(run_dir, timesteps=None) -> dict:
    """Continue a run from its latest checkpoint (see `train.run.resume`)."""
    from train.run import resume as _resume

    return _resume(run_dir, timesteps=timesteps)

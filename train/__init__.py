"""train: Stable-Baselines3 baselines for the mobman tasks (`mobman-train`).

```python
from train import TrainConfig, run
summary = run(TrainConfig(env_id="WheeledPuma-Circle-v0", timesteps=5_000_000, out="runs/ppo"))
```

```
mobman-train --env WheeledPuma-Circle-v0 --seed 0 --out runs/ppo     # PPO, 256 robots of the native vector env
mobman-train --resume runs/ppo --timesteps 10000000        # continue (also after Ctrl-C)
mobman-eval run --policy sb3:runs/ppo/model.zip --policy nnbc --dynamics kinematic
mobman-train report runs/ppo-s0 runs/ppo-s1 runs/ppo-s2 --out docs/results/rl-v2   # several seeds, one report
```

Modules: `config` (`TrainConfig`, frozen, a docstring per field, JSON round trip), `algos` (name -> SB3 class
and default hyperparameters, rl-zoo style), `wrappers` (the agent's view of the observation), `run` (`run`,
`resume`, the run folder; the training VecEnv), `vec_env` (`SB3VecEnv`: the native vector env as an SB3 VecEnv;
`AgentVecEnv`: the agent's view of a whole VecEnv), `runfolder` (naming, config.json, checkpoints, best model), `callbacks` (checkpoints, learning curve), `evaluation` (through `eval`), `agent`
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
* Envs: kinematic training steps `n_envs` = 256 robots of the native vector env (`mobman_env.vector`) in one
  process through `train.vec_env.SB3VecEnv` (autoreset in the same step); physics training steps one PyBullet
  world per process (SB3's `SubprocVecEnv`).
* Observation and actions: the `agent` wrapper, the robot-independent interface of `policies.agents.agent_interface`:
  no clock; position and velocity errors and the desired velocity in the heading frame, the joint state padded
  to the Panda's 7 arm joints with a mask, the heading as (cos, sin); 9 action slots (7 arm, 2 wheels), the
  padded ones ignored. Normalised by VecNormalize (`vecnormalize.pkl`). `config.json` records `"wrappers"` and
  `"obs_keys"`, which `policies.agents.sb3.SB3Policy` reproduces at inference (mapping the 9 slots to the robot's own).
* Actions: the env's normalised speeds. SAC/TD3 start with the actor's output layer scaled by 0.01, so the
  untrained agent commands about zero speed instead of random full-speed motions (PPO's orthogonal init does
  the same); SAC explores with gSDE.
* Seeds: training seed 0-999; periodic evaluation on development seeds 900-904 (held out: training envs are
  seeded once with the training seed); the final evaluation on reported seeds from 10,000 through `eval.run`,
  with the same env settings as `mobman-eval run` (the exact command is in `final_eval.json`).
* Progress: a line every `log_every_s` = 10 s to train.log and stderr (steps, steps/s, return, length and
  success of the episodes that ended), also off a terminal; the final evaluation announces itself and shows
  eval's progress bar (a line every 5 s off a terminal), its results table goes to train.log.
* Torch runs with one thread (`torch_threads`).
"""

from mobman_env.packages import check_not_shadowed

# a user's eval.py or policies.py beside their script would hide mobman's: say so before importing them
check_not_shadowed(("policies", "eval"))

import train.dev_env  # noqa: E402,F401  (registers MobMan-DevTrack-v0)
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

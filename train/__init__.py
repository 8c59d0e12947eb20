"""train: Stable-Baselines3 baselines for the mobman tasks (`mobman-train`).

```python
from train import TrainConfig, run
summary = run(TrainConfig(algo="sac", env_id="WheeledPuma-Circle-v0", timesteps=100_000, out="runs/sac"))
```

* `train.config.TrainConfig` — the frozen run configuration (a docstring per field, JSON round trip).
* `train.algos.ALGOS` — name -> SB3 class and default hyperparameters (ppo, sac, td3).
* `train.run.run(config)` / `train.run.resume(dir)` — train into a run folder / continue one.
* `train.cli.main(argv)` — the command line.

Importing `train` does not import torch or SB3; `run` does.
"""

from train.config import TrainConfig

__all__ = ["TrainConfig", "run", "resume"]


def run(config: TrainConfig) -> dict:
    """Train one agent (see `train.run.run`)."""
    from train.run import run as _run

    return _run(config)


def resume(run_dir, timesteps=None) -> dict:
    """Continue a run from its latest checkpoint (see `train.run.resume`)."""
    from train.run import resume as _resume

    return _resume(run_dir, timesteps=timesteps)

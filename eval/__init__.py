"""eval: benchmark policies on the wheeled PUMA 560 envs side by side, on identical episodes.

```python
from eval import EvalConfig, run
result = run(EvalConfig(policies=("nnbc", "jmpi"), episodes=5, dynamics=("kinematic",)),
             policies={"mine": MyController()})   # your own objects with reset/predict, beside the specs
result.aggregate    # one row per (env, policy, dynamics, model_error, obs_noise)
```

Command line: `mobman-eval run|sweep|paper|speed` (`eval.cli.main(argv)`); eval/README.md is the manual. Modules:
`config` (EvalConfig), `rollout` (the one rollout loop), `metrics` (pure functions), `checks` (everything checked
before the first rollout), `workers` (episodes in this process or N spawned ones), `runner` (`run`), `report`
(results.json / csv / summary.md, atomic writes), `plots`, `video`, `paper` (the paper's section IV), `speed`
(the speed benchmark), `ray_backend` (episodes as Ray tasks), `sweep`, `sweep_config`, `sweep_plots` (resumable
grids of policies x tasks x seeds x model errors x noise levels).
"""

from eval.config import EvalConfig, EvalError
from eval.runner import RunResult, run

__all__ = ["EvalConfig", "EvalError", "RunResult", "run"]

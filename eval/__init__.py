"""eval: benchmark policies on the wheeled mobile manipulator envs side by side, on identical episodes.

```python
from eval import EvalConfig, run
result = run(EvalConfig(policies=("nnbc", "jmpi"), episodes=5, dynamics=("kinematic",)),
             policies={"mine": MyController()})   # your own objects with reset/predict, beside the specs
result.aggregate    # one row per (env, policy, dynamics, model_error, obs_noise)
```

Command line: `mobman-eval run|sweep|bench|paper|speed` (`eval.cli.main(argv)`); eval/README.md is the manual.

## Layout and dependency rule

Each layer may import only the layers above it in this list (imports inside functions count; a test parses
every module and fails on a cycle or an upward import):

1. `errors` (EvalError; imports nothing), `metrics` (pure functions over recorded arrays)
2. `rollout` (make_env, make_policy, the one rollout loop)
3. `config` (EvalConfig), `batch_rollout` (the rollout loop for N episodes through one vector env and one
   batched policy)
4. `execution` (`tasks` <- `local`, `ray_backend` <- `dispatch`: where episodes run)
5. `checks` (everything checked before the first rollout), `output` (`files` <- `provenance`, `precision` <-
   `tables` <- `results`, `plots` <- `stat_plots`, `video`: what is written)
6. `runner` (`run`), `sweep` (`config`, `journal`, `report`, `plots` <- `run`: resumable grids)
7. `paper` (section IV of the paper), `bench` (the benchmark protocol v1: `config` <- `chaos`, `scorecard` <-
   `run`)
8. `speed` (the speed benchmark; `--paper` times `paper`)
9. `cli` (one module per subcommand; nothing imports it but `__main__`)

Across packages: `mobman_env` <- `policies` <- `eval` <- `train`; eval never imports `train`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from eval.errors import EvalError

if TYPE_CHECKING:
    from eval.config import EvalConfig
    from eval.runner import RunResult, run

__all__ = ["EvalConfig", "EvalError", "RunResult", "run"]


def __getattr__(name: str) -> Any:
    """`EvalConfig`, `RunResult` and `run` are imported on first use, after checking that no file of the user's
    hides `policies` or `mobman_env` (so `mobman-eval` can say so before anything imports them)."""
    if name in ("EvalConfig", "RunResult", "run"):
        from mobman_env.packages import check_not_shadowed

        check_not_shadowed(("mobman_env", "policies"))
        from eval import config, runner

        return {"EvalConfig": config.EvalConfig, "RunResult": runner.RunResult, "run": runner.run}[name]
    raise AttributeError(f"module 'eval' has no attribute {name!r}")

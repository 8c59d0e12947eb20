"""eval: benchmark policies on the wheeled mobile manipulator envs side by side, on identical episodes.

```python
from eval import EvalConfig, run
result = run(EvalConfig(policies=("nnbc", "jmpi"), episodes=5, dynamics=("kinematic",)),
             policies={"mine": MyController()})   # your own objects with reset/predict, beside the specs
result.aggregate    # one row per (env, policy, dynamics, model_error, obs_noise)

res = eval.load_results("runs/first")   # a results.json or its folder (schema 1, 2 or 3)
res.to_dataframe()                      # pandas: one row per episode (pip install "mobman[pandas]")
```

Command line: `mobman-eval run|sweep|bench|paper|speed|picture|readme|timings|compact|plots` (`eval.cli.main(argv)`);
eval/README.md is the manual.

## Layout and dependency rule

Each layer may import only the layers above it in this list (imports inside functions count; a test parses
every module and fails on a cycle or an upward import):

1. `errors` (EvalError; imports nothing), `metrics` (pure functions over recorded arrays), `heldout` (protocol
   v3's held-out family and its draw; imports numpy only)
2. `rollout` (make_env, make_vector_env, make_policy, the one rollout loop: `rollout` for one env, `rollout_batch`
   for a vector env and a batched policy), `schemas` (the JSON files eval reads: their reader, caps and shapes,
   and the names a scorecard may hold), `conditions` (the one conditions table and the name of any other
   condition)
3. `config` (EvalConfig)
4. `execution` (`tasks` <- `local`, `ray_backend` <- `dispatch`: where episodes run; `warmup`: numba's compile,
   announced, before the first episode)
5. `checks` (everything checked before the first rollout), `output` (`files` <- `provenance`, `precision` <-
   `tables` <- `results`, `styles` <- `plots` <- `stat_plots`, `video`, `picture`, `journal`, `readme` <-
   `layout`, `compact`: what is written)
6. `grid` (the one executor path of run and sweep: episodes dispatched, each record journaled as it ends)
7. `runner` (`run`), `sweep` (`config`, `report`, `plots` <- `run`: resumable grids)
8. `paper` (section IV of the paper), `bench` (the benchmark protocol v2: `config` <- `chaos`, `scorecard` <-
   `against` <- `run`)
9. `speed` (the speed benchmark; `--paper` times `paper`), `timings` (the README's steps timed), `redraw` (a
   folder's plots drawn again from its results files)
10. `cli` (one module per subcommand, `common`, `options`: the options generated from the config dataclasses;
    nothing in eval imports it but `__main__`; train's command lines use `options`)

Across packages: `mobman_env` <- `policies` <- `eval` <- `train`; eval never imports `train`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from eval.errors import EvalError

if TYPE_CHECKING:
    from eval.config import EvalConfig
    from eval.output.analysis import load_results
    from eval.runner import RunResult, run

__all__ = ["EvalConfig", "EvalError", "RunResult", "load_results", "run"]


def __getattr__(name: str) -> Any:
    """`EvalConfig`, `RunResult` and `run` are imported on first use, after checking that no file of the user's
    hides `policies` or `mobman_env` (so `mobman-eval` can say so before anything imports them);
    `load_results` (`eval.output.analysis`) on first use too."""
    if name in ("EvalConfig", "RunResult", "run"):
        from mobman_env.packages import check_not_shadowed

        check_not_shadowed(("mobman_env", "policies"))
        from eval import config, runner

        return {"EvalConfig": config.EvalConfig, "RunResult": runner.RunResult, "run": runner.run}[name]
    if name == "load_results":
        from eval.output.analysis import load_results

        return load_results
    raise AttributeError(f"module 'eval' has no attribute {name!r}")

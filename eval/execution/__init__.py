"""eval.execution: running episodes — `tasks` (what one episode is, and running tasks in this process),
`batches` (kinematic episodes of one condition and policy batched through a vector env, with a fallback to
single episodes), `local` (this process or N spawned worker processes), `ray_backend` (one Ray task per batch or
episode), `dispatch.execute` (the one entry, choosing by `config.backend`) and `warmup` (numba's compile, said
and done before the first episode).

May import: `eval.errors`, `eval.config`, `eval.rollout`, `eval.metrics`; never
`eval.output`, `eval.sweep`, `eval.cli` or the runners. Within the package: tasks <- batches <- local,
ray_backend <- dispatch; warmup stands alone.
"""

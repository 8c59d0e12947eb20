"""eval.execution: running episodes — `tasks` (what one episode is, and running tasks in this process), `local`
(N spawned worker processes), `ray_backend` (one Ray task per episode) and `dispatch.execute` (the one entry,
choosing by `config.backend`).

May import: `eval.errors`, `eval.config`, `eval.rollout`, `eval.metrics`; never `eval.output`, `eval.sweep`,
`eval.cli` or the runners. Within the package: tasks <- local, ray_backend <- dispatch.
"""

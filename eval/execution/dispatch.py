"""`execute(config, user, tasks, ...)`: the one entry point for running tasks, by `config.backend`."""

from __future__ import annotations

from eval.config import EvalConfig
from eval.execution.local import execute_local
from eval.execution.ray_backend import execute_ray
from eval.execution.tasks import Task


def execute(
    config: EvalConfig, user: dict, tasks: list[Task], user_bytes: bytes | None = None, on_result=None
) -> tuple[dict[int, dict], dict[int, dict]]:
    """Run `tasks` on `config.backend`; returns ({index: record}, {index: arrays}). `on_result(record)` is called
    as each episode ends (in this process)."""
    if config.backend == "ray":
        return execute_ray(config, user, tasks, on_result)
    return execute_local(config, user, tasks, user_bytes, on_result)

"""Checks made before any rollout; problems raise `EvalError` that name the bad value, what is accepted and the fix."""

from __future__ import annotations

import pickle
import warnings
from collections.abc import Callable
from typing import Any

from eval.config import EvalConfig
from eval.errors import EvalError
from eval.execution.ray_backend import check_address, require_ray, serialize_policies
from eval.rollout import make_env, make_policy


def check_env_id(env_id: str) -> None:
    import gymnasium as gym

    import mobman_env

    try:
        gym.spec(env_id)
    except Exception:
        raise EvalError(
            f"unknown env id {env_id!r}; available: {', '.join(mobman_env.ENV_IDS)} "
            f"(or any registered id of a WheeledPumaEnv)"
        ) from None


def check_user_policies(user: dict, specs: tuple[str, ...], workers: int) -> bytes | None:
    for name, obj in user.items():
        if not isinstance(name, str) or not name:
            raise EvalError(f"policy names must be non-empty strings, got {name!r}")
        if name in specs:
            raise EvalError(f"policy name {name!r} is given both as a spec and as an object; rename one")
        if not callable(getattr(obj, "predict", None)):
            raise EvalError(
                f"policy object {name!r} ({type(obj).__name__}) has no predict(observation, state=None, "
                f"episode_start=None, deterministic=True) method (see policies.base.Policy)"
            )
    if workers > 1 and user:
        try:
            return pickle.dumps(user)
        except Exception as exc:
            raise EvalError(
                f"policy objects {sorted(user)} cannot be sent to worker processes ({exc}); use workers=1 or "
                f"make them importable and pass them as --policy module:attr"
            ) from None
    return None


def build_env(env_id: str, dynamics: str, model_error: Any, obs_noise: Any, env_kwargs: dict) -> Any:
    """The env an episode of these settings makes (`eval.rollout.make_env`); EvalError naming them if it fails."""
    try:
        return make_env(env_id, dynamics, model_error, obs_noise, env_kwargs)
    except Exception as exc:
        raise EvalError(
            f"cannot make {env_id!r} with dynamics={dynamics!r} and env kwargs {env_kwargs}: {exc}"
        ) from None


class PolicyCheck:
    """Every policy spec built once on each env of a grid, the failures collected rather than raised at the first
    one, so that a refusal names every cell a spec cannot run on and why, before any episode runs.

    The user warnings raised while building (an agent evaluated on another env than it was trained on: one per
    env) are kept per spec, not printed: `warning_lines` sums them up in one line per spec; other categories (a
    library's DeprecationWarning) pass through Python's filters as usual."""

    def __init__(self, specs: tuple[str, ...], seed: int | None):
        self.specs, self.seed = specs, seed
        self.cells: list[Any] = []  # every cell checked, by its label
        self.failures: dict[str, dict[str, list[Any]]] = {}  # spec -> reason -> the cells it fails on
        self.warnings: dict[str, list[str]] = {}  # spec -> its distinct warnings, in order

    def on(self, env: Any, cell: Any) -> None:
        """Build every spec on `env` (cell `cell`), recording each failure's reason and each warning."""
        self.cells.append(cell)
        for spec in self.specs:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    make_policy(spec, env, self.seed)
                except EvalError as exc:
                    reason = str(exc).removeprefix(f"policy {spec!r}: ")
                    self.failures.setdefault(spec, {}).setdefault(reason, []).append(cell)
            mine = [w for w in caught if w.category is UserWarning]
            for w in caught:  # a library's deprecation and the like: shown as Python would have shown it
                if w not in mine:
                    warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            seen = self.warnings.setdefault(spec, [])
            seen += [m for m in dict.fromkeys(str(w.message) for w in mine) if m not in seen]

    def warning_lines(self) -> list[str]:
        """One line per spec whose building warned: its first warning and how many more like it."""
        lines = []
        for spec, msgs in self.warnings.items():
            if msgs and spec not in self.failures:
                more = f" (and {len(msgs) - 1} more like it)" if len(msgs) > 1 else ""
                lines.append(f"policy {spec!r}: {msgs[0]}{more}")
        return lines

    def refuse(
        self, describe: Callable[[list[Any]], str], fix: Callable[[list[Any]], str], unit: str = "cells"
    ) -> None:
        """EvalError for the first spec that failed anywhere: the spec, the cells (`describe(cells)`), the reason
        and `fix(cells)`. A spec failing alike on every cell (an unknown name, a missing file) keeps its own
        message: its cells are not the problem."""
        for spec, reasons in self.failures.items():
            reason, cells = next(iter(reasons.items()))
            if len(reasons) == 1 and len(cells) == len(self.cells):
                where = f" (on every one of the {len(cells)} {unit})" if len(cells) > 1 else ""
                raise EvalError(f"policy {spec!r}: {reason}{where}")
            raise EvalError(
                f"policy {spec!r} cannot run on {len(cells)} of the {len(self.cells)} {unit} ({describe(cells)}): "
                f"{reason}. {fix(cells)}"
            )


def check_all(config: EvalConfig, user: dict, checked: tuple[str, ...] = ()) -> None:
    """Build every env (per dynamics mode) and every spec policy once on each env; raise EvalError on any
    problem, naming every env a policy cannot run on. `checked`: specs the caller already built on these very
    envs (the bench's pre-flight, `eval.bench.preflight`), not built again."""
    if config.backend == "ray":
        require_ray()
        check_address(config.address)
        serialize_policies(user)  # policy objects Ray cannot pickle are refused here, naming them
    for env_id in config.envs:
        check_env_id(env_id)
    check = PolicyCheck(tuple(s for s in config.policies if s not in checked), config.seed)
    for env_id in config.envs:
        for dyn in config.dynamics:
            env = build_env(env_id, dyn, config.model_error, config.obs_noise, config.env_kwargs)
            try:
                if dyn == config.dynamics[0]:
                    check.on(env, env_id)
            finally:
                env.close()
    check.refuse(
        ", ".join,
        lambda cells: (
            "Run it on the other env(s) ("
            + ", ".join(e for e in config.envs if e not in cells)
            + ") with --env, or leave the policy out."
        ),
        unit="envs",
    )
    for line in check.warning_lines():
        warnings.warn(line, stacklevel=2)

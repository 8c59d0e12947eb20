"""Checks made before any rollout; problems raise `EvalError` that name the bad value, what is accepted and the fix."""

from __future__ import annotations

import pickle

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


def check_all(config: EvalConfig, user: dict) -> None:
    """Build every env (per dynamics mode) and every spec policy once; raise EvalError on any problem."""
    if config.backend == "ray":
        require_ray()
        check_address(config.address)
        serialize_policies(user)  # policy objects Ray cannot pickle are refused here, naming them
    for env_id in config.envs:
        check_env_id(env_id)
    for env_id in config.envs:
        for dyn in config.dynamics:
            try:
                env = make_env(env_id, dyn, config.model_error, config.obs_noise, config.env_kwargs)
            except Exception as exc:
                raise EvalError(
                    f"cannot make {env_id!r} with dynamics={dyn!r} and env kwargs {config.env_kwargs}: {exc}"
                ) from None
            try:
                if dyn == config.dynamics[0]:
                    for spec in config.policies:
                        make_policy(spec, env, config.seed)
            finally:
                env.close()

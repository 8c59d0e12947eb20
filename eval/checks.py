"""Checks made before any rollout, and building policies from specs; problems raise `EvalError` that name the
bad value, what is accepted and the fix."""

from __future__ import annotations

import pickle
from datetime import datetime, timezone
from pathlib import Path

from eval.config import EvalConfig, EvalError
from eval.rollout import make_env


def _known_policies_text() -> str:
    try:
        import policies

        known = getattr(policies, "KNOWN_POLICIES", {})
        names = ", ".join(known) if known else "see the policies package"
    except Exception as exc:  # pragma: no cover - policies broken: say so
        names = f"(the policies package failed to import: {exc})"
    return f"known: {names}; also sb3:PATH and module:attr"


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


def make_policy(spec: str, env, seed: int | None):
    """`policies.make(spec, env, seed)`; errors become `EvalError` naming the spec and the known names."""
    try:
        import policies
    except Exception as exc:
        raise EvalError(f"cannot import the policies package to build {spec!r}: {exc}") from None
    try:
        return policies.make(spec, env, seed=seed)
    except FileNotFoundError as exc:
        raise EvalError(f"policy {spec!r}: model file not found: {exc}") from None
    except Exception as exc:
        msg = str(exc)
        if "known" not in msg:
            msg += f" ({_known_policies_text()})"
        raise EvalError(f"policy {spec!r}: {msg}") from None


def resolve_out(config: EvalConfig) -> Path:
    if config.out:
        return Path(config.out)
    stamp = datetime.now(timezone.utc).strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{config.command}-{stamp}"


def check_out(out: Path, overwrite: bool) -> None:
    if out.exists() and not out.is_dir():
        raise EvalError(f"--out {str(out)!r} exists and is not a directory; choose another --out")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise EvalError(
            f"--out {str(out)!r} exists and is not empty; choose another --out or pass --overwrite "
            f"(files of the same name are then replaced, others are kept)"
        )


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

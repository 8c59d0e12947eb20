"""`run(config)`: train one agent into a run folder; `resume(run_dir)`: continue it.

Run folder (DESIGN "train"):

| file | content |
|---|---|
| `model.zip` | the final (or last saved) SB3 model |
| `vecnormalize.pkl` | VecNormalize statistics (when `normalize_obs`) |
| `config.json` | `TrainConfig.to_dict()` plus "hyperparams_resolved", "env_make_kwargs", "eval_env_kwargs", "versions"; the keys SB3Policy reads: "algo", "env_id", "env_kwargs", "obs_keys", "wrappers" |
| `checkpoints/` | `model_<N>_steps.zip`, `vecnormalize_<N>_steps.pkl`, the latest `replay_buffer.pkl` (SAC, TD3), `latest.json` |
| `learning_curve.csv`, `learning_curve.png` | tracking error on the development seeds vs env steps |
| `monitor.csv` | training episodes (return, length) |
| `best/` | the model with the lowest worst-episode RMS error on the development seeds (a run folder itself) |
| `final_eval.json`, `final_eval/` | the final evaluation (eval's report) of `model.zip`, `best/model.zip` and `zero` with the benchmark's env settings on the reported seeds |
| `summary.json` | status (done / interrupted), steps, wall time, final metrics |
| `train.log`, `tensorboard/` | log; TensorBoard events with `--tensorboard` |
| `progress.csv` | SB3's training statistics of the latest session (without `--tensorboard`) |

Ctrl-C during training saves a checkpoint and the model, then raises `TrainingInterrupted`; `resume(run_dir)`
continues from the latest checkpoint up to `config.timesteps` (or a new total).
"""

from __future__ import annotations

import functools
import logging
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym

from policies.agents.agent_interface import BASE_ACTION
from train import algos
from train.callbacks import (
    CheckpointSaver,
    PeriodicEval,
    ProgressLog,
    read_curve,
    truncate_curve,
    write_curve_png,
    write_json,
)
from train.config import TrainConfig
from train.evaluation import ZeroPolicy
from train.runfolder import (
    check_run_folder,
    latest_checkpoint,
    load_run_config,
    make_run_folder,
    read_checkpoint,
    read_json_file,
    run_config_dict,
    save_checkpoint,
    save_final,
    save_if_best,
    setup_logging,
)
from train.wrappers import AgentObservation

log = logging.getLogger("train")


class TrainingInterrupted(Exception):
    """Training stopped by Ctrl-C after saving a checkpoint; `.run_dir`, `.timesteps`."""

    def __init__(self, run_dir: Path, timesteps: int):
        super().__init__(
            f"interrupted at {timesteps} steps; checkpoint saved in {run_dir}; continue with "
            f"`mobman-train --resume {run_dir}`"
        )
        self.run_dir = run_dir
        self.timesteps = timesteps


# --- envs -------------------------------------------------------------------------------------------------
def _make_env(env_id: str, env_kwargs: dict, in_subprocess: bool) -> gym.Env:
    """One raw env (the agent's view is applied to the whole VecEnv by `AgentVecEnv`)."""
    if in_subprocess:  # Ctrl-C goes to the whole process group: only the parent handles it
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    return gym.make(f"mobman_env:{env_id}", **env_kwargs)


def make_vec_env(config: TrainConfig, seed_offset: int = 0):
    """The training VecEnv, the agent's view (`AgentVecEnv`) with the alive bonus (VecMonitor and VecNormalize
    are added by the caller), seeded: robot / env i starts from seed + seed_offset + i.

    Kinematic: the native vector env (`mobman_env.vector`, N = `n_envs` robots in this process, autoreset in
    the same step) through `SB3VecEnv`. Physics: `n_envs` PyBullet worlds, one per process (`SubprocVecEnv`;
    `DummyVecEnv` for 1), as contacts are not batched."""
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    from train.vec_env import AgentVecEnv, SB3VecEnv, VecAliveBonus

    if config.dynamics == "kinematic":
        base: Any = SB3VecEnv(
            gym.make_vec(
                f"mobman_env:{config.env_id}",
                num_envs=config.num_envs,
                vectorization_mode="vector_entry_point",
                autoreset_mode="SameStep",
                **config.train_env_kwargs,
            )
        )
    else:
        sub = config.num_envs > 1
        fns: list[Callable[[], gym.Env]] = [
            functools.partial(_make_env, config.env_id, config.train_env_kwargs, sub) for _ in range(config.num_envs)
        ]
        base = SubprocVecEnv(fns) if sub else DummyVecEnv(fns)
    venv: Any = AgentVecEnv(base, config.wrappers, config.obs_keys)
    if config.alive_bonus:
        venv = VecAliveBonus(venv, config.alive_bonus)
    venv.seed(config.seed + seed_offset)
    return venv


def probe_envs(config: TrainConfig, build_model: bool = True) -> None:
    """Build the training and evaluation envs once and reset them, and build the model once on the training
    env, so bad env arguments and hyperparameters fail before anything is written."""
    # the evaluation env has no base controller: a residual agent's base action is added at inference
    eval_keys = tuple(k for k in config.obs_keys if k != BASE_ACTION)
    for env_id, kwargs, keys in (
        (config.env_id, config.train_env_kwargs, config.obs_keys),
        (config.eval_env_id, config.eval_env_kwargs, eval_keys),
    ):
        try:
            env = AgentObservation(_make_env(env_id, kwargs, False), config.wrappers, keys)
        except (TypeError, ValueError, KeyError) as exc:
            raise ValueError(f"bad env arguments {kwargs}: {exc}") from None
        try:
            env.reset(seed=0)
        finally:
            env.close()
    if not build_model:
        return
    # the model only reads the spaces and n_envs: the kinematic vector env costs little; physics worlds are
    # built in this process rather than in n_envs subprocesses
    venv = make_vec_env(config if config.dynamics == "kinematic" else config.replace(n_envs=1))
    try:
        _build_model(config, _wrap_normalize(config, venv), None)
    except Exception as exc:  # SB3 checks its arguments with asserts and TypeErrors deep inside the build
        raise ValueError(
            f"the hyperparameters of {config.algo} {config.resolved_hyperparams} do not build a model: "
            f"{type(exc).__name__}: {exc}"
        ) from None
    finally:
        venv.close()


# --- evaluation hooks -------------------------------------------------------------------------------------
def _periodic_evaluator(config: TrainConfig):
    from train.agent import Agent
    from train.evaluation import evaluate

    def _evaluate(model: Any) -> dict:
        agent = Agent(model, model.get_vec_normalize_env(), config.wrappers, config.obs_keys, config.residual)
        return evaluate(
            config.eval_env_id,
            config.eval_env_kwargs,
            agent,
            config.eval_seed,
            config.eval_episodes,
            config.tolerance,
            name=config.algo,
        )

    return _evaluate


def final_evaluation(config: TrainConfig, out: Path) -> dict:
    """Evaluate the saved agent (`out/model.zip`, through `eval.run` and `SB3Policy`) and `zero` with the
    benchmark's env settings on the reported seeds; write `final_eval.json` (the report is in `final_eval/`)."""
    from train.evaluation import final_evaluation as _final

    result = _final(
        config.eval_env_id,
        config.eval_env_kwargs,
        out,
        config.final_eval_seed,
        config.final_eval_episodes,
        config.tolerance,
    )
    result = {
        "env_id": config.eval_env_id,
        "env_kwargs": config.eval_env_kwargs,
        "first_seed": config.final_eval_seed,
        "episodes": config.final_eval_episodes,
        "tolerance_m": config.tolerance,
        **result,
    }
    write_json(out / "final_eval.json", result)
    return result


# --- training ---------------------------------------------------------------------------------------------
def _build_model(config: TrainConfig, venv: Any, out: Path | None) -> Any:
    spec = algos.get(config.algo)
    kwargs = algos.build_kwargs(config.algo, config.resolved_hyperparams, venv.action_space.shape[0])
    model = spec.load_class()(
        "MultiInputPolicy",
        venv,
        seed=config.seed,
        device=config.device,
        verbose=config.verbose,
        tensorboard_log=str(out / "tensorboard") if config.tensorboard and out is not None else None,
        **kwargs,
    )
    if spec.off_policy and config.actor_out_scale != 1.0:
        scale_actor_output(model, config.actor_out_scale)
    return model


def scale_actor_output(model: Any, scale: float) -> None:
    """Scale the actor's last linear layer (SAC: `actor.mu`; TD3: the last Linear of `actor.mu`), and copy it
    into the target actor if there is one."""
    import torch

    mu = model.actor.mu
    layer = mu if isinstance(mu, torch.nn.Linear) else [m for m in mu if isinstance(m, torch.nn.Linear)][-1]
    with torch.no_grad():
        layer.weight.mul_(scale)
        layer.bias.mul_(scale)
    target = getattr(model, "actor_target", None)
    if target is not None:
        target.load_state_dict(model.actor.state_dict())


def _wrap_normalize(config: TrainConfig, venv: Any) -> Any:
    from stable_baselines3.common.vec_env import VecNormalize

    if not (config.normalize_obs or config.do_normalize_reward):
        return venv
    return VecNormalize(
        venv,
        norm_obs=config.normalize_obs,
        norm_reward=config.do_normalize_reward,
        gamma=float(config.resolved_hyperparams.get("gamma", 0.99)),
    )


def _prepare(config: TrainConfig, build_model: bool = True) -> None:
    """Every check that can fail before training: hyperparameter names, env arguments, and (new runs) that
    the hyperparameters build a model."""
    algos.check_keys(config.algo, config.resolved_hyperparams)
    if config.tensorboard:
        import importlib.util

        if importlib.util.find_spec("tensorboard") is None:
            raise ValueError(
                "--tensorboard needs the tensorboard package, which is not installed: "
                'pip install tensorboard (or pip install "mobman[rl]"), or drop --tensorboard'
            )
    probe_envs(config, build_model=build_model)


def run(config: TrainConfig) -> dict:
    """Train `config.algo` on `config.env_id` into the run folder; return the summary (also `summary.json`).

    Everything that can be checked (arguments, envs, hyperparameters, a writable `out`) is checked before the
    run folder is created."""
    import torch
    from stable_baselines3.common.vec_env import VecMonitor

    out = check_run_folder(config)
    _prepare(config)
    out = make_run_folder(config, out)
    setup_logging(out)
    write_json(out / "config.json", run_config_dict(config))
    torch.set_num_threads(config.torch_threads)
    venv = _wrap_normalize(config, VecMonitor(make_vec_env(config), str(out / "monitor.csv")))
    model = _build_model(config, venv, out)
    log.info(
        "training %s on %s (%s) for %d steps, %d env(s), seed %d -> %s",
        config.algo,
        config.env_id,
        config.dynamics,
        config.timesteps,
        config.n_envs,
        config.seed,
        out,
    )
    return _train(config, model, out, wall_offset=0.0)


def resume(run_dir: Path | str, timesteps: int | None = None, progress_bar: bool | None = None) -> dict:
    """Continue a run from its latest checkpoint up to `timesteps` (default: the run's own total)."""
    import torch
    from stable_baselines3.common.vec_env import VecMonitor

    out = Path(run_dir)
    config = load_run_config(out)
    changes: dict = {"out": str(out), "overwrite": True}
    if timesteps is not None:
        changes["timesteps"] = timesteps
    if progress_bar is not None:
        changes["progress_bar"] = progress_bar
    config = config.replace(**changes)
    ckpt = latest_checkpoint(out)
    if ckpt is None:
        raise ValueError(f"{out} has no checkpoint (checkpoints/latest.json) to resume from; start a new run")
    if ckpt["steps"] >= config.timesteps:
        raise ValueError(
            f"{out} already has {ckpt['steps']} steps >= timesteps {config.timesteps}; pass a larger "
            f"--timesteps to train further"
        )
    state = read_checkpoint(ckpt, out)  # before anything is written: a refused checkpoint changes nothing
    _prepare(config, build_model=False)
    setup_logging(out)
    write_json(out / "config.json", run_config_dict(config))
    torch.set_num_threads(config.torch_threads)
    venv = VecMonitor(make_vec_env(config, seed_offset=ckpt["steps"]), str(out / f"monitor_{ckpt['steps']}.csv"))
    model = load_checkpoint(config, ckpt, out, venv, state)
    # SB3's load() re-seeds the env with the run's own seed (set_random_seed(seed) -> env.seed(seed)), which
    # would replay the first session's episodes: seed the resumed session with seed + steps done instead
    model.set_random_seed(config.seed + ckpt["steps"])
    truncate_curve(out / "learning_curve.csv", ckpt["steps"])
    log.info("resuming %s at %d steps, up to %d", out, ckpt["steps"], config.timesteps)
    return _train(config, model, out, wall_offset=_wall_so_far(out))


def load_checkpoint(config: TrainConfig, ckpt: dict, out: Path, venv: Any, state: dict) -> Any:
    """The model (with its normaliser and replay buffer) of checkpoint entry `ckpt` on `venv`; the pickled
    parts come from `read_checkpoint` (`state`), never from plain pickle."""
    if state["vecnormalize"] is not None:
        state["vecnormalize"].set_venv(venv)  # what VecNormalize.load does after unpickling
        venv = state["vecnormalize"]
        venv.training = True
    model = (
        algos.get(config.algo)
        .load_class()
        .load(
            out / "checkpoints" / ckpt["model"],
            env=venv,
            device=config.device,
            tensorboard_log=str(out / "tensorboard") if config.tensorboard else None,
            custom_objects=state["custom_objects"],
        )
    )
    if state["replay_buffer"] is not None:
        from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

        assert isinstance(model, OffPolicyAlgorithm)  # only off-policy runs save a replay buffer
        model.replay_buffer = state["replay_buffer"]  # what load_replay_buffer does after unpickling
        model.replay_buffer.device = model.device
    return model


def _wall_so_far(out: Path) -> float:
    """Wall time of the earlier sessions: the last session's summary, or (if it never wrote one) the
    learning curve's last row."""
    prev = read_json_file(out / "summary.json") if (out / "summary.json").exists() else {}
    curve = read_curve(out / "learning_curve.csv")
    return float(prev.get("wall_s", curve[-1]["wall_s"] if curve else 0.0))


def _train(config: TrainConfig, model: Any, out: Path, wall_offset: float) -> dict:
    """Learn up to `config.timesteps`, save, evaluate; the summary (also `summary.json`). Ctrl-C saves a
    checkpoint and raises `TrainingInterrupted`."""
    from train.evaluation import evaluate

    reference = evaluate(
        config.eval_env_id,
        config.eval_env_kwargs,
        ZeroPolicy(),
        config.eval_seed,
        max(config.eval_episodes, 1),
        config.tolerance,
        name="zero",
    )
    t0 = time.time()
    start_steps = int(model.num_timesteps)
    status = _learn(config, model, out, _callbacks(config, out, reference, t0, wall_offset))
    _save_after_learning(config, model, out, interrupted=(status == "interrupted"))
    summary: dict[str, Any] = {
        "status": status,
        "timesteps": int(model.num_timesteps),
        "wall_s": round(wall_offset + time.time() - t0, 1),
        "run_dir": str(out),
        "steps_per_s_this_session": round((model.num_timesteps - start_steps) / max(time.time() - t0, 1e-9), 1),
    }
    if status == "done":
        if config.eval_freq:
            _final_curve_point(config, out, model, reference, t0, wall_offset)
        if config.final_eval_episodes:
            summary.update(_final_evaluation_summary(config, out))
    write_json(out / "summary.json", summary)
    if status == "interrupted":
        raise TrainingInterrupted(out, int(model.num_timesteps))
    return summary


def _callbacks(config: TrainConfig, out: Path, reference: dict, t0: float, wall_offset: float) -> Any:
    """Checkpoints every `checkpoint_freq` steps, the periodic evaluation (learning curve, best model) and a
    progress line every `log_every_s`."""
    from stable_baselines3.common.callbacks import CallbackList

    off_policy = algos.get(config.algo).off_policy
    return CallbackList(
        [
            CheckpointSaver(config.checkpoint_freq, lambda m: save_checkpoint(m, out, off_policy)),
            PeriodicEval(
                config.eval_freq,
                _periodic_evaluator(config),
                out / "learning_curve.csv",
                out / "learning_curve.png",
                reference,
                t0,
                wall_offset,
                on_result=lambda m, row: save_if_best(m, row, config, out),
            ),
            # after PeriodicEval: its clock starts once the evaluation at the start of training is done
            ProgressLog(config.log_every_s, config.tolerance),
        ]
    )


def _learn(config: TrainConfig, model: Any, out: Path, callbacks: Any) -> str:
    """`model.learn` up to `config.timesteps`: "done", or "interrupted" after Ctrl-C."""
    if not config.tensorboard:
        # SB3 would otherwise create an empty /tmp/SB3-<date> folder for its logger on every learn()
        from stable_baselines3.common.logger import configure

        model.set_logger(configure(str(out), ["stdout", "csv"] if config.verbose else ["csv"]))
    try:
        model.learn(
            total_timesteps=config.timesteps - model.num_timesteps,
            callback=callbacks,
            progress_bar=config.progress_bar,
            reset_num_timesteps=False,
            tb_log_name=config.algo,
        )
    except KeyboardInterrupt:
        log.info("Ctrl-C at %d steps: saving", model.num_timesteps)
        return "interrupted"
    return "done"


def _save_after_learning(config: TrainConfig, model: Any, out: Path, interrupted: bool) -> None:
    """A checkpoint at the last step (unless there is one) and the final model; then close the envs."""
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not corrupt the save
    try:
        latest = latest_checkpoint(out)
        if latest is None or latest["steps"] != model.num_timesteps:
            save_checkpoint(model, out, algos.get(config.algo).off_policy)
        save_final(model, out)
    finally:
        signal.signal(signal.SIGINT, previous)
        close_vec_env(model.get_env(), interrupted=interrupted)


def _final_evaluation_summary(config: TrainConfig, out: Path) -> dict:
    """Run the final evaluation; its summary entry, or "final_eval_error" (the model is saved: a failed
    evaluation is reported with the command that reruns it, never loses the run)."""
    n_agents = 2 if (out / "best" / "model.zip").is_file() else 1
    log.info(
        "final evaluation: %d episodes each of the agent%s and zero on seeds %d..%d (%s); eval's progress follows",
        config.final_eval_episodes,
        ", best/" if n_agents == 2 else "",
        config.final_eval_seed,
        config.final_eval_seed + config.final_eval_episodes - 1,
        config.dynamics,
    )
    try:
        fe = final_evaluation(config, out)
    except Exception:
        import traceback

        from train.evaluation import eval_command, eval_config

        cmd = eval_command(
            eval_config(
                config.eval_env_id,
                config.eval_env_kwargs,
                [out / "model.zip"],
                out / "final_eval",
                config.final_eval_seed,
                config.final_eval_episodes,
                config.tolerance,
            )
        )
        error = traceback.format_exc()
        log.error("final evaluation failed (the model is saved); rerun it with:\n  %s\n%s", cmd, error)
        return {"final_eval_error": error}
    log.info(
        "final eval (seeds %d..%d, %s): median RMS %.1f mm (zero %.1f mm), median max %.1f mm, success %.0f%%",
        fe["first_seed"],
        fe["first_seed"] + fe["episodes"] - 1,
        config.dynamics,
        1e3 * fe["agent"]["median_rms_error_m"],
        1e3 * fe["zero"]["median_rms_error_m"],
        1e3 * fe["agent"]["median_max_error_m"],
        100 * fe["agent"]["success_rate"],
    )
    if "best" in fe:
        log.info(
            "final eval of best/ (dev-seed selection): median RMS %.1f mm, median max %.1f mm, success %.0f%%",
            1e3 * fe["best"]["median_rms_error_m"],
            1e3 * fe["best"]["median_max_error_m"],
            100 * fe["best"]["success_rate"],
        )
    return {
        "final_eval": {
            **{k: _drop_episodes(fe[k]) for k in ("agent", "best", "zero") if k in fe},
            "first_seed": fe["first_seed"],
            "episodes": fe["episodes"],
            "eval_command": fe["eval_command"],
        }
    }


def close_vec_env(venv: Any, interrupted: bool) -> None:
    """Close the training VecEnv. After Ctrl-C, subprocess workers are terminated instead: the interrupt may
    have come between two of SubprocVecEnv's pipe messages, and its polite close would wait for a reply that
    never comes."""
    from stable_baselines3.common.vec_env import SubprocVecEnv

    base = venv.unwrapped
    if interrupted and isinstance(base, SubprocVecEnv):
        for process in base.processes:
            process.terminate()
        for process in base.processes:
            process.join(timeout=10)
        base.closed = True
        return
    venv.close()


def _final_curve_point(config, out, model, reference, t0, wall_offset) -> None:
    """Add the last step to the learning curve unless the last evaluation was already there."""
    from train.callbacks import append_curve_row, read_curve

    rows = read_curve(out / "learning_curve.csv")
    if rows and int(rows[-1]["timesteps"]) == model.num_timesteps:
        return
    s = _periodic_evaluator(config)(model)
    row = {
        "timesteps": model.num_timesteps,
        "wall_s": round(wall_offset + time.time() - t0, 1),
        **{
            k: s[k]
            for k in ("median_rms_error_m", "max_rms_error_m", "median_max_error_m", "max_max_error_m", "success_rate")
        },
    }
    append_curve_row(out / "learning_curve.csv", row)
    save_if_best(model, row, config, out)
    write_curve_png(out / "learning_curve.csv", out / "learning_curve.png", reference)


def _drop_episodes(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k != "episodes"}

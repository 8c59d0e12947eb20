"""The run folder of `mobman-train` (layout in `train.run`): naming, config.json, checkpoints, the best model."""

from __future__ import annotations

import logging
import os
import pickle
import sys
from pathlib import Path
from typing import Any

from eval.output.provenance import versions
from mobman_env.validation import folder_name
from policies.agents.untrusted_json import read_json
from train.callbacks import write_json
from train.config import TrainConfig

log = logging.getLogger("train")
CONFIG_SCHEMA = 1


def check_run_folder(config: TrainConfig) -> Path:
    """The run folder `config.out` (or the default `runs/train-<algo>-<task>-<UTC date-time>`), checked before
    anything is written: not a file, empty unless `overwrite`, writable (eval's `check_out`)."""
    from eval.output.files import check_out, resolve_out

    task = config.env_id.split("-")[1].lower() if "-" in config.env_id else config.env_id
    out = resolve_out(config.out, f"train-{config.algo}-{task}")
    if out.is_dir() and any(out.iterdir()) and not config.overwrite:
        raise ValueError(
            f"--out {out} exists and is not empty; pass --overwrite, choose another --out, or "
            f"continue it with --resume {out}"
        )
    check_out(out, config.overwrite)
    return out


def make_run_folder(config: TrainConfig, out: Path) -> Path:
    """Create the checked run folder; a default name is created exclusively (two runs never share one)."""
    from eval.output.files import make_out

    return make_out(out, exclusive=not config.out)


def run_config_dict(config: TrainConfig) -> dict:
    """What `config.json` holds."""
    return {
        "schema": CONFIG_SCHEMA,
        **config.to_dict(),
        "hyperparams_resolved": config.resolved_hyperparams,
        "env_make_kwargs": config.train_env_kwargs,
        "eval_env_kwargs": config.eval_env_kwargs,
        "versions": versions(),  # eval's provenance: python, mobman, numpy, gymnasium, pybullet, SB3, torch
    }


#: Cap on a run folder's JSON file (config.json: 2 kB; summary.json and latest.json: less).
MAX_RUN_JSON_BYTES = 16 * 2**20


def read_json_file(path: Path) -> dict:
    """A JSON object from a run folder's file (config.json, summary.json, checkpoints/latest.json) through the
    one JSON reader (`policies.agents.untrusted_json.read_json`: a regular file of at most `MAX_RUN_JSON_BYTES`, so a
    FIFO or a symlink to /dev/zero is refused; UTF-8; bounded nesting); ValueError naming the file otherwise."""
    try:
        data = read_json(path, MAX_RUN_JSON_BYTES, "run file")
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path} is not a readable JSON file ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} must hold a JSON object, got {type(data).__name__}")
    return data


def load_run_config(run_dir: Path | str) -> TrainConfig:
    """The TrainConfig of a run folder's config.json (errors name the file)."""
    path = Path(run_dir) / "config.json"
    if not path.exists():
        raise ValueError(f"{run_dir} is not a run folder (no config.json); pass the --out folder of a mobman-train run")
    try:
        return TrainConfig.from_dict(read_json_file(path), ignore_extra=True)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"cannot resume from {path}: {exc}") from None


#: Keys of checkpoints/latest.json: step count and the file names (None: not saved) inside checkpoints/.
CHECKPOINT_KEYS = ("steps", "model", "vecnormalize", "replay_buffer")


def latest_checkpoint(run_dir: Path) -> dict | None:
    """checkpoints/latest.json (None without one), checked: its keys, and that the files it names exist."""
    folder = Path(run_dir) / "checkpoints"
    path = folder / "latest.json"
    if not path.exists():
        return None
    entry = read_json_file(path)
    missing = [k for k in CHECKPOINT_KEYS if k not in entry]
    if missing or isinstance(entry["steps"], bool) or not isinstance(entry["steps"], int):
        raise ValueError(
            f"{path} is not a checkpoint index (keys {list(CHECKPOINT_KEYS)}, an integer 'steps'); got {entry}"
        )
    names = {k: entry[k] for k in ("model", "vecnormalize", "replay_buffer") if entry[k] is not None}
    for key, name in names.items():
        folder_name(f"{path}: {key}", name, hint="a file of checkpoints/; restore latest.json, or start a new run")
    for key, name in names.items():
        if not (folder / str(name)).is_file():
            raise ValueError(
                f"{path} names {key} file {folder / str(name)}, which is missing; restore it, or start a new run"
            )
    return entry


#: What a mobman-train checkpoint may unpickle: SB3's checkpoint state and mobman-train's own schedule.
CHECKPOINT_PAIRS = frozenset({("train.algos", "LinearSchedule")})


def read_checkpoint(ckpt: dict, out: Path) -> dict:
    """The pickled parts of checkpoint entry `ckpt`, read through `policies.agents.untrusted`'s allow-list (never
    plain pickle; SB3 reads the weights with `weights_only=True`): {"custom_objects": every serialized entry
    of the model.zip, "vecnormalize": a VecNormalize without its venv or None, "replay_buffer": a
    ReplayBuffer or None}. ValueError naming the file when one is refused or unreadable; nothing is
    written."""
    from stable_baselines3.common.buffers import ReplayBuffer
    from stable_baselines3.common.vec_env import VecNormalize

    from policies.agents.sb3_files import read_zip_data, safe_custom_objects
    from policies.agents.untrusted import ALLOWED_CHECKPOINT, UnsafePickleError, load_pickle_file

    folder = Path(out) / "checkpoints"
    allowed = ALLOWED_CHECKPOINT | CHECKPOINT_PAIRS
    model = folder / str(ckpt["model"])
    state: dict = {"custom_objects": safe_custom_objects(read_zip_data(model), model, allowed)}
    for key, cls, what in (
        ("vecnormalize", VecNormalize, "VecNormalize statistics"),
        ("replay_buffer", ReplayBuffer, "a replay buffer"),
    ):
        state[key] = None
        if ckpt[key] is None:
            continue
        path = folder / str(ckpt[key])
        try:
            obj = load_pickle_file(path, allowed, f"a mobman-train checkpoint's {what}")
        except UnsafePickleError as exc:
            raise ValueError(f"{path}: {exc}; resume only from checkpoints you trust") from None
        except (ValueError, pickle.UnpicklingError, EOFError, AttributeError, TypeError, ImportError) as exc:
            raise ValueError(
                f"cannot resume from {path} ({type(exc).__name__}: {exc}); restore it, or start a new run"
            ) from None
        if not isinstance(obj, cls):
            raise ValueError(f"cannot resume from {path}: it holds a {type(obj).__name__}, not {what}")
        state[key] = obj
    return state


def setup_logging(out: Path, verbose: bool = True) -> None:
    log.setLevel(logging.INFO)
    for h in list(log.handlers):
        log.removeHandler(h)
        h.close()
    fh = logging.FileHandler(out / "train.log")
    fh.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
    log.addHandler(fh)
    sh = logging.StreamHandler(sys.stderr)
    sh.setFormatter(logging.Formatter("[train] %(message)s"))
    log.addHandler(sh)
    log.propagate = False


# --- saving -----------------------------------------------------------------------------------------------
def save_checkpoint(model: Any, out: Path, off_policy: bool) -> dict:
    """Model, normaliser and (off-policy) replay buffer at the current step; `latest.json` points at them."""
    ckpt = out / "checkpoints"
    ckpt.mkdir(exist_ok=True)
    n = int(model.num_timesteps)
    entry: dict[str, Any] = {"steps": n, "model": f"model_{n}_steps.zip", "vecnormalize": None, "replay_buffer": None}
    model.save(ckpt / entry["model"])
    vn = model.get_vec_normalize_env()
    if vn is not None:
        entry["vecnormalize"] = f"vecnormalize_{n}_steps.pkl"
        vn.save(ckpt / entry["vecnormalize"])
    if off_policy:
        tmp = ckpt / ".replay_buffer.tmp.pkl"
        model.save_replay_buffer(tmp)
        os.replace(tmp, ckpt / "replay_buffer.pkl")
        entry["replay_buffer"] = "replay_buffer.pkl"
    write_json(ckpt / "latest.json", entry)
    log.info("checkpoint at %d steps", n)
    return entry


#: Selection key of the best model: the worst RMS error over the development seeds (robust, not lucky).
BEST_KEY = "max_rms_error_m"


def save_if_best(model: Any, row: dict, config: TrainConfig, out: Path) -> bool:
    """Keep the model with the lowest `BEST_KEY` on the development seeds in `out/best/`, a complete run
    folder of its own (model.zip, vecnormalize.pkl, config.json, best.json), like rl-zoo's best_model."""
    best_dir = out / "best"
    info_path = best_dir / "best.json"
    previous = read_json_file(info_path) if info_path.exists() else None
    if previous is not None and previous[BEST_KEY] <= row[BEST_KEY]:
        return False
    best_dir.mkdir(exist_ok=True)
    save_final(model, best_dir)
    write_json(best_dir / "config.json", run_config_dict(config))
    write_json(
        info_path,
        {
            "timesteps": int(row["timesteps"]),
            "selected_by": f"lowest {BEST_KEY} on development "
            f"seeds {config.eval_seed}..{config.eval_seed + config.eval_episodes - 1}",
            **row,
        },
    )
    return True


def save_final(model: Any, out: Path) -> None:
    model.save(out / "model.zip")
    vn = model.get_vec_normalize_env()
    if vn is not None:
        vn.save(out / "vecnormalize.pkl")

"""Reading a Stable-Baselines3 run folder without running code it names (the files of `policies.agents.sb3`).

Both files of an SB3 agent hold pickles, and `pickle.load` runs whatever callable a pickle names: a crafted
`vecnormalize.pkl` can call `os.system`. This module reads them with `policies.agents.untrusted`'s restricted
unpickler, whose `find_class` resolves only an allow-list of exact (module, name) pairs those files
legitimately contain and refuses every dotted name; anything else is refused with `UnsafePickleError`, naming
the module and attribute:

* `vecnormalize.pkl` (`load_vecnormalize_stats`): the `VecNormalize` object and its `RunningMeanStd`
  statistics are rebuilt as plain attribute holders (`_State`), the gymnasium spaces and numpy random state it
  also carries as inert placeholders; only numpy arrays, scalars and dtypes are really constructed. No
  Stable-Baselines3 or gymnasium code runs, and SB3 need not be installed.
* `model.zip` (`safe_custom_objects`): SB3 stores the non-JSON entries of its `data` file as base64 cloudpickles
  and lets the loader replace any of them (`custom_objects`). Entries inference does not use (the last
  observation, episode buffers, schedules, buffer classes, action noise) are replaced by neutral values
  without being decoded; the others (`policy_class`, `observation_space`, `action_space`, `policy_kwargs`) are
  decoded with the restricted unpickler (`ALLOWED_MODEL`: SB3 policy and feature-extractor classes,
  gymnasium spaces, torch activation and optimiser classes, and numpy data). The weights (`*.pth`) are read
  by SB3 with `torch.load(..., weights_only=True)`. The zip's `data` entry may inflate to at most
  `MAX_MODEL_DATA_BYTES`, all entries together to `MAX_MODEL_ZIP_BYTES`, counting the records of the archives
  inside it (torch's `policy.pth`), read from their central directories before anything is inflated
  (`check_nested_zip_sizes`); a statistics file must be a regular file of at most `MAX_STATS_BYTES`.

Where the files are (`find_run`): a mobman-train or plain SB3 folder holds `model.zip` and, optionally, the
statistics under mobman's name `vecnormalize.pkl` or `VecNormalize.save`'s conventional `vec_normalize.pkl`
(both present: refused, naming both); an rl-baselines3-zoo run folder (`logs/<algo>/<ENV>_<n>/`) holds
`<ENV>.zip` (the final model; `best_model.zip` is used only without it) and `<ENV>/` with `vecnormalize.pkl`,
`config.yml` and `args.yml`. The zoo's YAML files are written with `!!python/object/apply:collections.OrderedDict`
tags; `load_zoo_yaml` reads them with a `yaml.SafeLoader` that builds only that tag (as a dict of its pairs),
never `yaml.unsafe_load`.

This narrows what a file can do; it is not a sandbox: load only agents you trust (README, `--help`).
May import numpy and the standard library; torch, gymnasium, yaml and Stable-Baselines3 only inside functions.
"""

from __future__ import annotations

import ast
import base64
import binascii
import json
import pickle
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from policies.agents.untrusted import (
    ALLOWED_MODEL,
    CONTAINERS,
    MAX_MODEL_DATA_BYTES,
    MAX_MODEL_ZIP_BYTES,
    NUMPY_DATA,
    NUMPY_RANDOM,
    SPACES,
    VEC_NORMALIZE,
    FileRefused,
    UnsafePickleError,
    check_nested_zip_sizes,
    check_zip_sizes,
    load_pickle,
    read_regular,
)

__all__ = [
    "RunFiles",
    "UnsafePickleError",
    "find_run",
    "load_vecnormalize_stats",
    "load_zoo_yaml",
    "read_zip_data",
    "safe_custom_objects",
    "unused_pickles",
]

#: The file names of VecNormalize statistics: mobman-train's, and the one SB3's docs and examples use.
STATS_NAMES = ("vecnormalize.pkl", "vec_normalize.pkl")


class _State:
    """Stands in for a pickled object whose attributes are data (VecNormalize, RunningMeanStd)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def __setstate__(self, state: Any) -> None:
        if isinstance(state, tuple) and len(state) == 2:  # (dict, slots)
            state = {**(state[0] or {}), **(state[1] or {})}
        if isinstance(state, dict):
            self.__dict__.update({str(k): v for k, v in state.items()})


class _Inert:
    """Stands in for a pickled object that is not used (spaces and RNG state inside vecnormalize.pkl)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def __setstate__(self, state: Any) -> None:
        pass


def _inert_factory(*args: Any, **kwargs: Any) -> _Inert:
    return _Inert()


#: The spaces of SB3 1.x (gym) files, never imported.
_GYM_SPACES = frozenset((m.replace("gymnasium.", "gym.", 1), n) for m, n in SPACES)


#: vecnormalize.pkl: numpy data for real, the SB3 objects as `_State`, spaces and RNGs as `_Inert` (classes)
#: or `_inert_factory` (numpy's `__..._ctor` functions); nothing of SB3 or gymnasium is imported.
class _VecNormalizeState(_State):
    """Stands in for the pickled VecNormalize object (the top of a statistics file)."""


_STATS_SUBSTITUTES: dict[tuple[str, str], Any] = {
    **{pair: _VecNormalizeState if pair[1] == "VecNormalize" else _State for pair in VEC_NORMALIZE},
    **{pair: _Inert for pair in SPACES | _GYM_SPACES},
    **{pair: _inert_factory if pair[1].startswith("__") else _Inert for pair in NUMPY_RANDOM},
}
_STATS_WHAT = "VecNormalize statistics (numpy data, VecNormalize, RunningMeanStd, spaces, random states)"
_MODEL_WHAT = (
    "a model.zip entry (numpy data, gymnasium spaces, Stable-Baselines3 policy and feature-extractor classes, "
    "torch activations and optimisers)"
)
_CHECKPOINT_WHAT = (
    "a training checkpoint (a model.zip's classes and Stable-Baselines3's schedules, buffers, train frequency and "
    "action noise)"
)

#: Cap on a VecNormalize file (mobman's are about 5 kB).
MAX_STATS_BYTES = 16 * 2**20


def load_vecnormalize_stats(path: Path) -> dict[str, Any]:
    """The observation statistics of a `VecNormalize` pickle, without unpickling any code.

    Returns {"norm_obs": bool, "obs_rms": {key: (mean, var)} or (mean, var), "norm_obs_keys": list or None,
    "epsilon": float, "clip_obs": float}. Raises ValueError naming the file when it cannot be read."""
    raw = read_regular(path, MAX_STATS_BYTES, "VecNormalize file")
    try:
        vn = load_pickle(raw, NUMPY_DATA | CONTAINERS, _STATS_SUBSTITUTES, _STATS_WHAT)
    except UnsafePickleError as exc:
        raise ValueError(
            f"{path}: {exc}; a vecnormalize.pkl written by VecNormalize.save holds only statistics. "
            f"Load only agents you trust"
        ) from None
    except Exception as exc:  # truncated, not a pickle, ...
        raise ValueError(
            f"{path} is not a readable VecNormalize file ({type(exc).__name__}: {exc}); copy it again from "
            f"the training run (or delete it if the agent was trained without VecNormalize)"
        ) from None
    if not isinstance(vn, _VecNormalizeState):
        raise ValueError(
            f"{path} does not hold VecNormalize statistics (it unpickles to a {type(vn).__name__}, not a "
            f"VecNormalize); give the file VecNormalize.save wrote during training, or delete it if the agent was "
            f"trained without VecNormalize"
        )
    state = vn.__dict__
    try:
        norm_obs = bool(state.get("norm_obs", False))
        rms = state.get("obs_rms")
        if norm_obs and rms is None:
            raise ValueError("norm_obs is on but there is no obs_rms")
        if isinstance(rms, dict):
            stats: Any = {str(k): _mean_var(v) for k, v in rms.items()}
        else:
            stats = _mean_var(rms) if norm_obs else None
        keys = state.get("norm_obs_keys")
        return {
            "norm_obs": norm_obs,
            "obs_rms": stats,
            "norm_obs_keys": None if keys is None else [str(k) for k in keys],
            "epsilon": float(state.get("epsilon", 1e-8)),
            "clip_obs": float(state.get("clip_obs", 10.0)),
        }
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"{path} does not hold VecNormalize statistics ({exc}); copy it again from the training run"
        ) from None


def _mean_var(rms: Any) -> tuple[np.ndarray, np.ndarray]:
    mean, var = getattr(rms, "mean", None), getattr(rms, "var", None)
    if not (isinstance(mean, (np.ndarray, float)) and isinstance(var, (np.ndarray, float))):
        raise TypeError("a RunningMeanStd without numeric mean and var")
    return np.asarray(mean, dtype=np.float64), np.asarray(var, dtype=np.float64)


def read_zip_data(path: Path) -> dict[str, Any]:
    """The JSON `data` entry of an SB3 model.zip; ValueError naming the file when it is not one."""
    try:
        with zipfile.ZipFile(path) as zf:
            check_zip_sizes(zf, path, {"data": MAX_MODEL_DATA_BYTES}, MAX_MODEL_ZIP_BYTES)
            check_nested_zip_sizes(zf, path, MAX_MODEL_ZIP_BYTES)
            data = json.loads(zf.read("data"))
    except FileRefused:
        raise
    except (zipfile.BadZipFile, KeyError, ValueError, OSError) as exc:
        raise ValueError(
            f"{path} is not a Stable-Baselines3 model file (a zip with a 'data' entry): {type(exc).__name__}: "
            f"{exc}; copy model.zip again from the training run"
        ) from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: its 'data' entry is not a JSON object; copy model.zip again from the training run")
    return data


#: model.zip entries that inference does not use, and what replaces them (`_setup_model` rebuilds the
#: learning-rate schedule; buffers and noise are only for learning).
NEUTRAL_ENTRIES: dict[str, Any] = {
    "_last_obs": None,
    "_last_original_obs": None,
    "_last_episode_starts": None,
    "ep_info_buffer": None,
    "ep_success_buffer": None,
    "lr_schedule": None,
    "learning_rate": 0.0,
    "clip_range": 0.2,
    "clip_range_vf": None,
    "train_freq": 1,
    "replay_buffer_class": None,
    "rollout_buffer_class": None,
    "action_noise": None,
}


def safe_custom_objects(
    data: dict[str, Any], path: Path, allowed: frozenset[tuple[str, str]] | None = None
) -> dict[str, Any]:
    """SB3 `custom_objects` for `Algo.load` so that it unpickles nothing: every serialized entry of `data`,
    neutral for those inference does not use, decoded with the restricted unpickler (`ALLOWED_MODEL`) for the
    others. Given `allowed` (a training checkpoint: `ALLOWED_CHECKPOINT` and more), every entry is decoded
    with it, none replaced."""
    objects: dict[str, Any] = {}
    neutral = NEUTRAL_ENTRIES if allowed is None else {}
    what = _MODEL_WHAT if allowed is None else _CHECKPOINT_WHAT
    allowed = ALLOWED_MODEL if allowed is None else allowed
    for key, value in data.items():
        if not (isinstance(value, dict) and ":serialized:" in value):
            continue
        if key in neutral:
            objects[key] = neutral[key]
            continue
        try:
            raw = base64.b64decode(value[":serialized:"].encode())
            objects[key] = load_pickle(raw, allowed, what=what)
        except UnsafePickleError as exc:
            raise ValueError(
                f"{path}: entry {key!r}: {exc}. A model.zip saved by Stable-Baselines3 for a mobman env names only "
                f"those; load only agents you trust"
            ) from None
        except (binascii.Error, pickle.UnpicklingError, EOFError, AttributeError, TypeError, ValueError) as exc:
            raise ValueError(
                f"{path}: entry {key!r} cannot be read ({type(exc).__name__}: {exc}); copy model.zip again "
                f"from the training run"
            ) from None
    return objects


# --- where the files of a run are ------------------------------------------------------------------------
@dataclass(frozen=True)
class RunFiles:
    """The files of one agent. layout: "mobman" (model.zip + config.json, or plain SB3) or "zoo"
    (rl-baselines3-zoo). stats: the VecNormalize file or None. config_json: mobman's config.json or None.
    zoo_dir: the zoo's `<ENV>/` folder (config.yml, args.yml) or None. note: a choice made (e.g. which of
    two zoo models was taken), "" if none."""

    model: Path
    layout: str
    stats: Path | None
    config_json: Path | None
    zoo_dir: Path | None
    note: str = ""


def _stats_file(folder: Path) -> Path | None:
    found = [folder / n for n in STATS_NAMES if (folder / n).is_file()]
    if len(found) > 1:
        raise ValueError(
            f"{folder} holds two VecNormalize files, {found[0].name} and {found[1].name}; it is not clear which "
            f"one the agent was trained with: delete or rename the other one"
        )
    return found[0] if found else None


def unused_pickles(run: RunFiles) -> list[Path]:
    """The `*.pkl` files beside the agent's files (the model's folder, rl-zoo's `<ENV>/`) that are not its
    statistics file: statistics saved under another name are not read, so `SB3Policy` warns about them."""
    folders = [run.model.parent] + ([run.zoo_dir] if run.zoo_dir is not None else [])
    return sorted(p for folder in folders for p in folder.glob("*.pkl") if p.is_file() and p != run.stats)


def _zoo_dirs(folder: Path) -> list[Path]:
    """Sub-folders of `folder` laid out as rl-zoo's `<ENV>/` (a config.yml or args.yml inside)."""
    if not folder.is_dir():
        return []
    return sorted(
        d for d in folder.iterdir() if d.is_dir() and ((d / "config.yml").is_file() or (d / "args.yml").is_file())
    )


def find_run(path: Path) -> RunFiles:
    """The files of the agent at `path` (a folder or a .zip). FileNotFoundError/ValueError naming what is missing
    or ambiguous."""
    folder = path if path.is_dir() else path.parent
    zoo = _zoo_dirs(folder)
    if len(zoo) > 1:
        raise ValueError(
            f"{folder} holds several rl-zoo env folders ({', '.join(d.name for d in zoo)}); give the model file, "
            f"e.g. sb3:{folder / (zoo[0].name + '.zip')}"
        )
    if zoo and not (folder / "model.zip").is_file():
        env_dir = zoo[0]
        final, best = folder / f"{env_dir.name}.zip", folder / "best_model.zip"
        note = ""
        if path.is_dir():
            if final.is_file():
                model = final
                if best.is_file():
                    note = f"took the final model {final.name}, not {best.name} (give sb3:{best} for that one)"
            elif best.is_file():
                model, note = best, f"took {best.name}: the final model {final.name} is missing"
            else:
                raise FileNotFoundError(
                    f"{folder} looks like an rl-zoo run folder (it has {env_dir.name}/) but holds neither "
                    f"{final.name} nor {best.name}; copy the model from the training run"
                )
        else:
            model = path
        return RunFiles(model, "zoo", _stats_file(env_dir), None, env_dir, note)
    model = folder / "model.zip" if path.is_dir() else path
    if not model.is_file():
        raise FileNotFoundError(
            f"no SB3 model at {str(model)!r}; give a model.zip (a mobman-train or SB3 folder, sb3:DIR or "
            f"sb3:DIR/model.zip) or an rl-zoo run folder (sb3:logs/ppo/<ENV>_1)"
        )
    config = folder / "config.json"
    return RunFiles(model, "mobman", _stats_file(folder), config if config.is_file() else None, None)


def load_zoo_yaml(path: Path) -> dict[str, Any]:
    """An rl-zoo config.yml / args.yml as a dict; only the `collections.OrderedDict` tag is built (from its
    list of [key, value] pairs), every other tag is refused by yaml's SafeLoader. ValueError naming the file."""
    import yaml

    class _ZooLoader(yaml.SafeLoader):
        pass

    def _ordered_dict(loader: yaml.SafeLoader, node: yaml.Node) -> dict[str, Any]:
        args = loader.construct_sequence(node, deep=True)  # OrderedDict(*args)
        pairs = args[0] if len(args) == 1 and isinstance(args[0], list) else None
        if pairs is None or not all(isinstance(p, list) and len(p) == 2 and isinstance(p[0], str) for p in pairs):
            raise yaml.constructor.ConstructorError(None, None, "an OrderedDict of [key, value] pairs", node.start_mark)
        return {k: v for k, v in pairs}

    _ZooLoader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict", _ordered_dict)
    try:
        data = yaml.load(path.read_text(), Loader=_ZooLoader)  # a SafeLoader subclass: no arbitrary tags
    except (yaml.YAMLError, OSError, UnicodeDecodeError) as exc:
        raise ValueError(
            f"{path} is not a readable rl-zoo YAML file ({type(exc).__name__}: {exc}); copy it again from the "
            f"training run"
        ) from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} must hold a mapping (rl-zoo's OrderedDict), got {type(data).__name__}")
    return data


def zoo_normalize(value: Any, where: Any) -> dict[str, Any]:
    """rl-baselines3-zoo's `normalize` hyperparameter (a bool, a dict, or the dict's Python text, as zoo files
    write it) as VecNormalize keyword arguments with `norm_obs` and `norm_reward` always present (`true`:
    VecNormalize's defaults, both on; `false`: both off); other keys of a dict are kept."""
    if isinstance(value, str):
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            raise ValueError(f"{where}: normalize {value!r} is neither a bool nor a dict") from None
    if isinstance(value, bool):
        return {"norm_obs": value, "norm_reward": value}
    if isinstance(value, dict):
        return {
            **value,
            "norm_obs": bool(value.get("norm_obs", True)),
            "norm_reward": bool(value.get("norm_reward", True)),
        }
    raise ValueError(f"{where}: normalize {value!r} is neither a bool nor a dict")

"""`SB3Policy`: a trained Stable-Baselines3 agent behind the same interface as the controllers.

`policies.make("sb3:runs/sac/model.zip", env)` (or the run folder, or the alias `sb3:sac-circle`) reads a run
folder written by `mobman-train`:

* `model.zip` - the agent. Its algorithm comes from `config.json`'s `"algo"`; without it, from the policy class
  recorded in the zip; failing that, PPO, SAC, TD3, A2C and DDPG are tried in turn.
* `vecnormalize.pkl` (optional) - the `VecNormalize` statistics of training. Observations are normalised
  exactly as `VecNormalize.normalize_obs` does: `clip((obs - mean) / sqrt(var + epsilon), -clip_obs,
  clip_obs)` cast to float32, with the saved `obs_rms`, `epsilon` and `clip_obs`, only for the keys in its
  `norm_obs_keys` (and only if `norm_obs` was on). The statistics are frozen: evaluation never updates them.
* `config.json` (optional) - `"algo"`, `"env_id"`, `"env_kwargs"`, `"obs_keys"` (the Dict keys the agent sees:
  the observation is filtered to them) and `"wrappers"` (a list of wrapper names or `{"name": ..., "kwargs":
  {...}}` dicts, applied in order as training applied them per env, before `VecNormalize`). Observation
  wrappers that are reproduced: `FilterObservation` (kwarg `filter_keys`) and `FlattenObservation` (the
  filtered keys concatenated in sorted order, as gymnasium's `Dict` space orders them). Wrappers that do not
  change what the agent sees at inference (`TimeLimit`, `Monitor`, `RecordEpisodeStatistics`, `ClipAction`,
  reward and termination wrappers) are accepted and ignored; any other name is refused with the list, so a
  mismatch cannot pass silently. Without `obs_keys`, the keys of the model's own observation space are used.

The agent is stateless between steps (no recurrent policies), so `reset` does nothing and `predict` accepts an
unbatched observation, a batch of one, or a longer batch (one action per env). torch and Stable-Baselines3 are
imported only when an `SB3Policy` is built; by default torch is set to one thread (`torch_threads`), which
is fastest for these small networks and kindest to a shared 2-core machine.
"""

from __future__ import annotations

import json
import pickle
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

#: Aliases of models shipped as package data: name -> path inside the installed `train` package.
ALIASES = {"sac-circle": "models/sac-circle/model.zip"}

ALGOS = ("ppo", "sac", "td3", "a2c", "ddpg")
_OBS_WRAPPERS = ("FilterObservation", "FlattenObservation")
_NEUTRAL_WRAPPERS = ("TimeLimit", "Monitor", "RecordEpisodeStatistics", "ClipAction", "TransformReward",
                     "NormalizeReward", "ClipReward", "OrderEnforcing", "PassiveEnvChecker")


def resolve_model_path(text: str) -> Path:
    """`sac-circle` -> the packaged model; a folder -> its `model.zip`; else the path itself (must exist)."""
    text = text.strip()
    if text in ALIASES:
        import importlib.resources

        try:
            root = importlib.resources.files("train")
        except ModuleNotFoundError:
            raise FileNotFoundError(f"sb3:{text} is the model shipped with the `train` package, which is not "
                                    f"installed; install mobman with `pip install -e .`") from None
        path = Path(str(root.joinpath(ALIASES[text])))
        if not path.is_file():
            raise FileNotFoundError(f"sb3:{text}: the packaged model {path} is missing (it ships with the train "
                                    f"package's baseline); train one with mobman-train and use sb3:DIR/model.zip")
        return path
    if not text:
        raise FileNotFoundError(f"sb3: needs a path, e.g. sb3:runs/sac/model.zip, or an alias: {', '.join(ALIASES)}")
    path = Path(text).expanduser()
    if path.is_dir():
        path = path / "model.zip"
    if not path.is_file():
        raise FileNotFoundError(f"no SB3 model at {str(path)!r}; give a model.zip of a mobman-train run folder "
                                f"(sb3:DIR/model.zip) or an alias: {', '.join('sb3:' + a for a in ALIASES)}")
    return path


def _algo_classes() -> dict[str, type]:
    import stable_baselines3 as sb3

    return {"ppo": sb3.PPO, "sac": sb3.SAC, "td3": sb3.TD3, "a2c": sb3.A2C, "ddpg": sb3.DDPG}


def _algo_from_zip(path: Path) -> str | None:
    """The algorithm recorded in the zip: the module of its policy class (e.g. stable_baselines3.sac.policies)."""
    try:
        with zipfile.ZipFile(path) as zf:
            data = json.loads(zf.read("data"))
        module = data["policy_class"]["__module__"]
    except (KeyError, ValueError, zipfile.BadZipFile, TypeError):
        return None
    for algo in ALGOS:
        if f".{algo}." in module:
            return algo
    return None


def _wrapper_name(item: Any) -> tuple[str, dict]:
    if isinstance(item, str):
        return item.rsplit(".", 1)[-1], {}
    if isinstance(item, dict):
        name = item.get("name", item.get("type", item.get("class")))
        if isinstance(name, str):
            return name.rsplit(".", 1)[-1], dict(item.get("kwargs", {}))
    raise ValueError(f"config.json 'wrappers' entries must be names or {{'name': ..., 'kwargs': {{...}}}}, got {item!r}")


class SB3Policy:
    """A Stable-Baselines3 agent from a run folder; see the module docstring for what is read and how."""

    name = "sb3"

    def __init__(self, model_path: str | Path, *, device: str = "cpu", torch_threads: int | None = 1):
        self.path = resolve_model_path(str(model_path))
        self.run_dir = self.path.parent
        cfg_file = self.run_dir / "config.json"
        self.config: dict = json.loads(cfg_file.read_text()) if cfg_file.is_file() else {}
        if torch_threads is not None:
            import torch

            torch.set_num_threads(int(torch_threads))
        self.model = self._load_model(device)
        self._flatten = False
        self.obs_keys = self._observation_keys()
        self._load_normalisation()

    # --- loading ---------------------------------------------------------------------------------------
    def _load_model(self, device: str) -> Any:
        classes = _algo_classes()
        algo = self.config.get("algo")
        if algo is not None:
            key = str(algo).lower()
            if key not in classes:
                raise ValueError(f"{self.run_dir / 'config.json'}: unknown algo {algo!r}; accepted: {', '.join(ALGOS)}")
            self.algo = key
            return classes[key].load(self.path, device=device)
        order = list(ALGOS)
        guess = _algo_from_zip(self.path)
        if guess:
            order.remove(guess)
            order.insert(0, guess)
        errors = []
        for key in order:
            try:
                model = classes[key].load(self.path, device=device)
            except Exception as exc:  # a zip of another algorithm fails somewhere inside load
                errors.append(f"{key}: {type(exc).__name__}: {exc}")
                continue
            self.algo = key
            return model
        raise ValueError(f"could not load {self.path} with any of {', '.join(ALGOS)}; add \"algo\" to "
                         f"{self.run_dir / 'config.json'}. Errors: " + "; ".join(errors))

    def _observation_keys(self) -> tuple[str, ...] | None:
        """The Dict keys the agent sees (None: the agent takes the whole observation unchanged)."""
        model_space = self.model.observation_space
        model_keys = tuple(getattr(model_space, "spaces", {}).keys()) or None
        keys = self.config.get("obs_keys")
        for item in self.config.get("wrappers", []) or []:
            name, kwargs = _wrapper_name(item)
            if name == "FilterObservation":
                keys = kwargs.get("filter_keys", keys)
            elif name == "FlattenObservation":
                self._flatten = True
            elif name not in _NEUTRAL_WRAPPERS:
                raise ValueError(f"{self.run_dir / 'config.json'}: wrapper {name!r} cannot be reproduced at "
                                 f"inference; supported: {', '.join(_OBS_WRAPPERS + _NEUTRAL_WRAPPERS)}")
        if keys is None:
            return model_keys
        keys = tuple(keys)
        if self._flatten:
            keys = tuple(sorted(keys))  # gymnasium's Dict space sorts its keys; flatten follows that order
        elif model_keys is not None and set(keys) != set(model_keys):
            raise ValueError(f"{self.run_dir / 'config.json'}: obs_keys {list(keys)} differ from the model's "
                             f"observation keys {list(model_keys)}")
        elif model_keys is not None:
            keys = model_keys
        return keys

    def _load_normalisation(self) -> None:
        self._norm = None
        pkl = self.run_dir / "vecnormalize.pkl"
        if not pkl.is_file():
            return
        with open(pkl, "rb") as f:
            vn = pickle.load(f)  # a VecNormalize without its venv (its __setstate__ drops it)
        if not getattr(vn, "norm_obs", False):
            return
        rms = vn.obs_rms
        if isinstance(rms, dict):
            keys = list(vn.norm_obs_keys) if vn.norm_obs_keys is not None else list(rms)
            self._norm = {k: (rms[k].mean, rms[k].var) for k in keys}
        else:
            self._norm = (rms.mean, rms.var)
        self._eps = float(vn.epsilon)
        self._clip = float(vn.clip_obs)

    # --- checks ----------------------------------------------------------------------------------------
    def check_compatible(self, facts: Any) -> None:
        """Fail early (before any rollout) if the env lacks a key the agent needs or has another action size."""
        if self.obs_keys is not None and facts.obs_keys:
            missing = [k for k in self.obs_keys if k not in facts.obs_keys]
            if missing:
                raise ValueError(f"the agent {self.path} needs observation keys {missing} that the env lacks "
                                 f"(env keys: {list(facts.obs_keys)})")
        n = int(np.prod(self.model.action_space.shape))
        if n != len(facts.action_scale):
            raise ValueError(f"the agent {self.path} outputs {n} actions; the env takes {len(facts.action_scale)}")

    # --- the Policy contract ---------------------------------------------------------------------------
    def reset(self, obs: dict, info: dict | None = None, *, seed: int | None = None) -> None:
        """Nothing to re-initialise: the agent is stateless between steps."""

    def transform(self, observation: dict) -> Any:
        """The observation as the agent saw it in training: filtered, wrapped and normalised."""
        if self.obs_keys is not None and isinstance(observation, dict):
            obs: Any = {k: np.asarray(observation[k]) for k in self.obs_keys}
        else:
            obs = observation
        if self._flatten:
            batched = np.asarray(obs[self.obs_keys[0]]).ndim == 2
            obs = np.concatenate([np.asarray(obs[k], dtype=np.float32) for k in self.obs_keys], axis=-1 if batched else 0)
        if self._norm is None:
            return obs
        eps, clip = self._eps, self._clip
        if isinstance(self._norm, dict):
            for k, (mean, var) in self._norm.items():
                obs[k] = np.clip((obs[k] - mean) / np.sqrt(var + eps), -clip, clip).astype(np.float32)
            return obs
        mean, var = self._norm
        return np.clip((obs - mean) / np.sqrt(var + eps), -clip, clip).astype(np.float32)

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self.model.predict(self.transform(observation), state=state, episode_start=episode_start,
                                  deterministic=deterministic)

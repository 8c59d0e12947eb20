"""`SB3Policy`: a trained Stable-Baselines3 agent behind the same interface as the controllers.

`policies.make("sb3:runs/sac/model.zip", env)` (or the run folder, or the alias `sb3:sac-circle`) reads a run
folder written by `mobman-train`:

* `model.zip` - the agent. Its algorithm comes from `config.json`'s `"algo"`; without it, from the policy class
  recorded in the zip; failing that, PPO, SAC, TD3, A2C and DDPG are tried in turn.
* `vecnormalize.pkl` (optional) - the `VecNormalize` statistics of training. Observations are normalised
  exactly as `VecNormalize.normalize_obs` does: `clip((obs - mean) / sqrt(var + epsilon), -clip_obs,
  clip_obs)` cast to float32, with the saved `obs_rms`, `epsilon` and `clip_obs`, only for the keys in its
  `norm_obs_keys` (and only if `norm_obs` was on). The statistics are frozen: evaluation never updates them.
* `config.json` (optional) - `"algo"`, `"env_id"`, `"env_kwargs"`, `"obs_keys"` (the Dict keys the agent sees,
  in order) and `"wrappers"` (names of observation wrappers, applied in order to the raw observation before
  it is reduced to `obs_keys`, as `mobman-train` applies them per env before `VecNormalize`). Reproduced
  here (`OBS_WRAPPERS`): `"pos_error"` adds `pos_error = target_pos - ee_pos` (3, m, float32). Names of
  wrappers that do not change what the agent sees at inference (`TimeLimit`, `Monitor`,
  `RecordEpisodeStatistics`, `ClipAction`, reward wrappers) are accepted and ignored; any other name is
  refused with the list, so a mismatch cannot pass silently. Without `obs_keys`, the keys of the model's own
  observation space are used. The kept keys are cast to float32 (the dtype the agent saw through the VecEnv's
  buffers) before normalisation.

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

#: Aliases of models shipped as package data: name -> path inside this package (policies/models/).
ALIASES = {"sac-circle": "models/sac-circle/model.zip"}

ALGOS = ("ppo", "sac", "td3", "a2c", "ddpg")


def _pos_error(obs: dict) -> dict:
    out = dict(obs)
    out["pos_error"] = (np.asarray(obs["target_pos"]) - np.asarray(obs["ee_pos"])).astype(np.float32)
    return out


#: Observation wrappers reproduced at inference: name -> (transform of the raw dict, raw keys it reads).
#: Same names and semantics as `mobman-train`'s `train.wrappers` (which may not be imported from here: the
#: dependencies point mobman_env <- policies <- eval <- train).
OBS_WRAPPERS = {"pos_error": (_pos_error, ("target_pos", "ee_pos"))}
_NEUTRAL_WRAPPERS = (
    "TimeLimit",
    "Monitor",
    "RecordEpisodeStatistics",
    "ClipAction",
    "TransformReward",
    "NormalizeReward",
    "ClipReward",
    "OrderEnforcing",
    "PassiveEnvChecker",
)


def resolve_model_path(text: str) -> Path:
    """`sac-circle` -> the packaged model; a folder -> its `model.zip`; else the path itself (must exist)."""
    text = text.strip()
    if text in ALIASES:
        # found through this package's own folder, never by importing a package by name: a user's `train.py`
        # or `policies.py` beside their script cannot hide the shipped models
        path = Path(__file__).resolve().parent / ALIASES[text]
        if not path.is_file():
            raise FileNotFoundError(
                f"sb3:{text}: the packaged model {path} is missing (it ships with mobman's policies "
                f"package); reinstall mobman, or train one with mobman-train and use sb3:DIR/model.zip"
            )
        return path
    if not text:
        raise FileNotFoundError(f"sb3: needs a path, e.g. sb3:runs/sac/model.zip, or an alias: {', '.join(ALIASES)}")
    path = Path(text).expanduser()
    if path.is_dir():
        path = path / "model.zip"
    if not path.is_file():
        raise FileNotFoundError(
            f"no SB3 model at {str(path)!r}; give a model.zip of a mobman-train run folder "
            f"(sb3:DIR/model.zip) or an alias: {', '.join('sb3:' + a for a in ALIASES)}"
        )
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


def _wrapper_names(items: Any, where: Path) -> tuple[str, ...]:
    """The observation wrappers to reproduce, in order (neutral ones dropped); unknown names fail."""
    names = []
    for item in items or []:
        name = item.get("name") if isinstance(item, dict) else item
        if not isinstance(name, str):
            raise ValueError(f"{where}: 'wrappers' entries must be names, got {item!r}")
        name = name.rsplit(".", 1)[-1]
        if name in OBS_WRAPPERS:
            names.append(name)
        elif name not in _NEUTRAL_WRAPPERS:
            raise ValueError(
                f"{where}: wrapper {name!r} cannot be reproduced at inference; supported: "
                f"{', '.join((*OBS_WRAPPERS, *_NEUTRAL_WRAPPERS))}"
            )
    return tuple(names)


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
        self.wrappers = _wrapper_names(self.config.get("wrappers"), self.run_dir / "config.json")
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
        raise ValueError(
            f'could not load {self.path} with any of {", ".join(ALGOS)}; add "algo" to '
            f"{self.run_dir / 'config.json'}. Errors: " + "; ".join(errors)
        )

    def _observation_keys(self) -> tuple[str, ...] | None:
        """The Dict keys the agent sees, in order (None: the agent takes the observation unchanged)."""
        model_keys = tuple(getattr(self.model.observation_space, "spaces", {}).keys()) or None
        keys = self.config.get("obs_keys")
        if keys is None:
            return model_keys
        keys = tuple(keys)
        if model_keys is not None and set(keys) != set(model_keys):
            raise ValueError(
                f"{self.run_dir / 'config.json'}: obs_keys {list(keys)} differ from the model's "
                f"observation keys {list(model_keys)}"
            )
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
    def required_keys(self) -> list[str]:
        """The raw observation keys the agent needs (before its wrappers add derived keys)."""
        derived = {name for name in self.wrappers}
        needed = [k for k in (self.obs_keys or ()) if k not in derived]
        for name in self.wrappers:
            needed += [k for k in OBS_WRAPPERS[name][1] if k not in needed]
        return needed

    def check_compatible(self, facts: Any) -> None:
        """Fail early (before any rollout) if the env lacks a key the agent needs or has another action size."""
        if facts.obs_keys:
            missing = [k for k in self.required_keys() if k not in facts.obs_keys]
            if missing:
                raise ValueError(
                    f"the agent {self.path} needs observation keys {missing} that the env lacks "
                    f"(env keys: {list(facts.obs_keys)})"
                )
        n = int(np.prod(self.model.action_space.shape))
        if n != len(facts.action_scale):
            raise ValueError(f"the agent {self.path} outputs {n} actions; the env takes {len(facts.action_scale)}")

    # --- the Policy contract ---------------------------------------------------------------------------
    def reset(self, obs: dict, info: dict | None = None, *, seed: int | None = None) -> None:
        """Nothing to re-initialise: the agent is stateless between steps."""

    def transform(self, observation: Any) -> Any:
        """The observation as the agent saw it in training: wrapped, reduced to `obs_keys`, normalised."""
        obs = observation
        if isinstance(obs, dict):
            for name in self.wrappers:
                obs = OBS_WRAPPERS[name][0](obs)
            keys = self.obs_keys if self.obs_keys is not None else tuple(obs)
            obs = {k: np.asarray(obs[k], dtype=np.float32) for k in keys}
        if self._norm is None:
            return obs
        eps, clip = self._eps, self._clip
        if isinstance(self._norm, dict):
            for k, (mean, var) in self._norm.items():
                obs[k] = np.clip((obs[k] - mean) / np.sqrt(var + eps), -clip, clip).astype(np.float32)
            return obs
        mean, var = self._norm
        return np.clip((np.asarray(obs, dtype=np.float32) - mean) / np.sqrt(var + eps), -clip, clip).astype(np.float32)

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self.model.predict(
            self.transform(observation), state=state, episode_start=episode_start, deterministic=deterministic
        )

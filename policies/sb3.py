"""`SB3Policy`: a trained Stable-Baselines3 agent behind the same interface as the controllers.

`policies.make("sb3:runs/sac/model.zip", env)` (or the run folder, or the alias `sb3:sac-circle`) reads a run
folder written by `mobman-train`:

* `model.zip` - the agent. Its algorithm comes from `config.json`'s `"algo"`; without it, from the policy class
  recorded in the zip (a file naming none is refused: add "algo" to config.json). SB3 loads it with every
  pickled entry supplied by `policies.sb3_files.safe_custom_objects`, so nothing in it is unpickled by SB3.
* `vecnormalize.pkl` (optional) - the `VecNormalize` statistics of training, read without unpickling code
  (`policies.sb3_files.load_vecnormalize_stats`). Observations are normalised
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

**Only load agents you trust.** SB3's files hold pickles, which can run code; `policies.sb3_files` reads
them with a restricted unpickler (numpy data, SB3 policy classes, gymnasium spaces, torch layers only) and
SB3 reads the weights with `torch.load(weights_only=True)`, which narrows what a crafted file can do, but a
model file is still a program's input and not a sandboxed one.

The agent is stateless between steps (no recurrent policies), so `reset` does nothing and `predict` accepts an
unbatched observation, a batch of one, or a longer batch (one action per env). torch and Stable-Baselines3 are
imported only when an `SB3Policy` is built; by default torch is set to one thread (`torch_threads`), which
is fastest for these small networks and kindest to a shared 2-core machine.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from policies.sb3_files import load_vecnormalize_stats, read_zip_data, safe_custom_objects

#: Aliases of models shipped as package data: name -> path inside this package (`policies/models/`), found
#: through this file's own location, so a user's `train.py` or `policies.py` beside their script cannot hide it.
ALIASES = {"sac-circle": "models/sac-circle/model.zip"}

#: What `sb3:` policies need, and how to install it.
INSTALL_HINT = 'pip install "mobman[rl]"'

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
        path = Path(__file__).resolve().parent / ALIASES[text]
        if not path.is_file():
            raise FileNotFoundError(
                f"sb3:{text}: the packaged model {path} is missing (it ships with mobman's policies package); "
                f"reinstall mobman, or train one with mobman-train and use sb3:DIR/model.zip"
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


def require_sb3() -> None:
    """Import torch and Stable-Baselines3, or raise ImportError naming the extra to install."""
    try:
        import stable_baselines3  # noqa: F401
        import torch  # noqa: F401
    except ImportError as exc:
        raise ImportError(
            f"sb3: policies need Stable-Baselines3 and torch, which are not installed here ({exc}); install "
            f"them with {INSTALL_HINT}"
        ) from None


def _algo_classes() -> dict[str, Any]:
    import stable_baselines3 as sb3

    return {"ppo": sb3.PPO, "sac": sb3.SAC, "td3": sb3.TD3, "a2c": sb3.A2C, "ddpg": sb3.DDPG}


def _algo_from_zip(data: dict) -> str | None:
    """The algorithm recorded in the zip: the module of its policy class (e.g. stable_baselines3.sac.policies)."""
    try:
        module = data["policy_class"]["__module__"]
    except (KeyError, TypeError):
        return None
    for algo in ALGOS:
        if f".{algo}." in str(module):
            return algo
    return None


def _read_config(path: Path) -> dict:
    """The run folder's config.json ({} without one); ValueError naming the file when it is not JSON."""
    if not path.is_file():
        return {}
    try:
        data = json.loads(path.read_text())
    except (ValueError, OSError) as exc:
        raise ValueError(
            f"{path} is not a readable JSON file ({type(exc).__name__}: {exc}); copy it again from the training "
            f"run, or delete it to load model.zip on its own"
        ) from None
    if not isinstance(data, dict):
        raise ValueError(f"{path} must hold a JSON object (the run's config), got {type(data).__name__}")
    return data


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
        require_sb3()
        self.path = resolve_model_path(str(model_path))
        self.run_dir = self.path.parent
        self.config: dict = _read_config(self.run_dir / "config.json")
        if torch_threads is not None:
            import torch

            torch.set_num_threads(int(torch_threads))
        self.model = self._load_model(device)
        self.wrappers = _wrapper_names(self.config.get("wrappers"), self.run_dir / "config.json")
        self.obs_keys = self._observation_keys()
        self._load_normalisation()

    # --- loading ---------------------------------------------------------------------------------------
    def _load_model(self, device: str) -> Any:
        """Load model.zip once with the algorithm of config.json's "algo" (else the one its policy class
        names); SB3 unpickles nothing (`safe_custom_objects`)."""
        classes = _algo_classes()
        data = read_zip_data(self.path)
        algo = self.config.get("algo")
        key: str | None
        if algo is not None:
            key = str(algo).lower()
            if key not in classes:
                raise ValueError(f"{self.run_dir / 'config.json'}: unknown algo {algo!r}; accepted: {', '.join(ALGOS)}")
        else:
            key = _algo_from_zip(data)
        if key is None:
            raise ValueError(
                f"{self.path}: its policy class names no known algorithm ({', '.join(ALGOS)}); add "
                f'"algo" to {self.run_dir / "config.json"}'
            )
        objects = safe_custom_objects(data, self.path)
        try:
            model = classes[key].load(self.path, device=device, custom_objects=objects)
        except Exception as exc:
            raise ValueError(
                f"{self.path}: cannot load it as a {key.upper()} model ({type(exc).__name__}: {exc})"
            ) from None
        self.algo = key
        return model

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
        self._norm: Any = None
        pkl = self.run_dir / "vecnormalize.pkl"
        if not pkl.is_file():
            return
        stats = load_vecnormalize_stats(pkl)
        if not stats["norm_obs"]:
            return
        rms = stats["obs_rms"]
        if isinstance(rms, dict):
            keys = stats["norm_obs_keys"] if stats["norm_obs_keys"] is not None else list(rms)
            missing = [k for k in keys if k not in rms]
            if missing:
                raise ValueError(f"{pkl}: norm_obs_keys {missing} have no statistics; copy it again from training")
            self._norm = {k: rms[k] for k in keys}
        else:
            self._norm = rms
        self._eps = stats["epsilon"]
        self._clip = stats["clip_obs"]

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

"""`SB3Policy`: a trained Stable-Baselines3 agent behind the same interface as the controllers.

`policies.make("sb3:runs/sac/model.zip", env)` (or the run folder, or the alias of a shipped model, `ALIASES`:
the name of a folder of `policies/models/`, e.g. `sb3:sac-circle`, `sb3:ppo-circle`) reads a run folder
written by `mobman-train`, by plain Stable-Baselines3 (`model.save("DIR/model.zip")`, optionally
`VecNormalize.save("DIR/vec_normalize.pkl")`) or by rl-baselines3-zoo (see below):

* `model.zip` - the agent. Its algorithm comes from `config.json`'s `"algo"`; without it, from the policy class
  recorded in the zip (PPO or A2C for the actor-critic class they share, by PPO's own entries; a file naming
  none is refused: add "algo" to config.json). SB3 loads it with every
  pickled entry supplied by `policies.agents.sb3_files.safe_custom_objects`, so nothing in it is unpickled by SB3.
* `vecnormalize.pkl` or `vec_normalize.pkl` (optional; both present: refused, naming both) - the
  `VecNormalize` statistics of training, read without unpickling code
  (`policies.agents.sb3_files.load_vecnormalize_stats`). Observations are normalised
  exactly as `VecNormalize.normalize_obs` does: `clip((obs - mean) / sqrt(var + epsilon), -clip_obs,
  clip_obs)` cast to float32, with the saved `obs_rms`, `epsilon` and `clip_obs`, only for the keys in its
  `norm_obs_keys` (and only if `norm_obs` was on). The statistics are frozen: evaluation never updates them.
  A file that does not unpickle to VecNormalize statistics is refused, as is a missing (or norm_obs-off)
  statistics file when config.json says `"normalize_obs": true` (what mobman-train records), so an agent is
  never evaluated silently unnormalised; any other `*.pkl` beside the agent (statistics saved under another
  name) gives a `UserWarning` naming it, since it is not read.
* `config.json` (optional) - `"algo"`, `"env_id"`, `"env_kwargs"`, `"obs_keys"` (the Dict keys the agent sees,
  in order) and `"wrappers"` (names of observation wrappers, applied in order to the raw observation before
  it is reduced to `obs_keys`, as `mobman-train` applies them per env before `VecNormalize`). Reproduced
  here (`OBS_WRAPPERS`): `"pos_error"` adds `pos_error = target_pos - ee_pos` (3, m, float32); `"agent"` is
  the robot-independent, clock-free interface of `policies.agents.agent_interface` (mobman-train's default): the
  observation becomes its keys, and the agent's 9 action slots are mapped to the env's n + 2 actuators in
  `predict` (the padded slots dropped), so one agent acts on arms of up to 7 joints. Names of
  wrappers that do not change what the agent sees at inference (`TimeLimit`, `Monitor`,
  `RecordEpisodeStatistics`, `ClipAction`, reward wrappers) are accepted and ignored; any other name is
  refused with the list, so a mismatch cannot pass silently. Without `obs_keys`, the keys of the model's own
  observation space are used. The kept keys are cast to the dtype of the model's space for them (what the
  agent saw through the VecEnv's buffers; float32 for mobman's envs) before normalisation.

A model whose observation space is a `Box` was trained on `gymnasium.wrappers.FlattenObservation`: the kept
keys (all of the env's keys without `obs_keys`) are concatenated in the order of a `gymnasium.spaces.Dict`
of them (gymnasium sorts a plain dict's keys), each flattened, and cast to the model's dtype, exactly as
`gymnasium.spaces.flatten` and the VecEnv's buffer do, before normalisation.

rl-baselines3-zoo (`sb3:logs/ppo/WheeledPuma-Circle-v0_1`, the folder or its `<ENV>.zip`): the final model
`<ENV>.zip` (else `best_model.zip`; when both exist the final one is taken and a warning says so), the
statistics `<ENV>/vecnormalize.pkl`, and `<ENV>/config.yml` (the hyperparameters): its `env_wrapper`
`train.wrappers.AgentObservation` (kwargs `wrappers`, `obs_keys`) gives the wrappers and keys above,
`train.wrappers.AliveBonus` (reward only) and `gymnasium.wrappers.FlattenObservation` (reproduced from the
model's Box space) are accepted, any other wrapper, and `frame_stack`, is refused, naming it; `normalize`
asking for observation statistics without the file is refused. `<ENV>/args.yml`'s `env` and `env_kwargs`
are recorded (`trained_env`), as are config.json's `env_id`/`env_kwargs`; the algorithm is args.yml's `algo`.
The zoo's zip also pickles a learning-rate schedule naming `rl_zoo3`: like every entry inference does not
use, it is replaced without being decoded, so rl_zoo3 need not be installed.

Before any rollout (`check_compatible`, which `policies.make` calls) the env's observation, passed through the
agent's transforms, must have the model's observation space (keys and shapes) and the env's action space the
model's (shape and bounds); otherwise the load is refused naming both spaces. An env id other than the one
the agent was trained on gives a `UserWarning` (evaluating on another task is legitimate, e.g. a
generalisation test, but should be deliberate); env kwargs are not compared (the learning-only ones such as
`reward_weights` and `error_bound` differ from evaluation by design).

**Only load agents you trust.** SB3's files hold pickles, which can run code; `policies.agents.sb3_files` reads
them with a restricted unpickler (numpy data, SB3 policy classes, gymnasium spaces, torch layers only) and
SB3 reads the weights with `torch.load(weights_only=True)`, which narrows what a crafted file can do, but a
model file is still a program's input and not a sandboxed one.

The agent is stateless between steps (no recurrent policies), so `reset` does nothing and `predict` accepts an
unbatched observation, a batch of one, or a longer batch (one action per env). torch and Stable-Baselines3 are
imported only when an `SB3Policy` is built; by default torch is set to one thread (`torch_threads`), which
is fastest for these small networks and kindest to a shared 2-core machine.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from policies.agents import agent_interface
from policies.agents.sb3_files import (
    STATS_NAMES,
    RunFiles,
    find_run,
    load_vecnormalize_stats,
    load_zoo_yaml,
    read_zip_data,
    safe_custom_objects,
    unused_pickles,
    zoo_normalize,
)
from policies.agents.untrusted import file_sha256
from policies.agents.untrusted_json import read_json

#: Cap on an agent's config.json (the shipped ones: 2 kB).
MAX_CONFIG_BYTES = 16 * 2**20

#: The observation wrapper name of `policies.agents.agent_interface`: an agent trained with it outputs the interface's
#: `N_ACTIONS` padded actions, which `predict` maps back to the env's n + 2.
AGENT_WRAPPER = "agent"

#: Folder of the models shipped as package data, `policies/models/` (found through this file's own location, so a
#: user's `train.py` or `policies.py` beside their script cannot hide it).
MODELS_DIR = Path(__file__).resolve().parents[1] / "models"


def _shipped_models() -> dict[str, str]:
    """name -> path inside this package of every shipped model: each folder of `models/` holding a model.zip
    (and a README.md saying how it was trained and chosen), by its folder name."""
    if not MODELS_DIR.is_dir():
        return {}
    return {d.name: f"models/{d.name}/model.zip" for d in sorted(MODELS_DIR.iterdir()) if (d / "model.zip").is_file()}


#: Aliases of the shipped models (`sb3:sac-circle`, `sb3:ppo-circle`, ...): the folders of `policies/models/`.
ALIASES = _shipped_models()

#: What `sb3:` policies need, and how to install it.
INSTALL_HINT = 'pip install "mobman[rl]"'

ALGOS = ("ppo", "sac", "td3", "a2c", "ddpg")


def _pos_error(obs: dict) -> dict:
    out = dict(obs)
    out["pos_error"] = (np.asarray(obs["target_pos"]) - np.asarray(obs["ee_pos"])).astype(np.float32)
    return out


#: Observation wrappers reproduced at inference: name -> (transform of the raw dict, raw keys it reads).
#: Same names and semantics as `mobman-train`'s `train.wrappers` (which may not be imported from here: the
#: dependencies point mobman_env <- policies <- eval <- train). `"agent"` is the robot-independent interface of
#: `policies.agents.agent_interface` (clock-free observation; its 9-slot action is mapped back to the robot's own).
OBS_WRAPPERS = {
    "pos_error": (_pos_error, ("target_pos", "ee_pos")),
    AGENT_WRAPPER: (agent_interface.agent_observation, agent_interface.ENV_KEYS),
}
#: The keys a wrapper adds (default: its own name, as "pos_error").
_WRAPPER_KEYS = {AGENT_WRAPPER: agent_interface.AGENT_OBS_KEYS}
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

#: rl-zoo `env_wrapper` entries: the one that defines the agent's view, and those that do not change it.
ZOO_AGENT_VIEW = "train.wrappers.AgentObservation"
ZOO_NEUTRAL = ("train.wrappers.AliveBonus", "gymnasium.wrappers.FlattenObservation")


def resolve_model_path(text: str) -> Path:
    """`ppo-circle` (an alias of `ALIASES`) -> the packaged model; a folder -> its model (`model.zip`, or
    rl-zoo's `<ENV>.zip`); else
    the path itself (must exist)."""
    return resolve_run(text).model


def resolve_run(text: str) -> RunFiles:
    """The files of the agent `text` names (an alias, a folder, a model file); see
    `policies.agents.sb3_files.find_run`."""
    return find_run(_model_path(text))


def _model_path(text: str) -> Path:
    text = text.strip()
    if text in ALIASES:
        path = MODELS_DIR.parent / ALIASES[text]
        if not path.is_file():
            raise FileNotFoundError(
                f"sb3:{text}: the packaged model {path} is missing (it ships with mobman's policies package); "
                f"reinstall mobman, or train one with mobman-train and use sb3:DIR/model.zip"
            )
        return path
    if not text:
        raise FileNotFoundError(f"sb3: needs a path, e.g. sb3:runs/sac/model.zip, or an alias: {', '.join(ALIASES)}")
    path = Path(text).expanduser()
    if not path.exists():
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
    """The algorithm recorded in the zip: the module of its policy class (e.g. stable_baselines3.sac.policies);
    for the actor-critic policies PPO and A2C share (stable_baselines3.common.policies, what plain SB3 saves for
    `"MultiInputPolicy"`), PPO if the zip holds PPO's own `n_epochs` and `clip_range`, else A2C."""
    try:
        module = str(data["policy_class"]["__module__"])
    except (KeyError, TypeError):
        return None
    for algo in ALGOS:
        if f".{algo}." in module:
            return algo
    if module == "stable_baselines3.common.policies":
        return "ppo" if "n_epochs" in data and "clip_range" in data else "a2c"
    return None


def _read_config(path: Path) -> dict:
    """The run folder's config.json ({} without one); ValueError naming the file when it is not JSON."""
    if not path.exists() and not path.is_symlink():
        return {}
    try:  # the one JSON reader: a regular file under a cap (a FIFO or /dev/zero is refused), UTF-8, bounded nesting
        data = read_json(path, MAX_CONFIG_BYTES, "run config")
    except (ValueError, OSError) as exc:
        raise ValueError(
            f"{path} is not a readable JSON file ({exc}); copy it again from the training run, or delete it to "
            f"load model.zip on its own"
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


def _zoo_view(config: dict, where: Path) -> dict:
    """mobman's config keys (`wrappers`, `obs_keys`) from rl-zoo's `env_wrapper`; refuses what it cannot reproduce."""
    if config.get("frame_stack"):
        raise ValueError(f"{where}: frame_stack {config['frame_stack']!r} cannot be reproduced at inference")
    items = config.get("env_wrapper") or []
    items = items if isinstance(items, list) else [items]
    view: dict = {}
    for item in items:
        name, kwargs = next(iter(item.items())) if isinstance(item, dict) and len(item) == 1 else (item, None)
        if not isinstance(name, str):
            raise ValueError(f"{where}: env_wrapper entry {item!r} is not a name or {{name: kwargs}}")
        if name == ZOO_AGENT_VIEW:
            kwargs = kwargs or {}
            view["wrappers"] = list(kwargs.get("wrappers") or [])
            if kwargs.get("obs_keys") is not None:
                view["obs_keys"] = list(kwargs["obs_keys"])
        elif name not in ZOO_NEUTRAL:
            raise ValueError(
                f"{where}: env_wrapper {name!r} cannot be reproduced at inference; accepted: "
                f"{', '.join((ZOO_AGENT_VIEW, *ZOO_NEUTRAL))}"
            )
    return view


def _describe(space: Any) -> str:
    """A one-line text of a gymnasium space: Box(low, high, shape, dtype) with the bounds' range, Dict of them."""
    import gymnasium

    if isinstance(space, gymnasium.spaces.Box):
        low, high = np.asarray(space.low), np.asarray(space.high)
        lo = f"{low.min():g}" if low.min() == low.max() else f"{low.min():g}..{low.max():g}"
        hi = f"{high.min():g}" if high.min() == high.max() else f"{high.min():g}..{high.max():g}"
        return f"Box({lo}, {hi}, {space.shape}, {space.dtype})"
    if isinstance(space, gymnasium.spaces.Dict):
        return "Dict(" + ", ".join(f"{k!r}: {_describe(v)}" for k, v in space.spaces.items()) + ")"
    return repr(space)


class SB3Policy:
    """A Stable-Baselines3 agent from a run folder; see the module docstring for what is read and how.

    Attributes after loading: `path` (the model file), `run_dir`, `layout` ("mobman" or "zoo"), `stats_path`
    (the VecNormalize file or None), `config` (config.json's content, or for rl-zoo the keys derived from
    config.yml), `trained_env` ({"env_id", "env_kwargs"} the run recorded, values None when unknown),
    `artefacts` (every file read: `[{"path": str, "sha256": hex}, ...]`, the model first, then the statistics
    and the configuration files; the `policy` artefacts of results.json schema 3)."""

    name = "sb3"
    #: the knowledge class (`policies.knowledge`): an agent learns from observations and rewards alone
    knowledge = "none"

    def __init__(self, model_path: str | Path, *, device: str = "cpu", torch_threads: int | None = 1):
        require_sb3()
        run = resolve_run(str(model_path))
        self.path, self.run_dir, self.layout, self.stats_path = run.model, run.model.parent, run.layout, run.stats
        if run.note:
            warnings.warn(f"sb3:{model_path}: {run.note}", UserWarning, stacklevel=2)
        unused = unused_pickles(run)
        if unused:
            warnings.warn(
                f"sb3:{model_path}: {', '.join(str(p) for p in unused)} not used: only "
                f"{' or '.join(STATS_NAMES)} is read as the agent's VecNormalize statistics; if one of them holds "
                f"the statistics, rename it to {STATS_NAMES[0]}, else move it out of the agent's folder",
                UserWarning,
                stacklevel=2,
            )
        self._config_file = run.config_json or self.run_dir / "config.json"
        if run.zoo_dir is not None:
            self._config_file = run.zoo_dir / "config.yml"
            self.config = self._zoo_config(run)
        else:
            self.config = _read_config(self._config_file)
        self.trained_env = {"env_id": self.config.get("env_id"), "env_kwargs": self.config.get("env_kwargs")}
        if torch_threads is not None:
            import torch

            torch.set_num_threads(int(torch_threads))
        self.model = self._load_model(device)
        from policies.agents.sb3_actor import numpy_actor

        self._actor = numpy_actor(self.model)  # deterministic actions, the same bits for any batch size
        self.wrappers = _wrapper_names(self.config.get("wrappers"), self._config_file)
        self.obs_keys = self._observation_keys()
        self._residual_settings()
        self._load_normalisation()
        loaded = [self.path, self.stats_path, *self._config_files(run)]
        self.artefacts = [{"path": str(p), "sha256": file_sha256(p)} for p in loaded if p is not None]

    # --- loading ---------------------------------------------------------------------------------------
    def _residual_settings(self) -> None:
        """A residual agent (config.json's env_kwargs name `residual_base`: `train.dev_env`): its base spec, a
        built-in controller (a file names no code), and the residual's scale. `policies.make` builds the base for
        the env (`base`) and gives the agent the base's knowledge class."""
        kwargs = self.config.get("env_kwargs") or {}
        base = kwargs.get(agent_interface.RESIDUAL_BASE) if isinstance(kwargs, dict) else None
        self.residual_base: str | None = None
        self.base: Any = None
        self._base_slots: np.ndarray | None = None
        if base is None:
            return
        name, _, options = base.partition(":") if isinstance(base, str) else ("", "", "")
        if not re.fullmatch(r"[a-z][a-z0-9-]*", name) or (options and "=" not in options):
            raise ValueError(
                f"{self._config_file}: {agent_interface.RESIDUAL_BASE}={base!r} is not a built-in controller "
                "spec (a name such as 'qp', with options 'qp:key=value'); a residual agent's base must be one"
            )
        scale = kwargs.get(agent_interface.RESIDUAL_SCALE, agent_interface.DEFAULT_RESIDUAL_SCALE)
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not scale > 0:
            raise ValueError(f"{self._config_file}: {agent_interface.RESIDUAL_SCALE}={scale!r} must be a number > 0")
        # `policies.make` checks the name against the built-ins, builds the base for the env and sets `knowledge`
        # to the base's (the agent reads what its base reads, e.g. the catalogue: nominal)
        self.residual_base, self.residual_scale = base, float(scale)

    def _config_files(self, run: RunFiles) -> list[Path]:
        """The configuration files read: config.json, or rl-zoo's config.yml and args.yml."""
        if run.zoo_dir is not None:
            return [p for p in (run.zoo_dir / "config.yml", run.zoo_dir / "args.yml") if p.is_file()]
        return [self._config_file] if self._config_file.is_file() else []

    def _zoo_config(self, run: RunFiles) -> dict:
        """mobman's config keys from rl-zoo's `<ENV>/config.yml` and `<ENV>/args.yml`."""
        assert run.zoo_dir is not None
        cfg_path, args_path = run.zoo_dir / "config.yml", run.zoo_dir / "args.yml"
        hp = load_zoo_yaml(cfg_path) if cfg_path.is_file() else {}
        args = load_zoo_yaml(args_path) if args_path.is_file() else {}
        config: dict = {"env_id": args.get("env", run.zoo_dir.name), "env_kwargs": args.get("env_kwargs") or {}}
        if isinstance(args.get("algo"), str):
            config["algo"] = args["algo"]
        config.update(_zoo_view(hp, cfg_path))
        if zoo_normalize(hp.get("normalize", False), cfg_path)["norm_obs"] and run.stats is None:
            raise ValueError(
                f"{cfg_path}: normalize {hp.get('normalize')!r} says the agent saw normalised observations, but "
                f"{run.zoo_dir / 'vecnormalize.pkl'} is missing; copy it from the training run"
            )
        return config

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
                raise ValueError(f"{self._config_file}: unknown algo {algo!r}; accepted: {', '.join(ALGOS)}")
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

    @property
    def flattens(self) -> bool:
        """Whether the agent takes a Box (a `FlattenObservation` of the dict) rather than a Dict."""
        import gymnasium

        return isinstance(self.model.observation_space, gymnasium.spaces.Box)

    def _observation_keys(self) -> tuple[str, ...] | None:
        """The Dict keys the agent sees, in order (None: all of the observation's keys)."""
        model_keys = tuple(getattr(self.model.observation_space, "spaces", {}).keys()) or None
        keys = self.config.get("obs_keys")
        if keys is None:
            return model_keys
        keys = tuple(keys)
        if model_keys is not None and set(keys) != set(model_keys):
            raise ValueError(
                f"{self._config_file}: obs_keys {list(keys)} differ from the model's "
                f"observation keys {list(model_keys)}"
            )
        return keys

    def _load_normalisation(self) -> None:
        self._norm: Any = None
        pkl = self.stats_path
        says = self.config.get("normalize_obs")  # mobman-train's config.json records it
        if pkl is None:
            if says is True:
                raise ValueError(
                    f"{self._config_file}: normalize_obs is true (the agent saw normalised observations) but "
                    f"{self.run_dir} holds no {STATS_NAMES[0]}; copy it from the training run"
                )
            return
        stats = load_vecnormalize_stats(pkl)
        if says is True and not stats["norm_obs"]:
            raise ValueError(
                f"{self._config_file}: normalize_obs is true but {pkl} holds statistics with norm_obs off; copy the "
                f"statistics of this run from its training folder"
            )
        if not stats["norm_obs"]:
            return
        rms = stats["obs_rms"]
        if isinstance(rms, dict):
            if self.flattens:
                raise ValueError(f"{pkl} holds per-key statistics but the model {self.path} takes a Box observation")
            keys = stats["norm_obs_keys"] if stats["norm_obs_keys"] is not None else list(rms)
            missing = [k for k in keys if k not in rms]
            if missing:
                raise ValueError(f"{pkl}: norm_obs_keys {missing} have no statistics; copy it again from training")
            self._norm = {k: rms[k] for k in keys}
        else:
            if not self.flattens:
                raise ValueError(f"{pkl} holds statistics of a Box observation but the model {self.path} takes a Dict")
            self._norm = rms
        self._eps = stats["epsilon"]
        self._clip = stats["clip_obs"]

    # --- checks ----------------------------------------------------------------------------------------
    def required_keys(self) -> list[str]:
        """The raw observation keys the agent needs (before its wrappers add derived keys)."""
        derived = {key for name in self.wrappers for key in _WRAPPER_KEYS.get(name, (name,))}
        derived.add(agent_interface.BASE_ACTION)  # a residual agent's base computes it
        needed = [k for k in (self.obs_keys or ()) if k not in derived]
        for name in self.wrappers:
            needed += [k for k in OBS_WRAPPERS[name][1] if k not in needed]
        return needed

    def check_compatible(self, facts: Any, env: Any = None) -> None:
        """Fail early (before any rollout) if the env lacks a key the agent needs, or (given `env`) if the env's
        observation after the agent's transforms, or its action space, differs from the model's (naming both
        spaces). Warns when `env` is another env id than the agent was trained on."""
        if facts.obs_keys:
            missing = [k for k in self.required_keys() if k not in facts.obs_keys]
            if missing:
                raise ValueError(
                    f"the agent {self.path} needs observation keys {missing} that the env lacks "
                    f"(env keys: {list(facts.obs_keys)})"
                )
        n = int(np.prod(self.model.action_space.shape))
        if self.padded:
            if n != agent_interface.N_ACTIONS:
                raise ValueError(
                    f"the agent {self.path} lists the {AGENT_WRAPPER!r} interface but outputs {n} actions, not "
                    f"{agent_interface.N_ACTIONS}; its config.json does not match its model"
                )
            agent_interface.arm_joints(len(facts.action_scale))  # the env's arm fits the 7 arm slots
        elif n != len(facts.action_scale):
            raise ValueError(f"the agent {self.path} outputs {n} actions; the env takes {len(facts.action_scale)}")
        if env is not None:
            self._check_spaces(env)

    def _check_spaces(self, env: Any) -> None:
        import gymnasium

        from policies.base import unwrap_env

        base = unwrap_env(env)
        raw = base.observation_space
        if isinstance(raw, gymnasium.spaces.Dict):
            zeros = {k: np.zeros(tuple(sp.shape or ()), dtype=sp.dtype or np.float32) for k, sp in raw.spaces.items()}
            view = self._view(zeros)
            produced = {key for name in self.wrappers for key in _WRAPPER_KEYS.get(name, ())}
            seen: Any = (
                gymnasium.spaces.Box(-np.inf, np.inf, np.shape(view), np.asarray(view).dtype)
                if not isinstance(view, dict)
                else gymnasium.spaces.Dict(
                    {
                        k: raw.spaces[k]
                        if k in raw.spaces and k not in produced
                        else gymnasium.spaces.Box(-np.inf, np.inf, np.shape(v), v.dtype)
                        for k, v in view.items()
                    }
                )
            )
        else:
            seen = raw
        model_obs = self.model.observation_space
        if isinstance(model_obs, gymnasium.spaces.Dict):
            same = (
                isinstance(seen, gymnasium.spaces.Dict)
                and set(seen.spaces) == set(model_obs.spaces)
                and all(seen.spaces[k].shape == model_obs.spaces[k].shape for k in model_obs.spaces)
            )
        else:
            same = not isinstance(seen, gymnasium.spaces.Dict) and seen.shape == model_obs.shape
        if not same:
            raise ValueError(
                f"the agent {self.path} takes observations {_describe(model_obs)}, but the env's observation "
                f"through the agent's transforms (wrappers {list(self.wrappers)}, keys "
                f"{list(self.obs_keys) if self.obs_keys else 'all'}{', flattened' if self.flattens else ''}) is "
                f"{_describe(seen)}; evaluate it on the env (and obs_keys / wrappers) it was trained with"
            )
        model_act, act = self.model.action_space, getattr(base, "action_space", None)
        if self.padded:
            act = None  # checked in check_compatible: the 9 slots map onto any arm of up to 7 joints
        if act is not None and not (
            getattr(act, "shape", None) == model_act.shape
            and np.array_equal(np.asarray(getattr(act, "low", np.nan)), np.asarray(model_act.low))
            and np.array_equal(np.asarray(getattr(act, "high", np.nan)), np.asarray(model_act.high))
        ):
            raise ValueError(
                f"the agent {self.path} outputs actions in {_describe(model_act)}, but the env takes "
                f"{_describe(act)}; evaluate it on the env it was trained with"
            )
        try:
            env_id = base.spec.id
        except AttributeError:
            env_id = None
        trained = self.trained_env.get("env_id")
        if trained and env_id and trained not in (env_id, agent_interface.DEV_TRACK_ID):
            warnings.warn(
                f"the agent {self.path} was trained on {trained} and is evaluated on {env_id}",
                UserWarning,
                stacklevel=3,
            )

    # --- the Policy contract ---------------------------------------------------------------------------
    def reset(self, obs: dict, info: dict | None = None, *, seed: int | None = None) -> None:
        """The agent is stateless between steps; a residual agent resets its base."""
        if self.base is not None:
            self.base.reset(obs, info, seed=seed)

    def _view(self, observation: Any) -> Any:
        """The observation through the agent's wrappers and keys (and flattened for a Box model), unnormalised."""
        obs = observation
        if not isinstance(obs, dict):
            return obs
        for name in self.wrappers:
            obs = OBS_WRAPPERS[name][0](obs)
        if self.residual_base is not None:  # the base's action of this step (zeros before any: the space check)
            lead = np.shape(obs["pos_error"])[:-1]
            slots = self._base_slots
            obs = {
                **obs,
                agent_interface.BASE_ACTION: np.zeros((*lead, agent_interface.N_ACTIONS), np.float32)
                if slots is None
                else slots,
            }
        keys = self.obs_keys if self.obs_keys is not None else tuple(obs)
        space = self.model.observation_space
        if self.flattens:
            import gymnasium

            # gymnasium.spaces.flatten's order: that of a Dict space of the kept keys (sorted for a plain dict)
            order = list(gymnasium.spaces.Dict({k: gymnasium.spaces.Discrete(1) for k in keys}).spaces)
            arrays = [np.asarray(obs[k]) for k in order]
            batched = arrays[0].ndim >= 2
            parts = [a.reshape(a.shape[0], -1) if batched else a.reshape(-1) for a in arrays]
            return np.concatenate(parts, axis=-1).astype(space.dtype)
        dtypes = getattr(space, "spaces", {})
        return {k: np.asarray(obs[k], dtype=dtypes[k].dtype if k in dtypes else np.float32) for k in keys}

    def transform(self, observation: Any) -> Any:
        """The observation as the agent saw it in training: wrapped, reduced to `obs_keys` (flattened for a Box
        model), normalised."""
        obs = self._view(observation)
        if self._norm is None:
            return obs
        if isinstance(self._norm, dict):
            for k, (mean, var) in self._norm.items():
                obs[k] = self._normalize(obs[k], mean, var)
            return obs
        mean, var = self._norm
        return self._normalize(np.asarray(obs), mean, var)

    def _normalize(self, x: Any, mean: Any, var: Any) -> np.ndarray:
        """`VecNormalize.normalize_obs`'s formula (one home): clip((x - mean) / sqrt(var + eps), +-clip_obs), float32."""
        return np.clip((x - mean) / np.sqrt(var + self._eps), -self._clip, self._clip).astype(np.float32)

    @property
    def padded(self) -> bool:
        """Whether the agent speaks the robot-independent interface (9 action slots, mapped to the env's own)."""
        return AGENT_WRAPPER in self.wrappers

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        if self.residual_base is not None:
            return self._predict_residual(observation, episode_start, deterministic), state
        action, state = self._act(self.transform(observation), state, episode_start, deterministic)
        if self.padded:
            action = agent_interface.env_action(action, np.shape(observation["joint_pos"])[-1])
        return action, state

    def _act(self, obs: Any, state: Any, episode_start: Any, deterministic: bool) -> tuple[Any, Any]:
        """The model's action for the transformed observation: `policies.agents.sb3_actor` where it serves
        (deterministic actor-critic MLPs: row i's bits do not depend on the batch), else SB3's `predict`."""
        if deterministic and self._actor is not None:
            return self._actor(obs), state
        return self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)

    def _predict_residual(self, observation: dict, episode_start: Any, deterministic: bool) -> np.ndarray:
        """The base's action plus the agent's scaled residual (`agent_interface.residual_action`, as in training)."""
        if self.base is None:
            raise RuntimeError(
                f"the residual agent {self.path} has no base controller: build it with policies.make('sb3:...', env)"
            )
        self._base_slots = agent_interface.base_action(self.base, observation, episode_start)
        residual, _ = self._act(self.transform(observation), None, None, deterministic)
        combined = agent_interface.residual_action(self._base_slots, residual, self.residual_scale)
        return agent_interface.env_action(combined, np.shape(observation["joint_pos"])[-1])

"""`TrainConfig`: everything one training run needs, frozen, with a JSON round trip.

The CLI parses into it and calls `train.run.run(config)`; the run folder's `config.json` holds `to_dict()` plus
the resolved hyperparameters and the keys `policies.agents.sb3.SB3Policy` reads ("algo", "env_id", "env_kwargs",
"obs_keys", "wrappers").
"""

from __future__ import annotations

import dataclasses
import inspect
import json
from dataclasses import dataclass, field
from typing import Any

from eval.metrics import DEFAULT_TOLERANCE
from mobman_env.validation import integer, number
from policies.agents import agent_interface
from policies.agents.agent_interface import AGENT_OBS_KEYS
from train import algos
from train.wrappers import check_wrappers

#: Env arguments chosen for learning (not for evaluation): a reward in units of 5 cm of error (tracking weight
#: 20, the env's effort/tracking ratio of 1e-3 kept) and episodes that end once the error passes 10 cm, so
#: early experience stays near the path instead of 2000 steps of flailing. Dropped by every evaluation.
LEARNING_ENV_KWARGS: dict = {"reward_weights": {"tracking": 20.0, "effort": 0.02}, "error_bound": 0.1}
#: The env arguments that only shape learning; evaluation (periodic and final) uses the env's defaults instead.
LEARNING_ONLY_KEYS = ("reward_weights", "error_bound")
#: the dev-track training env (`train.dev_env`) and the fixed id its runs' periodic and final evaluations use
DEV_TRACK_ID = agent_interface.DEV_TRACK_ID
DEV_TRACK_EVAL_ID = "WheeledPuma-Circle-v0"
#: env arguments of a residual agent (`train.dev_env`): recorded in config.json for `sb3:`, never passed to
#: the evaluation envs
RESIDUAL_KEYS = (agent_interface.RESIDUAL_BASE, agent_interface.RESIDUAL_SCALE)
#: Observation the agent sees: every key of the robot-independent, clock-free interface of
#: `policies.agents.agent_interface` (the "agent" wrapper): position and velocity errors and the desired velocity in
#: the heading frame, the joint state padded to the Panda's 7 joints with a mask, the heading. No `time`: a
#: policy that sees the clock can memorise one path (release 0.3's `sb3:ppo-circle` did).
DEFAULT_OBS_KEYS = AGENT_OBS_KEYS
#: The observation wrappers of a new run (see `train.wrappers`).
DEFAULT_WRAPPERS = ("agent",)
#: Robots per training run when `n_envs` is not given: kinematic (one process), physics (one process each).
KINEMATIC_N_ENVS = 256
PHYSICS_N_ENVS = 1
#: Development seeds (DESIGN "Seeds"): periodic evaluation must stay below this.
DEV_SEED_END = 1000
#: First reported seed: the final evaluation starts here by default.
REPORTED_SEED_START = 10_000
_ENV_ARGS_NOT_ALLOWED = {"dynamics": "use --dynamics / TrainConfig.dynamics", "render_mode": "training renders nothing"}


@dataclass(frozen=True)
class TrainConfig:
    algo: str = "ppo"
    """Algorithm name from `train.algos.ALGOS` (ppo, sac, td3). PPO by default: its recipe is the one measured
    to learn on the batched env (`train.algos`); SAC's updates cost far more per env step."""
    env_id: str = "WheeledPuma-Circle-v0"
    """Registered env id (`mobman_env.ENV_IDS`); worker processes make it as `mobman_env:<env_id>`."""
    timesteps: int = 5_000_000
    """Total env steps to train for (over all robots). With `--resume`, the new total. The default is about 5
    minutes of the default recipe on a quiet 2-core machine (~20,000 steps/s, learner included)."""
    n_envs: int | None = None
    """Robots trained on at once; None: `KINEMATIC_N_ENVS` (256) in kinematic mode, `PHYSICS_N_ENVS` (1) in
    physics mode (resolved when the config is made, so config.json records the number). Kinematic: N robots of one
    native vector env (`mobman_env.vector`) in this process, stepped by one kernel call (about 1 us per
    robot-step against ~1 ms of SB3 per step of the whole batch: a large N amortises SB3's per-step cost).
    Physics: one PyBullet world per env, `SubprocVecEnv` when > 1 (contacts are not batched; use about as many
    as cores), `DummyVecEnv` for 1."""
    seed: int = 0
    """Seed of the algorithm (torch, numpy) and of the training envs (env i is reset with seed + i once)."""
    out: str | None = None
    """Run folder; None: `runs/train-<algo>-<task>-<UTC timestamp>`. An existing non-empty folder is refused
    unless `overwrite`."""
    overwrite: bool = False
    """Allow writing into an existing non-empty `out` (its files are replaced)."""
    dynamics: str = "kinematic"
    """Env dynamics mode for training and for every evaluation of this run ("kinematic" or "physics"). Default
    kinematic, unlike `mobman-eval run` (physics, the envs' default): a physics step costs about 30 kinematic ones,
    and training takes 1e5-1e6 of them."""
    env_kwargs: dict = field(default_factory=lambda: json.loads(json.dumps(LEARNING_ENV_KWARGS)))
    """Extra env constructor arguments for training (not `dynamics`). Defaults: `LEARNING_ENV_KWARGS`. The
    learning-only keys (`LEARNING_ONLY_KEYS`) are dropped for evaluation; the others (e.g. `model_error`,
    `obs_noise`, `path`) define the task and are kept."""
    alive_bonus: float = 2.0
    """Reward added per step during training (a wrapper, not the env). Set to tracking weight x error_bound,
    so that every step inside the bound earns >= 0 and ending the episode early never pays."""
    wrappers: tuple[str, ...] = DEFAULT_WRAPPERS
    """Observation wrappers (names from `train.wrappers.OBS_WRAPPERS`) applied before `obs_keys` is taken."""
    obs_keys: tuple[str, ...] = DEFAULT_OBS_KEYS
    """Observation keys the agent sees, in order (after the wrappers)."""
    hyperparams: dict = field(default_factory=dict)
    """Overrides of the algorithm's defaults (`train.algos`), e.g. from `--hyperparams FILE` (YAML or JSON)."""
    actor_out_scale: float = 0.01
    """SAC/TD3: multiply the initial weights and bias of the actor's output layer by this, so the untrained
    policy commands about zero speed instead of large random ones (the task's useful actions are ~5% of the
    speed limits). PPO is unaffected: SB3's orthogonal init already gives its action layer a gain of 0.01."""
    normalize_obs: bool = True
    """Normalise observations with VecNormalize's running mean and std (saved as `vecnormalize.pkl`)."""
    normalize_reward: bool | None = None
    """Normalise rewards with VecNormalize; None: the algorithm's choice (PPO yes, SAC/TD3 no)."""
    eval_freq: int = 1_000_000
    """Evaluate every this many env steps on the held-out development seeds (0: never). An evaluation runs
    `eval_episodes` single-env episodes through `eval` (about 1 s each): every 1 M steps (~50 s of training)
    it costs a few percent of the run."""
    eval_seed: int = 900
    """First development seed of the periodic evaluation; episode k uses reset(seed=eval_seed + k)."""
    eval_episodes: int = 5
    """Episodes per periodic evaluation."""
    final_eval_seed: int = REPORTED_SEED_START
    """First seed of the final evaluation (reported seeds start at 10,000)."""
    final_eval_episodes: int = 5
    """Episodes of the final evaluation with the benchmark's env settings (0: skip)."""
    tolerance: float = DEFAULT_TOLERANCE
    """Success threshold of the evaluations, m (max tracking error); eval's default, the paper's 6 mm."""
    checkpoint_freq: int = 1_000_000
    """Save a checkpoint (model, normaliser, replay buffer) every this many env steps (0: only at the end or
    on Ctrl-C)."""
    torch_threads: int = 1
    """`torch.set_num_threads`: one thread is as fast on 2 cores and far faster when anything else runs."""
    device: str = "cpu"
    """Torch device ("cpu", "cuda", "auto")."""
    tensorboard: bool = False
    """Write TensorBoard logs to `<out>/tensorboard`."""
    log_every_s: float = 10.0
    """A progress line (steps, steps/s, mean return, length and success of the episodes that ended) to the
    run's log and stderr every this many seconds of wall clock."""
    progress_bar: bool = True
    """Show SB3's progress bar (`mobman-train` shows it only when stderr is a terminal: a CI log would get a line
    per update)."""
    verbose: int = 0
    """SB3 verbosity (0, 1, 2)."""

    def __post_init__(self) -> None:
        algos.get(self.algo)
        integer("timesteps", self.timesteps, low=1, hint="e.g. --timesteps 100000")
        if self.n_envs is None:
            object.__setattr__(self, "n_envs", KINEMATIC_N_ENVS if self.dynamics == "kinematic" else PHYSICS_N_ENVS)
        integer("n_envs", self.n_envs, low=1, hint="e.g. --n-envs 256 (kinematic) or 2 (physics)")
        integer("seed", self.seed, low=0, hint="use a development seed 0-999")
        for name in ("eval_freq", "eval_episodes", "final_eval_episodes", "checkpoint_freq", "final_eval_seed"):
            integer(name, getattr(self, name), low=0, hint="use 0 to disable")
        integer("eval_seed", self.eval_seed, low=0, hint="use a development seed 0-999")
        integer("torch_threads", self.torch_threads, low=1, hint="1 is best on a shared 2-core machine")
        integer("verbose", self.verbose, low=0, high=2, hint="SB3 verbosity")
        if self.eval_freq and self.eval_seed + self.eval_episodes > DEV_SEED_END:
            raise ValueError(
                f"periodic evaluation seeds {self.eval_seed}..{self.eval_seed + self.eval_episodes - 1} leave the "
                f"development range 0-{DEV_SEED_END - 1} (reported seeds are never used while training); "
                f"lower eval_seed"
            )
        from mobman_env.sim import DYNAMICS_MODES

        if self.dynamics not in DYNAMICS_MODES:
            raise ValueError(f"unknown dynamics {self.dynamics!r}; accepted: {', '.join(DYNAMICS_MODES)}")
        _check_env_id(self.env_id)
        if not isinstance(self.env_kwargs, dict):
            raise ValueError(f"env_kwargs must be a dict (JSON object), got {self.env_kwargs!r}")
        _check_env_kwargs(self.env_kwargs, self.env_id)
        if not isinstance(self.hyperparams, dict):
            raise ValueError(f"hyperparams must be a dict, got {self.hyperparams!r}")
        algos.resolve(self.algo, self.hyperparams)
        number("alive_bonus", self.alive_bonus, hint="reward per training step, e.g. 2.0")
        number("actor_out_scale", self.actor_out_scale, low=0, open_low=True, hint="1: SB3's init")
        number("tolerance", self.tolerance, low=0, open_low=True, hint="m, e.g. 0.006")
        number("log_every_s", self.log_every_s, low=0, open_low=True, hint="s, e.g. 10")
        object.__setattr__(self, "wrappers", tuple(self.wrappers))
        object.__setattr__(self, "obs_keys", tuple(self.obs_keys))
        if agent_interface.RESIDUAL_BASE in self.env_kwargs and agent_interface.BASE_ACTION not in self.obs_keys:
            # a residual agent sees its base's action (recorded in config.json's obs_keys)
            object.__setattr__(self, "obs_keys", (*self.obs_keys, agent_interface.BASE_ACTION))
        check_wrappers(self.wrappers)
        if not self.obs_keys:
            raise ValueError("obs_keys is empty; the agent must see at least one observation key")
        if self.device not in ("cpu", "cuda", "auto") and not str(self.device).startswith("cuda:"):
            raise ValueError(f"unknown device {self.device!r}; accepted: cpu, cuda, cuda:N, auto")

    # --- derived --------------------------------------------------------------------------------------
    @property
    def num_envs(self) -> int:
        """`n_envs` as resolved in `__post_init__` (never None)."""
        assert self.n_envs is not None
        return self.n_envs

    @property
    def train_env_kwargs(self) -> dict:
        """Constructor arguments of the training envs."""
        return {**self.env_kwargs, "dynamics": self.dynamics}

    @property
    def eval_env_id(self) -> str:
        """The id of the periodic and final evaluations: `env_id`, or for the dev-track training env (which draws
        its episodes: `train.dev_env`) `DEV_TRACK_EVAL_ID`; the agent's dev-track figures come from
        `mobman-eval bench --against`."""
        return DEV_TRACK_EVAL_ID if self.env_id == DEV_TRACK_ID else self.env_id

    @property
    def residual(self) -> tuple[str, float] | None:
        """A residual agent's (base spec, scale) from `env_kwargs` (`train.dev_env`), else None."""
        base = self.env_kwargs.get(agent_interface.RESIDUAL_BASE)
        if base is None:
            return None
        return str(base), float(
            self.env_kwargs.get(agent_interface.RESIDUAL_SCALE, agent_interface.DEFAULT_RESIDUAL_SCALE)
        )

    @property
    def eval_env_kwargs(self) -> dict:
        """Constructor arguments of the evaluation envs: the training ones minus the learning-only keys."""
        kw = {k: v for k, v in self.env_kwargs.items() if k not in (*LEARNING_ONLY_KEYS, *RESIDUAL_KEYS)}
        return {**kw, "dynamics": self.dynamics}

    @property
    def resolved_hyperparams(self) -> dict:
        return algos.resolve(self.algo, self.hyperparams)

    @property
    def do_normalize_reward(self) -> bool:
        return algos.get(self.algo).normalize_reward if self.normalize_reward is None else bool(self.normalize_reward)

    # --- JSON -----------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["wrappers"] = list(self.wrappers)
        d["obs_keys"] = list(self.obs_keys)
        return json.loads(json.dumps(d))

    @classmethod
    def from_dict(cls, data: dict, *, ignore_extra: bool = False) -> TrainConfig:
        """Build from `to_dict()` output. Unknown keys fail (listing the fields) unless `ignore_extra` (used
        for a run folder's config.json, which holds more than the config)."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown and not ignore_extra:
            raise ValueError(f"unknown TrainConfig field(s) {unknown}; fields: {', '.join(sorted(names))}")
        return cls(**{k: v for k, v in data.items() if k in names})

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> TrainConfig:
        return cls.from_dict(json.loads(text))

    def replace(self, **changes: Any) -> TrainConfig:
        return dataclasses.replace(self, **changes)


def _check_env_id(env_id: str) -> None:
    import gymnasium as gym

    import mobman_env

    if env_id not in gym.registry:
        raise ValueError(f"unknown env id {env_id!r}; known: {', '.join(mobman_env.ENV_IDS)}")


def _check_env_kwargs(kwargs: dict, env_id: str) -> None:
    from mobman_env.env import WheeledPumaEnv

    for key, why in _ENV_ARGS_NOT_ALLOWED.items():
        if key in kwargs:
            raise ValueError(f"env_kwargs may not contain {key!r}: {why}")
    residual = [k for k in RESIDUAL_KEYS if k in kwargs]
    if residual and env_id != DEV_TRACK_ID:
        raise ValueError(f"env_kwargs {residual} (a residual agent) are taken by --env {DEV_TRACK_ID} only")
    accepted = [p for p in inspect.signature(WheeledPumaEnv.__init__).parameters if p != "self"] + residual
    unknown = sorted(set(kwargs) - set(accepted))
    if unknown:
        raise ValueError(
            f"unknown env argument(s) {unknown}; accepted: {', '.join(a for a in accepted if a not in _ENV_ARGS_NOT_ALLOWED)}"
        )

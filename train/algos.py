"""The algorithm table: name -> SB3 class and default hyperparameters (rl-baselines3-zoo style).

Hyperparameters are plain data (JSON/YAML-able) so the resolved set is saved in the run's `config.json`;
`build_kwargs` turns the few non-plain entries into SB3 objects:

* `policy_kwargs.activation_fn`: a name from `ACTIVATIONS` ("relu", "tanh", "elu", "leaky_relu").
* `learning_rate` (and PPO's `clip_range`): a number, or `"lin_<value>"` for a linear decay from value to 0
  over the run (rl-zoo's notation).
* `action_noise` (TD3, SAC): `{"type": "normal" | "ornstein_uhlenbeck", "sigma": float}` (sigma in the normalised
  action units, the same for every actuator).

SAC and TD3: chosen for the tracking task (`WheeledPuma-*-v0`, 100 Hz, 2000-step episodes) on development seeds,
starting from the zoo's PyBullet settings: a short horizon (gamma 0.98, about 0.5 s) because the reward is the
instantaneous tracking error, and small networks because the policy is close to a linear map from the error to
the joint speeds (what release 0.3's shipped baselines used).

PPO (the default algorithm): the recipe for the batched env, 256 robots of the native vector env x 64 steps =
16,384 env steps per rollout, 4 minibatches of 4,096 x 5 epochs (20 gradient steps per rollout, so the learner
costs about as much as stepping the robots and every rollout is fresh: 37,000-41,000 env steps/s, learner
included, in this recipe's first runs on the shared 2-core machine at load ~1.7; not a benchmark figure), a constant learning rate 3e-4, 64 x 64 tanh networks,
`log_std_init` -3.5 (exploration std 0.03 of the speed limits: the useful commands are ~5% of them; release
0.3's -2.0, std 0.14, made the robots drift by centimetres from the noise alone), gamma 0.99 with GAE 0.95.

What was measured (release 0.4 tuning, PUMA Circle, kinematic, model_error 0.05, development seeds only: the
training envs' seeds from 0, evaluation on seeds 500-519 with success = max error <= 6 mm over the 20 s
episode; a shared 2-core machine, so step counts, not times, compare the runs): no run reached a successful
episode (0/20 each), so the issue's goal (90% in 5 minutes) is not met by this or any tried recipe. The
deterministic agent tracks the start of the circle within 1-4 mm; what limits it is how far into the episode it
has learned to go: with gamma 0.9 it loses the path at 4.1-4.4 s after 3 M steps (it traces the circle with the
wrist and the platform, the wrist's range runs out: a myopic strategy); gamma 0.98 and 0.99 keep improving, and
at 8 M steps (gamma 0.99) it stays within ~6 mm for 5.5-6 s and within 9 mm up to 8 s, then drives arm joints
into their limits and loses the path by 10 s. Training episodes (ended at 10 cm error) grew from 250 to 1,040
of 2,000 steps over those 8 M steps. Tried and not better at equal steps: lr 1e-3 with 10 epochs; effort weight
x100 (to favour the waist over the wrist: still the wrist); error_bound 0.3 (worse near the start).
"""

from __future__ import annotations

import copy
import inspect
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # the annotation only: importing train loads neither torch nor SB3
    from stable_baselines3.common.base_class import BaseAlgorithm

ACTIVATIONS = ("relu", "tanh", "elu", "leaky_relu")
NOISE_TYPES = ("normal", "ornstein_uhlenbeck")


@dataclass(frozen=True)
class AlgoSpec:
    """One row of the table. class_path: "module:Class" of the SB3 algorithm (imported lazily, so importing
    `train.algos` does not load torch). off_policy: has a replay buffer (saved with checkpoints for `--resume`).
    defaults: hyperparameters passed to the class (plain data). normalize_reward: whether VecNormalize also
    normalises the reward (on-policy only: off-policy value targets are fine with the raw, bounded reward)."""

    class_path: str
    off_policy: bool
    defaults: dict
    normalize_reward: bool

    def load_class(self) -> type[BaseAlgorithm]:
        import importlib

        module, name = self.class_path.split(":")
        return getattr(importlib.import_module(module), name)


ALGOS: dict[str, AlgoSpec] = {
    "sac": AlgoSpec(
        class_path="stable_baselines3:SAC",
        off_policy=True,
        normalize_reward=False,
        defaults={
            "learning_rate": 7.3e-4,
            "buffer_size": 300_000,
            "batch_size": 256,
            "learning_starts": 2_000,
            "gamma": 0.98,
            "tau": 0.02,
            "train_freq": 8,
            "gradient_steps": 8,
            "ent_coef": "auto_0.1",
            "use_sde": True,
            "policy_kwargs": {"net_arch": [256, 256], "log_std_init": -3.5},
        },
    ),
    "td3": AlgoSpec(
        class_path="stable_baselines3:TD3",
        off_policy=True,
        normalize_reward=False,
        defaults={
            "learning_rate": 1e-3,
            "buffer_size": 300_000,
            "batch_size": 256,
            "learning_starts": 2_000,
            "gamma": 0.98,
            "tau": 0.005,
            "train_freq": 8,
            "gradient_steps": 8,
            "action_noise": {"type": "normal", "sigma": 0.1},
            "policy_kwargs": {"net_arch": [256, 256]},
        },
    ),
    "ppo": AlgoSpec(
        class_path="stable_baselines3:PPO",
        off_policy=False,
        normalize_reward=True,
        # the recipe for the batched env (module docstring, "PPO"): 256 robots x 64 steps = 16,384 per rollout
        defaults={
            "learning_rate": 3e-4,
            "n_steps": 64,
            "batch_size": 4096,
            "n_epochs": 5,
            "gamma": 0.99,
            "gae_lambda": 0.95,
            "clip_range": 0.2,
            "ent_coef": 0.0,
            "max_grad_norm": 0.5,
            "policy_kwargs": {
                "net_arch": {"pi": [64, 64], "vf": [64, 64]},
                "log_std_init": -3.5,
                "activation_fn": "tanh",
            },
        },
    ),
}

#: Keys `TrainConfig` / the run function set themselves; a hyperparameter file may not contain them.
RESERVED = ("policy", "env", "seed", "verbose", "tensorboard_log", "device", "_init_setup_model")


def algo_names() -> tuple[str, ...]:
    return tuple(ALGOS)


def get(name: str) -> AlgoSpec:
    try:
        return ALGOS[name]
    except KeyError:
        raise ValueError(f"unknown algorithm {name!r}; known: {', '.join(ALGOS)}") from None


def accepted_keys(name: str) -> tuple[str, ...]:
    """The constructor arguments of the algorithm a hyperparameter file may set."""
    params = inspect.signature(get(name).load_class()).parameters
    return tuple(k for k in params if k not in ("self",) + RESERVED)


def resolve(name: str, overrides: dict | None = None) -> dict:
    """The algorithm's defaults updated with `overrides` (top-level keys replace; `policy_kwargs` is merged
    key by key). Checks value shapes that are cheap to check without importing SB3."""
    spec = get(name)
    hp = copy.deepcopy(spec.defaults)
    for key, value in (overrides or {}).items():
        if key in RESERVED:
            raise ValueError(
                f"hyperparameter {key!r} is set by mobman-train itself; remove it from the hyperparameter file "
                f"(use --seed, --tensorboard or TrainConfig fields instead)"
            )
        if key == "policy_kwargs" and isinstance(value, dict):
            hp["policy_kwargs"] = {**hp.get("policy_kwargs", {}), **copy.deepcopy(value)}
        else:
            hp[key] = copy.deepcopy(value)
    for key in ("learning_rate", "clip_range"):
        if isinstance(hp.get(key), str):
            _schedule(hp[key], key)
    act = hp.get("policy_kwargs", {}).get("activation_fn")
    if act is not None and act not in ACTIVATIONS:
        raise ValueError(f"unknown activation_fn {act!r}; known: {', '.join(ACTIVATIONS)}")
    noise = hp.get("action_noise")
    if noise is not None:
        if spec.off_policy is False:
            raise ValueError(f"action_noise is for off-policy algorithms (sac, td3), not {name!r}; remove it")
        if (
            not isinstance(noise, dict)
            or noise.get("type") not in NOISE_TYPES
            or not isinstance(noise.get("sigma"), (int, float))
        ):
            raise ValueError(
                f"action_noise must be {{'type': one of {list(NOISE_TYPES)}, 'sigma': float}}, got {noise!r}"
            )
    return hp


def check_keys(name: str, hp: dict) -> None:
    """Fail (listing the accepted keys) if a hyperparameter is not an argument of the algorithm's class."""
    accepted = accepted_keys(name)
    unknown = sorted(set(hp) - set(accepted))
    if unknown:
        raise ValueError(f"unknown hyperparameter(s) {unknown} for {name}; accepted: {', '.join(accepted)}")


def build_kwargs(name: str, hp: dict, n_actions: int) -> dict[str, Any]:
    """Turn the plain-data hyperparameters into the keyword arguments of the SB3 class."""
    import torch.nn as nn
    from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

    kwargs = copy.deepcopy(hp)
    pk = kwargs.get("policy_kwargs")
    if pk and "activation_fn" in pk:
        pk["activation_fn"] = {"relu": nn.ReLU, "tanh": nn.Tanh, "elu": nn.ELU, "leaky_relu": nn.LeakyReLU}[
            pk["activation_fn"]
        ]
    if isinstance(pk, dict) and isinstance(pk.get("net_arch"), dict):
        pk["net_arch"] = {k: list(v) for k, v in pk["net_arch"].items()}
    noise = kwargs.get("action_noise")
    if isinstance(noise, dict):
        cls = NormalActionNoise if noise["type"] == "normal" else OrnsteinUhlenbeckActionNoise
        kwargs["action_noise"] = cls(mean=np.zeros(n_actions), sigma=float(noise["sigma"]) * np.ones(n_actions))
    for key in ("learning_rate", "clip_range"):
        if isinstance(kwargs.get(key), str):
            kwargs[key] = _schedule(kwargs[key], key)
    if isinstance(kwargs.get("train_freq"), list):
        kwargs["train_freq"] = tuple(kwargs["train_freq"])
    return kwargs


def _schedule(text: str, key: str):
    """ "lin_3e-4" -> a callable of SB3's progress_remaining (1 -> 0): linear decay to 0."""
    if not text.startswith("lin_"):
        raise ValueError(f"{key} {text!r}: expected a number or 'lin_<number>' (linear decay), e.g. 'lin_3e-4'")
    try:
        start = float(text[4:])
    except ValueError:
        raise ValueError(f"{key} {text!r}: expected a number after 'lin_', e.g. 'lin_3e-4'") from None
    return LinearSchedule(start)


class LinearSchedule:
    """value(progress_remaining) = start * progress_remaining (picklable, unlike a closure), with the progress
    clipped to [0, 1]: SB3 computes it as 1 - steps / budget, which goes below 0 when the last rollout overshoots
    the budget (e.g. a budget smaller than one rollout of N robots x n_steps), and a negative learning rate
    would climb the loss (the weights turned to NaN)."""

    def __init__(self, start: float):
        self.start = start

    def __call__(self, progress_remaining: float) -> float:
        return self.start * min(max(progress_remaining, 0.0), 1.0)

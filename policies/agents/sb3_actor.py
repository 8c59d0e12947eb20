"""`NumpyActor`: the deterministic action of an SB3 actor-critic MLP (PPO, A2C) computed in numpy, row by row.

Why: torch's matrix products choose their kernel by the batch size, so the same agent's action for one robot
differed in the last float32 bit (6e-8 measured on `sb3:ppo-circle`) between a batch of 64 robots and a batch of
one; an agent's episodes would then depend on how `eval` batched them. Here every layer is a stacked product,
`(N, 1, k) @ (k, m)`, which numpy evaluates as N products of one row (the same kernel for every N: the model-
based laws rely on it too, `policies.kernels.shared`), so row i's action is the same bits for any N; the elementwise
activations and the bias add do not depend on N. `policies.agents.sb3.SB3Policy` uses it for every deterministic
predict it can serve (single env and batched alike), SB3's torch `predict` otherwise (SAC, TD3, gSDE, other
extractors or networks). It equals torch's action to float32 rounding (a test compares them).

Supported: `ActorCriticPolicy` and `MultiInputActorCriticPolicy` without gSDE and without a squashed output, a
`FlattenExtractor` or a `CombinedExtractor` of flattened keys, a policy network of `Linear` layers with
Tanh/ReLU/ELU/LeakyReLU between them, a `Linear` action head; the action is its mean clipped to the action
space, as SB3's `predict` does. Imports numpy (and reads the torch model it is given).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

_ACTIVATIONS: dict[str, Callable[[np.ndarray, Any], np.ndarray]] = {
    "Tanh": lambda x, m: np.tanh(x),
    "ReLU": lambda x, m: np.maximum(x, np.float32(0.0)),
    "ELU": lambda x, m: np.where(x > 0, x, np.float32(m.alpha) * np.expm1(x)).astype(np.float32),
    "LeakyReLU": lambda x, m: np.where(x >= 0, x, np.float32(m.negative_slope) * x).astype(np.float32),
}


class NumpyActor:
    """The actor's deterministic action for a batch of (already normalised) observations (module docstring)."""

    def __init__(self, keys: tuple[str, ...] | None, layers: list[tuple[str, Any]], low: Any, high: Any):
        self.keys = keys  # the CombinedExtractor's order; None: a Box observation
        self.layers = layers  # ("linear", (W.T, b)) or (activation name, module)
        self.low, self.high = np.asarray(low, np.float32), np.asarray(high, np.float32)

    def __call__(self, obs: Any) -> np.ndarray:
        if self.keys is None:
            x = np.asarray(obs, np.float32)
            single = x.ndim == 1
            x = x.reshape(1 if single else x.shape[0], -1)
        else:
            first = np.asarray(obs[self.keys[0]])
            single = first.ndim <= 1
            n = 1 if single else first.shape[0]
            x = np.concatenate([np.asarray(obs[k], np.float32).reshape(n, -1) for k in self.keys], axis=1)
        h = np.ascontiguousarray(x, dtype=np.float32)
        for kind, value in self.layers:
            if kind == "linear":
                weight_t, bias = value
                h = (h[:, None, :] @ weight_t)[:, 0, :] + bias
            else:
                h = _ACTIVATIONS[kind](h, value)
        action = np.clip(h, self.low, self.high)
        return action[0] if single else action


def numpy_actor(model: Any) -> NumpyActor | None:
    """The `NumpyActor` of an SB3 model, or None where it does not apply (module docstring)."""
    try:
        from stable_baselines3.common.policies import ActorCriticPolicy
        from stable_baselines3.common.torch_layers import CombinedExtractor, FlattenExtractor
    except ImportError:  # pragma: no cover - SB3 is there whenever a model is
        return None
    policy = getattr(model, "policy", None)
    if not isinstance(policy, ActorCriticPolicy) or policy.use_sde or policy.squash_output:
        return None
    from gymnasium import spaces
    from stable_baselines3.common.distributions import DiagGaussianDistribution

    if not isinstance(policy.action_dist, DiagGaussianDistribution) or not isinstance(model.action_space, spaces.Box):
        return None
    extractor = policy.pi_features_extractor
    keys: tuple[str, ...] | None
    if isinstance(extractor, CombinedExtractor):
        if not all(type(m).__name__ == "Flatten" for m in extractor.extractors.values()):
            return None
        keys = tuple(extractor.extractors.keys())
    elif isinstance(extractor, FlattenExtractor):
        keys = None
    else:
        return None
    layers = _layers([*policy.mlp_extractor.policy_net, policy.action_net])
    if layers is None:
        return None
    return NumpyActor(keys, layers, model.action_space.low, model.action_space.high)


def _layers(modules: list[Any]) -> list[tuple[str, Any]] | None:
    import torch

    layers: list[tuple[str, Any]] = []
    for module in modules:
        name = type(module).__name__
        if isinstance(module, torch.nn.Linear):
            weight = module.weight.detach().cpu().numpy().astype(np.float32)
            bias = (
                np.zeros(weight.shape[0], np.float32)
                if module.bias is None
                else module.bias.detach().cpu().numpy().astype(np.float32)
            )
            layers.append(("linear", (np.ascontiguousarray(weight.T), bias)))
        elif name in _ACTIVATIONS:
            layers.append((name, module))
        else:
            return None
    return layers

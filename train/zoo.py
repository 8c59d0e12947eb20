"""rl-baselines3-zoo hyperparameter entries -> `TrainConfig` fields, so `mobman-train --hyperparams
train/hyperparams/ppo.yml` trains what `python -m rl_zoo3.train --conf-file train/hyperparams/ppo.yml` trains.

A zoo file maps env ids to entries (`WheeledPuma-Circle-v0: {n_timesteps: ..., policy: ..., ...}`). An entry's
zoo-only keys become config fields; everything else is an algorithm hyperparameter (checked by `train.algos`):

| zoo key | TrainConfig field |
|---|---|
| `n_timesteps` | `timesteps` |
| `n_envs` | `n_envs` |
| `policy` | must be `MultiInputPolicy` (mobman's observation is a Dict) |
| `normalize` | `normalize_obs`, `normalize_reward` (a bool, or a dict / its text with `norm_obs`, `norm_reward`; `true` is VecNormalize's default, both on) |
| `env_wrapper` | `train.wrappers.AgentObservation` (kwargs `wrappers`, `obs_keys`) -> `wrappers`, `obs_keys`; `train.wrappers.AliveBonus` (kwarg `bonus`) -> `alive_bonus` (absent: 0, as the zoo would train) |
| `policy_kwargs` | the text `dict(net_arch=..., activation_fn=nn.Tanh, ...)` -> plain data (`activation_fn` by name) |

Other zoo keys (`frame_stack`, `callback`, `vec_env_wrapper`, ...) and other wrappers are refused, naming them:
`mobman-train` has no equivalent, and ignoring one would train something else than the file says.
"""

from __future__ import annotations

import ast
from typing import Any

#: Zoo `env_wrapper` entries mobman-train reproduces.
AGENT_VIEW = "train.wrappers.AgentObservation"
ALIVE_BONUS = "train.wrappers.AliveBonus"
#: `nn.<Class>` of a zoo `policy_kwargs` text -> `train.algos.ACTIVATIONS` name.
ACTIVATION_NAMES = {"ReLU": "relu", "Tanh": "tanh", "ELU": "elu", "LeakyReLU": "leaky_relu"}
#: Zoo keys with no mobman-train equivalent.
UNSUPPORTED = ("frame_stack", "callback", "vec_env_wrapper", "env_kwargs", "eval_env_kwargs", "policy_delay_kwargs")


def is_env_keyed(data: dict) -> bool:
    """Whether a hyperparameter mapping is zoo style, keyed by env id (`Name-vN` keys holding mappings)."""
    return bool(data) and all(
        isinstance(k, str) and "-v" in k and isinstance(v, dict) and k.rsplit("-v", 1)[1].isdigit()
        for k, v in data.items()
    )


def entry_fields(entry: dict, where: str) -> dict[str, Any]:
    """The TrainConfig fields of one zoo entry (see the module docstring); "hyperparams" holds the rest."""
    hp = dict(entry)
    fields: dict[str, Any] = {}
    bad = sorted(set(hp) & set(UNSUPPORTED))
    if bad:
        raise ValueError(f"{where}: zoo setting(s) {bad} have no mobman-train equivalent; remove them")
    if "n_timesteps" in hp:
        fields["timesteps"] = int(float(hp.pop("n_timesteps")))
    if "n_envs" in hp:
        fields["n_envs"] = int(hp.pop("n_envs"))
    policy = hp.pop("policy", "MultiInputPolicy")
    if policy != "MultiInputPolicy":
        raise ValueError(
            f"{where}: policy {policy!r}; mobman's observation is a Dict, which SB3 trains with "
            f"'MultiInputPolicy' (mobman-train sets it): use that"
        )
    if "normalize" in hp:
        fields.update(_normalize(hp.pop("normalize"), where))
    fields.update(_wrappers(hp.pop("env_wrapper", None), where))
    if isinstance(hp.get("policy_kwargs"), str):
        hp["policy_kwargs"] = parse_policy_kwargs(hp["policy_kwargs"], where)
    fields["hyperparams"] = hp
    return fields


def _normalize(value: Any, where: str) -> dict[str, bool]:
    from policies.agents.sb3_files import zoo_normalize

    kw = zoo_normalize(value, where)
    extra = sorted(set(kw) - {"norm_obs", "norm_reward"})
    if extra:
        raise ValueError(
            f"{where}: normalize {value!r} sets {extra}; accepted: true, false, or a dict of norm_obs / norm_reward "
            f"(mobman-train sets VecNormalize's other arguments itself)"
        )
    return {"normalize_obs": kw["norm_obs"], "normalize_reward": kw["norm_reward"]}


def _wrappers(value: Any, where: str) -> dict[str, Any]:
    entries = [] if value is None else value if isinstance(value, list) else [value]
    fields: dict[str, Any] = {"alive_bonus": 0.0}
    view = False
    for item in entries:
        name, kwargs = (item, {}) if isinstance(item, str) else next(iter(item.items()))
        kwargs = dict(kwargs or {})
        if name == AGENT_VIEW:
            view = True
            fields["wrappers"] = tuple(kwargs.pop("wrappers", ()))
            if "obs_keys" in kwargs:
                fields["obs_keys"] = tuple(kwargs.pop("obs_keys"))
        elif name == ALIVE_BONUS:
            fields["alive_bonus"] = float(kwargs.pop("bonus", 0.0))
        else:
            raise ValueError(
                f"{where}: env_wrapper {name!r} is not one mobman-train reproduces; accepted: {AGENT_VIEW}, "
                f"{ALIVE_BONUS}"
            )
        if kwargs:
            raise ValueError(f"{where}: unknown argument(s) {sorted(kwargs)} of env_wrapper {name}")
    if not view:
        raise ValueError(
            f"{where}: env_wrapper has no {AGENT_VIEW} (the agent's observation keys); add it, e.g. "
            f"{{{AGENT_VIEW}: {{wrappers: [pos_error], obs_keys: [pos_error, target_vel, ...]}}}}"
        )
    return fields


def parse_policy_kwargs(text: str, where: str) -> dict:
    """`"dict(net_arch=dict(pi=[64], vf=[64]), activation_fn=nn.Tanh)"` -> {"net_arch": {...}, "activation_fn":
    "tanh"}: literals, `dict(...)` calls and `nn.<activation>` only (nothing is evaluated)."""
    try:
        tree = ast.parse(text.strip(), mode="eval").body
        return _literal(tree, where)
    except SyntaxError:
        raise ValueError(f"{where}: policy_kwargs {text!r} is not a Python expression") from None


def _literal(node: ast.AST, where: str) -> Any:
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict" and not node.args:
        return {kw.arg: _literal(kw.value, where) for kw in node.keywords}
    if isinstance(node, ast.Dict):
        return {_literal(k, where): _literal(v, where) for k, v in zip(node.keys, node.values) if k is not None}
    if isinstance(node, ast.List | ast.Tuple):
        return [_literal(e, where) for e in node.elts]
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "nn":
        if node.attr in ACTIVATION_NAMES:
            return ACTIVATION_NAMES[node.attr]
        raise ValueError(f"{where}: activation nn.{node.attr}; accepted: nn.{', nn.'.join(ACTIVATION_NAMES)}")
    if isinstance(node, ast.UnaryOp | ast.Constant):
        return ast.literal_eval(node)
    raise ValueError(
        f"{where}: policy_kwargs may hold literals, dict(...) and nn.<activation>, not {ast.unparse(node)!r}"
    )

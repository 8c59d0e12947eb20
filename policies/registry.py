"""Policy specs -> policy objects: `policies.make(spec, env)`.

Spec grammar (one string, as the CLI takes it):

* `name[:key=value,...]` - a built-in controller; keys are the fields of its config dataclass; values are
  parsed as bool (`true`/`false`), int, float, or else kept as a string: `nnbc:gamma=20,mu=20,j0=probe`.
* `sb3:PATH` - a Stable-Baselines3 agent; the whole rest of the string is the path (a `model.zip` or its run
  folder), or the alias of a shipped baseline (a folder name of `policies/models/`: `sb3:sac-circle`,
  `sb3:ppo-circle`, ...).
* `module:attr[:key=value,...]` - your own policy (`policies.user_specs`): `attr` (dotted for nested
  attributes) in `module` is a Policy object, a class whose instances have `reset` and `predict`, or a function
  marked `@policies.controller_factory`, checked to be one before it is called; a class or factory is called
  with the env if its signature has a positional parameter, else without, and with the options as keyword
  arguments (parsed as for built-in specs: `mymod:Ctrl:gain=5,horizon=3` calls `Ctrl(env, gain=5, horizon=3)`;
  options its signature does not take are refused naming the ones it does, an option naming the env's
  parameter is refused). `mymod.py:Ctrl` is refused with the fix (drop the .py). Only a spec you typed may
  have this form: a file's specs are checked with `data_spec_problem`.

Option values: bool, int, float or string; a value with a control character or a non-ASCII digit (`２０`,
which Python's `int` and `float` would read as 20) is refused, naming it.

Who gets what: the controllers that read no parameter (`nnbc`, `nnbc-full`, `nnbc-plus`, `nnbc-plus-wb`, `broyden`,
`rls`, `zero`, `random`) are built from `EnvFacts.from_env(env)` only. `jmpi`, `clik`, `qp`, `mpc` (and `nnbc:j0=nominal`) receive a provider of the env's
`nominal_params`, read at each episode start (a random-arm env draws a new nominal robot per reset); so does
`calib-qp`, for which the nominal robot is only the prior it calibrates from (its knowledge class is
`structure`, `policies.knowledge`). The oracles (`oracle`, `qp-oracle`, `mpc-oracle`) receive a provider that reads the env's current `true_params` at each episode start - the only code in this
package that touches `true_params`; `mpc-oracle` also gets one of its `true_actuator_tau` (the episode's lag).
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib
import typing
import unicodedata
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from policies.base import EnvFacts, unwrap_env
from policies.batched import (
    BatchedAgent,
    BatchedPolicy,
    _RobotView,
    check_vector_env,
    is_native_vector_env,
    is_vector_env,
)
from policies.user_specs import make_user
from policies.views import KnowledgeView


@dataclass(frozen=True)
class _Entry:
    description: str
    module: str  # imported lazily, when the spec is built
    cls: str
    config_cls: str
    preset: dict
    model: str  # "none" (model-free), "nominal" (nominal_params) or "true" (params_provider)


_REGISTRY: dict[str, _Entry] = {
    "nnbc": _Entry(
        "the paper's model-free NNBC, eqs. (7)-(15) (J_hat of r_a_dot - [p_c_dot; 0])",
        "policies.laws.nnbc",
        "NNBC",
        "NNBCConfig",
        {},
        "none",
    ),
    "nnbc-full": _Entry(
        "NNBC with J_hat of the whole r_a_dot (the platform can drive)",
        "policies.laws.nnbc",
        "NNBC",
        "NNBCConfig",
        {"full": True},
        "none",
    ),
    "nnbc-plus": _Entry(
        "NNBC improved: no kinematic parameter, but the structured estimate knows the chain's kind (class structure; see policies.laws.nnbc_plus)",
        "policies.laws.nnbc_plus",
        "NNBCPlus",
        "NNBCPlusConfig",
        {},
        "none",
    ),
    "nnbc-plus-wb": _Entry(
        "nnbc-plus with its whole-body estimate instead of the structured one: knows no structure (class none)",
        "policies.laws.nnbc_plus",
        "NNBCPlus",
        "NNBCPlusConfig",
        {"formulation": "whole_body"},
        "none",
    ),
    "broyden": _Entry(
        "model-free: Broyden's secant Jacobian update in nnbc-plus's probe / excitation / control law",
        "policies.laws.broyden_rls",
        "Broyden",
        "BroydenConfig",
        {},
        "none",
    ),
    "rls": _Entry(
        "model-free: recursive least squares with forgetting in nnbc-plus's probe / excitation / control law",
        "policies.laws.broyden_rls",
        "RLS",
        "RLSConfig",
        {},
        "none",
    ),
    "jmpi": _Entry(
        "open-loop Jacobian pseudo-inverse on the nominal model (the paper's comparison)",
        "policies.laws.jmpi",
        "JMPI",
        "JMPIConfig",
        {},
        "nominal",
    ),
    "jmpi-full": _Entry(
        "open-loop pseudo-inverse of the nominal whole-body Jacobian",
        "policies.laws.jmpi",
        "JMPI",
        "JMPIConfig",
        {"full": True},
        "nominal",
    ),
    "clik": _Entry(
        "closed-loop eq. (10) on the nominal model (resolved rate, paper's J): the practitioner's baseline",
        "policies.laws.jmpi",
        "CLIK",
        "CLIKConfig",
        {},
        "nominal",
    ),
    "clik-full": _Entry(
        "closed-loop eq. (10) on the nominal whole-body Jacobian",
        "policies.laws.jmpi",
        "CLIK",
        "CLIKConfig",
        {"full": True},
        "nominal",
    ),
    "oracle": _Entry(
        "eq. (10) with the true robot's Jacobian: the known-model bound",
        "policies.laws.jmpi",
        "Oracle",
        "OracleConfig",
        {},
        "true",
    ),
    "oracle-full": _Entry(
        "eq. (10) with the true whole-body Jacobian",
        "policies.laws.jmpi",
        "Oracle",
        "OracleConfig",
        {"full": True},
        "true",
    ),
    "qp": _Entry(
        "whole-body differential-IK QP on the nominal model: joint-limit dampers, speed bounds, posture term",
        "policies.laws.qp",
        "QP",
        "QPConfig",
        {},
        "nominal",
    ),
    "qp-oracle": _Entry(
        "the whole-body QP on the true robot: the known-model ceiling (respects joint limits)",
        "policies.laws.qp",
        "QP",
        "QPConfig",
        {},
        "true",
    ),
    "calib-qp": _Entry(
        "the whole-body QP on a model calibrated online: a Kalman filter on the worn lengths, from the catalogue",
        "policies.laws.calib_qp",
        "CalibQP",
        "CalibQPConfig",
        {},
        "nominal",
    ),
    "mpc": _Entry(
        "receding-horizon whole-body QP on the nominal model: path preview, actuator lag (identified online), speed limits",
        "policies.laws.mpc",
        "MPC",
        "MPCConfig",
        {},
        "nominal",
    ),
    "mpc-oracle": _Entry(
        "the receding-horizon QP on the true robot and the true actuator lag: the known-model reference",
        "policies.laws.mpc",
        "MPC",
        "MPCConfig",
        {},
        "true",
    ),
    "zero": _Entry("zero speeds: the floor reference", "policies.laws.simple", "Zero", "ZeroConfig", {}, "none"),
    "random": _Entry(
        "uniform random actions from the policy's own seed",
        "policies.laws.simple",
        "Random",
        "RandomConfig",
        {},
        "none",
    ),
}

#: name -> one-line description of every built-in policy name (for the CLI's help and error messages).
KNOWN_POLICIES: dict[str, str] = {name: e.description for name, e in _REGISTRY.items()}

#: The two spec forms that are not names.
SPEC_FORMS: dict[str, str] = {
    "sb3:PATH": "a Stable-Baselines3 agent: DIR/model.zip of a mobman-train run (or a shipped baseline, e.g. sb3:ppo-circle)",
    "module:attr": "your own Policy object, controller class (with reset and predict) or "
    "@policies.controller_factory function, importable as module:attr (from the working directory too); "
    "module:attr:key=value,... passes keyword arguments to the class or factory",
}


def _known_text() -> str:
    return ", ".join([*_REGISTRY, *SPEC_FORMS])


def data_spec_problem(spec: object) -> str | None:
    """Why `spec`, read from a file someone else wrote (a scorecard, a results file), may not be built and run
    here, or None if it may: only a built-in name with options (`qp`, `oracle:gamma=10`) and an `sb3:` agent
    (a path or an alias, read through `policies.agents.untrusted`'s checks) are data. `module:attr` names code, which
    only a spec you type may do (`policies.user_specs`)."""
    if not isinstance(spec, str) or not spec.strip():
        return f"{spec!r} is not a policy spec (a non-empty string)"
    if spec.startswith("sb3:") and len(spec) > 4:
        return None
    name, _, rest = spec.partition(":")
    if name not in _REGISTRY:
        return (
            f"{spec!r} names code; a file may name only built-in controllers (known: {', '.join(_REGISTRY)}) and "
            f"sb3: agents"
        )
    try:
        parse_options(rest, spec)
    except ValueError as exc:
        return str(exc)
    return None


def parse_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """Split `name[:key=value,...]` into (name, {key: value}); values parsed as bool, int, float or str."""
    name, _, rest = spec.partition(":")
    return name.strip(), parse_options(rest, spec)


def parse_options(rest: str, spec: str) -> dict[str, Any]:
    """`key=value,...` of a spec as {key: value} (bool, int, float or str), ValueError naming a bad item."""
    kwargs: dict[str, Any] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, text = item.partition("=")
        key, text = key.strip(), text.strip()
        if not eq or not key or not text:
            raise ValueError(
                f"bad option {item!r} in policy spec {spec!r}: write key=value pairs separated by "
                f"commas, e.g. 'nnbc:gamma=20,mu=20,j0=probe'"
            )
        if key in kwargs:
            raise ValueError(f"option {key!r} given twice in policy spec {spec!r}")
        kwargs[key] = _parse_value(text, spec)
    return kwargs


def _parse_value(text: str, spec: str = "") -> Any:
    """`text` as bool, int, float or str; ValueError for a control character (a terminal escape, a NUL, a
    right-to-left override) or a non-ASCII digit, which `int`/`float` would accept (`２０` is 20): what a
    spec shows must be what it means."""
    bad = [c for c in text if unicodedata.category(c) in ("Cc", "Cf") or (c.isdigit() and not c.isascii())]
    if bad:
        kind = "a control character" if unicodedata.category(bad[0]).startswith("C") else "a non-ASCII digit"
        raise ValueError(
            f"option value {text!r} in policy spec {spec!r} holds {kind} ({bad[0]!r}, U+{ord(bad[0]):04X}); write "
            f"numbers with the ASCII digits 0-9 and values without control characters"
        )
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


def _coerce(cfg_cls: type, key: str, value: Any, hint: Any, spec: str) -> Any:
    """Convert a parsed spec value to the config field's type (int -> float allowed), or fail clearly."""
    is_num = isinstance(value, (int, float)) and not isinstance(value, bool)
    if hint is float and is_num:
        return float(value)
    if hint is int and isinstance(value, int) and not isinstance(value, bool):
        return value
    if (hint is bool and isinstance(value, bool)) or (hint is str and isinstance(value, str)):
        return value
    if hint not in (float, int, bool, str):
        return value
    raise ValueError(
        f"option {key}={value!r} in policy spec {spec!r} must be a {hint.__name__} ({cfg_cls.__name__}.{key})"
    )


def build_config(cfg_cls: type, options: dict[str, Any], spec: str = "") -> Any:
    """Build a config dataclass from spec options; unknown keys fail listing the fields."""
    fields = {f.name: f for f in dataclasses.fields(cfg_cls)}
    unknown = sorted(set(options) - set(fields))
    if unknown:
        known = ", ".join(fields) or "(none: this policy has no options)"
        raise ValueError(f"unknown option(s) {unknown} in policy spec {spec!r}; {cfg_cls.__name__} accepts: {known}")
    hints = typing.get_type_hints(cfg_cls)
    kwargs = {k: _coerce(cfg_cls, k, v, hints.get(k), spec) for k, v in options.items()}
    return cfg_cls(**kwargs)


def _load_entry(name: str, entry: _Entry) -> tuple[type, type]:
    try:
        module = importlib.import_module(entry.module)
    except ModuleNotFoundError as exc:
        if exc.name == entry.module:
            raise ValueError(
                f"policy {name!r} is not available in this install: module {entry.module} is missing"
            ) from None
        raise
    return getattr(module, entry.cls), getattr(module, entry.config_cls)


def make(spec: str, env: Any, seed: int | None = None) -> Any:
    """Build the policy named by `spec` for `env` (a gym.Env, any wrappers, or an SB3 VecEnv with one env).
    For a Gymnasium vector env (`mobman_env.vector`) it returns one `policies.batched.BatchedPolicy` for its N
    robots: on the native vector env the spec's vectorised law where its class has one (a `batched`
    constructor: `zero`, `random`, `jmpi`, `clik`, `oracle`, `nnbc`, their `-full` forms, `qp`, `qp-oracle`,
    `calib-qp`, `mpc`, `mpc-oracle`, `nnbc-plus`, `nnbc-plus-wb`, `broyden`, `rls`),
    else (every other spec, `sb3:` and `module:attr` included, and every spec on a `SyncVectorEnv` of single
    envs: mobman's physics mode and random arm) a loop of this spec built for each robot. Other vector envs
    (e.g. `AsyncVectorEnv`) are refused naming the fix.

    `seed` seeds the policy's own Generator (controllers re-seed on `reset(seed=...)`). Returns an object with
    `reset(obs, info=None, *, seed=None)` and SB3's `predict` (see `policies.base.Policy`).
    """
    if not isinstance(spec, str) or not spec.strip():
        raise TypeError(
            f"policy spec must be a non-empty string such as 'nnbc' or 'sb3:runs/x/model.zip', "
            f"got {spec!r}; known: {_known_text()}"
        )
    spec = spec.strip()
    if is_vector_env(env):  # one batched policy for the N robots of a gymnasium vector env (policies.batched)
        check_vector_env(env)
        name = spec.partition(":")[0]
        native = is_native_vector_env(env)
        if native and name in _REGISTRY and hasattr(_load_entry(name, _REGISTRY[name])[0], "batched"):
            return _make_builtin_batched(spec, env, seed)
        if native and name == "sb3":
            agent = make(spec, _RobotView(env, 0), seed)  # checked against robot 0 (the robots share spaces)
            if getattr(agent, "_actor", None) is not None:  # row-by-row actions: batch it (policies.agents.sb3_actor)
                if agent.residual_base is not None:
                    agent.base = make(agent.residual_base, env, seed)  # the base's vectorised law
                return BatchedAgent(spec, agent, env.num_envs)
        return BatchedPolicy.for_vector_env(spec, env, lambda s, robot: make(s, robot, seed))
    if spec.startswith("sb3:"):
        from policies.agents.sb3 import SB3Policy

        policy = SB3Policy(spec[4:])
        policy.check_compatible(EnvFacts.from_env(env), env)
        if policy.residual_base is not None:  # a residual agent: its base controller, built for this env
            base_name = policy.residual_base.partition(":")[0]
            if base_name not in _REGISTRY:  # a file names a built-in, never code (make_user is not reached)
                raise ValueError(
                    f"{spec}: its residual_base {policy.residual_base!r} is not a built-in controller; accepted: "
                    f"{_known_text()}"
                )
            policy.base = make(policy.residual_base, env, seed)
            policy.knowledge = policy.base.knowledge  # the agent reads what its base reads
        return policy
    name, _, rest = spec.partition(":")
    if name in _REGISTRY:
        return _make_builtin(spec, env, seed)
    attr, _, options = rest.partition(":")
    if attr and "=" not in attr:  # module:attr[:key=value,...]
        return make_user(name, attr, parse_options(options, spec), env, spec, _known_text())
    hint = difflib.get_close_matches(name, list(_REGISTRY), n=1)
    did = f" (did you mean {hint[0]!r}?)" if hint else ""
    raise ValueError(f"unknown policy {name!r} in spec {spec!r}{did}; known: {_known_text()}")


def _make_builtin(spec: str, env: Any, seed: int | None) -> Any:
    name, options = parse_spec(spec)
    entry = _REGISTRY[name]
    cls, cfg_cls = _load_entry(name, entry)
    config = build_config(cfg_cls, {**entry.preset, **options}, spec)
    view = KnowledgeView(unwrap_env(env), view_class(entry, config))  # all the controller can reach of the env
    facts = EnvFacts.from_env(view)
    extra: dict[str, Any] = {}
    if view.knowledge == "nominal":
        extra["nominal_params"] = nominal_params_provider(view)
    elif view.knowledge == "true":
        extra["params_provider"] = true_params_provider(view)
        if getattr(cls, "reads_true_lag", False):
            extra["lag_provider"] = true_lag_provider(view)
    return cls(facts, config, seed, **extra)


def view_class(entry: _Entry, config: Any) -> str:
    """The knowledge class a built-in is built with (`policies.views`): "true" for a true-model law, "nominal" for
    a catalogue law (and `nnbc:j0=nominal`), else "none" (the model-free and structure classes read the same: the
    facts). `policies.knowledge_of(spec)` reports the same class, or "structure" where this says "none"."""
    if entry.model == "true":
        return "true"
    if entry.model == "nominal" or getattr(config, "j0", None) == "nominal":
        return "nominal"
    return "none"


def _make_builtin_batched(spec: str, venv: Any, seed: int | None) -> Any:
    """The vectorised law of a built-in spec for the N robots of `venv` (its class's `batched`): the model-based
    ones get row-indexed providers, nominal (`venv.nominal_params_of(i)`: robot i's, which for the random arm family
    is its episode's drawn design) or true (`venv.true_params(i)`)."""
    check_vector_env(venv)
    name, options = parse_spec(spec)
    entry = _REGISTRY[name]
    cls, cfg_cls = _load_entry(name, entry)
    config = build_config(cfg_cls, {**entry.preset, **options}, spec)
    knowledge = view_class(entry, config)
    view = KnowledgeView(venv, knowledge)  # all the law can reach of the vector env
    facts = EnvFacts.from_env(KnowledgeView(_RobotView(venv, 0), knowledge))
    extra: dict[str, Any] = {}
    if knowledge == "nominal":
        extra["nominal_params"] = lambda i: nominal_of(view, i)
    elif knowledge == "true":
        extra["params_provider"] = view.true_params
        if getattr(cls, "reads_true_lag", False):
            extra["lag_provider"] = view.true_actuator_tau
    law = getattr(cls, "batched")(facts, config, venv.num_envs, seed, **extra)  # noqa: B009  (not every class has it)
    law.spec = spec
    return law


def nominal_of(venv: Any, i: int) -> Any:
    """Robot i's nominal robot of a vector env: `nominal_params_of(i)` where the env has it (mobman's vector envs:
    the random arm family draws one per robot and reset), else its one `nominal_params`."""
    of = getattr(venv, "nominal_params_of", None)
    return venv.nominal_params if of is None else of(i)


def nominal_params_provider(env: Any) -> Callable[[], Any]:
    """A callable returning the env's current nominal robot: the catalogue robot, or for the random arm family
    the episode's drawn design (it changes at every reset). Model-based policies call it at every episode start."""
    base = unwrap_env(env)

    def provider() -> Any:
        return base.nominal_params

    return provider


def true_params_provider(env: Any) -> Callable[[], Any]:
    """A callable returning the env's current true robot (read through `get_attr` for a VecEnv).

    The oracle calls it at every episode start; nothing else in `policies` reads `true_params`.
    """
    base = unwrap_env(env)

    def provider() -> Any:
        return base.true_params

    return provider


def true_lag_provider(env: Any) -> Callable[[], float]:
    """A callable returning the time constant of the env's current actuator lag, s (`true_actuator_tau`: the
    episode's condition). `mpc-oracle` calls it at every episode start, beside `true_params_provider`."""
    base = unwrap_env(env)

    def provider() -> float:
        return float(base.true_actuator_tau)

    return provider

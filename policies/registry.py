"""Policy specs -> policy objects: `policies.make(spec, env)`.

Spec grammar (one string, as the CLI takes it):

* `name[:key=value,...]` - a built-in controller; keys are the fields of its config dataclass; values are
  parsed as bool (`true`/`false`), int, float, or else kept as a string: `nnbc:gamma=20,mu=20,j0=probe`.
* `sb3:PATH` - a Stable-Baselines3 agent; the whole rest of the string is the path (a `model.zip` or its run
  folder), or the alias of a shipped baseline (a folder name of `policies/models/`: `sb3:sac-circle`,
  `sb3:ppo-circle`, ...).
* `module:attr[:key=value,...]` - your own policy: `attr` (dotted for nested attributes) in `module` is a
  Policy object, or a class / factory that is called with the env if its signature accepts one positional
  argument, else with no arguments, and with the options as keyword arguments (parsed as for built-in specs:
  `mymod:Ctrl:gain=5,horizon=3` calls `Ctrl(env, gain=5, horizon=3)`; options its signature does not take are
  refused naming the ones it does). The result must have `reset` and `predict` (see `policies.base.Policy`).
  `module` is imported from `sys.path`, else from the working directory (`import_user_module`: only that
  module is loaded from there; the working directory is not put on `sys.path`). `mymod.py:Ctrl` is refused
  with the fix (drop the .py).

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
import importlib.machinery
import importlib.util
import inspect
import os
import sys
import types
import typing
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from policies.base import EnvFacts, unwrap_env
from policies.batched import BatchedPolicy, _RobotView, check_vector_env, is_native_vector_env, is_vector_env


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
        "policies.nnbc",
        "NNBC",
        "NNBCConfig",
        {},
        "none",
    ),
    "nnbc-full": _Entry(
        "NNBC with J_hat of the whole r_a_dot (the platform can drive)",
        "policies.nnbc",
        "NNBC",
        "NNBCConfig",
        {"full": True},
        "none",
    ),
    "nnbc-plus": _Entry(
        "NNBC improved: no kinematic parameter, but the structured estimate knows the chain's kind (class structure; see policies.nnbc_plus)",
        "policies.nnbc_plus",
        "NNBCPlus",
        "NNBCPlusConfig",
        {},
        "none",
    ),
    "nnbc-plus-wb": _Entry(
        "nnbc-plus with its whole-body estimate instead of the structured one: knows no structure (class none)",
        "policies.nnbc_plus",
        "NNBCPlus",
        "NNBCPlusConfig",
        {"formulation": "whole_body"},
        "none",
    ),
    "broyden": _Entry(
        "model-free: Broyden's secant Jacobian update in nnbc-plus's probe / excitation / control law",
        "policies.broyden_rls",
        "Broyden",
        "BroydenConfig",
        {},
        "none",
    ),
    "rls": _Entry(
        "model-free: recursive least squares with forgetting in nnbc-plus's probe / excitation / control law",
        "policies.broyden_rls",
        "RLS",
        "RLSConfig",
        {},
        "none",
    ),
    "jmpi": _Entry(
        "open-loop Jacobian pseudo-inverse on the nominal model (the paper's comparison)",
        "policies.jmpi",
        "JMPI",
        "JMPIConfig",
        {},
        "nominal",
    ),
    "jmpi-full": _Entry(
        "open-loop pseudo-inverse of the nominal whole-body Jacobian",
        "policies.jmpi",
        "JMPI",
        "JMPIConfig",
        {"full": True},
        "nominal",
    ),
    "clik": _Entry(
        "closed-loop eq. (10) on the nominal model (resolved rate, paper's J): the practitioner's baseline",
        "policies.jmpi",
        "CLIK",
        "CLIKConfig",
        {},
        "nominal",
    ),
    "clik-full": _Entry(
        "closed-loop eq. (10) on the nominal whole-body Jacobian",
        "policies.jmpi",
        "CLIK",
        "CLIKConfig",
        {"full": True},
        "nominal",
    ),
    "oracle": _Entry(
        "eq. (10) with the true robot's Jacobian: the known-model bound",
        "policies.jmpi",
        "Oracle",
        "OracleConfig",
        {},
        "true",
    ),
    "oracle-full": _Entry(
        "eq. (10) with the true whole-body Jacobian", "policies.jmpi", "Oracle", "OracleConfig", {"full": True}, "true"
    ),
    "qp": _Entry(
        "whole-body differential-IK QP on the nominal model: joint-limit dampers, speed bounds, posture term",
        "policies.qp",
        "QP",
        "QPConfig",
        {},
        "nominal",
    ),
    "qp-oracle": _Entry(
        "the whole-body QP on the true robot: the known-model ceiling (respects joint limits)",
        "policies.qp",
        "QP",
        "QPConfig",
        {},
        "true",
    ),
    "calib-qp": _Entry(
        "the whole-body QP on a model calibrated online: a Kalman filter on the worn lengths, from the catalogue",
        "policies.calib_qp",
        "CalibQP",
        "CalibQPConfig",
        {},
        "nominal",
    ),
    "mpc": _Entry(
        "receding-horizon whole-body QP on the nominal model: path preview, actuator lag (identified online), speed limits",
        "policies.mpc",
        "MPC",
        "MPCConfig",
        {},
        "nominal",
    ),
    "mpc-oracle": _Entry(
        "the receding-horizon QP on the true robot and the true actuator lag: the known-model reference",
        "policies.mpc",
        "MPC",
        "MPCConfig",
        {},
        "true",
    ),
    "zero": _Entry("zero speeds: the floor reference", "policies.simple", "Zero", "ZeroConfig", {}, "none"),
    "random": _Entry(
        "uniform random actions from the policy's own seed", "policies.simple", "Random", "RandomConfig", {}, "none"
    ),
}

#: name -> one-line description of every built-in policy name (for the CLI's help and error messages).
KNOWN_POLICIES: dict[str, str] = {name: e.description for name, e in _REGISTRY.items()}

#: The two spec forms that are not names.
SPEC_FORMS: dict[str, str] = {
    "sb3:PATH": "a Stable-Baselines3 agent: DIR/model.zip of a mobman-train run (or a shipped baseline, e.g. sb3:ppo-circle)",
    "module:attr": "your own Policy object, class or factory, importable as module:attr (from the working "
    "directory too); module:attr:key=value,... passes keyword arguments to the class or factory",
}


def _known_text() -> str:
    return ", ".join([*_REGISTRY, *SPEC_FORMS])


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
        kwargs[key] = _parse_value(text)
    return kwargs


def _parse_value(text: str) -> Any:
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
        return BatchedPolicy.for_vector_env(spec, env, lambda s, robot: make(s, robot, seed))
    if spec.startswith("sb3:"):
        from policies.sb3 import SB3Policy

        policy = SB3Policy(spec[4:])
        policy.check_compatible(EnvFacts.from_env(env), env)
        return policy
    name, _, rest = spec.partition(":")
    if name in _REGISTRY:
        return _make_builtin(spec, env, seed)
    attr, _, options = rest.partition(":")
    if attr and "=" not in attr:  # module:attr[:key=value,...]
        return _make_user(name, attr, parse_options(options, spec), env, spec)
    hint = difflib.get_close_matches(name, list(_REGISTRY), n=1)
    did = f" (did you mean {hint[0]!r}?)" if hint else ""
    raise ValueError(f"unknown policy {name!r} in spec {spec!r}{did}; known: {_known_text()}")


def _make_builtin(spec: str, env: Any, seed: int | None) -> Any:
    name, options = parse_spec(spec)
    entry = _REGISTRY[name]
    cls, cfg_cls = _load_entry(name, entry)
    config = build_config(cfg_cls, {**entry.preset, **options}, spec)
    facts = EnvFacts.from_env(env)
    extra: dict[str, Any] = {}
    if entry.model == "nominal" or getattr(config, "j0", None) == "nominal":
        extra["nominal_params"] = nominal_params_provider(env)
    elif entry.model == "true":
        extra["params_provider"] = true_params_provider(env)
        if getattr(cls, "reads_true_lag", False):
            extra["lag_provider"] = true_lag_provider(env)
    return cls(facts, config, seed, **extra)


def _make_builtin_batched(spec: str, venv: Any, seed: int | None) -> Any:
    """The vectorised law of a built-in spec for the N robots of `venv` (its class's `batched`): the model-based
    ones get row-indexed providers, nominal (`venv.nominal_params_of(i)`: robot i's, which for the random arm family
    is its episode's drawn design) or true (`venv.true_params(i)`)."""
    check_vector_env(venv)
    name, options = parse_spec(spec)
    entry = _REGISTRY[name]
    cls, cfg_cls = _load_entry(name, entry)
    config = build_config(cfg_cls, {**entry.preset, **options}, spec)
    facts = EnvFacts.from_env(_RobotView(venv, 0))
    extra: dict[str, Any] = {}
    if entry.model == "nominal" or getattr(config, "j0", None) == "nominal":
        extra["nominal_params"] = lambda i: nominal_of(venv, i)
    elif entry.model == "true":
        extra["params_provider"] = venv.true_params
        if getattr(cls, "reads_true_lag", False):
            extra["lag_provider"] = venv.true_actuator_tau
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


def import_user_module(module_name: str) -> types.ModuleType:
    """`module_name` as `import` finds it on `sys.path`, else from the working directory: the module (for a
    dotted name, its top-level package) is loaded from there by name, and the working directory is never put
    on `sys.path`, so no other import of the run can pick up a file there (a planted `defusedxml.py`).
    ModuleNotFoundError when neither has it."""
    top = module_name.partition(".")[0]
    if top not in sys.modules and importlib.util.find_spec(top) is None:
        spec = importlib.machinery.PathFinder.find_spec(top, [os.getcwd()])
        if spec is not None and spec.loader is not None:
            module = importlib.util.module_from_spec(spec)
            sys.modules[top] = module
            try:
                spec.loader.exec_module(module)
            except BaseException:
                del sys.modules[top]
                raise
    return importlib.import_module(module_name)


def _make_user(module_name: str, attr: str, options: dict[str, Any], env: Any, spec: str) -> Any:
    if module_name.endswith(".py"):
        raise ValueError(
            f"policy spec {spec!r}: {module_name!r} is a file name; name the module, without .py: "
            f"{module_name[:-3]}:{attr}"
        )
    try:
        module = import_user_module(module_name)
    except ModuleNotFoundError as exc:
        # the module itself (or its package) is missing: an unknown spec. A missing import *inside* the user's
        # module is their error and propagates unchanged.
        if exc.name is not None and (module_name == exc.name or module_name.startswith(exc.name + ".")):
            raise ValueError(
                f"unknown policy {spec!r}: {module_name!r} is neither a known policy nor an importable "
                f"module ({exc}: put {module_name.split('.')[0]}.py in the working directory or on PYTHONPATH); "
                f"known: {_known_text()}"
            ) from None
        raise
    obj: Any = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ValueError(f"policy spec {spec!r}: module {module_name!r} has no attribute {attr!r}") from None
    if not inspect.isclass(obj) and _is_policy(obj):
        if options:
            raise ValueError(
                f"policy spec {spec!r}: {attr} is a policy object, which takes no options {sorted(options)}; name "
                f"a class or factory to pass options to it, or drop them"
            )
        return obj
    if not callable(obj):
        raise TypeError(f"policy spec {spec!r}: {attr!r} is neither a policy (reset + predict) nor a class or factory")
    try:
        sig = inspect.signature(obj)
    except (TypeError, ValueError):
        sig = None
    if sig is not None and _binds(sig, env, **options):
        policy = obj(env, **options)
    elif sig is None or _binds(sig, **options):
        policy = obj(**options)
    elif options and (_binds(sig, env) or _binds(sig)):
        params = list(sig.parameters.values())[1 if _binds(sig, env) else 0 :]  # not the env's parameter
        accepted = [p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
        raise ValueError(
            f"policy spec {spec!r}: {attr}{sig} does not take the options {sorted(options)}; its keyword "
            f"arguments are {accepted} (module:attr:key=value,... passes them)"
        )
    else:
        raise TypeError(f"policy spec {spec!r}: {attr}{sig} can be called neither with (env) nor with no arguments")
    if not _is_policy(policy):
        raise TypeError(
            f"policy spec {spec!r}: {attr} returned a {type(policy).__name__}, which lacks "
            f"reset(obs, info=None, *, seed=None) and/or predict(observation, state=None, "
            f"episode_start=None, deterministic=True); see policies.base.Policy"
        )
    return policy


def _binds(sig: inspect.Signature, *args: Any, **kwargs: Any) -> bool:
    try:
        sig.bind(*args, **kwargs)
    except TypeError:
        return False
    return True


def _is_policy(obj: Any) -> bool:
    return callable(getattr(obj, "reset", None)) and callable(getattr(obj, "predict", None))

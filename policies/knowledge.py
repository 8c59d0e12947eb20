"""What a policy knows about the robot: its knowledge class, `knowledge_of(policy_or_spec)`.

Every built-in policy class declares `knowledge`, one of `KNOWLEDGE_CLASSES` (DESIGN, release 0.3):

| class | what the policy knows | built-in policies |
|---|---|---|
| `none` | no kinematic parameter and no structure | `nnbc`, `nnbc-full`, `nnbc-plus-wb`, `broyden`, `rls`, `zero`, `random`, every `sb3:` agent; `nnbc-plus:formulation=whole_body` or `=paper` |
| `structure` | the kind of chain and platform (which joints, a planar base, a sensed mount), no parameter value | `nnbc-plus` (its default structured estimate) |
| `nominal` | the catalogue's parameters | `jmpi`, `jmpi-full`, `clik`, `clik-full`, `qp`, `mpc`, `calib-qp` (it calibrates the catalogue online: the catalogue is its start, release 0.4; it was labelled `structure` in 0.3); `nnbc:j0=nominal` |
| `true` | the worn robot's parameters | `oracle`, `oracle-full`, `qp-oracle`, `mpc-oracle` (the worn robot and the episode's actuator lag) |

Where the class depends on an option, `knowledge` is a property of the built object: `nnbc-plus` follows its
`formulation`, `nnbc` its `j0` (`"unknown"` for a `J0=` matrix of the Python API, whose origin it cannot tell),
`QP` and `MPC` their model source. A user's policy without the attribute is `"unknown"`. Scorecards, tables and plots group
by the class; "model-free" is said only of class `none`.

```python
import policies
policies.knowledge_of("nnbc-plus")                        # "structure"
policies.knowledge_of("nnbc-plus-wb")                     # "none" (formulation=whole_body)
policies.knowledge_of(policies.make("qp-oracle", env))     # "true"
```

Imports `policies.registry` (which class a spec builds) and, for `sb3:` specs, `policies.agents.sb3` (which imports
neither torch nor Stable-Baselines3 until an agent is built).
"""

from __future__ import annotations

import importlib
import inspect
import types
from typing import Any

import numpy as np

from policies import registry

#: The knowledge classes, from the least to the most the policy knows about the robot.
KNOWLEDGE_CLASSES: tuple[str, ...] = ("none", "structure", "nominal", "true")

#: What `knowledge_of` says of a policy that declares no class (a user's object, class or factory).
UNKNOWN = "unknown"


def knowledge_of(policy: Any) -> str:
    """The knowledge class of `policy`: a policy object, or a spec string as `policies.make` takes it.

    An object: its `knowledge` attribute; a batched policy of built-in specs (`policies.batched`) has the class of
    its spec; a batched loop or stack of policies the class all its rows share (else "unknown"); anything without
    a class, "unknown". A spec: the class of the object the spec builds, with its options (`nnbc-plus` with
    `formulation=whole_body` is "none"), without loading an agent or touching an env (a class whose `knowledge`
    is a property is built for a stand-in env that has only the facts); `module:attr` imports the module and
    reads `attr`'s `knowledge` (a factory, or an object without one: "unknown").

    Returns one of `KNOWLEDGE_CLASSES` or "unknown". ValueError for a spec naming no policy or with a bad option
    (as `policies.make`), or a declared value outside the classes.
    """
    if isinstance(policy, str):
        return _of_spec(policy)
    value = getattr(policy, "knowledge", None)
    if value is not None:
        return _checked(value, type(policy).__name__)
    spec = getattr(policy, "spec", None)  # a vectorised law built by policies.make names its spec
    if isinstance(spec, str) and (spec.startswith("sb3:") or spec.partition(":")[0] in registry.KNOWN_POLICIES):
        return _of_spec(spec)
    rows = getattr(policy, "rows", None)  # policies.batched: a loop of single policies; a StackedPolicy
    if isinstance(rows, (list, tuple)) and rows:
        kinds = {knowledge_of(row) for row in rows}
        return kinds.pop() if len(kinds) == 1 else UNKNOWN
    return UNKNOWN


def _checked(value: Any, owner: str) -> str:
    if value not in (*KNOWLEDGE_CLASSES, UNKNOWN):
        raise ValueError(
            f"{owner}.knowledge is {value!r}; accepted: {', '.join(KNOWLEDGE_CLASSES)} (or {UNKNOWN!r}): set the "
            f"class attribute to the class of what the policy knows about the robot (policies.knowledge)"
        )
    return str(value)


def _of_spec(spec: str) -> str:
    spec = spec.strip()
    if spec.startswith("sb3:"):
        from policies.agents.sb3 import SB3Policy

        return _checked(inspect.getattr_static(SB3Policy, "knowledge"), "SB3Policy")
    name, _, rest = spec.partition(":")
    entry = registry._REGISTRY.get(name)
    if entry is None and rest and "=" not in rest:
        return _of_user_attr(name, rest, spec)
    if entry is None:
        registry.make(spec, None)  # raises the registry's error: the unknown name, its closest match, the known ones
        raise AssertionError(f"policies.make accepted the unknown spec {spec!r}")
    options = registry.parse_spec(spec)[1]
    cls, cfg_cls = registry._load_entry(name, entry)
    registry.build_config(cfg_cls, {**entry.preset, **options}, spec)  # a bad option fails as in make()
    declared = inspect.getattr_static(cls, "knowledge", None)
    if isinstance(declared, str):
        return _checked(declared, cls.__name__)
    # the class depends on an option or the model source (a property): read it from the object the spec builds
    # for an env that has only the facts; building reads no robot model (the providers are called at reset)
    return knowledge_of(registry.make(spec, _FactsOnlyEnv()))


def _of_user_attr(module_name: str, attr: str, spec: str) -> str:
    try:
        obj: Any = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name is not None and (module_name == exc.name or module_name.startswith(exc.name + ".")):
            raise ValueError(
                f"unknown policy {spec!r}: {module_name!r} is neither a known policy nor an importable module; "
                f"known: {', '.join([*registry.KNOWN_POLICIES, *registry.SPEC_FORMS])}"
            ) from None
        raise
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ValueError(f"policy spec {spec!r}: module {module_name!r} has no attribute {attr!r}") from None
    declared = (
        inspect.getattr_static(obj, "knowledge", None) if inspect.isclass(obj) else getattr(obj, "knowledge", None)
    )
    if isinstance(declared, str):
        return _checked(declared, getattr(obj, "__name__", type(obj).__name__))
    return UNKNOWN


class _FactsOnlyEnv:
    """What `policies.make` needs to build a spec without an env: the envs' control period (100 Hz), the PUMA's 8
    actuators and an observation space of no keys; its robot models raise if anything reads them."""

    dt = 0.01
    action_scale = np.ones(8)
    observation_space = types.SimpleNamespace(spaces={})

    @property
    def nominal_params(self) -> Any:
        raise RuntimeError("knowledge_of builds a spec only to read its class: nothing may read its robot model")

    @property
    def true_params(self) -> Any:
        raise RuntimeError("knowledge_of builds a spec only to read its class: nothing may read its robot model")

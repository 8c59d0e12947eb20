"""What a built-in controller may read of its env, by knowledge class: it is built from a view holding that only.

A knowledge class (`policies.knowledge`) was a declaration: `calib-qp` read the catalogue (the object class
`nominal` reads) and called itself `structure`. From release 0.4 the registry builds every built-in through a
`KnowledgeView` of the env (or of the vector env) that answers only what the class may read and raises
`KnowledgeError` on anything else, naming the attribute, the class and what it may read:

| class | may read |
|---|---|
| `none` | the spaces, `dt`, `action_scale` (`EnvFacts`), the number of robots of a vector env |
| `structure` | the same: the kind of chain and platform is the controller's own design (the structured estimate knows the platform is planar and the mount is sensed; no value comes from the env) |
| `nominal` | that, plus the catalogue: `nominal_params` (`nominal_params_of(i)` on a vector env) |
| `true` | that, plus the worn robot: `true_params` (`true_params(i)` on a vector env) and the episode's actuator lag, `true_actuator_tau` |

The class a spec is built with is the one `policies.knowledge_of(spec)` reports (a test checks both agree for
every built-in), so a controller that reads more than its class fails when it is built or at its first episode
start, not in a scorecard. Agents (`sb3:`) and the user's `module:attr` controllers are not built through a view:
an agent reads only observations (its checks are in `policies.agents.sb3`), and a user's class is the user's.

Imports nothing.
"""

from __future__ import annotations

from typing import Any

#: What every class may read (the facts of `policies.base.EnvFacts`, the spaces, a vector env's size).
_FACTS = frozenset(
    {
        "dt",
        "action_scale",
        "observation_space",
        "action_space",
        "single_observation_space",
        "single_action_space",
        "num_envs",
        "metadata",
        "spec",
    }
)
#: What each class may read beyond the facts.
ALLOWED: dict[str, frozenset[str]] = {
    "none": _FACTS,
    "structure": _FACTS,
    "nominal": _FACTS | {"nominal_params", "nominal_params_of"},
    "true": _FACTS | {"nominal_params", "nominal_params_of", "true_params", "true_actuator_tau"},
}


class KnowledgeError(AttributeError):
    """A controller read something its knowledge class may not."""


class KnowledgeView:
    """`base` (an unwrapped env: `policies.base.unwrap_env(env)`, a native vector env, or a `policies.batched` row
    view) as a controller of class `knowledge` may see it: the attributes `ALLOWED[knowledge]`, each read through to
    `base`; anything else raises `KnowledgeError`. `unwrapped` is the view itself, so `policies.base.unwrap_env`
    and `EnvFacts.from_env` see the view, never the env behind it."""

    def __init__(self, base: Any, knowledge: str):
        if knowledge not in ALLOWED:
            raise ValueError(f"unknown knowledge class {knowledge!r}; accepted: {', '.join(ALLOWED)}")
        object.__setattr__(self, "_base", base)
        object.__setattr__(self, "_knowledge", knowledge)

    @property
    def unwrapped(self) -> KnowledgeView:
        return self

    @property
    def knowledge(self) -> str:
        """The class this view serves."""
        return self._knowledge

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        allowed = ALLOWED[self._knowledge]
        if name not in allowed:
            raise KnowledgeError(
                f"a controller of knowledge class {self._knowledge!r} read the env's {name!r}, which that class may "
                f"not read; it may read: {', '.join(sorted(allowed))}. Declare the class the controller needs "
                "(policies.knowledge) or read only what its class may"
            )
        return getattr(self._base, name)

    def __setattr__(self, name: str, value: Any) -> None:
        raise KnowledgeError(f"a controller may not write the env's {name!r} (a KnowledgeView is read-only)")

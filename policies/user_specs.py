"""`module:attr[:key=value,...]`: your own controller, checked to be one before anything is called.

A spec of this form runs code of your choosing, so it is accepted only where you typed it (a command line, your
own sweep YAML, `policies.make` in your script), never from a file someone else wrote (a scorecard, a results
file: `policies.registry.data_spec_problem`). Even typed, `attr` is checked before it is called, so that a
typo or a pasted line cannot call an arbitrary library function with your options (`os:system:command=...`
named a function taking a keyword argument, and was run):

* a **class** whose instances have `reset` and `predict` (the class defines them: `policies.base.Policy`) is
  called with the env and the options;
* a **function marked as a controller factory** (`@policies.controller_factory`, which sets
  `__mobman_controller_factory__ = True` on it) is called the same way, and what it returns must have `reset`
  and `predict`;
* an **object** that already has `reset` and `predict` is used as it is (nothing is called);
* anything else (an unmarked function, a class without `predict`, a module) is refused, naming what it is and
  the fix.

The env goes to the constructor's first positional parameter if it has one (`Ctrl(env, gain=1.0)`); an option
naming that parameter (`mymod:Ctrl:env=3`) would silently replace the env and is refused, naming it. A class
without one (`Ctrl(*, gain=1.0)` or `Ctrl()`) is called with the options only.

`module` is imported from `sys.path`, else from the working directory (`import_user_module`: only that module
is loaded from there; the working directory is not put on `sys.path`).

Imports the standard library only.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import inspect
import os
import sys
import types
from collections.abc import Callable
from typing import Any, TypeVar

#: The attribute `controller_factory` sets on a function: the module's author declares it builds controllers.
FACTORY_MARK = "__mobman_controller_factory__"

F = TypeVar("F", bound=Callable[..., Any])


def controller_factory(func: F) -> F:
    """Mark `func` as a controller factory, so that `module:func[:key=value,...]` may call it (with the env as
    first argument if it takes one, and the options as keyword arguments); it must return an object with
    `reset` and `predict`. Unmarked functions are never called from a spec::

        import policies

        @policies.controller_factory
        def tuned(env, gain=5.0):
            return MyCtrl(env, gain=gain)
    """
    setattr(func, FACTORY_MARK, True)
    return func


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


def is_policy(obj: Any) -> bool:
    """`obj` has callable `reset` and `predict` (for a class: its instances will)."""
    return callable(getattr(obj, "reset", None)) and callable(getattr(obj, "predict", None))


def resolve_user(module_name: str, attr: str, spec: str, known: str) -> Any:
    """The object `attr` (dotted for nested attributes) of `module_name`, ValueError naming the fix when the
    module or the attribute does not exist (`known`: the built-in names, for the message)."""
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
                f"known: {known}"
            ) from None
        raise
    obj: Any = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ValueError(f"policy spec {spec!r}: module {module_name!r} has no attribute {attr!r}") from None
    return obj


def check_constructor(obj: Any, attr: str, spec: str) -> None:
    """Refuse `obj` unless it is a class whose instances have `reset` and `predict`, or a function marked with
    `controller_factory`: nothing else may be called from a spec (the module docstring). TypeError naming what
    `obj` is and the fix."""
    if inspect.isclass(obj):
        if is_policy(obj):
            return
        raise TypeError(
            f"policy spec {spec!r}: the class {attr} lacks reset(obs, info=None, *, seed=None) and/or "
            f"predict(observation, state=None, episode_start=None, deterministic=True), so it is not a "
            f"controller and is not called; see policies.base.Policy"
        )
    if getattr(obj, FACTORY_MARK, False) is True and callable(obj):
        return
    kind = "a function" if callable(obj) else f"a {type(obj).__name__}"
    raise TypeError(
        f"policy spec {spec!r}: {attr} is {kind}, neither a controller class (with reset and predict) nor a "
        f"function marked as a controller factory, so it is not called; name your controller class, or mark "
        f"your factory with @policies.controller_factory"
    )


def env_parameter(sig: inspect.Signature | None) -> str | None:
    """The name of the parameter the env is passed to: the first positional one (None: there is none)."""
    if sig is None:
        return None
    for p in sig.parameters.values():
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD):
            return p.name
        if p.kind is p.VAR_POSITIONAL:
            return None
    return None


def make_user(module_name: str, attr: str, options: dict[str, Any], env: Any, spec: str, known: str) -> Any:
    """The controller of `module:attr[:options]` for `env`, after the checks of the module docstring."""
    obj = resolve_user(module_name, attr, spec, known)
    if not inspect.isclass(obj) and is_policy(obj):
        if options:
            raise ValueError(
                f"policy spec {spec!r}: {attr} is a policy object, which takes no options {sorted(options)}; name "
                f"a class or factory to pass options to it, or drop them"
            )
        return obj
    check_constructor(obj, attr, spec)
    try:
        sig: inspect.Signature | None = inspect.signature(obj)
    except (TypeError, ValueError):
        sig = None
    first = env_parameter(sig)
    if first is not None and first in options:
        raise ValueError(
            f"policy spec {spec!r}: the option {first}={options[first]!r} names the parameter {attr} receives the "
            f"env in (its first positional parameter), and would replace the env; drop the option, or rename the "
            f"parameter (or make it keyword-only: def __init__(self, env, *, {first}=...))"
        )
    return _call(obj, attr, sig, options, env, spec)


def _call(obj: Any, attr: str, sig: inspect.Signature | None, options: dict[str, Any], env: Any, spec: str) -> Any:
    """Call the checked class or factory with (env, **options) if its signature takes them, else (**options)."""
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
    if not is_policy(policy):
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

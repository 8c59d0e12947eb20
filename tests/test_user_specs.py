"""`module:attr` specs are checked to name a controller before anything is called (`policies.user_specs`), and
spec option values are plain text (`policies.registry`): on every path that builds a spec (`policies.make`,
`mobman-eval run`, a sweep YAML's pre-flight check)."""

from __future__ import annotations

import json
import re
import sys

import pytest
import yaml
from conftest import SHORT_CIRCLE

import policies
from eval.cli import main

USER_MODULE = """
import numpy as np
import policies


class Ctrl:
    def __init__(self, env, gain=1.0):
        self.gain = gain
        self.n = env.action_space.shape[0]

    def reset(self, obs, info=None, *, seed=None):
        pass

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros(self.n, dtype=np.float32), state


class NoEnv:
    def __init__(self, *, gain=1.0):
        self.gain = gain

    reset = Ctrl.reset

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros(8, dtype=np.float32), state


@policies.controller_factory
def tuned(env, gain=5.0):
    return Ctrl(env, gain=gain)


def unmarked(env, gain=5.0):
    open(MARK, "w").close()
    return Ctrl(env, gain=gain)
"""


@pytest.fixture
def usermod(tmp_path, monkeypatch):
    """`usermod_specs` importable from tmp_path; its `unmarked` function would create tmp_path/CALLED."""
    (tmp_path / "usermod_specs.py").write_text(f"MARK = {str(tmp_path / 'CALLED')!r}\n" + USER_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "usermod_specs", raising=False)
    return tmp_path


@pytest.fixture
def env():
    import gymnasium as gym

    import mobman_env  # noqa: F401

    e = gym.make("WheeledPuma-Circle-v0", path=SHORT_CIRCLE)
    yield e
    e.close()


def test_a_library_function_is_never_called_from_a_spec(env, tmp_path):
    """`os:system:command=...` named a function taking a keyword argument, and was run; now only a controller
    class or a marked factory is called, checked before the call."""
    pwned = tmp_path / "PWNED"
    with pytest.raises(TypeError, match=r"system is a function, neither a controller class .* not called"):
        policies.make(f"os:system:command=touch {pwned}", env)
    with pytest.raises(TypeError, match=r"the class Popen lacks reset"):
        policies.make(f"subprocess:Popen:args=touch {pwned}", env)
    assert not pwned.exists()


def test_a_marked_factory_and_a_class_are_called_an_unmarked_function_is_not(env, usermod):
    assert policies.make("usermod_specs:tuned:gain=3", env).gain == 3
    assert policies.make("usermod_specs:Ctrl:gain=2", env).gain == 2
    assert policies.make("usermod_specs:NoEnv:gain=4", env).gain == 4  # no positional parameter: options only
    with pytest.raises(TypeError, match=r"mark your factory with @policies.controller_factory"):
        policies.make("usermod_specs:unmarked", env)
    assert not (usermod / "CALLED").exists()


def test_an_option_naming_the_env_parameter_is_refused(env, tmp_path, monkeypatch):
    """`Ctrl:env=3` called `Ctrl(env=3)`: the env silently replaced by the option."""
    plain = USER_MODULE.split("@policies.controller_factory")[0].replace("import policies\n", "")
    (tmp_path / "usermod_plain.py").write_text(plain)
    monkeypatch.syspath_prepend(str(tmp_path))
    assert policies.make("usermod_plain:Ctrl:gain=2", env).gain == 2
    with pytest.raises(ValueError, match=r"the option env=3 names the parameter Ctrl receives the env in"):
        policies.make("usermod_plain:Ctrl:env=3", env)


def test_an_option_naming_a_factorys_env_parameter_is_refused(env, usermod):
    with pytest.raises(ValueError, match=r"the option env='x' names the parameter tuned receives the env in"):
        policies.make("usermod_specs:tuned:env=x", env)


@pytest.mark.parametrize(
    "spec, shown",
    [
        ("nnbc:gamma=\uff12\uff10", "a non-ASCII digit ('\uff12', U+FF12)"),  # fullwidth 20: float() reads 20.0
        ("nnbc:gamma=2\u0660", "a non-ASCII digit ('\u0660', U+0660)"),  # Arabic-Indic zero
        ("usermod_specs:Ctrl:gain=\u0665", "a non-ASCII digit"),
        ("nnbc:j0=pro\x1b[2Jbe", "a control character ('\\x1b', U+001B)"),
        ("usermod_specs:Ctrl:gain=1\u202e0", "a control character ('\\u202e', U+202E)"),
    ],
)
def test_option_values_with_unicode_digits_or_control_characters_are_refused(env, usermod, spec, shown):
    with pytest.raises(ValueError, match="option value .* holds " + re.escape(shown)):
        policies.make(spec, env)


def test_a_file_may_name_only_built_in_specs_and_sb3_agents():
    from policies.registry import data_spec_problem

    assert data_spec_problem("qp") is None and data_spec_problem("oracle:gamma=10") is None
    assert data_spec_problem("sb3:ppo-circle") is None and data_spec_problem("sb3:runs/x/model.zip") is None
    for spec in ("os:system:command=id", "mymod:Ctrl", "sb3:", "", 3, "nnbc:gamma=\uff12"):
        assert data_spec_problem(spec) is not None, spec


def _run_args(tmp_path) -> list[str]:
    return ["--seeds", "1", "--dynamics", "kinematic", "--quiet", "--no-plots", "--out", str(tmp_path / "o")]


@pytest.mark.timeout(120)
def test_run_refuses_a_library_function_before_calling_it(tmp_path, capsys):
    pwned = tmp_path / "PWNED"
    assert main(["run", "--policy", f"os:system:command=touch {pwned}", *_run_args(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "neither a controller class" in err and "Traceback" not in err
    assert not pwned.exists()


@pytest.mark.timeout(120)
def test_a_sweep_yaml_naming_a_library_function_runs_nothing(tmp_path, capsys):
    """The same spec in a sweep YAML ran the command during the sweep's pre-flight check."""
    pwned = tmp_path / "PWNED"
    spec = {
        "envs": ["WheeledPuma-Circle-v0"],
        "policies": ["zero", f"os:system:command=touch {pwned}"],
        "seeds": {"start": 10_000, "count": 1},
        "dynamics": ["kinematic"],
        "env_kwargs": {"path": SHORT_CIRCLE},
    }
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(spec))
    args = ["sweep", "--config", str(tmp_path / "s.yaml"), "--out", str(tmp_path / "o"), "--quiet", "--no-plots"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "neither a controller class" in err and "Traceback" not in err
    assert not pwned.exists() and not (tmp_path / "o").exists()


def test_run_through_a_marked_factory(tmp_path, usermod, monkeypatch):
    monkeypatch.chdir(tmp_path)
    args = ["run", "--policy", "usermod_specs:tuned:gain=2", *_run_args(tmp_path)]
    assert main([*args, "--env-kwargs", json.dumps({"path": SHORT_CIRCLE})]) == 0
    episodes = json.loads((tmp_path / "o" / "results.json").read_text())["episodes"]
    assert [e["status"] for e in episodes] == ["ok"]

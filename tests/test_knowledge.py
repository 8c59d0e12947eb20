"""Knowledge classes (`policies.knowledge`): every built-in policy declares what it knows about the robot, the
class follows the options it depends on, and `knowledge_of` reads the same class from a spec and from the
object the spec builds (single and vector env)."""

from __future__ import annotations

import sys

import gymnasium as gym
import pytest

import policies
from policies.knowledge import KNOWLEDGE_CLASSES, UNKNOWN, knowledge_of

#: DESIGN, release 0.3: the class of every built-in name (a new name must be added here, with its class)
EXPECTED = {
    "nnbc": "none",
    "nnbc-full": "none",
    "nnbc-plus": "structure",
    "nnbc-plus-wb": "none",
    "broyden": "none",
    "rls": "none",
    "jmpi": "nominal",
    "jmpi-full": "nominal",
    "clik": "nominal",
    "clik-full": "nominal",
    "oracle": "true",
    "oracle-full": "true",
    "qp": "nominal",
    "qp-oracle": "true",
    "calib-qp": "structure",
    "mpc": "nominal",
    "mpc-oracle": "true",
    "zero": "none",
    "random": "none",
}


@pytest.fixture
def env():
    e = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    yield e
    e.close()


def test_every_built_in_name_has_its_class():
    assert set(EXPECTED) == set(policies.KNOWN_POLICIES), "a policy name was added or removed: classify it here"
    got = {name: knowledge_of(name) for name in policies.KNOWN_POLICIES}
    assert got == EXPECTED
    assert set(got.values()) <= set(KNOWLEDGE_CLASSES)
    assert knowledge_of("sb3:ppo-circle") == "none"  # read from SB3Policy's class: no agent is loaded


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("nnbc-plus", "structure"),
        ("nnbc-plus:formulation=structured", "structure"),
        ("nnbc-plus:formulation=whole_body", "none"),
        ("nnbc-plus:formulation=paper", "none"),
        ("rls:formulation=paper", "none"),
        ("nnbc:j0=probe", "none"),
        ("nnbc:j0=nominal", "nominal"),
        ("clik:gamma=10", "nominal"),
    ],
)
def test_the_class_follows_the_options(env, spec, expected):
    assert knowledge_of(spec) == expected
    assert knowledge_of(policies.make(spec, env)) == expected


def test_objects_say_what_their_spec_says(env):
    for name in policies.KNOWN_POLICIES:
        assert knowledge_of(policies.make(name, env)) == EXPECTED[name], name


def test_batched_policies_have_their_spec_class():
    venv = gym.make_vec(
        "WheeledPuma-Circle-v0", num_envs=2, vectorization_mode="vector_entry_point", dynamics="kinematic"
    )
    try:
        for spec in ("qp-oracle", "clik", "nnbc", "zero"):  # vectorised laws
            assert knowledge_of(policies.make(spec, venv)) == EXPECTED[spec], spec
        law = policies.make("nnbc-plus:formulation=whole_body", venv)  # the vectorised model-free law
        assert knowledge_of(law) == "none"
        assert knowledge_of(policies.make("nnbc-plus", venv)) == "structure"
    finally:
        venv.close()


def test_an_sb3_agent_object_is_class_none(env):
    pytest.importorskip("stable_baselines3")
    assert knowledge_of(policies.make("sb3:ppo-circle", env)) == "none"


class _Declared:
    knowledge = "nominal"

    def reset(self, obs, info=None, *, seed=None): ...

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return None, state


class _Silent:
    def reset(self, obs, info=None, *, seed=None): ...

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return None, state


def test_user_policies(monkeypatch):
    assert knowledge_of(_Silent()) == UNKNOWN
    assert knowledge_of(_Declared()) == "nominal"
    module = type(sys)("my_knowledge_ctrl")
    module.Declared, module.Silent, module.factory = _Declared, _Silent, lambda: _Declared()
    monkeypatch.setitem(sys.modules, "my_knowledge_ctrl", module)
    assert knowledge_of("my_knowledge_ctrl:Declared") == "nominal"
    assert knowledge_of("my_knowledge_ctrl:Silent") == UNKNOWN
    assert knowledge_of("my_knowledge_ctrl:factory") == UNKNOWN  # a factory is not called to find out


def test_bad_values_and_specs_fail_naming_what_is_accepted():
    wrong = _Silent()
    wrong.knowledge = "partial"  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match=r"_Silent.knowledge is 'partial'; accepted: none, structure, nominal, true"):
        knowledge_of(wrong)
    with pytest.raises(ValueError, match=r"unknown policy 'nbc'.*did you mean 'nnbc'.*known: nnbc"):
        knowledge_of("nbc")
    with pytest.raises(ValueError, match=r"unknown option\(s\) \['gama'\].*NNBCPlusConfig accepts"):
        knowledge_of("nnbc-plus:gama=3")
    with pytest.raises(ValueError, match=r"formulation must be one of"):
        knowledge_of("nnbc-plus:formulation=whole")
    with pytest.raises(ValueError, match=r"neither a known policy nor an importable module"):
        knowledge_of("no_such_module_xyz:Thing")

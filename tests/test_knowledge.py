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
    "calib-qp": "nominal",
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


# --- the classes are enforced: a built-in is built from a view holding what its class may read (policies.views) --
def test_a_view_answers_only_what_its_class_may_read():
    import gymnasium as gym

    from policies.views import ALLOWED, KnowledgeError, KnowledgeView

    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    env.reset(seed=0)
    base = env.unwrapped
    for cls, readable in ALLOWED.items():
        view = KnowledgeView(base, cls)
        assert view.dt == base.dt and view.unwrapped is view
        for name in ("nominal_params", "true_params", "sim", "_batch", "model_error"):
            if name in readable:
                assert getattr(view, name) is not None
            else:
                with pytest.raises(KnowledgeError, match=f"knowledge class '{cls}' read the env's '{name}'"):
                    getattr(view, name)
        with pytest.raises(KnowledgeError, match="read-only"):
            view.dt = 0.5
    env.close()


@pytest.mark.parametrize("name", sorted(policies.KNOWN_POLICIES))
def test_every_built_in_is_built_from_the_view_of_the_class_it_reports(name):
    """The class a built-in is built with equals the one it reports (none and structure read the same), so a
    label cannot claim less than the controller reads (release 0.3's calib-qp read the catalogue as `structure`)."""
    from policies import registry

    entry = registry._REGISTRY[name]
    config = registry.build_config(registry._load_entry(name, entry)[1], dict(entry.preset), name)
    built_with = registry.view_class(entry, config)
    reported = policies.knowledge_of(name)
    assert built_with == ("none" if reported == "structure" else reported)


def test_a_controller_built_below_its_class_gets_no_model(monkeypatch):
    """calib-qp built as class none (its registry entry changed) receives no catalogue and fails at once."""
    import dataclasses

    import gymnasium as gym

    from policies import registry

    monkeypatch.setitem(
        registry._REGISTRY, "calib-qp", dataclasses.replace(registry._REGISTRY["calib-qp"], model="none")
    )
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    with pytest.raises((TypeError, ValueError), match="nominal_params"):
        policies.make("calib-qp", env)
    env.close()

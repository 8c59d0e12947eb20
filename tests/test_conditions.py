"""The one conditions table (`eval.conditions`): its form, the names it gives, and the conditions it took over."""

import dataclasses
import inspect
import json

import pytest

from eval import heldout as H
from eval.conditions import (
    AXES,
    CONDITIONS,
    HELDOUT_SHA256,
    TABLE_TRACKS,
    Condition,
    condition_name,
    conditions_markdown,
    get,
    heldout_digest,
)
from eval.errors import EvalError
from mobman_env.env import WheeledPumaEnv


def test_the_axes_are_plain_env_arguments_with_the_envs_defaults():
    params = inspect.signature(WheeledPumaEnv).parameters
    assert params["model_error"].default == AXES["model_error"] and params["obs_noise"].default == AXES["obs_noise"]
    for c in CONDITIONS.values():
        assert set(AXES) <= set(c.env_kwargs) and c.track in TABLE_TRACKS
        assert set(c.env_kwargs) <= set(params), c.name  # every argument is the env's own
        assert c.extra_kwargs == {k: v for k, v in c.env_kwargs.items() if k not in AXES}


def test_protocol_v2s_heldout_definitions_hash_as_committed_in_their_v2_form():
    assert heldout_digest() == HELDOUT_SHA256


def test_either_protocols_form_reads_into_the_same_condition():
    for c in CONDITIONS.values():
        assert Condition.from_dict(c.to_dict()) == c
        as_v2 = dataclasses.replace(c, track="heldout", retired=None) if c.retired == "v2" else c
        assert Condition.from_dict(c.v2_dict()) == as_v2  # protocol v2 wrote its held-out conditions as such
        assert json.loads(json.dumps(c.to_dict())) == c.to_dict()
    for d in H.draw("0" * 32):  # a v3 held-out draw is the table's form
        assert Condition.from_dict(d).to_dict() == {**d, "env_kwargs": {**AXES, **d["env_kwargs"]}, "retired": None}


def test_an_episodes_condition_is_the_tables_name_when_its_arguments_are_an_entrys():
    assert condition_name({}) == "default"
    assert condition_name({"dynamics": "kinematic", "model_error": None, "obs_noise": None}) == "default"
    assert condition_name({"model_error": 0.2}) == "wear20"
    assert condition_name({"obs_noise": 0.001, "obs_noise_vel": 0.01}) == "noise"
    assert condition_name({"dynamics": "physics", "actuator_tau": 0.05}) == "physics-lag"
    assert condition_name({"actuator_tau": 0.1}) == "lag100"  # a held-out entry of protocol v2 is a name too
    assert condition_name({"model_error": 0.2, "obs_noise": 0.001}) == "kinematic, model_error=0.2, obs_noise=0.001"
    assert (
        condition_name({"dynamics": "physics", "path": {"type": "circle", "duration": 5.0}, "actuator_tau": 0.07})
        == 'physics, model_error=0.05, obs_noise=0, actuator_tau=0.07, path={"duration":5.0,"type":"circle"}'
    )
    # the same arguments make one name; two entries share their env arguments only where their robots differ
    # (a bench's episodes carry their condition's name itself: `BenchConfig.tasks_of`)
    shared = {
        c.name: condition_name(c.env_kwargs) for c in CONDITIONS.values() if condition_name(c.env_kwargs) != c.name
    }
    assert shared == {"scaled-arms": "default", "physics-robots": "physics"}
    assert CONDITIONS["scaled-arms"].robots != CONDITIONS["default"].robots


def test_the_research_conditions_are_the_values_their_pages_recorded():
    """docs/results/calib-qp/dev.py and docs/results/nnbc-plus-v5/panel.py read their conditions from the table:
    the values their committed results were run with, as those scripts defined them."""
    recorded = {  # name: (model_error, obs_noise, further env arguments)
        "noise20": (0.2, 0.001, {"obs_noise_vel": 0.01}),
        "yaw-noise20": (0.2, 0.0, {"obs_noise_yaw": 0.005}),
        "joint-vel-noise20": (0.2, 0.0, {"obs_noise_joint_vel": 0.05}),
        "delay20": (0.2, 0.0, {"obs_delay": 2}),
        "lag20": (0.2, 0.0, {"actuator_tau": 0.02}),
        "jv05": (0.05, 0.0, {"obs_noise_joint_vel": 0.05}),
        "heavy15": (0.05, 0.003, {"obs_noise_vel": 0.03, "obs_noise_yaw": 0.0045}),
        "lag150": (0.05, 0.0, {"actuator_tau": 0.15}),
        "lag": (0.05, 0.0, {"actuator_tau": 0.05}),
        "yaw-noise": (0.05, 0.0, {"obs_noise_yaw": 0.001}),
    }
    for name, (me, on, extra) in recorded.items():
        c = CONDITIONS[name]
        assert (c.model_error, c.obs_noise, c.extra_kwargs) == (me, on, extra), name


def test_an_unknown_name_is_refused_naming_the_close_one_and_the_table():
    with pytest.raises(EvalError, match=r"unknown condition 'wear2'.*did you mean 'wear20'.*known: default, wear20"):
        get("wear2")


def test_the_markdown_table_renders_both_forms_alike():
    table = {n: c.to_dict() for n, c in CONDITIONS.items() if not c.retired}
    old = {n: c.v2_dict() for n, c in CONDITIONS.items() if not c.retired}
    assert conditions_markdown(table) == conditions_markdown(old)
    assert "| `lag100` | dev (held out in v2) |" in conditions_markdown({"lag100": CONDITIONS["lag100"].to_dict()})
    assert "| `noise` | dev | puma, ur5, panda, random-arm | all | kinematic | 0.05 | 1 | `obs_noise_vel` 0.01 |" in (
        conditions_markdown(table)
    )

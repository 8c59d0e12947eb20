"""The shipped `sb3:` baselines (policies/models/): every folder is an alias, each loads through the restricted
loader and acts in a short rollout, and the PPO ones are what the committed multi-seed report says they are
(the median-seed run's model, byte for byte, with the README the report generates). Accuracy is asserted on
development seeds only."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import policies
from eval.output.compact import stored_bytes
from policies.agents import sb3

pytest.importorskip("stable_baselines3")

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "policies" / "models"
REPORT = ROOT / "docs" / "results" / "rl-v2" / "results.json"
#: alias -> family of the models the committed report shipped (`mobman-train report --ship ALIAS=FAMILY`)
REPORTED = dict(json.loads(stored_bytes(REPORT))["config"]["ship"])


def test_every_model_folder_is_an_alias_with_a_readme():
    folders = sorted(d.name for d in MODELS.iterdir() if d.is_dir() and not d.name.startswith("_"))
    assert folders == sorted(sb3.ALIASES)
    assert {"sac-circle", "ppo-circle"} <= set(sb3.ALIASES)
    assert set(REPORTED) <= set(sb3.ALIASES)
    for alias in sb3.ALIASES:
        assert sb3.resolve_model_path(alias) == MODELS / alias / "model.zip"
        assert (MODELS / alias / "README.md").is_file(), f"{alias} has no README"


@pytest.mark.parametrize("alias", sorted(sb3.ALIASES))
def test_shipped_model_loads_and_acts(alias):
    dynamics = json.loads((MODELS / alias / "config.json").read_text())["dynamics"]
    env = gym.make("WheeledPuma-Circle-v0", dynamics=dynamics)
    try:
        policy = policies.make(f"sb3:{alias}", env)
        assert policy.path == (MODELS / alias / "model.zip").resolve()
        obs, info = env.reset(seed=901)  # a development seed
        policy.reset(obs, info, seed=901)
        actions = []
        for _ in range(50):
            action, _ = policy.predict(obs, deterministic=True)
            assert env.action_space.contains(np.asarray(action, dtype=env.action_space.dtype))
            actions.append(action)
            obs, _, terminated, truncated, _ = env.step(action)
            assert not (terminated or truncated)
        assert np.ptp(np.array(actions), axis=0).max() > 0  # it reacts to the state: not a constant output
    finally:
        env.close()


@pytest.mark.parametrize("alias", sorted(REPORTED))
def test_shipped_ppo_is_the_reports_median_seed_model(alias):
    from train.report import sha256
    from train.report_text import model_readme

    family = REPORTED[alias]
    results = json.loads(stored_bytes(REPORT))
    median = results["median_seed_models"][family]
    run = next(r for r in results["runs"] if r["name"] == median["run"])
    assert run["family"] == family
    assert sha256(MODELS / alias / "model.zip") == run["model_sha256"]
    rel = str(REPORT.relative_to(ROOT))
    assert (MODELS / alias / "README.md").read_text() == model_readme(results, family, alias, rel), (
        f"policies/models/{alias}/README.md differs from what `mobman-train report --ship` generates"
    )
    shipped_cfg = json.loads((MODELS / alias / "config.json").read_text())
    assert shipped_cfg["seed"] == median["seed"] and shipped_cfg["algo"] == "ppo"


@pytest.mark.parametrize("alias", sorted(set(sb3.ALIASES) - set(REPORTED)))
def test_models_outside_the_report_ship_without_optimiser_state(alias):
    """The optimiser state (Adam's moments) serves only further training: `sac-circle` ships without it (its
    README), the weights and every other entry as trained. (The PPO models stay byte for byte the report's.)"""
    import io
    import zipfile

    import torch

    with zipfile.ZipFile(MODELS / alias / "model.zip") as z:
        names = [n for n in z.namelist() if n.endswith("optimizer.pth")]
        states = [torch.load(io.BytesIO(z.read(n)), weights_only=True) for n in names]
    assert names and all(s["state"] == {} and s["param_groups"] for s in states), names


def test_shipped_kinematic_ppo_tracks_on_development_seeds():
    """Accuracy on development seeds (never reported ones): better than standing still by far."""
    from eval.rollout import make_env, rollout

    env = make_env("WheeledPuma-Circle-v0", env_kwargs={"dynamics": "kinematic"})
    try:
        policy = policies.make("sb3:ppo-circle", env)
        rec = rollout(env, policy, 902, meta={"policy": "ppo-circle"})[0]
    finally:
        env.close()
    assert rec["status"] == "ok"
    assert rec["rms_error_m"] < 0.05  # zero's RMS error on this path is ~0.47 m

"""The policy's seed reveals nothing the env drew (issue 12, "No leaks"): `policies.base.policy_seed`.

Before this rule eval called `policy.reset(seed=S + k)` with the env's own episode seed, and
`RobotParams.nominal().perturbed(np.random.default_rng(seed), model_error)` rebuilt the true robot exactly.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from conftest import SHORT_CIRCLE

import mobman_env  # noqa: F401  (registers the ids)
from eval.rollout import rollout
from mobman_env.params import RobotParams
from policies.base import POLICY_STREAM_ID, policy_seed


class ReconstructionAttack:
    """A policy that tries to rebuild the true robot from the seed it is given (the attack of issue 12)."""

    def __init__(self, model_error: float):
        self.model_error = model_error
        self.guesses: list[tuple[str, str]] = []

    def reset(self, obs, info=None, *, seed=None):
        guess = RobotParams.nominal().perturbed(np.random.default_rng(seed), self.model_error)
        self.guesses.append((guess.hash(), info["true_params_hash"]))

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        return np.zeros(8, dtype=np.float32), state


@pytest.mark.parametrize("model_error", [0.05, 0.2])
def test_the_seed_eval_gives_a_policy_does_not_rebuild_the_true_robot(model_error):
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE, model_error=model_error)
    try:
        attack = ReconstructionAttack(model_error)
        for seed in range(5):
            rec, _ = rollout(env, attack, seed)
            assert rec["status"] == "ok", rec["error"]
        # the attack itself works: handed the episode seed, it rebuilds the robot exactly (the old leak)
        obs, info = env.reset(seed=3)
        leaked = ReconstructionAttack(model_error)
        leaked.reset(obs, info, seed=3)
    finally:
        env.close()
    assert leaked.guesses[0][0] == leaked.guesses[0][1]
    assert len(attack.guesses) == 5
    assert all(guess != true for guess, true in attack.guesses), attack.guesses


def test_policy_seed_rule():
    """Deterministic, documented (SeedSequence of the episode seed and the stream id), distinct per episode,
    never the episode seed itself; bad seeds are refused by name."""
    assert policy_seed(10_000) == policy_seed(10_000)
    expected = int(np.random.SeedSequence([10_000, POLICY_STREAM_ID]).generate_state(1, np.uint64)[0])
    assert policy_seed(10_000) == expected
    seeds = [policy_seed(s) for s in range(1000)]
    assert len(set(seeds)) == 1000
    assert all(p != s for s, p in enumerate(seeds))
    assert policy_seed(np.int64(7)) == policy_seed(7)
    # the Generator a policy builds from it does not start in the env's state
    assert np.random.default_rng(policy_seed(5)).standard_normal() != np.random.default_rng(5).standard_normal()
    for bad in (-1, 1.5, True, "3"):
        with pytest.raises(ValueError, match="episode_seed"):
            policy_seed(bad)

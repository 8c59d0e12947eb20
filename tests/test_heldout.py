"""Protocol v3's held-out track (`eval.heldout`): the family and its draw are fixed, the release's seed is
committed as a digest before its tuning, and every drawn condition runs."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import mobman_env  # noqa: F401  (registers the ids)
from eval import heldout as H
from eval.bench.config import ROBOTS, TASKS
from mobman_env.env import WheeledPumaEnv

ROOT = Path(__file__).resolve().parents[1]
KNOWN_ANSWER = json.loads((Path(__file__).parent / "data" / "heldout_v3_draw_seed0.json").read_text())


def test_the_family_is_the_one_committed():
    """A change of the family is a new protocol version, never an edit: its digest is pinned."""
    assert H.family_digest() == H.FAMILY_SHA256


def test_the_draw_of_a_known_seed_is_pinned():
    """The draw itself cannot change after the seed's digest was committed: a public seed's draw is pinned."""
    assert H.draw(KNOWN_ANSWER["seed"]) == KNOWN_ANSWER["conditions"]


def test_different_seeds_draw_different_conditions_inside_the_family():
    axes = {a.name: a for a in H.AXES}
    seen: set[str] = set()
    for k in range(200):
        for c in H.draw(f"{k:032x}"):
            kw = c["env_kwargs"]
            assert kw["dynamics"] in ("kinematic", "physics")
            assert H.WEAR_RANGE[0] <= kw["model_error"] <= H.WEAR_RANGE[1]
            assert len(c["robots"]) == (1 if kw["dynamics"] == "physics" else H.ROBOTS_PER_CONDITION)
            assert set(c["robots"]) <= set(H.ROBOT_FAMILIES)
            stressors = [n for n in kw if n in axes]
            assert stressors, c
            for n in stressors:
                a = axes[n]
                assert (kw[n] in a.choices) if a.scale == "choice" else a.low * 0.999 <= kw[n] <= a.high * 1.001
                seen.add(n)
            if "path" in kw:
                assert c["tasks"] == ["random"] and 6.0 <= kw["path"]["duration"] <= 20.0
            else:
                assert c["tasks"] is None
    assert seen == set(axes)  # every stressor of the family shows up in 200 draws
    assert H.draw(f"{1:032x}") != H.draw(f"{2:032x}")


@pytest.mark.parametrize("seed", ["0" * 31, "0" * 33, "G" * 32, "A" * 32, 7])
def test_a_seed_is_32_lowercase_hex_digits(seed):
    with pytest.raises(ValueError, match="32 lowercase hex digits"):
        H.draw(seed)


def test_the_release_seed_digest_is_committed_and_the_seed_not(monkeypatch):
    digest = H.RELEASE_SEED_SHA256["0.4"]
    assert len(digest) == 64 and int(digest, 16) >= 0
    assert H.seed_digest("0" * 32, "0.4") != H.seed_digest("0" * 32, "0.5")  # salted per release
    assert "0.4" not in H.REVEALED_SEEDS or H.seed_digest(H.REVEALED_SEEDS["0.4"], "0.4") == digest
    monkeypatch.setitem(H.RELEASE_SEED_SHA256, "0.9", "0" * 64)  # a digest committed, its seed not revealed
    with pytest.raises(ValueError, match="not revealed yet"):
        H.revealed_draw("0.9")
    with pytest.raises(ValueError, match="committed no held-out seed"):
        H.revealed_draw("0.1")


def test_the_revealed_draw_of_release_0_4_is_its_seeds_draw_and_its_conditions_run():
    """Release 0.4's revealed seed matches the digest committed at ae362a4, and its draw is what the conditions
    table holds on the heldout track (named `h3-K-0.4`)."""
    from eval.conditions import CONDITIONS

    seed = H.REVEALED_SEEDS["0.4"]
    assert H.seed_digest(seed, "0.4") == H.RELEASE_SEED_SHA256["0.4"]
    drawn = H.revealed_draw("0.4")
    assert drawn == H.draw(seed) and len(drawn) == H.N_CONDITIONS
    for d in drawn:
        c = CONDITIONS[f"{d['name']}-0.4"]
        assert c.track == "heldout" and c.robots == tuple(d["robots"])
        assert dict(c.env_kwargs) == {"obs_noise": 0.0, **d["env_kwargs"]}  # the table fills the axes' defaults


def test_every_drawn_condition_makes_an_env_that_steps():
    """Every condition of a draw runs: its env arguments exist and are accepted, on its robots and tasks."""
    params = set(WheeledPumaEnv.__init__.__code__.co_varnames)
    for c in KNOWN_ANSWER["conditions"]:
        kw = dict(c["env_kwargs"])
        assert set(kw) <= params
        task = (c["tasks"] or list(TASKS))[0]
        env = gym.make(f"{ROBOTS[c['robots'][0]]}-{TASKS[task]}-v0", **kw)
        try:
            obs, _ = env.reset(seed=0)
            obs, *_ = env.step(np.zeros(env.action_space.shape, dtype=np.float32))
            assert np.isfinite(obs["ee_pos"]).all()
        finally:
            env.close()


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()


def test_the_seed_digest_was_committed_in_the_commit_the_module_names():
    """`RELEASE_SEED_COMMIT` exists, is in main's history and is where the digest first appears (so "committed
    before the tuning" can be checked against the commits that follow it). An unpacked sdist has no history: there
    the test checks that it is one (PKG-INFO) and that the commit is a full hash."""
    commit = H.RELEASE_SEED_COMMIT["0.4"]
    assert len(commit) == 40 and int(commit, 16) >= 0
    if not (ROOT / ".git").exists():
        assert (ROOT / "PKG-INFO").is_file(), "neither a git checkout nor an unpacked sdist"
        return
    if _git("rev-parse", "--is-shallow-repository") == "true":
        _git("fetch", "--unshallow", "--quiet")
    _git("merge-base", "--is-ancestor", commit, "HEAD")  # raises if not in HEAD's history
    digest = H.RELEASE_SEED_SHA256["0.4"]
    assert digest in _git("show", f"{commit}:eval/heldout.py")
    parent = subprocess.run(["git", "show", f"{commit}~1:eval/heldout.py"], cwd=ROOT, capture_output=True, text=True)
    assert digest not in parent.stdout


def test_a_withdrawn_seed_digest_is_in_its_commit_and_never_the_release_draw():
    """A withdrawn digest was committed where the record says, is not the release's current digest and is never
    revealed (a lost seed cannot be; revealing one would be a second draw of the same release)."""
    for release, entries in H.WITHDRAWN_SEEDS.items():
        for digest, commit, reason in entries:
            assert len(digest) == 64 and len(commit) == 40 and reason
            assert digest != H.RELEASE_SEED_SHA256[release]
            assert release not in H.REVEALED_SEEDS or H.seed_digest(H.REVEALED_SEEDS[release], release) != digest
            if (ROOT / ".git").exists():
                if _git("rev-parse", "--is-shallow-repository") == "true":
                    _git("fetch", "--unshallow", "--quiet")
                _git("merge-base", "--is-ancestor", commit, "HEAD")
                assert digest in _git("show", f"{commit}:eval/heldout.py")

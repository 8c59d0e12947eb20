"""train's file writes and resume seeding (issue 10: mutants that survived the suite).

* A write that fails half-way (the disk is full) leaves the previous file intact: tested through the run
  folder's public writers with a real short write (RLIMIT_FSIZE), whatever helper they use inside.
* `resume` seeds the training envs by the rule of `train.run.make_vec_env`: config.seed + the steps already
  done, so a resumed run does not replay the episodes of the first session.
"""

from __future__ import annotations

import contextlib
import json
import signal
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from test_train import tiny_config

import mobman_env
from train.runfolder import latest_checkpoint, save_checkpoint


@contextlib.contextmanager
def file_size_limit(n_bytes: int):
    """Writes beyond `n_bytes` of any file fail with OSError (EFBIG), as on a full disk, in this process."""
    import resource  # POSIX

    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    old_handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of a killed process
    resource.setrlimit(resource.RLIMIT_FSIZE, (n_bytes, hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
        signal.signal(signal.SIGXFSZ, old_handler)


class _FakeModel:
    """What `save_checkpoint` needs of an SB3 model: the step count and `save` (an empty file here)."""

    def __init__(self, steps: int):
        self.num_timesteps = steps

    def save(self, path) -> None:
        Path(path).write_bytes(b"")

    def get_vec_normalize_env(self):
        return None


def test_a_failing_checkpoint_write_keeps_the_previous_latest_json(tmp_path):
    first = save_checkpoint(_FakeModel(100), tmp_path, off_policy=False)
    before = (tmp_path / "checkpoints" / "latest.json").read_bytes()
    assert latest_checkpoint(tmp_path) == first and len(before) > 40
    # latest.json is ~100 bytes: its write fails half-way, an error naming the file (mobman-train exits 2 with it)
    with file_size_limit(16), pytest.raises(ValueError, match=r"cannot write .*latest.json \(File too large\)"):
        save_checkpoint(_FakeModel(200), tmp_path, off_policy=False)
    assert (tmp_path / "checkpoints" / "latest.json").read_bytes() == before
    assert latest_checkpoint(tmp_path)["steps"] == 100
    # and with room on the disk the next checkpoint replaces it
    assert save_checkpoint(_FakeModel(300), tmp_path, off_policy=False)["steps"] == 300
    assert latest_checkpoint(tmp_path)["steps"] == 300


def test_resume_seeds_the_training_envs_with_seed_plus_steps_done(tmp_path, monkeypatch):
    from mobman_env.vector import WheeledPumaVectorEnv
    from train.run import resume, run

    seeds: list[int] = []
    reset = mobman_env.WheeledPumaEnv.reset
    vector_reset = WheeledPumaVectorEnv.reset

    def recording_reset(self, *, seed=None, options=None):
        if seed is not None:
            seeds.append(seed)
        return reset(self, seed=seed, options=options)

    def recording_vector_reset(self, *, seed=None, options=None):  # the training env: robot i gets seed + i
        if seed is not None:
            seeds.append(seed if isinstance(seed, int) else seed[0])
        return vector_reset(self, seed=seed, options=options)

    monkeypatch.setattr(mobman_env.WheeledPumaEnv, "reset", recording_reset)
    monkeypatch.setattr(WheeledPumaVectorEnv, "reset", recording_vector_reset)
    out = tmp_path / "sac"
    config = tiny_config("sac", out, timesteps=100, checkpoint_freq=100, final_eval_episodes=0, eval_freq=0)
    # besides the training env, seeded resets come from the env probe (seed 0) and the zero-policy reference
    # on the development seeds (eval_seed ...)
    others = {0, *range(config.eval_seed, config.eval_seed + max(config.eval_episodes, 1))}
    run(config)
    assert [s for s in seeds if s not in others] == [config.seed]
    steps = json.loads((out / "checkpoints" / "latest.json").read_text())["steps"]
    assert 100 <= steps < 100 + 2 * 8  # the last checkpoint: the budget, rounded up to whole rounds of the 2 envs
    seeds.clear()
    resume(out, timesteps=150, progress_bar=False)
    assert [s for s in seeds if s not in others] == [config.seed + steps]

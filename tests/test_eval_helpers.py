"""User policies for the eval tests, importable as `test_eval_helpers:<Name>` (a researcher's own module).

No tests here: pytest collects nothing from this file.
"""

from __future__ import annotations

import numpy as np


class HoldStill:
    """A user controller built from the env (`module:attr` calls a class with the env): all speeds zero."""

    def __init__(self, env=None):
        self.n_reset = 0
        self.n_predict = 0

    def reset(self, obs, info=None, *, seed=None):
        self.n_reset += 1

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self.n_predict += 1
        return np.zeros(8, dtype=np.float32), state


class CrashOnOddSeed(HoldStill):
    """Raises inside `predict` at step 5 of episodes with an odd seed (the crash must be recorded, not fatal)."""

    def reset(self, obs, info=None, *, seed=None):
        super().reset(obs, info, seed=seed)
        self.seed = seed
        self.k = 0

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self.k += 1
        if self.seed % 2 == 1 and self.k == 5:
            raise RuntimeError(f"deliberate crash at step 5 of seed {self.seed}")
        return super().predict(observation, state, episode_start, deterministic)


class ProportionalBatched:
    """Returns a batch of one (1, 8) like an SB3 model would; moves only the wheels, proportionally to the
    x error (a crude but real controller)."""

    def reset(self, obs, info=None, *, seed=None):
        pass

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        err = np.asarray(observation["target_pos"], float) - np.asarray(observation["ee_pos"], float)
        a = np.zeros((1, 8), dtype=np.float32)
        a[0, 6:] = np.clip(-err[0], -1, 1)
        return a, state


class ExitOnOddSeed(HoldStill):
    """Kills its own process (as a segfault would) in episodes with an odd seed."""

    def reset(self, obs, info=None, *, seed=None):
        super().reset(obs, info, seed=seed)
        self.seed = seed

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if self.seed % 2 == 1:
            import os

            os._exit(3)
        return super().predict(observation, state, episode_start, deterministic)

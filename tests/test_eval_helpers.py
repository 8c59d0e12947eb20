"""Shared pieces of the eval tests: the short task, the fields that may differ between runs, and user
policies importable as `test_eval_helpers:<Name>` (a researcher's own module).

No tests here: pytest collects nothing from this file.
"""

from __future__ import annotations

import numpy as np

from policies.base import policy_seed

ENV = "WheeledPuma-Circle-v0"
#: a 1 s circle of radius 0.1 m (100 steps at 100 Hz): keeps the eval tests fast
SHORT = {"path": {"type": "circle", "radius": 0.1, "duration": 1.0}}
#: fields that may differ between runs of the same episodes (timing and process)
VOLATILE = {"wall_s", "pid", "predict_us_median", "predict_us_p99"}


#: policy seed -> the episode seed eval derived it from (`policies.base.policy_seed`), for the episode seeds the
#: eval tests use; the fault-injection policies below read the episode's parity through it
_EPISODE_SEED = {policy_seed(s): s for s in range(10_000, 10_100)}


def episode_seed(seed: int) -> int:
    """The episode seed (10,000-10,099) whose `policy_seed` a policy's `reset(seed=...)` received."""
    return _EPISODE_SEED[seed]


def stable(rec: dict) -> dict:
    """An episode record without its timing and process fields."""
    return {k: v for k, v in rec.items() if k not in VOLATILE}


def terminal_sigint() -> None:
    """`preexec_fn` of a child that a test interrupts with SIGINT: the default SIGINT disposition, as a program
    started from a terminal has. A shell starts background jobs (`cmd &`, `nohup`) with SIGINT ignored and children
    inherit that, so without this a suite launched in the background would test an uninterruptible program."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def short_config(tmp_path, name="out", **kw):
    """An EvalConfig of 2 short kinematic episodes into tmp_path/name; keyword arguments override."""
    from eval import EvalConfig

    base = dict(
        envs=(ENV,),
        episodes=2,
        seed=10_000,
        out=str(tmp_path / name),
        dynamics=("kinematic",),
        env_kwargs=SHORT,
        progress=False,
        plots=False,
    )
    base.update(kw)
    return EvalConfig(**base)


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
        self.seed = episode_seed(seed)
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
        self.seed = episode_seed(seed)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if self.seed % 2 == 1:
            import os

            os._exit(3)
        return super().predict(observation, state, episode_start, deterministic)


class ExitInConstructor(HoldStill):
    """`sys.exit(3)` while being built (a user's script-style module): a failure with a message, not a silent
    exit of the CLI."""

    def __init__(self, env=None):
        raise SystemExit(3)


class ExitInPredict(HoldStill):
    """`sys.exit(4)` inside predict at step 3 of every episode: a failed episode, with its traceback."""

    def reset(self, obs, info=None, *, seed=None):
        super().reset(obs, info, seed=seed)
        self.k = 0

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self.k += 1
        if self.k == 3:
            raise SystemExit(4)
        return super().predict(observation, state, episode_start, deterministic)


class SlowMarked(HoldStill):
    """Sleeps 5 ms per predict (a 1 s episode takes about 0.5 s) and, as an episode ends (its last step),
    touches `$MOBMAN_TEST_MARKS/<seed>`, so a test knows how many episodes have finished."""

    def reset(self, obs, info=None, *, seed=None):
        super().reset(obs, info, seed=seed)
        self.seed = seed
        self.k = 0

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        import os
        import time
        from pathlib import Path

        self.k += 1
        time.sleep(0.005)
        if self.k == 100 and os.environ.get("MOBMAN_TEST_MARKS"):
            (Path(os.environ["MOBMAN_TEST_MARKS"]) / str(self.seed)).touch()
        return super().predict(observation, state, episode_start, deterministic)

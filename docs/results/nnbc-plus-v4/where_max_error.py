"""When `nnbc-plus` and `qp-oracle` reach their max error: PUMA, kinematic, the dev track's default condition (5%
wear), four tasks, development seeds 0-4. Prints, per episode, the max error, the step it is reached at and the
max over the first second (the probe and the start) and over the rest.

    python docs/results/nnbc-plus-v4/where_max_error.py > docs/results/nnbc-plus-v4/where-max-error.txt
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np

import mobman_env  # noqa: F401 (registers the ids)
import policies

warnings.filterwarnings("ignore")
for task in ("Circle", "Line", "Lemniscate", "Random"):
    env = gym.make(f"WheeledPuma-{task}-v0", dynamics="kinematic")
    for seed in range(5):
        for spec in ("nnbc-plus", "qp-oracle"):
            policy = policies.make(spec, env)
            obs, info = env.reset(seed=seed)
            policy.reset(obs, info, seed=policies.policy_seed(seed))
            errors = []
            while True:
                action, _ = policy.predict(obs)
                obs, _, terminated, truncated, info = env.step(action)
                errors.append(info["tracking_error"])
                if terminated or truncated:
                    break
            e = np.array(errors) * 1e3
            print(
                f"{task:10s} seed {seed} {spec:9s} max {e.max():.3f} mm at step {int(e.argmax()):4d} of {len(e)};"
                f" first second {e[:100].max():.3f} mm, after {e[100:].max():.3f} mm"
            )
    env.close()

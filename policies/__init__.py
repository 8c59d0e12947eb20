"""policies: controllers and agents behind one interface (SB3's `predict`, plus `reset`).

```python
import gymnasium as gym, mobman_env, policies
env = gym.make("WheeledPuma-Circle-v0")
policy = policies.make("nnbc", env)            # or "jmpi", "oracle", "sb3:runs/sac/model.zip", "mymod:MyPolicy"
obs, info = env.reset(seed=10_000)
policy.reset(obs, info, seed=10_000)
action, _ = policy.predict(obs)
```

| name | what |
|---|---|
| `nnbc`, `nnbc-full` | the paper's model-free controller (`policies.nnbc`) |
| `nnbc-plus` | the improved model-free controller (`policies.nnbc_plus`) |
| `jmpi`, `jmpi-full` | open-loop pseudo-inverse of the nominal model (`policies.jmpi`) |
| `oracle`, `oracle-full` | eq. (10) with the true model (`policies.jmpi`) |
| `zero`, `random` | floor references (`policies.simple`) |
| `sb3:PATH` | a Stable-Baselines3 agent (`policies.sb3`) |
| `module:attr` | your own policy object, class or factory |

Importing this package loads neither torch nor Stable-Baselines3 (`SB3Policy` imports them when built).
"""

from policies.base import ControllerPolicy, EnvFacts, Policy, unwrap_env
from policies.jmpi import JMPI, JMPIConfig, Oracle, OracleConfig
from policies.nnbc import NNBC, NNBCConfig
from policies.registry import KNOWN_POLICIES, SPEC_FORMS, make, parse_spec, true_params_provider
from policies.sb3 import SB3Policy, resolve_model_path
from policies.simple import Random, RandomConfig, Zero, ZeroConfig

__all__ = [
    "JMPI",
    "KNOWN_POLICIES",
    "NNBC",
    "SPEC_FORMS",
    "ControllerPolicy",
    "EnvFacts",
    "JMPIConfig",
    "NNBCConfig",
    "Oracle",
    "OracleConfig",
    "Policy",
    "Random",
    "RandomConfig",
    "SB3Policy",
    "Zero",
    "ZeroConfig",
    "make",
    "parse_spec",
    "resolve_model_path",
    "true_params_provider",
    "unwrap_env",
]

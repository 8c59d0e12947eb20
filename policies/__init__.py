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
| `nnbc`, `nnbc-full` | the paper's model-free controller (`policies.laws.nnbc`) |
| `nnbc-plus` | the improved controller: a Kalman-filtered, structured J (`policies.laws.nnbc_plus`) |
| `broyden`, `rls` | `nnbc-plus`'s scaffolding with Broyden's update / recursive least squares (`policies.laws.broyden_rls`) |
| `jmpi`, `jmpi-full` | open-loop pseudo-inverse of the nominal model (`policies.laws.jmpi`) |
| `clik`, `clik-full` | eq. (10), closed loop, on the nominal model: the practitioner's baseline (`policies.laws.jmpi`) |
| `oracle`, `oracle-full` | eq. (10) with the true model (`policies.laws.jmpi`) |
| `qp`, `qp-oracle` | whole-body QP with joint-limit dampers, nominal / true model; `qp-oracle` is the ceiling (`policies.laws.qp`) |
| `calib-qp` | `qp`'s QP on a model calibrated online from the catalogue: the adaptive baseline (class nominal; `policies.laws.calib_qp`) |
| `zero`, `random` | floor references (`policies.laws.simple`) |
| `sb3:PATH` | a Stable-Baselines3 agent (`policies.agents.sb3`) |
| `module:attr` | your own policy object, controller class or `@policies.controller_factory` function (`policies.user_specs`) |

What each policy knows about the robot, its knowledge class (`none`, `structure`, `nominal`, `true`), is
`policies.knowledge_of(policy_or_spec)` (`policies.knowledge`).

Every closed-loop law defaults to the task-space gain gamma = 20 1/s; the paper-exact `nnbc` keeps the paper's
gamma = mu = 10 (for the paper's oracle use `oracle:gamma=10`). Eval seeds a policy with
`policies.base.policy_seed(episode_seed)`, never with the env's own seed.

The parts: the interface at the top level (`base`: the contract; `registry`: specs to policies; `batched`,
`stacked`: one policy for a vector env's N robots; `views`, `knowledge`: knowledge classes; `user_specs`: your own
controllers; `warm`: the numba warm-up that `python -m policies` runs) and three sub-packages, `policies.laws`
(the built-in controllers, one module per family), `policies.kernels` (their numba kernels over N rows, which the
laws import) and `policies.agents` (the `sb3:` agents, their interface and the checked readers of their files and
of every JSON mobman loads). The registry names each law by its module and imports it when a spec is built.

Importing this package loads neither torch nor Stable-Baselines3 (`SB3Policy` imports them when built), nor
qpsolvers (`QP` and `CalibQP` import it when built).
"""

from policies.agents.sb3 import SB3Policy, resolve_model_path
from policies.base import ControllerPolicy, EnvFacts, Policy, policy_seed, unwrap_env
from policies.knowledge import KNOWLEDGE_CLASSES, knowledge_of
from policies.laws.jmpi import CLIK, JMPI, CLIKConfig, JMPIConfig, Oracle, OracleConfig
from policies.laws.nnbc import NNBC, NNBCConfig
from policies.laws.simple import Random, RandomConfig, Zero, ZeroConfig
from policies.registry import KNOWN_POLICIES, SPEC_FORMS, make, parse_spec, true_params_provider
from policies.user_specs import controller_factory

__all__ = [
    "CLIK",
    "JMPI",
    "KNOWLEDGE_CLASSES",
    "KNOWN_POLICIES",
    "NNBC",
    "SPEC_FORMS",
    "CLIKConfig",
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
    "controller_factory",
    "knowledge_of",
    "make",
    "parse_spec",
    "policy_seed",
    "resolve_model_path",
    "true_params_provider",
    "unwrap_env",
]

"""Model-based baselines: JMPI (the paper's comparison, open loop on the nominal model), CLIK (the
practitioner's closed loop on the nominal model) and the oracle (the same closed loop on the true model).

Both evaluate a kinematic model at the *measured* joint angles and heading (`joint_pos[:n]`, `base_yaw`), and
invert it with the same damped pseudo-inverse as NNBC (`policies.kernels.shared.damped_pinv_apply_rows`; the
damping is zero away from singularities, so these are the plain pseudo-inverse methods on this task).

* `jmpi` - the conventional Jacobian pseudo-inverse method the paper compares against:
  u = J_nom^+ (r_d_dot - [p_c_dot; 0]) with J_nom the paper's Jacobian of eq. (6) for the *nominal* robot.
  Open loop: no position feedback, so the error of the nominal model (the env draws a "worn" true robot with
  5% error by default) and the integration drift accumulate. `jmpi-full`: u = J_wb,nom^+ r_d_dot with the
  whole-body Jacobian (the platform's translation modelled, nothing measured subtracted).
* `oracle` - eq. (10) with the *true* robot's Jacobian: u = J^+ (r_d_dot - [p_c_dot; 0] + gamma (r_d - r_a)).
  The known-model bound: what a perfect model plus the paper's feedback achieves. The true parameters come
  from a `params_provider` callable, called once at every episode start (the env draws a new robot per reset).
  `oracle-full` uses the whole-body Jacobian: u = J_wb^+ (r_d_dot + gamma (r_d - r_a)).
* `clik` - closed-loop inverse kinematics (resolved-rate control), what an engineer with the catalogue model
  runs: the oracle's eq. (10) with the *nominal* model's Jacobian, u = J_nom^+ (r_d_dot - [p_c_dot; 0] +
  gamma (r_d - r_a)); `clik-full`: u = J_wb,nom^+ (r_d_dot + gamma (r_d - r_a)). The feedback corrects the
  model error that makes `jmpi` drift, so this, not `jmpi`, is the baseline a model-free method must beat.
  All three are one law and one implementation (`ModelLaw`, batched over N robots; the single-env classes are
  its N = 1 case): u = J^+ (v) with v = r_d_dot - [p_c_dot; 0] + gamma (r_d - r_a); JMPI is its gamma = 0 case
  on the nominal model, CLIK the gamma = 20 case on the nominal model, the oracle the gamma = 20 case on the
  true model (row i's own robot in a batch).

Units: gamma in 1/s; v in m/s; u in rad/s (the base class clips u to the speed limits); damping and
sigma_threshold in m/rad. Default gamma = 20 1/s, the benchmark's one task-space gain for every closed-loop law
(DESIGN, Release 0.2); the paper's eq. (10) experiments use 10 (`oracle:gamma=10`, as `mobman-eval paper`
does). None of these laws knows the joint limits: on Circle-v0 joint 1 reaches its stop on many seeds (see
`policies.laws.qp` for the known-model law that respects them).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env.validation import number
from policies.base import EnvFacts, current_model, reject_extra
from policies.batched import BatchedController, LawView
from policies.kernels.shared import ModelJacobians, damped_pinv_apply_rows

#: The benchmark's task-space feedback gain for every closed-loop law, 1/s (DESIGN, Release 0.2).
DEFAULT_GAMMA = 20.0


def _check_positive(obj: Any, names: tuple[str, ...], allow_zero: tuple[str, ...] = ()) -> None:
    """Validate (and convert to float) the numeric fields `names` of a frozen config: > 0, or >= 0 if allowed."""
    for name in names:
        value = number(f"{type(obj).__name__}.{name}", getattr(obj, name), low=0.0, open_low=name not in allow_zero)
        object.__setattr__(obj, name, value)


@dataclass(frozen=True)
class JMPIConfig:
    """Options of the Jacobian pseudo-inverse method. Spec keys: `jmpi:gamma=0,full=false,...`."""

    gamma: float = 0.0
    """Position feedback gain of eq. (10), 1/s: 0 is the paper's open-loop JMPI (`jmpi:gamma=20` is `clik`)."""
    full: bool = False
    """False: the paper's J of eq. (6) and the measured p_c_dot subtracted. True: the whole-body Jacobian."""
    damping: float = 0.02
    """Maximum damping of the pseudo-inverse, m/rad (acts only when sigma_min < sigma_threshold)."""
    sigma_threshold: float = 0.02
    """Smallest singular value below which damping starts, m/rad."""

    def __post_init__(self):
        _check_positive(self, ("gamma", "damping", "sigma_threshold"), allow_zero=("gamma",))


@dataclass(frozen=True)
class CLIKConfig(JMPIConfig):
    """Options of CLIK, eq. (10) on the nominal model: JMPI's fields with the benchmark's feedback gain.
    Spec keys: `clik:gamma=20,full=false,...`."""

    gamma: float = DEFAULT_GAMMA
    """Position feedback gain of eq. (10), 1/s (the benchmark's 20)."""


@dataclass(frozen=True)
class OracleConfig(JMPIConfig):
    """Options of the known-model oracle, eq. (10). Spec keys: `oracle:gamma=20,full=false,...`."""

    gamma: float = DEFAULT_GAMMA
    """Position feedback gain of eq. (10), 1/s (the benchmark's 20; the paper's experiments use 10)."""


class ModelLaw(BatchedController):
    """The one law of this module for N robots, u = J^+ (r_d_dot - [p_c_dot; 0] + gamma (r_d - r_a)) (whole
    body: no p_c_dot term), with J row i's model's Jacobian at its measured state (batched,
    `policies.kernels.shared.ModelJacobians`). `params(i)` returns row i's `RobotParams` (nominal or true); it is read
    at each of the row's episode starts. The single-env classes below are its N = 1 case."""

    _keys = ("joint_pos", "base_yaw", "target_vel", "arm_base_vel")

    def __init__(self, facts: EnvFacts, config: Any, n: int, seed: int | None, params: Callable[[int], Any], name: str):
        super().__init__(facts, n, seed)
        self.name = self.spec = name
        self.config = config
        self._full = bool(config.full)
        self._model = ModelJacobians(n, params)
        self.uses_keys = self._keys + (("target_pos", "ee_pos") if config.gamma > 0 else ())

    @property
    def params(self) -> list[Any]:
        """The `RobotParams` each row inverts this episode (None before its first episode start)."""
        return self._model.params

    def _reset_rows(self, rows: np.ndarray, obs: dict) -> None:
        self._model.load(rows.tolist())

    def _act(self, obs: dict) -> np.ndarray:
        c = self.config
        if c.gamma > 0:
            v = obs["target_vel"] + c.gamma * (obs["target_pos"] - obs["ee_pos"])
        else:  # open loop (JMPI): the position is not read at all
            v = obs["target_vel"].copy()
        if not self._full:
            v[:, :2] -= obs["arm_base_vel"]
        J = self._model(obs["joint_pos"], obs["base_yaw"], self._full)
        return damped_pinv_apply_rows(J, v, c.damping, c.sigma_threshold)


class _ModelPolicy(LawView):
    """A single-env model-based controller: the N = 1 case of `ModelLaw`. Subclasses say where the model comes
    from (`_provider`, a callable f(i) for the law); `params` is the `RobotParams` inverted this episode."""

    def __init__(self, facts: EnvFacts, config: Any, seed: int | None, provider: Callable[[int], Any]):
        self.law: ModelLaw = ModelLaw(facts, config, 1, seed, provider, self.name)
        super().__init__(facts, seed)
        self.config = config

    @property
    def params(self) -> Any:
        return self.law.params[0]


class JMPI(_ModelPolicy):
    """Jacobian pseudo-inverse on the nominal model: u = J_nom^+ (r_d_dot - [p_c_dot; 0]) (open loop, gamma = 0).

    `JMPI(facts, config=None, seed=None, *, nominal_params)`.
    """

    name = "jmpi"
    config_cls: type[JMPIConfig] = JMPIConfig
    #: the knowledge class (`policies.knowledge`): the catalogue's parameters (CLIK inherits it)
    knowledge = "nominal"

    def __init__(
        self,
        facts: EnvFacts,
        config: JMPIConfig | None = None,
        seed: int | None = None,
        *,
        nominal_params: Any = None,
        **extra: Any,
    ):
        cls = type(self).__name__
        reject_extra(self, extra, "nominal_params")
        if nominal_params is None:
            raise ValueError(
                f"{cls} needs nominal_params (a RobotParams: the catalogue model it inverts, or a callable returning "
                "the episode's nominal RobotParams)"
            )
        super().__init__(facts, config or self.config_cls(), seed, lambda i: current_model(nominal_params))

    @classmethod
    def batched(cls, facts: EnvFacts, config: Any, n: int, seed: int | None, *, nominal_params: Any) -> ModelLaw:
        """The batched law for n robots (`policies.make(spec, vector_env)`); `nominal_params(i)`: row i's model."""
        return ModelLaw(facts, config, n, seed, nominal_params, cls.name)


class CLIK(JMPI):
    """Closed-loop resolved-rate control on the nominal model: eq. (10) with J_nom, gamma = 20 1/s by default
    (the oracle's law with the catalogue model; JMPI's with feedback).

    `CLIK(facts, config=None, seed=None, *, nominal_params)`.
    """

    name = "clik"
    config_cls = CLIKConfig


class Oracle(_ModelPolicy):
    """Eq. (10) with the true robot's Jacobian (closed loop, gain gamma): the known-model bound.

    `Oracle(facts, config=None, seed=None, *, params_provider)`: `params_provider()` returns the current true
    `RobotParams`; it is called at every episode start (reset or `episode_start`).
    """

    name = "oracle"
    #: the knowledge class (`policies.knowledge`): the worn robot's parameters
    knowledge = "true"

    def __init__(
        self,
        facts: EnvFacts,
        config: OracleConfig | None = None,
        seed: int | None = None,
        *,
        params_provider: Callable[[], Any] | None = None,
        **extra: Any,
    ):
        reject_extra(self, extra, "params_provider")
        if params_provider is None or not callable(params_provider):
            raise ValueError("Oracle needs params_provider: a callable returning the env's current true RobotParams")
        self._provider = params_provider  # read through self at each episode start (a test spies on it)
        super().__init__(facts, config or OracleConfig(), seed, lambda i: self._provider())

    @classmethod
    def batched(cls, facts: EnvFacts, config: Any, n: int, seed: int | None, *, params_provider: Any) -> ModelLaw:
        """The batched law for n robots; `params_provider(i)` returns robot i's current true robot."""
        return ModelLaw(facts, config, n, seed, params_provider, cls.name)

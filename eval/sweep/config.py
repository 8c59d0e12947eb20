"""`SweepConfig`: the grid of a `mobman-eval sweep`, read from YAML and validated with clear errors.

```yaml
envs: [WheeledPuma-Circle-v0]          # env ids (a single value may be written without brackets)
policies: [nnbc, jmpi, oracle]         # policy specs, as --policy
seeds: {start: 10000, count: 8}        # or a list: [10000, 10001, 10005]
dynamics: [kinematic]                  # physics and/or kinematic
model_error: [0.0, 0.02, 0.05, 0.1]    # relative std of the true robot's lengths
obs_noise: [0.0, 0.0005, 0.002]        # position sensor noise std, m
env_kwargs: {}                         # further env arguments, the same for every episode
tolerance: 0.006                       # success threshold on the max tracking error, m
settle_time: 0.5                       # steady-state errors use t >= settle_time, s
```

Every combination (env, dynamics, model_error, obs_noise, policy, seed) is one episode; all keys are optional
(defaults as `mobman-eval run`). Unknown keys, wrong types, empty or repeated lists fail naming the key, the
bad value and what is accepted.
"""

from __future__ import annotations

import difflib
import json
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from eval.config import DYNAMICS_CHOICES
from eval.errors import EvalError
from eval.metrics import DEFAULT_SETTLE_TIME, DEFAULT_TOLERANCE
from eval.rollout import FLAG_KWARGS
from mobman_env.validation import integer, number


@dataclass(frozen=True)
class SweepConfig:
    """A grid of episodes: every (env, dynamics, model_error, obs_noise, policy, seed) combination runs once."""

    envs: tuple[str, ...] = ("WheeledPuma-Circle-v0",)
    """Gymnasium env ids (`mobman_env.ENV_IDS` lists ours)."""
    policies: tuple[str, ...] = ("nnbc", "jmpi", "oracle")
    """Policy specs for `policies.make` (`name[:key=value,...]`, `sb3:PATH`, `module:attr`)."""
    seeds: tuple[int, ...] = tuple(range(10_000, 10_005))
    """Episode seeds: `env.reset(seed)` and `policy.reset(..., seed=policy_seed(seed))`; every cell gets the same ones."""
    dynamics: tuple[str, ...] = ("physics",)
    """Dynamics modes ("physics", "kinematic")."""
    model_error: tuple[float, ...] = (0.05,)
    """Relative std of the true robot's lengths (env argument), each >= 0."""
    obs_noise: tuple[float, ...] = (0.0,)
    """Std of the position sensor noise, m (env argument), each >= 0."""
    env_kwargs: dict = field(default_factory=dict)
    """Further env constructor arguments, the same for every episode (e.g. {"path": {...}})."""
    tolerance: float = DEFAULT_TOLERANCE
    """Success threshold on the max tracking error, m (the paper's 6 mm)."""
    settle_time: float = DEFAULT_SETTLE_TIME
    """Start of the steady-state error window, s (`steady_max_error_m`, `steady_rms_error_m`)."""

    @property
    def n_episodes(self) -> int:
        return (
            len(self.envs)
            * len(self.dynamics)
            * len(self.model_error)
            * len(self.obs_noise)
            * len(self.policies)
            * len(self.seeds)
        )

    def to_dict(self) -> dict[str, Any]:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: Any, source: str = "sweep config") -> SweepConfig:
        """Validate plain data (parsed YAML) into a SweepConfig; EvalError names the key and the fix."""
        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise EvalError(
                f"{source}: the top level must be a mapping of keys ({', '.join(KEYS)}), got {type(data).__name__}"
            )
        unknown = [k for k in data if k not in KEYS]
        if unknown:
            hints = []
            for k in unknown:
                close = difflib.get_close_matches(str(k), KEYS, n=1)
                hints.append(f"{k!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
            raise EvalError(f"{source}: unknown key(s) {', '.join(hints)}; accepted: {', '.join(KEYS)}")
        kw: dict[str, Any] = {}
        if "envs" in data:
            kw["envs"] = _str_list(data["envs"], "envs", source)
        if "policies" in data:
            kw["policies"] = _str_list(data["policies"], "policies", source)
        if "seeds" in data:
            kw["seeds"] = _seeds(data["seeds"], source)
        if "dynamics" in data:
            dyn = _str_list(data["dynamics"], "dynamics", source)
            for d in dyn:
                if d not in DYNAMICS_CHOICES:
                    raise EvalError(f"{source}: dynamics: unknown mode {d!r}; accepted: {', '.join(DYNAMICS_CHOICES)}")
            kw["dynamics"] = dyn
        for name in ("model_error", "obs_noise"):
            if name in data:
                kw[name] = _nonneg_list(data[name], name, source)
        if "env_kwargs" in data:
            kw["env_kwargs"] = _env_kwargs(data["env_kwargs"], source)
        if "tolerance" in data:
            kw["tolerance"] = number(
                f"{source}: tolerance", data["tolerance"], low=0, open_low=True, hint="m, e.g. 0.006", error=EvalError
            )
        if "settle_time" in data:
            kw["settle_time"] = number(
                f"{source}: settle_time", data["settle_time"], low=0, hint="s, e.g. 0.5", error=EvalError
            )
        return cls(**kw)


#: the keys a sweep file may have, in the documented order
KEYS = tuple(f.name for f in fields(SweepConfig))


@dataclass(frozen=True)
class SweepRun:
    """How a resumable grid runs this time (a sweep, or the sweeps of a bench): the keyword arguments of
    `eval.sweep.run.run_sweep` and `eval.bench.run.run_bench` beside the backend's (`EvalConfig.backend`,
    `address`, `workers`, `batch_size`)."""

    out: str | None = None
    """Output directory; an existing sweep (or bench) there is resumed. None: `runs/sweep-<config file stem>`
    for a sweep, `runs/bench` for a bench."""
    max_episodes: int | None = None
    """Run at most this many episodes not yet done, then write the tables and stop (run the same command again
    to go on); None: every episode left."""
    retry_failed: bool = False
    """Run again the episodes recorded as failed."""
    rerun_changed: bool = False
    """Run again the episodes the journal holds from other code than this (another mobman version, an edited
    source): without it such a journal is refused, because one result never mixes two code versions."""
    plots: bool = True
    """Write the PNG plots."""
    progress: bool = True
    """Show a progress bar (stderr) and the summary table (stdout)."""


def load_sweep(path: str | Path) -> SweepConfig:
    """Read and validate a sweep YAML file."""
    import yaml

    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise EvalError(
            f"sweep config {str(path)!r} not found; `mobman-eval sweep --example > sweep.yaml` writes "
            f"an example to start from"
        ) from None
    except OSError as exc:
        raise EvalError(f"cannot read sweep config {str(path)!r}: {exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise EvalError(f"{path}: not valid YAML: {exc}") from None
    return SweepConfig.from_dict(data, source=str(path))


def example_path() -> Path:
    """The example sweep shipped with the package (eval/sweep/examples/sweep.yaml)."""
    return Path(__file__).resolve().parent / "examples" / "sweep.yaml"


# --- value checks ----------------------------------------------------------------------------------------


def _as_list(value: Any, name: str, source: str) -> list:
    items = list(value) if isinstance(value, (list, tuple)) else [value]
    if not items:
        raise EvalError(f"{source}: {name} is empty; give at least one value")
    dup = sorted({json.dumps(v, default=str) for v in items if items.count(v) > 1})
    if dup:
        raise EvalError(f"{source}: {name} lists {', '.join(dup)} more than once; give each value once")
    return items


def _str_list(value: Any, name: str, source: str) -> tuple[str, ...]:
    items = _as_list(value, name, source)
    for i, v in enumerate(items):
        if not isinstance(v, str) or not v:
            raise EvalError(f"{source}: {name}[{i}] must be a non-empty string, got {v!r}")
    return tuple(items)


def _nonneg_list(value: Any, name: str, source: str) -> tuple[float, ...]:
    items = _as_list(value, name, source)
    return tuple(number(f"{source}: {name}[{i}]", v, low=0, error=EvalError) for i, v in enumerate(items))


def _seeds(value: Any, source: str) -> tuple[int, ...]:
    form = "a list of integers >= 0 such as [10000, 10001] or {start: 10000, count: 8}"
    if isinstance(value, dict):
        unknown = sorted(set(value) - {"start", "count"})
        missing = sorted({"start", "count"} - set(value))
        if unknown or missing:
            what = f"unknown: {', '.join(map(repr, unknown))}" if unknown else f"missing: {', '.join(missing)}"
            raise EvalError(f"{source}: seeds as a mapping takes exactly 'start' and 'count' ({what})")
        start = integer(f"{source}: seeds.start", value["start"], low=0, error=EvalError)
        count = integer(f"{source}: seeds.count", value["count"], low=1, error=EvalError)
        return tuple(range(start, start + count))
    if not isinstance(value, (list, tuple)):
        raise EvalError(f"{source}: seeds must be {form}; got {value!r}")
    items = _as_list(value, "seeds", source)
    return tuple(integer(f"{source}: seeds[{i}]", v, low=0, error=EvalError) for i, v in enumerate(items))


def _env_kwargs(value: Any, source: str) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise EvalError(
            f"{source}: env_kwargs must be a mapping of env arguments, e.g. "
            f"{{path: {{type: circle, duration: 2.0}}}}; got {value!r}"
        )
    clash = sorted(set(value) & (set(FLAG_KWARGS) | {"render_mode"}))
    if clash:
        raise EvalError(
            f"{source}: env_kwargs sets {clash}; use the sweep keys dynamics / model_error / obs_noise "
            f"instead (render_mode is not available in sweeps)"
        )
    try:
        json.dumps(value, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise EvalError(f"{source}: env_kwargs must be plain data (numbers, strings, lists, mappings): {exc}") from None
    return dict(value)

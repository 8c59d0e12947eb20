"""`EvalConfig`: everything one `mobman-eval run` needs, as a frozen dataclass (the CLI parses into it)."""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from typing import Any

from eval.errors import EvalError
from eval.metrics import DEFAULT_SETTLE_TIME, DEFAULT_TOLERANCE
from eval.rollout import FLAG_KWARGS
from mobman_env.sim import DYNAMICS_MODES
from mobman_env.validation import integer, number

#: the env's dynamics modes (one home: mobman_env.sim)
DYNAMICS_CHOICES = DYNAMICS_MODES
SAVE_ARRAYS_CHOICES = ("all", "first", "none")
STDOUT_FORMATS = ("table", "markdown", "json", "csv")
BACKEND_CHOICES = ("local", "ray")


@dataclass(frozen=True)
class EvalConfig:
    """One benchmark run: every (env, dynamics, policy) pair faces the same `episodes` episodes.

    Episode k (0-based) of every pair uses `env.reset(seed=seed + k)` and `policy.reset(..., seed=policies.policy_seed(seed + k))` (a seed derived from the episode seed that reveals nothing the env drew).
    """

    envs: tuple[str, ...] = ("WheeledPuma-Circle-v0",)
    """Gymnasium env ids (registered ones; `mobman_env.ENV_IDS` lists ours)."""
    policies: tuple[str, ...] = ("nnbc", "jmpi", "oracle")
    """Policy specs for `policies.make` (`name[:key=value,...]`, `sb3:PATH`, `module:attr`)."""
    episodes: int = 5
    """Seeds per (env, dynamics, policy): episode k uses seed + k, so this is the number of episodes of each."""
    seed: int = 10_000
    """Seed of episode 0 (reported results use seeds >= 10,000; tune on 0-999)."""
    out: str | None = None
    """Output directory; None: `runs/<command>-<UTC timestamp>`."""
    overwrite: bool = False
    """Write into an existing non-empty `out` (files of the same name are replaced atomically)."""
    resume: bool = False
    """Continue the run in `out` where it stopped (a full disk, a kill): the episodes in its journal
    (episodes.jsonl) are kept, the others run, then every file is written. The settings that change episodes
    (env_kwargs, tolerance, settle_time) must be those of the run there; more envs, policies or seeds may be
    added. The kept episodes have no per-step arrays, so their plots are missing."""
    rerun_changed: bool = False
    """With `resume`: run again the episodes the journal holds from other code than this (another mobman
    version, an edited source); without it such a journal is refused: one result never mixes two code
    versions."""
    workers: int = 1
    """Parallel episodes. Local backend: processes (one PyBullet client each; 1 runs in this process). Ray
    backend: the CPUs of the local Ray instance started for the run (ignored when this process already called
    `ray.init`; must stay 1 with `address`, where the cluster's CPUs decide)."""
    batch_size: int = 64
    """Most kinematic episodes stepped together through one vector env and one batched policy
    (`eval.execution.batches`): episodes of the same env, condition and built-in policy spec are batched;
    physics mode, `sb3:` agents, `module:attr` specs, policy objects and batches smaller than
    `eval.execution.batches.MIN_BATCH` (4) run one by one. 1: every episode on the single path. Results are the same either way (timing fields and `pid` aside); a failing batch is run
    again episode by episode; Ctrl-C loses the episodes of the batch in progress."""
    backend: str = "local"
    """Where episodes run: "local" (this machine's processes) or "ray" (one Ray task per batch or episode; needs
    `pip install "mobman[cluster]"`)."""
    address: str | None = None
    """Ray cluster to connect to ("auto", "HOST:6379", "ray://HOST:10001"); None: start a local Ray instance
    (or use the one this process already initialised). Only with backend="ray"."""
    dynamics: tuple[str, ...] = ("physics",)
    """Dynamics modes to run ("physics", "kinematic"); each is a separate condition. Default physics, the envs'
    own default: evaluation runs the realistic mode (contact dynamics, torque limits, wheel slip) unless asked
    otherwise. (`mobman-train` trains kinematic by default: a physics step costs about 30 kinematic ones.)"""
    model_error: float | None = None
    """Relative std of the true robot's lengths (env argument); None: the env's default (0.05)."""
    obs_noise: float | None = None
    """Std of the position sensor noise, m (env argument); None: the env's default (0)."""
    env_kwargs: dict = field(default_factory=dict)
    """Further env constructor arguments, e.g. {"path": {...}, "n_substeps": 4}."""
    tolerance: float = DEFAULT_TOLERANCE
    """Success threshold on the max tracking error, m (the paper's 6 mm)."""
    settle_time: float = DEFAULT_SETTLE_TIME
    """Start of the window of the steady-state errors `steady_max_error_m` / `steady_rms_error_m`, s (the
    samples with t >= settle_time count; the whole-episode errors are reported beside them)."""
    video: bool = False
    """Also write a video of episode 0 of each policy (first env and dynamics mode)."""
    plots: bool = True
    """Write the PNG plots."""
    save_arrays: str = "first"
    """Per-step arrays in episodes.npz: episode 0 of each condition ("first"), "all" episodes (kept in memory
    until the end of the run: about 0.3 MB per 20 s episode), or "none"."""
    progress: bool = True
    """Show a progress bar (stderr) and the results (stdout, in `stdout_format`)."""
    stdout_format: str = "table"
    """What is printed on stdout at the end: "table" (a compact console table), or the content of one of
    the files, "markdown" (summary.md), "json" (results.json), "csv" (results.csv), so a run can be piped.
    The files are written whatever the format; progress and messages go to stderr."""
    command: str = "run"
    """Name used for the default output directory."""

    def __post_init__(self):
        for name in ("envs", "policies", "dynamics"):
            value = getattr(self, name)
            if isinstance(value, str):
                value = (value,)
            object.__setattr__(self, name, tuple(value))
        object.__setattr__(self, "env_kwargs", dict(self.env_kwargs or {}))

    def validate(self) -> None:
        """Raise `EvalError` naming the bad value, the accepted ones and the fix."""
        if self.resume and not self.out:
            raise EvalError("--resume continues the run in --out DIR: name that folder (--out DIR --resume)")
        if self.resume and self.overwrite:
            raise EvalError("--resume keeps the episodes in --out, --overwrite starts over: pass one of them")
        if not self.envs:
            raise EvalError("no env given; pass at least one --env, e.g. --env WheeledPuma-Circle-v0")
        integer("episodes", self.episodes, low=1, hint="the number of seeds, e.g. --seeds 5", error=EvalError)
        integer("seed", self.seed, low=0, hint="reported seeds start at 10000", error=EvalError)
        integer("workers", self.workers, low=1, hint="e.g. --workers 2", error=EvalError)
        integer("batch_size", self.batch_size, low=1, hint="e.g. --batch-size 64", error=EvalError)
        self.validate_backend()
        for name in ("envs", "policies"):
            values = getattr(self, name)
            dup = sorted({v for v in values if values.count(v) > 1})
            if dup:
                raise EvalError(f"{name} given more than once: {dup}; give each once (use --seeds for more episodes)")
        if not self.dynamics:
            raise EvalError("no dynamics mode given; accepted: physics, kinematic")
        for d in self.dynamics:
            if d not in DYNAMICS_CHOICES:
                raise EvalError(f"unknown dynamics mode {d!r}; accepted: {', '.join(DYNAMICS_CHOICES)}")
        if len(set(self.dynamics)) != len(self.dynamics):
            raise EvalError(f"dynamics modes repeated: {list(self.dynamics)}")
        number("tolerance", self.tolerance, low=0, open_low=True, hint="m, e.g. 0.006", error=EvalError)
        if self.stdout_format not in STDOUT_FORMATS:
            raise EvalError(f"stdout_format must be one of {', '.join(STDOUT_FORMATS)}, got {self.stdout_format!r}")
        number("settle_time", self.settle_time, low=0.0, hint="s, e.g. 0.5 (0: the whole episode)", error=EvalError)
        if self.save_arrays not in SAVE_ARRAYS_CHOICES:
            raise EvalError(f"save_arrays must be one of {', '.join(SAVE_ARRAYS_CHOICES)}, got {self.save_arrays!r}")
        if not isinstance(self.env_kwargs, dict):
            raise EvalError(f"env_kwargs must be a dict (JSON object), got {self.env_kwargs!r}")
        clash = sorted(set(self.env_kwargs) & (set(FLAG_KWARGS) | {"render_mode"}))
        if clash:
            raise EvalError(
                f"--env-kwargs sets {clash}; use the flags --dynamics / --model-error / --obs-noise instead "
                f"(render_mode is set by --video)"
            )
        try:
            json.dumps(self.env_kwargs)
        except (TypeError, ValueError) as exc:
            raise EvalError(f"env_kwargs must be plain JSON data: {exc}") from None

    def validate_backend(self) -> None:
        """The backend, address and workers fit together (whether Ray is installed is checked by
        `eval.checks.check_all`, before any rollout)."""
        if self.backend not in BACKEND_CHOICES:
            raise EvalError(f"unknown backend {self.backend!r}; accepted: {', '.join(BACKEND_CHOICES)}")
        if self.address is not None and self.backend != "ray":
            raise EvalError(f"--address {self.address!r} needs --backend ray (the local backend runs on this machine)")
        if self.backend == "ray" and self.address is not None and self.workers != 1:
            raise EvalError(
                f"--workers {self.workers} sets the CPUs of a Ray instance started for this run; with --address "
                f"{self.address!r} the cluster's CPUs set the parallelism: drop --workers"
            )

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        for k in ("envs", "policies", "dynamics"):
            d[k] = list(d[k])
        return d


@dataclass(frozen=True)
class Execution:
    """Where and how a grid's episodes run, apart from what they are (`run`, `sweep` and `bench` share it): the
    backend, its address, the parallel workers and the largest batch of a vector env (`EvalConfig`'s fields of
    the same names say what each does)."""

    backend: str = "local"
    address: str | None = None
    workers: int = 1
    batch_size: int = 64

    def episode_config(self, out: Any, command: str, **grid: Any) -> EvalConfig:
        """The `EvalConfig` every episode of a sweep's or bench's grid runs under (each task brings its condition
        and seed; `grid`: the envs, policies, seeds, dynamics and env arguments it describes), validated: nothing
        is plotted or kept per step, the caller writes the tables."""
        config = EvalConfig(
            out=str(out),
            overwrite=True,
            workers=self.workers,
            batch_size=self.batch_size,
            backend=self.backend,
            address=self.address,
            plots=False,
            save_arrays="none",
            progress=False,
            command=command,
            **grid,
        )
        config.validate()
        return config

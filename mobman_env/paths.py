"""Time-parameterised desired paths r_d(t), fixed in the world frame, starting at a given point.

All paths use the paper's rest-to-rest timing s(t) = sin^2(0.5 pi t / T): s(0) = 0, s(T) = 1 and
s_dot(0) = s_dot(T) = 0, so the path starts and ends at rest. Each path is a frozen dataclass with analytic
`position(t)`, `velocity(t)` and `acceleration(t)` and a `to_spec()` / `path_from_spec()` round trip through
plain dicts. A spec holds no anchor: the start point is given separately (the env uses the end-effector's
initial position, so the initial error is zero).

Specs (all lengths m, angles rad, durations s):

* `{"type": "circle", "radius": 0.4, "tilt": 0.5236, "yaw": 3.1416, "duration": 20.0}` -- the paper's
  section IV circle. `yaw` is the direction of the centre seen from the start, in the world x-y plane; the
  plane of the circle contains that horizontal direction and is tilted by `tilt` about it. With yaw = pi this is
  exactly the paper's formula: x = l cos(2 pi s) - l + x0, y = l cos(tilt) sin(2 pi s) + y0,
  z = l sin(tilt) sin(2 pi s) + z0.
* `{"type": "line", "length": 3.0, "direction": [-1, 0, 0], "duration": 20.0}` -- a straight segment.
* `{"type": "lemniscate", "width": 0.6, "height": 0.3, "tilt": 0.5236, "yaw": 3.1416, "duration": 20.0}` --
  a figure eight (lemniscate of Gerono), `width` along `yaw`, `height` across it in the tilted plane.
* `{"type": "random", "seed": 7, "size": 0.3, "n_terms": 3, "duration": 20.0}` -- per axis a sum of
  `n_terms` sinusoids of the phase 2 pi s with random amplitudes and phases from `seed`, scaled so each axis
  moves at most `size` (m) from end to end of its range. A spec without `seed` gets one from the env's RNG.

Every field has an accepted range (`FIELD_RANGES`, listed in `validate_spec`): sizes up to 20 m, a line up to
50 m, durations from 0.01 s to one hour, at most 20 sinusoids per axis. Imports numpy and
`mobman_env.validation` and `mobman_env.engine` (whose `path_eval` evaluates every path) only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from mobman_env import engine
from mobman_env.validation import integer, number, vector

PATH_TYPES = ("circle", "line", "lemniscate", "random")
#: The four tasks' path specs, by task name: the one home of the tasks (the env ids `Wheeled<Robot>-<Task>-v0`
#: in `mobman_env.TASKS`, the start selection in `mobman_env.robots.starts` and the env's default path read them).
#: The circle is the paper's (section IV: radius 0.4 m, tilted pi/6, 20 s, its centre towards -x from the start);
#: the line runs 3 m along the heading; the figure eight is 0.6 m x 0.3 m; the random path has 3 harmonics of 0.3 m.
TASK_SPECS: dict[str, dict[str, Any]] = {
    "circle": {"type": "circle", "radius": 0.4, "tilt": math.pi / 6, "yaw": math.pi, "duration": 20.0},
    "line": {"type": "line", "length": 3.0, "direction": [-1.0, 0.0, 0.0], "duration": 20.0},
    "lemniscate": {
        "type": "lemniscate",
        "width": 0.6,
        "height": 0.3,
        "tilt": math.pi / 6,
        "yaw": math.pi,
        "duration": 20.0,
    },
    "random": {"type": "random", "size": 0.3, "n_terms": 3, "duration": 20.0},
}
Vec3 = tuple[float, float, float]


class Path(Protocol):
    duration: float

    def position(self, t: float) -> np.ndarray: ...
    def position_velocity(self, t: float) -> tuple[np.ndarray, np.ndarray]: ...
    def velocity(self, t: float) -> np.ndarray: ...
    def acceleration(self, t: float) -> np.ndarray: ...
    def to_spec(self) -> dict: ...


def _plane_axes(yaw: float, tilt: float) -> tuple[np.ndarray, np.ndarray]:
    """e1: horizontal unit vector at `yaw`; e2: perpendicular to e1, tilted up by `tilt` from the horizontal
    e1 x z (for yaw = pi: e1 = -x, e2 = [0, cos tilt, sin tilt], the paper's circle plane)."""
    e1 = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    h = np.array([e1[1], -e1[0], 0.0])  # e1 x z
    e2 = math.cos(tilt) * h + math.sin(tilt) * np.array([0.0, 0.0, 1.0])
    return e1, e2


#: one sinusoid term of a path: (k, amplitude per axis (m), phase per axis (rad)), see `_CoefficientPath`
Term = tuple[float, Any, Any]


class _CoefficientPath:
    """A path in the engine's form: per axis, r_d(t) = start + lin ph + sum_j amp_j (sin(k_j ph + phase_j) -
    sin(phase_j)), with the phase ph = 2 pi s(t) of the rest-to-rest timing s(t) = sin^2(0.5 pi t / T) (held at
    the ends). Every path type is this form (a circle is one harmonic, a figure eight two, a line the linear term).
    `coef` holds it in the layout of `mobman_env.engine` (`PATH_LEN` floats), each term as
    amp (sin(k ph) cos(phase) + cos(k ph) sin(phase)) - amp sin(phase) = S sin(k ph) + C (cos(k ph) - 1) with
    S = amp cos(phase), C = amp sin(phase) (terms of one harmonic k merged), so the engine takes one sine and one
    cosine per harmonic; position, velocity and acceleration are `engine.path_eval` of it, the very function the
    env's step evaluates."""

    start: np.ndarray
    duration: float
    coef: np.ndarray

    def _terms(self) -> tuple[Any, list[Term]]:
        """The linear term (3, m per unit of phase) and the sinusoid terms."""
        raise NotImplementedError

    def __post_init__(self) -> None:
        lin, terms = self._terms()
        harmonics: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        for k, amp, phase in terms:
            amp, phase = np.broadcast_to(np.asarray(amp, float), (3,)), np.broadcast_to(np.asarray(phase, float), (3,))
            S, C = harmonics.get(float(k), (np.zeros(3), np.zeros(3)))
            harmonics[float(k)] = (S + amp * np.cos(phase), C + amp * np.sin(phase))
        c = np.zeros(engine.PATH_LEN)
        c[0:3] = self.start
        c[3] = self.duration
        c[4:7] = lin
        c[7] = len(harmonics)
        for j, (k, (S, C)) in enumerate(harmonics.items()):
            base = engine.PATH_HEAD + engine.PATH_TERM * j
            c[base] = k
            c[base + 1 : base + 4] = S
            c[base + 4 : base + 7] = C
        object.__setattr__(self, "coef", c)

    def _eval(self, t: float) -> np.ndarray:
        out = np.empty((3, 3))
        engine.path_eval(self.coef, float(t), out)
        return out

    def position(self, t: float) -> np.ndarray:
        return self._eval(t)[0]

    def position_velocity(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """position(t) and velocity(t) from one evaluation."""
        out = self._eval(t)
        return out[0], out[1]

    def velocity(self, t: float) -> np.ndarray:
        return self._eval(t)[1]

    def acceleration(self, t: float) -> np.ndarray:
        return self._eval(t)[2]


def _vec3(value: Any, name: str) -> np.ndarray:
    return vector(name, value, sizes=(3,))


_ZERO3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True, eq=False)
class CirclePath(_CoefficientPath):
    """The paper's circle: starts at `start` and goes once round, the centre at `radius` towards `yaw`:
    l (cos ph - 1) u + l sin ph e2 with u = -e1 (from the centre to the start)."""

    start: np.ndarray
    radius: float = 0.4
    tilt: float = math.pi / 6
    yaw: float = math.pi
    duration: float = 20.0
    type: ClassVar[str] = "circle"
    coef: np.ndarray = field(init=False, repr=False)

    def _terms(self) -> tuple[Any, list[Term]]:
        e1, e2 = _plane_axes(self.yaw, self.tilt)
        l = self.radius
        # l (cos ph - 1) u + l sin(ph) e2 with u = -e1: S = l e2, C = -l e1
        return _ZERO3, [(1.0, l * e2, np.zeros(3)), (1.0, -l * e1, np.full(3, 0.5 * math.pi))]

    def to_spec(self) -> dict:
        return {"type": "circle", "radius": self.radius, "tilt": self.tilt, "yaw": self.yaw, "duration": self.duration}


@dataclass(frozen=True, eq=False)
class LemniscatePath(_CoefficientPath):
    """A figure eight (lemniscate of Gerono): W/2 sin(ph) e1 + H/2 sin(2 ph) e2 in the tilted plane."""

    start: np.ndarray
    width: float = 0.6
    height: float = 0.3
    tilt: float = math.pi / 6
    yaw: float = math.pi
    duration: float = 20.0
    type: ClassVar[str] = "lemniscate"
    coef: np.ndarray = field(init=False, repr=False)

    def _terms(self) -> tuple[Any, list[Term]]:
        e1, e2 = _plane_axes(self.yaw, self.tilt)
        return _ZERO3, [(1.0, 0.5 * self.width * e1, np.zeros(3)), (2.0, 0.5 * self.height * e2, np.zeros(3))]

    def to_spec(self) -> dict:
        return {
            "type": "lemniscate",
            "width": self.width,
            "height": self.height,
            "tilt": self.tilt,
            "yaw": self.yaw,
            "duration": self.duration,
        }


@dataclass(frozen=True, eq=False)
class LinePath(_CoefficientPath):
    """A straight segment of `length` along `direction` (normalised), rest to rest: length s(t) unit, i.e.
    the linear term length unit / (2 pi) of the phase."""

    start: np.ndarray
    length: float = 3.0
    direction: tuple[float, float, float] = (-1.0, 0.0, 0.0)
    duration: float = 20.0
    type: ClassVar[str] = "line"
    coef: np.ndarray = field(init=False, repr=False)

    def _terms(self) -> tuple[Any, list[Term]]:
        d = np.asarray(self.direction, dtype=float)
        return self.length * (d / np.linalg.norm(d)) / (2.0 * math.pi), []

    def to_spec(self) -> dict:
        return {
            "type": "line",
            "length": self.length,
            "direction": [float(v) for v in self.direction],
            "duration": self.duration,
        }


@dataclass(frozen=True, eq=False)
class RandomPath(_CoefficientPath):
    """Per axis a sum of `n_terms` sinusoids of the phase (harmonics 1..n_terms, random amplitudes falling as 1/k
    and random phases from `seed`), zero at the start; each axis spans at most `size`."""

    start: np.ndarray
    seed: int = 0
    size: float = 0.3
    n_terms: int = 3
    duration: float = 20.0
    type: ClassVar[str] = "random"
    coef: np.ndarray = field(init=False, repr=False)

    def _terms(self) -> tuple[Any, list[Term]]:
        rng = np.random.default_rng(self.seed)
        k = np.arange(1, self.n_terms + 1)
        amp = rng.uniform(-1.0, 1.0, (3, self.n_terms)) / k  # smoother: higher harmonics smaller
        phase = rng.uniform(0.0, 2 * math.pi, (3, self.n_terms))
        # scale each axis so its whole excursion (max - min over one period) is at most `size`
        grid = np.linspace(0.0, 2 * math.pi, 3601)
        vals = np.einsum("ak,akg->ag", amp, np.sin(k[None, :, None] * grid + phase[..., None]))
        span = vals.max(axis=1) - vals.min(axis=1)
        amp = amp * (0.999 * self.size / np.maximum(span, 1e-12))[:, None]  # 0.1% margin for the grid
        return _ZERO3, [(float(k[j]), amp[:, j], phase[:, j]) for j in range(self.n_terms)]

    def to_spec(self) -> dict:
        return {
            "type": "random",
            "seed": self.seed,
            "size": self.size,
            "n_terms": self.n_terms,
            "duration": self.duration,
        }


@dataclass(frozen=True)
class _Range:
    """The accepted values of one spec field: a real number (or an integer) in [low, high] (low open if
    `open_low`), in `unit`."""

    low: float
    high: float
    unit: str
    open_low: bool = False
    integer: bool = False


MAX_LENGTH = 50.0  # m: a line may leave the arm's reach (the platform drives at <= 2 m/s); 50 m is 25 s of that
MAX_SIZE = 20.0  # m: circle radius, lemniscate width / height, random size (the arm reaches about 1 m)
MAX_DURATION = 3600.0  # s: one hour, 360,000 control steps at 100 Hz
MIN_DURATION = 0.01  # s: one control step at 100 Hz (the timing law divides by the duration)
MAX_ANGLE = 2 * math.pi  # rad: tilt and yaw in [-2 pi, 2 pi]; every angle has a representative there
MAX_TERMS = 20  # sinusoids per axis of a random path (the amplitudes fall as 1/k: term 20 is 5% of term 1)
MAX_PEAK = 10.0  # a random path's `max_peak`: redraw until the reference law's peak speed ratio is at most this
MAX_DIRECTION = 1e6  # per component of a line's direction (only the direction counts: it is normalised)

_DURATION = _Range(MIN_DURATION, MAX_DURATION, "s")
_SIZE = _Range(0.0, MAX_SIZE, "m", open_low=True)
_ANGLE = _Range(-MAX_ANGLE, MAX_ANGLE, "rad, i.e. [-2 pi, 2 pi]")
#: every field of every path type with its accepted range (`direction` is checked on its own)
FIELD_RANGES: dict[str, dict[str, _Range | None]] = {
    "circle": {"radius": _SIZE, "tilt": _ANGLE, "yaw": _ANGLE, "duration": _DURATION},
    "line": {"length": _Range(0.0, MAX_LENGTH, "m", open_low=True), "direction": None, "duration": _DURATION},
    "lemniscate": {"width": _SIZE, "height": _SIZE, "tilt": _ANGLE, "yaw": _ANGLE, "duration": _DURATION},
    "random": {
        "seed": _Range(0, 2**63 - 1, "", integer=True),
        "size": _SIZE,
        "n_terms": _Range(1, MAX_TERMS, "", integer=True),
        "duration": _DURATION,
        "max_peak": _Range(0.0, MAX_PEAK, "(the peak speed ratio of mobman_env.feasibility, e.g. 0.9)", open_low=True),
    },
}
_CLASSES = {"circle": CirclePath, "line": LinePath, "lemniscate": LemniscatePath, "random": RandomPath}


def validate_spec(spec: Any) -> dict:
    """Check a path spec and return a normalised copy (floats, known keys only). Raises `ValueError` naming the
    bad key or value and the accepted ones. Accepted ranges (`FIELD_RANGES`):

    | field | paths | accepted |
    |---|---|---|
    | radius, width, height, size | circle, lemniscate, random | (0, 20] m |
    | length | line | (0, 50] m |
    | tilt, yaw | circle, lemniscate | [-2 pi, 2 pi] rad |
    | duration | all | [0.01, 3600] s |
    | direction | line | 3 finite numbers in [-1e6, 1e6], not all zero (normalised) |
    | seed | random | integer in [0, 2**63 - 1] |
    | n_terms | random | integer in [1, 20] |
    | max_peak | random (without a seed) | (0, 10]: redraw the path until it is feasible to this peak speed ratio |

    Bools, strings and complex numbers are refused, also where they would convert (`"0.4"`, `True`).
    """
    if not isinstance(spec, dict):
        raise ValueError(f"a path spec must be a dict such as {{'type': 'circle', 'radius': 0.4}}, got {spec!r}")
    kind = spec.get("type")
    if kind not in FIELD_RANGES:
        raise ValueError(f"unknown path type {kind!r}; known: {', '.join(PATH_TYPES)}")
    allowed = FIELD_RANGES[kind]
    unknown = sorted(set(spec) - set(allowed) - {"type"})
    if unknown:
        raise ValueError(f"{kind} path: unknown key(s) {unknown}; accepted: {sorted(allowed)}")
    out: dict[str, Any] = {"type": kind}
    for key, accepted in allowed.items():
        if key not in spec:
            continue
        value = spec[key]
        name = f"{kind} path: {key}"
        if accepted is None:  # the line's direction
            d = vector(name, value, sizes=(3,), low=-MAX_DIRECTION, high=MAX_DIRECTION, hint="e.g. [-1, 0, 0]")
            if np.linalg.norm(d) < 1e-9:
                raise ValueError(f"{name} must be non-zero, got {[float(v) for v in d]}")
            out[key] = [float(v) for v in d]
        elif accepted.integer:
            out[key] = integer(name, value, low=int(accepted.low), high=int(accepted.high))
        else:
            out[key] = number(
                name, value, low=accepted.low, high=accepted.high, open_low=accepted.open_low, hint=accepted.unit
            )
    if "max_peak" in out and "seed" in out:
        raise ValueError(
            f"{kind} path: max_peak redraws the path from the episode's generator until it is feasible, so it "
            f"cannot be combined with a fixed seed; give one of them (seed {out['seed']}, max_peak {out['max_peak']})"
        )
    return out


def path_from_spec(spec: dict, start: Any, rng: np.random.Generator | None = None):
    """Build a path from a spec, anchored at `start` (3,). A random spec without a seed draws one from `rng`."""
    spec = validate_spec(spec)
    kind = spec.pop("type")
    spec.pop("max_peak", None)  # the redraw is the engine batch's (`RobotBatch.set_path`): it needs the robot
    start = _vec3(start, "path start")
    if kind == "line" and "direction" in spec:
        spec["direction"] = tuple(spec["direction"])
    if kind == "random" and "seed" not in spec:
        if rng is None:
            raise ValueError("random path: the spec has no 'seed' and no rng was given to draw one")
        spec["seed"] = int(rng.integers(0, 2**31 - 1))
    return _CLASSES[kind](start=start, **spec)

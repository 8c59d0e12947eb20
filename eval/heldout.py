"""Protocol v3's held-out track: a declared family of conditions, drawn once per release from a secret seed.

Protocol v2 fixed its held-out conditions in code, where everyone could read them, and they leaked: a controller
change answered a held-out failure. Protocol v3 fixes a *family* instead, and draws the release's held-out
conditions from it with a seed nobody knows while the release is tuned:

1. before any tuning of a release starts, a random seed is made (`new_seed`) and kept off the repository; only
   its SHA-256 (`seed_digest`) is committed, in `RELEASE_SEED_SHA256`, together with this family and this draw
   (`FAMILY_SHA256` and the known-answer test of `draw` keep both from changing afterwards);
2. when the release's controllers are fixed, the seed is revealed (`REVEALED_SEEDS`, checked against the
   committed digest), `draw(seed)` gives the conditions, and they are run once on reported seeds and published as
   they come;
3. then the drawn conditions join the public set (the dev track), and the next release commits a new seed.

So no value of a held-out condition can be in a controller before the run (nobody knew it), and "the hash was
committed before the tuning" is checked against the repository's history (`RELEASE_SEED_COMMIT`).

**The family** (`AXES`, `ROBOT_FAMILIES`, `PATH_FAMILY`): every condition is kinematic or, with probability
`P_PHYSICS`, PyBullet contact dynamics on one robot; it runs on robots drawn from the arm families (PUMA 560, UR5,
Panda, a random arm per episode, a random arm scaled 0.7-1.4x); its robot is worn by `model_error` drawn
uniformly in [0, 0.25]; each stressor of `AXES` is present with its probability (at least one per condition):
actuator lag, observation delay, noise on the position, velocity, joint-speed and heading readings, another control
rate, wear drift; and with probability `P_CUSTOM_PATH` the condition replaces the four tasks by a random path of
drawn speed and richness (duration, size, harmonics). Joint angles are read from encoders that the env models as
exact (it has no noise option for them): every other sensor channel is in the family.

Ranges, and why: lags up to 150 ms and delays up to 3 steps bracket slow velocity loops and a late sensor bus;
noise ranges run from a good sensor to about twice protocol v2's heavy noise (positions 0.2-3 mm, velocities
0.002-0.03 m/s, joint speeds 0.005-0.06 rad/s, heading 0.2-4 mrad), drawn log-uniformly so each decade weighs
the same; control rates 30, 50 and 200 Hz beside the default 100; drift up to 0.8% per second; paths of 0.15-0.45
m in 6-20 s with 2-7 harmonics (a 0.45 m, 6 s path of 7 harmonics asks for speeds near the actuator limits:
feasibility is checked per episode).

This module imports the standard library and numpy.
"""

from __future__ import annotations

import hashlib
import json
import math
import secrets
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

#: The protocol whose held-out track this family defines.
PROTOCOL_VERSION = 3
#: Conditions per draw.
N_CONDITIONS = 8
#: Probability that a drawn condition runs with PyBullet contact dynamics (on one robot: physics is slow).
P_PHYSICS = 0.25
#: Probability that a drawn condition replaces the four tasks by a random path of drawn speed and richness.
P_CUSTOM_PATH = 0.5
#: The arm families a condition draws its robots from (`eval.bench.config.ROBOTS` names).
ROBOT_FAMILIES = ("puma", "ur5", "panda", "random-arm", "scaled-arm")
#: Robots per kinematic condition (physics: one).
ROBOTS_PER_CONDITION = 2
#: The robot's wear (`model_error`), drawn uniformly in this range for every condition.
WEAR_RANGE = (0.0, 0.25)


@dataclass(frozen=True)
class Axis:
    """One stressor of the family: an env argument, present with probability `p`, drawn in [low, high]."""

    name: str
    """The env argument (`WheeledPumaEnv`)."""
    p: float
    """Probability that a condition has this stressor (otherwise the env's default: none)."""
    low: float
    """Smallest value."""
    high: float
    """Largest value."""
    scale: str
    """"log" (log-uniform), "linear" (uniform), "int" (integers low..high) or "choice" (one of `choices`)."""
    choices: tuple[float, ...] = ()
    """The values of a "choice" axis."""
    unit: str = ""
    """Unit of the value (for the description)."""

    def sample(self, rng: np.random.Generator) -> float | int:
        """One value (always one draw from `rng`, whatever the scale, so that the stream does not depend on it)."""
        u = float(rng.random())
        if self.scale == "log":
            return _round3(math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low))))
        if self.scale == "linear":
            return _round3(self.low + u * (self.high - self.low))
        if self.scale == "int":
            return int(self.low + min(int(u * (self.high - self.low + 1)), int(self.high - self.low)))
        return self.choices[min(int(u * len(self.choices)), len(self.choices) - 1)]


#: The stressors, in draw order.
AXES: tuple[Axis, ...] = (
    Axis("actuator_tau", 0.5, 0.02, 0.15, "linear", unit="s"),
    Axis("obs_delay", 0.3, 1, 3, "int", unit="steps"),
    Axis("obs_noise", 0.5, 2e-4, 3e-3, "log", unit="m"),
    Axis("obs_noise_vel", 0.5, 2e-3, 3e-2, "log", unit="m/s"),
    Axis("obs_noise_joint_vel", 0.4, 5e-3, 6e-2, "log", unit="rad/s"),
    Axis("obs_noise_yaw", 0.4, 2e-4, 4e-3, "log", unit="rad"),
    Axis("control_freq", 0.3, 30.0, 200.0, "choice", choices=(30.0, 50.0, 200.0), unit="Hz"),
    Axis("wear_rate", 0.3, 1e-3, 8e-3, "linear", unit="1/s"),
)
#: The random path of a condition that replaces the tasks: duration (s), size (m) and harmonics ranges.
PATH_FAMILY = {"duration": (6.0, 20.0), "size": (0.15, 0.45), "n_terms": (2, 7)}

#: SHA-256 of the family as declared (`family_digest`): a test keeps the family equal to it, so a change of the
#: family is a new protocol version, never an edit.
FAMILY_SHA256 = "9ac8e21fbd3d428a4466a153b09591d07aa63d042dca401f1dc52c590aa45927"
#: Per release: the SHA-256 of its secret seed (`seed_digest`), committed before the release's tuning started.
RELEASE_SEED_SHA256: dict[str, str] = {
    # release 0.4, second seed: its first seed (WITHDRAWN_SEEDS) was lost before any draw; this one was made and
    # committed on 2026-12-07, after the release's tuning so far and before any held-out condition of it was known
    "0.4": "0cc1ed2385c05c4e1dea2177a81cec95a609bd602b089de6f5ede4a440d0e6b2",
}
#: Per release: digests committed and then withdrawn, never drawn (digest, commit, reason). A withdrawn seed is
#: never revealed or run; the release's draw is the one of `RELEASE_SEED_SHA256`.
WITHDRAWN_SEEDS: dict[str, tuple[tuple[str, str, str], ...]] = {
    "0.4": (
        (
            "6e6a55d4e9fd221d229ebe55201780119cf08643d9835de007b0f9450a458634",
            "248394abd6b8dca7d593b24a14c2a4794c90f449",
            "committed on 2026-12-04 before any tuning of release 0.4; the seed, kept off the repository, was lost "
            "when the development machine was reset, before any draw was made from it, so it can never be revealed",
        ),
    ),
}
#: Per release: the commit that added its seed's digest (scorecards cite it; a test finds the digest in that commit).
RELEASE_SEED_COMMIT: dict[str, str] = {"0.4": "ae362a4ad366f859fc52a516b02200f460bcc2bc"}
#: Per release: its seed, once its held-out draw has been run (then `seed_digest(seed, release)` must equal the
#: committed digest).
REVEALED_SEEDS: dict[str, str] = {
    # release 0.4: revealed when nnbc-plus v5.1 and the other controllers were fixed, before the draw was run
    "0.4": "fe695981573ceb65cfb91b319ad8f96f",
}


def _round3(x: float) -> float:
    """`x` to three significant digits (drawn values are printed in tables)."""
    return float(f"{x:.3g}")


def family() -> dict[str, Any]:
    """The family as plain data (what `family_digest` hashes and scorecards record)."""
    return {
        "protocol": PROTOCOL_VERSION,
        "n_conditions": N_CONDITIONS,
        "p_physics": P_PHYSICS,
        "p_custom_path": P_CUSTOM_PATH,
        "robot_families": list(ROBOT_FAMILIES),
        "robots_per_condition": ROBOTS_PER_CONDITION,
        "wear_range": list(WEAR_RANGE),
        "axes": [asdict(a) | {"choices": list(a.choices)} for a in AXES],
        "path_family": {k: list(v) for k, v in PATH_FAMILY.items()},
    }


def family_digest() -> str:
    """SHA-256 of `family()` as canonical JSON."""
    return hashlib.sha256(json.dumps(family(), sort_keys=True).encode()).hexdigest()


def new_seed() -> str:
    """A new release seed: 128 random bits as 32 hex digits (`secrets`), to be kept off the repository."""
    return secrets.token_hex(16)


def seed_digest(seed: str, release: str) -> str:
    """The SHA-256 committed for `seed` of `release` (salted with the release, so one digest serves one release)."""
    return hashlib.sha256(
        f"mobman protocol {PROTOCOL_VERSION} held-out seed, release {release}: {seed}".encode()
    ).hexdigest()


def _check_seed(seed: str) -> int:
    """The seed as an integer; a seed is 32 lowercase hex digits (`new_seed`)."""
    if not (isinstance(seed, str) and len(seed) == 32 and all(c in "0123456789abcdef" for c in seed)):
        raise ValueError(f"a release seed is 32 lowercase hex digits (as new_seed() makes); got {seed!r}")
    return int(seed, 16)


def draw(seed: str) -> list[dict[str, Any]]:
    """The held-out conditions of `seed`: `N_CONDITIONS` plain dicts `{name, description, track, env_kwargs,
    robots, tasks}` (`tasks` None: the four tasks), with the old axes (`dynamics`, `model_error`) as env
    arguments. Deterministic: the same seed gives the same conditions on every machine (numpy's PCG64 from a
    `SeedSequence` of the seed, uniforms only)."""
    rng = np.random.default_rng(np.random.SeedSequence(_check_seed(seed)))
    return [_draw_one(rng, k + 1) for k in range(N_CONDITIONS)]


def _draw_one(rng: np.random.Generator, k: int) -> dict[str, Any]:
    """Condition number `k` of a draw (see `draw`)."""
    physics = bool(rng.random() < P_PHYSICS)
    order = rng.permutation(len(ROBOT_FAMILIES))
    robots = [ROBOT_FAMILIES[i] for i in sorted(order[: 1 if physics else ROBOTS_PER_CONDITION])]
    env_kwargs: dict[str, Any] = {
        "dynamics": "physics" if physics else "kinematic",
        "model_error": _round3(WEAR_RANGE[0] + float(rng.random()) * (WEAR_RANGE[1] - WEAR_RANGE[0])),
    }
    present = [bool(rng.random() < a.p) for a in AXES]
    forced = int(rng.integers(len(AXES)))
    if not any(present):
        present[forced] = True
    values = [a.sample(rng) for a in AXES]  # every axis draws, present or not: one stream per draw
    for a, on, v in zip(AXES, present, values):
        if on:
            env_kwargs[a.name] = v
    custom = bool(rng.random() < P_CUSTOM_PATH)
    (d0, d1), (s0, s1), (n0, n1) = PATH_FAMILY["duration"], PATH_FAMILY["size"], PATH_FAMILY["n_terms"]
    u = rng.random(3)
    tasks: list[str] | None = None
    if custom:
        env_kwargs["path"] = {
            "type": "random",
            "size": _round3(s0 + u[0] * (s1 - s0)),
            "n_terms": int(n0 + min(int(u[1] * (n1 - n0 + 1)), n1 - n0)),
            "duration": _round3(d0 + u[2] * (d1 - d0)),
        }
        tasks = ["random"]
    return {
        "name": f"h{PROTOCOL_VERSION}-{k}",
        "description": describe(env_kwargs),
        "track": "heldout",
        "env_kwargs": env_kwargs,
        "robots": robots,
        "tasks": tasks,
    }


def describe(env_kwargs: dict[str, Any]) -> str:
    """One line naming a drawn condition's values with their units."""
    units = {a.name: a.unit for a in AXES}
    parts = [env_kwargs["dynamics"], f"wear {env_kwargs['model_error']:g}"]
    parts += [f"{k} {v:g} {units[k]}" for k, v in env_kwargs.items() if k in units]
    if "path" in env_kwargs:
        p = env_kwargs["path"]
        parts.append(f"random path {p['size']:g} m, {p['n_terms']} harmonics, {p['duration']:g} s")
    return "held out: " + ", ".join(parts)


def revealed_draw(release: str) -> list[dict[str, Any]]:
    """The held-out conditions of `release`, once its seed is revealed and matches the committed digest."""
    if release not in RELEASE_SEED_SHA256:
        known = ", ".join(sorted(RELEASE_SEED_SHA256)) or "none"
        raise ValueError(f"release {release!r} committed no held-out seed; releases with one: {known}")
    if release not in REVEALED_SEEDS:
        raise ValueError(
            f"release {release!r}'s held-out seed is not revealed yet: its draw is run once, when the release's "
            "controllers are fixed (REVEALED_SEEDS)"
        )
    seed = REVEALED_SEEDS[release]
    if seed_digest(seed, release) != RELEASE_SEED_SHA256[release]:
        raise ValueError(f"the revealed seed of release {release!r} does not match its committed digest")
    return draw(seed)

"""`mobman-eval picture`: the README's picture, a rendered frame of the robot at the end of an episode with the
desired path (green), the end-effector's trace (orange) and the platform's (dark grey, on the ground) drawn into
the world.

One episode runs through the same loop as every evaluation (`eval.rollout.rollout`, with `render_mode=
"rgb_array"`), the trace is the true end-effector (`info["ee_pos_true"]`) every `TRACE_EVERY` control steps, and
the frame is PyBullet's TinyRenderer (headless, no GPU): the same image on every machine that runs the same
PyBullet. Next to the PNG, `<stem>.json` records the command, the episode's figures and the provenance.

`--gallery DIR` renders the robots instead (`render_gallery`): the PUMA 560, the UR5, the Panda and three
random arms, each on its platform in its start configuration of the Circle task with the desired path drawn, one
PNG each (`GALLERY`) and `gallery.json` (the command, the robots, the provenance). No episode runs: the env is
reset (kinematic mode) and rendered, and the camera frames every body but the ground. Beside them,
`paths.png` draws the desired path of each task (`PATHS`: the four PUMA tasks, the Random task on three seeds)
in the world frame over its whole duration, its start marked (matplotlib; `render_paths`).

`--traces PNG` plots instead the tracking error over one episode of one controller per family (`TRACES`: the
paper's two laws, the nominal-model CLIK and QP, the calibrating QP, the known-model MPC, and the model-free RLS and
nnbc-plus) on one env and seed (`--env`, `--seed`, `--dynamics`), on a log scale with the 6 mm tolerance, and a
JSON record beside it (`render_traces`): the controllers page's picture of how each family tracks.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from eval.errors import EvalError
from eval.output.files import atomic_write_bytes, atomic_write_json
from eval.output.provenance import provenance

#: the defaults: the headline controller on the Line (the platform drives 2 m), in physics mode, on the first
#: reported seed
DEFAULT_ENV = "WheeledPuma-Line-v0"
DEFAULT_POLICY = "nnbc-plus"
DEFAULT_SEED = 10_000
#: control steps between two trace markers (0.05 s at 100 Hz)
TRACE_EVERY = 5
#: the camera: degrees about the vertical and below the horizon
CAMERA_YAW, CAMERA_PITCH = 30.0, -30.0
#: the accepted image sizes, pixels per side
SIZE_RANGE = (64, 4096)
#: the gallery: file stem -> (env id, reset seed). The random arms are the draws of dev seeds 0, 1 and 2 (an
#: illustration, not a result); the named arms do not depend on the seed.
GALLERY: dict[str, tuple[str, int]] = {
    "puma": ("WheeledPuma-Circle-v0", 0),
    "ur5": ("WheeledUR5-Circle-v0", 0),
    "panda": ("WheeledPanda-Circle-v0", 0),
    "random-arm-0": ("WheeledRandomArm-Circle-v0", 0),
    "random-arm-1": ("WheeledRandomArm-Circle-v0", 1),
    "random-arm-2": ("WheeledRandomArm-Circle-v0", 2),
}
#: the tasks pictured in the gallery's paths.png: title -> (env id, reset seed); the Random task's draws are those of
#: dev seeds 0, 1 and 2 (an illustration, not a result)
PATHS: dict[str, tuple[str, int]] = {
    "Circle": ("WheeledPuma-Circle-v0", 0),
    "Line": ("WheeledPuma-Line-v0", 0),
    "Lemniscate": ("WheeledPuma-Lemniscate-v0", 0),
    "Random, seed 0": ("WheeledPuma-Random-v0", 0),
    "Random, seed 1": ("WheeledPuma-Random-v0", 1),
    "Random, seed 2": ("WheeledPuma-Random-v0", 2),
}
#: the controllers page's traces: spec -> its family, in the page's order (one controller per family)
TRACES: dict[str, str] = {
    "nnbc": "the paper's NNBC (model-free)",
    "jmpi": "the paper's JMPI (nominal model)",
    "clik-full": "CLIK (nominal model)",
    "qp": "whole-body QP (nominal model)",
    "calib-qp": "QP calibrating the catalogue",
    "mpc-oracle": "MPC (true model)",
    "rls": "RLS Jacobian (model-free)",
    "nnbc-plus": "nnbc-plus (model-free)",
}
#: points per path in paths.png
PATH_POINTS = 400
#: the gallery's camera: degrees about the vertical and below the horizon
GALLERY_YAW, GALLERY_PITCH = 30.0, -20.0


@dataclass(frozen=True)
class PictureConfig:
    """What one `mobman-eval picture` renders, and where it writes the PNG and its JSON record."""

    out: str = "docs/assets/robot.png"
    """The PNG file to write (its record goes beside it, with the suffix .json)."""
    env: str = DEFAULT_ENV
    """The env id of the episode."""
    policy: str = DEFAULT_POLICY
    """The policy spec that drives the robot (a built-in name, sb3:PATH or module:attr)."""
    seed: int = DEFAULT_SEED
    """The episode's seed (reported seeds start at 10000)."""
    dynamics: str = "physics"
    """The env's dynamics mode: physics (PyBullet contact dynamics) or kinematic."""
    gallery: str | None = None
    """A folder: render the gallery of robots into it (`GALLERY`: one PNG per robot and gallery.json) instead of
    an episode; --out, --env, --policy, --seed and --dynamics are then not used."""
    traces: str | None = None
    """A PNG file: plot the tracking error over one episode of each controller family (`TRACES`) on --env, --seed
    and --dynamics instead of rendering a frame (its record goes beside it, with the suffix .json)."""
    width: int = 960
    """Image width, pixels (64-4096)."""
    height: int = 540
    """Image height, pixels (64-4096)."""

    def command(self) -> str:
        """The command line that renders this picture (or this gallery)."""
        if self.gallery is not None:
            return f"mobman-eval picture --gallery {self.gallery} --width {self.width} --height {self.height}"
        if self.traces is not None:
            return f"mobman-eval picture --traces {self.traces} --env {self.env} --seed {self.seed} --dynamics {self.dynamics}"
        return (
            f"mobman-eval picture --out {self.out} --env {self.env} --policy {self.policy} --seed {self.seed} "
            f"--dynamics {self.dynamics} --width {self.width} --height {self.height}"
        )

    def validate(self) -> None:
        """Raise EvalError naming an `out` that is not a .png file or a size out of range, with the fix."""
        if self.traces is not None and Path(self.traces).suffix.lower() != ".png":
            raise EvalError(
                f"picture: --traces {self.traces!r} must name a .png file, e.g. --traces docs/assets/traces.png"
            )
        if self.gallery is not None and self.traces is not None:
            raise EvalError("picture: give --gallery or --traces, not both (each writes its own pictures)")
        if self.gallery is None and Path(self.out).suffix.lower() != ".png":
            raise EvalError(f"picture: --out {self.out!r} must name a .png file, e.g. --out docs/assets/robot.png")
        low, high = SIZE_RANGE
        for name in ("width", "height"):
            v = getattr(self, name)
            if not low <= v <= high:
                raise EvalError(f"picture: --{name} {v} is out of range; accepted: {low}..{high} pixels")


def _camera(points: np.ndarray, base_xy: np.ndarray) -> tuple[np.ndarray, float]:
    """Where to look and from how far: the middle of the box holding the path, the trace and the platform."""
    pts = np.vstack([points, [base_xy[0], base_xy[1], 0.0], [base_xy[0], base_xy[1], 1.0]])
    target = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    return target, 0.6 + 0.9 * float(np.ptp(pts, axis=0).max())


def render_picture(config: PictureConfig | None = None) -> dict:
    """Run one episode of `config.policy` on `config.env` (seed `config.seed`) and write its last frame, path and
    trace drawn, as the PNG `config.out`; returns the record written beside it (`out` with suffix `.json`)."""
    import pybullet

    from eval.rollout import make_env, make_policy, rollout

    c = config or PictureConfig()
    c.validate()
    out, env_id, policy, seed = Path(c.out), c.env, c.policy, c.seed
    env = make_env(env_id, dynamics=c.dynamics, render_mode="rgb_array")
    try:
        pol = make_policy(policy, env, seed=seed)
        u = env.unwrapped
        wheels: list[np.ndarray] = []  # the platform's trace: the point between the wheels, on the ground

        def on_step(k: int) -> None:
            if k % TRACE_EVERY == 0:
                wheels.append(np.array([*u.state().base_pose[:2], 0.004]))

        rec, arrays = rollout(env, pol, seed=seed, on_step=on_step)
        if arrays is None or rec["status"] != "ok":
            raise EvalError(f"picture: the episode of {policy!r} on {env_id} failed: {rec['error']}")
        trace = arrays["r_a"][::TRACE_EVERY]
        env.render()  # the body where the episode ended (kinematic mode shows the engine's state)
        sim = u.sim
        assert sim is not None
        for pts, rgba in ((trace, [0.95, 0.45, 0.05, 1]), (wheels, [0.2, 0.2, 0.25, 1])):
            shape = sim.client.createVisualShape(pybullet.GEOM_SPHERE, radius=0.009, rgbaColor=rgba)
            for p in pts:
                sim.client.createMultiBody(baseMass=0, baseVisualShapeIndex=shape, basePosition=[float(v) for v in p])
        points = np.vstack([arrays["r_d"], trace, wheels])
        base = u.state().base_pose[:2]
        target, distance = _camera(points, base)
        img = sim.render(target, distance, width=c.width, height=c.height, yaw=CAMERA_YAW, pitch=CAMERA_PITCH)
    finally:
        env.close()
    _write_png(out, img)
    record = {
        "command": c.command(),
        "env": env_id,
        "policy": policy,
        "seed": seed,
        "dynamics": c.dynamics,
        "size": [c.width, c.height],
        "rms_error_mm": round(1000.0 * float(rec["rms_error_m"]), 1),
        "success": bool(rec["success"]),
        "provenance": provenance(),
    }
    atomic_write_json(out.with_suffix(".json"), record)
    return record


def _write_png(path: Path, img: np.ndarray) -> None:
    """`img` (height, width, 3) as an optimised PNG, written atomically."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG", optimize=True)
    atomic_write_bytes(path, buf.getvalue())


def render_robot(env_id: str, seed: int, width: int, height: int) -> np.ndarray:
    """The robot of `env_id` reset with `seed` (kinematic mode), on its platform with the desired path drawn, as
    an RGB image; the camera looks at the middle of the box holding every body but the ground."""
    from eval.rollout import make_env

    env = make_env(env_id, dynamics="kinematic", render_mode="rgb_array")
    try:
        env.reset(seed=seed)
        env.render()  # builds the PyBullet world of the engine's state, path markers included
        sim = env.unwrapped.sim
        c = sim.client
        bodies = [c.getBodyUniqueId(i) for i in range(c.getNumBodies())]
        boxes = [c.getAABB(b, j) for b in bodies if b != sim.plane for j in range(-1, c.getNumJoints(b))]
        lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
        distance = 0.4 + 1.3 * float((hi - lo).max())
        return sim.render(0.5 * (lo + hi), distance, width, height, yaw=GALLERY_YAW, pitch=GALLERY_PITCH)
    finally:
        env.close()


def path_points(env_id: str, seed: int, n: int = PATH_POINTS) -> tuple[np.ndarray, float]:
    """`n` points of the desired path of `env_id`'s episode of `seed` (kinematic mode), evenly in time over the
    whole episode (world frame, m), and the episode's duration (s)."""
    import gymnasium as gym

    env = gym.make(env_id, dynamics="kinematic")
    try:
        env.reset(seed=seed)
        path = env.unwrapped.path  # type: ignore[attr-defined]  # WheeledPumaEnv (the id is one of ours)
        return np.array([path.position(t) for t in np.linspace(0.0, path.duration, n)]), float(path.duration)
    finally:
        env.close()


def render_paths(out: Path) -> None:
    """paths.png: one 3-D panel per task of `PATHS`, the desired path in the world frame with its start marked."""
    import matplotlib.pyplot as plt

    from eval.output.files import atomic_save_figure

    fig = plt.figure(figsize=(10.5, 6.4))
    for i, (title, (env_id, seed)) in enumerate(PATHS.items()):
        pts, duration = path_points(env_id, seed)
        ax = fig.add_subplot(2, 3, i + 1, projection="3d")
        ax.plot(*pts.T, color="tab:green", lw=1.6)
        ax.scatter(*pts[0], color="black", s=18, depthshade=False)
        ax.set_title(f"{title} ({duration:g} s)", fontsize=10)
        extent = np.maximum(np.ptp(pts, axis=0), 0.3 * np.ptp(pts, axis=0).max())  # a line gets a visible box
        centre = (pts.max(axis=0) + pts.min(axis=0)) / 2
        ax.set_xlim(centre[0] - extent[0] / 2, centre[0] + extent[0] / 2)
        ax.set_ylim(centre[1] - extent[1] / 2, centre[1] + extent[1] / 2)
        ax.set_zlim(centre[2] - extent[2] / 2, centre[2] + extent[2] / 2)
        ax.set_box_aspect(extent)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("x (m)", fontsize=8)
        ax.set_ylabel("y (m)", fontsize=8)
        ax.set_zlabel("z (m)", fontsize=8)
    fig.suptitle("The desired end-effector paths (PUMA 560; start marked in black)", fontsize=11)
    fig.tight_layout()
    atomic_save_figure(fig, out, dpi=90)
    plt.close(fig)


def render_traces(config: PictureConfig, traces: dict[str, str] | None = None, **env_kwargs: Any) -> dict:
    """Run one episode of each controller of `traces` (default `TRACES`) on `config.env` (seed `config.seed`,
    `config.dynamics`, `env_kwargs`), plot each one's tracking error (mm, log scale) against time into the PNG
    `config.traces`, and write the record beside it (its `.json`); returns the record. A failed episode is
    recorded as failed and left out of the plot."""
    import matplotlib.pyplot as plt

    from eval.metrics import DEFAULT_TOLERANCE
    from eval.output.files import atomic_save_figure
    from eval.output.styles import color_of, linestyle_of, tolerance_line
    from eval.rollout import make_env, make_policy, rollout

    assert config.traces is not None
    out = Path(config.traces)
    traces = TRACES if traces is None else traces
    fig, ax = plt.subplots(figsize=(9.0, 4.6))
    episodes = {}
    for spec, family in traces.items():
        env = make_env(config.env, dynamics=config.dynamics, env_kwargs=env_kwargs)
        try:
            rec, arrays = rollout(env, make_policy(spec, env, seed=config.seed), seed=config.seed)
        finally:
            env.close()
        episodes[spec] = {"family": family, "status": rec["status"], "max_error_mm": None}
        if arrays is None or rec["status"] != "ok":
            continue
        err_mm = np.maximum(1e3 * arrays["error"], 1e-4)  # log axis: an exact zero shows at 0.1 um
        episodes[spec]["max_error_mm"] = round(float(err_mm.max()), 4)
        ax.semilogy(arrays["t"], err_mm, color=color_of(spec), ls=linestyle_of(spec), lw=1.2, label=f"{spec}: {family}")
    tolerance_line(ax, DEFAULT_TOLERANCE)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tracking error (mm)")
    ax.set_title(f"{config.env}, {config.dynamics}, seed {config.seed}: one episode per controller family", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    atomic_save_figure(fig, out, dpi=90)
    plt.close(fig)
    record = {
        "command": config.command(),
        "env": config.env,
        "seed": config.seed,
        "dynamics": config.dynamics,
        "env_kwargs": env_kwargs,
        "episodes": episodes,
        "provenance": provenance(),
    }
    atomic_write_json(out.with_suffix(".json"), record)
    return record


def render_gallery(config: PictureConfig) -> dict:
    """Write one PNG per robot of `GALLERY` into `config.gallery` (`config.width` x `config.height`) and
    gallery.json beside them; returns that record."""
    config.validate()
    assert config.gallery is not None
    folder = Path(config.gallery)
    for stem, (env_id, seed) in GALLERY.items():
        _write_png(folder / f"{stem}.png", render_robot(env_id, seed, config.width, config.height))
    render_paths(folder / "paths.png")
    record = {
        "command": config.command(),
        "robots": {stem: {"env": env_id, "seed": seed} for stem, (env_id, seed) in GALLERY.items()},
        "paths": {title: {"env": env_id, "seed": seed} for title, (env_id, seed) in PATHS.items()},
        "size": [config.width, config.height],
        "provenance": provenance(),
    }
    atomic_write_json(folder / "gallery.json", record)
    return record

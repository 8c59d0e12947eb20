"""`--video`: re-run episode 0 of each policy (first env and dynamics mode) with `render_mode="rgb_array"`.

The video episode is a separate rollout through the same loop (`eval.rollout.rollout`), so the reported
results never depend on rendering. Frames are taken every `round(control_freq / render_fps)` control steps,
so the video plays in real time at the env's `metadata["render_fps"]`. MP4 (H.264 through imageio-ffmpeg)
when available, else an animated GIF.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from eval.output.files import atomic_write_bytes, slug
from eval.rollout import make_env, make_policy, rollout


def frame_stride(control_freq: float, render_fps: float) -> int:
    """Control steps per video frame (>= 1) so that the video plays at about `render_fps` in real time."""
    return max(1, int(round(control_freq / render_fps)))


def encode(frames: list[np.ndarray], path_stem: Path, fps: float) -> Path:
    """Write `frames` as `<stem>.mp4` (imageio-ffmpeg) or, failing that, `<stem>.gif`; returns the path."""
    import imageio.v2 as imageio

    try:
        import imageio_ffmpeg  # noqa: F401

        path = path_stem.with_suffix(".mp4")
        tmp = path.with_name(f".{path.name}.tmp.mp4")
        with imageio.get_writer(tmp, fps=fps, codec="libx264", quality=7, macro_block_size=8) as w:
            for f in frames:
                w.append_data(f)
        tmp.replace(path)
        return path
    except ImportError:
        import io

        path = path_stem.with_suffix(".gif")
        buf = io.BytesIO()
        imageio.mimsave(buf, frames, format="GIF", duration=1.0 / fps, loop=0)
        atomic_write_bytes(path, buf.getvalue())
        return path


def record_episode(
    env_id: str, name: str, user: dict, seed: int, config, dynamics: str
) -> tuple[list[np.ndarray], float, dict]:
    """Frames of one episode of policy `name` (a spec, or a key of `user`), the frame rate, and its record."""

    env = make_env(env_id, dynamics, config.model_error, config.obs_noise, config.env_kwargs, render_mode="rgb_array")
    try:
        # built on this env: the oracle reads the true robot of the env it was made with
        policy = user[name] if name in user else make_policy(name, env, config.seed)
        base = env.unwrapped
        fps = float(env.metadata.get("render_fps", 25))
        stride = frame_stride(base.control_freq, fps)
        frames: list[np.ndarray] = []

        def grab(k: int) -> None:
            if k % stride == 0:
                frames.append(env.render())

        rec, _ = rollout(env, policy, seed, tolerance=config.tolerance, on_step=grab)
        return frames, base.control_freq / stride, rec
    finally:
        env.close()


def write_videos(result, config, user: dict) -> list[Path]:
    """One video per policy: episode 0 of the first env and dynamics mode, into `<out>/videos/`."""
    env_id, dyn = config.envs[0], config.dynamics[0]
    written = []
    for name in list(config.policies) + list(user):
        frames, fps, _ = record_episode(env_id, name, user, config.seed, config, dyn)
        if frames:
            stem = Path(result.out) / "videos" / f"{slug(env_id)}_{dyn}_{slug(name)}_seed{config.seed}"
            stem.parent.mkdir(parents=True, exist_ok=True)
            written.append(encode(frames, stem, fps))
    return written

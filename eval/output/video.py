"""`--video`: re-run episode 0 of each policy (first env and dynamics mode) with `render_mode="rgb_array"`.

The video episode is a separate rollout through the same loop (`eval.rollout.rollout`), so the reported
results never depend on rendering. The video plays in real time: frames are taken every `stride =
round(control_freq / fps)` control steps, with `fps = min(env.metadata["render_fps"], MAX_FPS)`, and written
at `control_freq / stride` frames per second. MP4 (H.264) when imageio and imageio-ffmpeg are installed
(`pip install "mobman[video]"`), else an animated GIF through Pillow (a dependency of matplotlib). A progress
bar on stderr counts the policies.
"""

from __future__ import annotations

import importlib.util
import io
from pathlib import Path

import numpy as np

from eval.errors import EvalError
from eval.output.files import atomic_write_bytes, slug
from eval.output.progress import progress_bar
from eval.rollout import make_env, make_policy, rollout

#: Highest frame rate written, 1/s: an env rendering at its control rate (100 Hz) gives a 25 fps video (GIF
#: frame times are whole centiseconds, and players drop frames beyond ~50 fps).
MAX_FPS = 25.0


def video_format() -> str:
    """ "mp4" (imageio + imageio-ffmpeg) or "gif" (Pillow); EvalError before any rollout if neither is there."""
    if importlib.util.find_spec("imageio") is not None and importlib.util.find_spec("imageio_ffmpeg") is not None:
        return "mp4"
    if importlib.util.find_spec("PIL") is not None:
        return "gif"
    raise EvalError('--video needs imageio and imageio-ffmpeg (pip install "mobman[video]") or Pillow; drop --video')


def frame_stride(control_freq: float, render_fps: float) -> int:
    """Control steps per video frame (>= 1) so that the video plays at about `min(render_fps, MAX_FPS)` frames
    per second in real time."""
    return max(1, int(round(control_freq / min(render_fps, MAX_FPS))))


def encode(frames: list[np.ndarray], path_stem: Path, fps: float) -> Path:
    """Write `frames` as `<stem>.mp4` (imageio-ffmpeg) or, failing that, `<stem>.gif` (Pillow) at `fps`
    frames per second; returns the path. The suffix is appended (a stem may hold dots, e.g. gamma-0.5)."""
    path_stem = Path(path_stem)
    if video_format() == "mp4":
        import imageio.v2 as imageio

        path = path_stem.with_name(path_stem.name + ".mp4")
        tmp = path.with_name(f".{path.name}.tmp.mp4")
        w = imageio.get_writer(tmp, fps=fps, codec="libx264", quality=7, macro_block_size=8)
        with w:  # (imageio's stub types `with ... as w` as the base class, which has no append_data)
            for f in frames:
                w.append_data(f)
        tmp.replace(path)
        return path
    from PIL import Image

    path = path_stem.with_name(path_stem.name + ".gif")
    images = [Image.fromarray(np.asarray(f, dtype=np.uint8)) for f in frames]
    buf = io.BytesIO()
    images[0].save(
        buf, format="GIF", save_all=True, append_images=images[1:], duration=int(round(1000.0 / fps)), loop=0
    )
    atomic_write_bytes(path, buf.getvalue())
    return path


def video_name(env_id: str, dynamics: str, policy: str, seed: int) -> str:
    """The file name (without suffix) of a policy's video: readable and distinct for distinct specs
    (`nnbc:gamma=0.5` -> `nnbc-gamma=0.5`; `:` `/` and other characters become `-`)."""
    readable = "".join(c if c.isalnum() or c in "-_.=" else "-" for c in policy)
    return f"{slug(env_id)}_{dynamics}_{readable}_seed{seed}"


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
    names = list(config.policies) + list(user)
    written = []
    bar = progress_bar(len(names), "videos", "video", config.progress)
    try:
        for name in names:
            if bar is not None:
                bar.set_postfix_str(name, refresh=True)
            frames, fps, _ = record_episode(env_id, name, user, config.seed, config, dyn)
            if frames:
                stem = Path(result.out) / "videos" / video_name(env_id, dyn, name, config.seed)
                stem.parent.mkdir(parents=True, exist_ok=True)
                written.append(encode(frames, stem, fps))
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    return written

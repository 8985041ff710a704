"""Videos of episodes: one episode's frames (:func:`episode_frames`), written as GIF or MP4 by
imageio (:func:`write_video`; the ``render`` extra), and :class:`RecordStrokeVideo`, gymnasium's
``RecordVideo`` keeping every frame of a firing.

Gymnasium's ``RecordVideo`` calls ``env.render()`` after every step; given a list (the
``rgb_array_list`` mode), gymnasium 1.x records only its last frame (the others are handed back
by a later ``render()``). :class:`RecordStrokeVideo` records them all. Without it, save the
frames of ``rgb_array_list`` with ``gymnasium.utils.save_video.save_video`` (moviepy) or
:func:`write_video`.
"""
from __future__ import annotations

import math
import os
import secrets
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium.wrappers import RecordVideo

EXTRA = 'pip install "microconveyor-env[render]"'
FORMATS = (".gif", ".mp4")
# frames per second a video may play at, both formats: a GIF stores each frame's delay in whole
# centiseconds (Pillow truncates), so 100 fps is its fastest (faster rounds the delay to 0: a
# video of no length) and 655 s its longest delay; one frame every 10 s is slower than anyone
# watches an animation
FPS_RANGE = (0.1, 100.0)


class RecordStrokeVideo(RecordVideo):
    """``gymnasium.wrappers.RecordVideo`` that records every frame ``render()`` returns: for an
    env made with ``render_mode="rgb_array_list"`` and ``render_frames_per_stroke`` > 1, the
    frames during each firing (gymnasium's records only the last of each list). Same arguments
    and files as ``RecordVideo`` (it needs moviepy); ``fps`` defaults to the env's
    ``metadata["render_fps"]``."""

    def _capture_frame(self) -> None:
        if not str(self.env.render_mode).endswith("_list"):
            super()._capture_frame()
            return
        frames = self.env.render()
        if not isinstance(frames, list):
            raise TypeError(f"render() returned {type(frames).__name__} in a list render mode")
        self.render_history += frames  # as RecordVideo: a later render() still returns them
        self.recorded_frames += frames


def episode_frames(env: Any, act: Callable[[np.ndarray], np.ndarray], target: float,
                   seed: int = 0) -> tuple[list[np.ndarray], dict[str, Any]]:
    """One episode of ``env`` (``render_mode="rgb_array_list"``) to ``target`` [m] with actions
    ``act(observation)``: its frames and a summary (SI units)."""
    obs, _ = env.reset(seed=seed, options={"target": float(target)})
    frames: list[np.ndarray] = list(env.render())
    total, firings, info = 0.0, 0, {}
    while True:
        obs, reward, terminated, truncated, info = env.step(act(obs))
        frames += env.render()
        total += float(reward)
        firings += 1
        if terminated or truncated:
            break
    u = env.unwrapped
    return frames, {"target_m": float(target), "outcome": info["outcome"],
                    "is_success": bool(info["is_success"]),
                    "position_error_m": float(info["position_error_m"]),
                    "final_position_m": u.x, "sim_time_s": float(info["sim_time_s"]),
                    "firings": firings, "return": total}


def check_video_path(path: str | Path) -> Path:
    """A ``.gif`` or ``.mp4`` file name (the format follows the suffix)."""
    p = Path(path)
    if p.suffix.lower() not in FORMATS:
        raise ValueError(f"{str(path)!r}: the video's name must end in .gif or .mp4 (the format "
                         "follows the suffix)")
    if p.is_dir():
        raise ValueError(f"{str(path)!r} is a folder; give a file name ending in .gif or .mp4")
    return p


def check_writer(path: str | Path) -> Path:
    """The video path (:func:`check_video_path`), once its writer is known to be installed:
    imageio, and for MP4 imageio-ffmpeg (else ``ModuleNotFoundError`` naming the extra)."""
    p = check_video_path(path)
    needs = ["imageio"] + (["imageio_ffmpeg"] if p.suffix.lower() == ".mp4" else [])
    for name in needs:
        try:
            __import__(name)
        except ImportError as exc:
            raise ModuleNotFoundError(f"writing a {p.suffix[1:].upper()} needs "
                                      f"{name.replace('_', '-')}: {EXTRA}", name=name) from exc
    return p


def check_fps(fps: object) -> float:
    """``fps`` [1/s] as a float if it is a number in :data:`FPS_RANGE`, else ValueError."""
    lo, hi = FPS_RANGE
    x = float(fps) if isinstance(fps, (int, float, np.number)) else math.nan
    if not lo <= x <= hi:  # NaN too
        raise ValueError(f"fps = {fps!r} is invalid: must be in [{lo:g}, {hi:g}] frames per "
                         "second (a GIF stores whole centiseconds per frame)")
    return x


def write_video(frames: Sequence[np.ndarray], path: str | Path, fps: float) -> Path:
    """Write ``frames`` (uint8 (H, W, 3)) to ``path``: GIF (looping) or MP4 (H.264, yuv420p)
    by its suffix, ``fps`` frames per second (:data:`FPS_RANGE`). The video is written to a
    temporary file beside ``path`` and renamed to it once whole: a failed write leaves an
    existing file as it was and no partial one. Needs imageio (+ imageio-ffmpeg for MP4: the
    ``render`` extra)."""
    p = check_writer(path)
    if not frames:
        raise ValueError("no frames to write")
    fps = check_fps(fps)
    import imageio.v2 as iio2
    import imageio.v3 as iio

    p.parent.mkdir(parents=True, exist_ok=True)
    stack = np.stack(frames)
    # same folder (the rename is atomic), same suffix (the writer picks the format by it)
    tmp = p.with_name(f".{p.stem}.{secrets.token_hex(4)}.partial{p.suffix}")
    try:
        if p.suffix.lower() == ".gif":
            iio.imwrite(tmp, stack, extension=".gif", duration=1000.0 / fps, loop=0)
        else:
            stack = stack[:, : stack.shape[1] // 2 * 2, : stack.shape[2] // 2 * 2]  # even sizes
            with iio2.get_writer(tmp, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                 pixelformat="yuv420p", macro_block_size=1) as writer:
                for frame in stack:
                    writer.append_data(frame)  # type: ignore[attr-defined]
        os.replace(tmp, p)
    finally:
        tmp.unlink(missing_ok=True)
    return p

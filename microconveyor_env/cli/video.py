"""The env part of ``microconveyor video`` (the command: :mod:`agents.cli.video`, which adds
``--policy``): its options, the actor of a fixed schedule and a GIF or MP4 of one episode, the
part on the deforming surface during every stroke and slide."""
from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from .base import count

DEFAULT_FRAMES = 8
SCHEDULE = {"freq": ([950.0], "Hz"), "stroke": ([200e-6], "m"), "delay": ([0.0], "s")}


def video_file(text: str) -> str:
    """``--out``: a file name ending in .gif or .mp4."""
    from ..envs.core.video import check_video_path

    try:
        return str(check_video_path(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def frames_per_second(text: str) -> float:
    """``--fps``: a number in :data:`..envs.video.FPS_RANGE`, checked before any work."""
    from ..envs.core.video import FPS_RANGE, check_fps

    try:
        return check_fps(float(text))
    except ValueError:
        lo, hi = FPS_RANGE
        raise argparse.ArgumentTypeError(f"must be a number of frames per second in "
                                         f"[{lo:g}, {hi:g}], got {text}") from None


def number_list(text: str) -> list[float]:
    """A comma list of finite numbers >= 0."""
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give a number or a comma list") from None
    if not vals or not all(math.isfinite(v) and v >= 0 for v in vals):
        raise argparse.ArgumentTypeError(f"{text!r}: give finite numbers >= 0")
    return vals


def video_args(p: argparse.ArgumentParser) -> None:
    """The options of the episode and its video: ``--out``, ``--target``, ``--frames-per-stroke``,
    ``--fps``, ``--seed``."""
    from ..envs.line.frames import MAX_FRAMES_PER_STROKE
    from ..envs.core.video import FPS_RANGE

    p.add_argument("--out", type=video_file, default="episode.gif",
                   help="the video: .gif or .mp4, the format by the suffix (default: episode.gif)")
    p.add_argument("--target", type=float, default=1e-3,
                   help="target [m] beyond actuator 1 (default: 1e-3)")
    p.add_argument("--frames-per-stroke", type=count(1, MAX_FRAMES_PER_STROKE),
                   default=DEFAULT_FRAMES,
                   help=f"frames per phase of a firing: the stroke, the slide after it "
                        f"(default: {DEFAULT_FRAMES}; 1: one frame per firing)")
    p.add_argument("--fps", type=frames_per_second, default=None,
                   help=f"frames per second, in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}] (default: "
                        f"the env's render_fps, 4 x frames per stroke: each phase lasts 1/4 s; "
                        f"at most {FPS_RANGE[1]:g})")
    p.add_argument("--seed", type=int, default=0, help="the episode's seed (its start jitter)")


def schedule_args(p: argparse.ArgumentParser) -> None:
    """``--freq``, ``--stroke``, ``--delay``: the fixed schedule, one value per firing."""
    for name, (default, unit) in SCHEDULE.items():
        p.add_argument(f"--{name}", type=number_list, default=None, metavar="V[,V...]",
                       help=f"the schedule's {name} [{unit}], one value per firing (the last "
                            f"repeats) (default: {default[0]:g})")


def schedule_actor(args: argparse.Namespace, config: Any) -> tuple[Callable[[Any], Any],
                                                                    dict[str, Any]]:
    """``act(env) -> (observation -> action)`` firing the schedule of ``--freq/--stroke/--delay``
    (checked against the env's ranges: the env would clip), and the schedule (SI)."""
    from ..envs.core.actions import encode_actions

    values = {k: getattr(args, k) or d for k, (d, _) in SCHEDULE.items()}
    ranges = {"freq": config.freq_range, "stroke": config.stroke_range,
              "delay": config.delay_range}
    for key, vals in values.items():
        lo, hi = ranges[key]
        bad = [v for v in vals if not lo <= v <= hi]
        if bad:
            raise ValueError(f"--{key} {bad[0]:g} is outside the env's range [{lo:g}, {hi:g}] "
                             f"{SCHEDULE[key][1]}")
    n = config.n_actuators
    per = {k: [v[min(i, len(v) - 1)] for i in range(n)] for k, v in values.items()}
    acts = encode_actions(per["freq"], per["stroke"], per["delay"], config)

    def act(env: Any) -> Callable[[Any], Any]:
        return lambda _obs: acts[env.unwrapped.fired]

    return act, {"frequency_hz": per["freq"], "stroke_m": per["stroke"], "delay_s": per["delay"]}


def make_video(args: argparse.Namespace, config: Any, act: Callable[[Any], Any],
               **about: Any) -> dict[str, Any]:
    """One episode of the env ``config`` to ``--target`` with ``act(env)``'s actions, written to
    ``--out``; the summary (SI, unit-suffixed keys), with ``about`` (what acted)."""
    from pathlib import Path

    from ..envs import MicroConveyorEnv
    from ..envs.core.video import FPS_RANGE, check_writer, episode_frames, write_video

    check_writer(args.out)  # a missing writer fails before the episode is drawn
    env = MicroConveyorEnv(config=config, render_mode="rgb_array_list",
                           render_frames_per_stroke=args.frames_per_stroke)
    try:
        frames, episode = episode_frames(env, act(env), args.target, seed=args.seed)
    finally:
        env.close()
    fps = float(args.fps or min(env.metadata["render_fps"], FPS_RANGE[1]))
    path = write_video(frames, args.out, fps)
    return {"video": str(path), "format": path.suffix[1:].lower(), "frames": len(frames),
            "fps": fps, "duration_s": len(frames) / fps, "bytes": Path(path).stat().st_size,
            "frame_size_px": list(np.shape(frames[0])[1::-1]),
            "frames_per_stroke": args.frames_per_stroke, **about, **episode}


def video_text(r: dict[str, Any]) -> str:
    """The summary in the units people read."""
    w, h = r["frame_size_px"]
    return (f"wrote {r['video']}: {r['frames']} frames of {w}x{h} px at {r['fps']:g} fps "
            f"({r['duration_s']:.1f} s), {r['bytes'] / 1024:.0f} kB\n"
            f"{r['env_id']}, {r['actor']}: target {r['target_m'] * 1e3:.3f} mm, {r['outcome']} "
            f"after {r['firings']} firing(s) at {r['final_position_m'] * 1e3:.3f} mm (error "
            f"{r['position_error_m'] * 1e6:+.0f} µm), {r['sim_time_s'] * 1e3:.2f} ms simulated")

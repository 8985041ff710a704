"""The ``microconveyor video`` command: an episode of a fixed schedule (its options and writer:
:mod:`microconveyor_env.cli.video`) or, with ``--policy``, of a policy folder; on the plane
(MicroConveyor2D-v0) and the positioner (MicroPositioner-v0) an episode of a policy, one frame
per firing."""
from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np

from microconveyor_env.cli.base import command, emit
from microconveyor_env.cli.video import make_video, schedule_actor, schedule_args, video_args, \
    video_text
from microconveyor_env.env_ids import DEFAULT_ENV_ID, PLANE_ENV_IDS, POSITIONER_ENV_IDS

from .args import add_env_args, env_config_of, env_kwargs_of


def _video_args(p: argparse.ArgumentParser) -> None:
    video_args(p)
    p.add_argument("--target-y", type=float, default=None,
                   help="MicroConveyor2D-v0: the target's y [m] (--target is its x; default: "
                        "the middle of the grid's y range)")
    p.add_argument("--policy", default=None,
                   help="policy folder (e.g. agents/policies/MicroConveyor-v1/ppo, or 'shipped': "
                        "the default policy shipped for --env); without it, the fixed schedule "
                        "of --freq/--stroke/--delay")
    schedule_args(p)
    add_env_args(p, default=None,
                 default_text=f"the policy's env; without a policy {DEFAULT_ENV_ID}",
                 what=" (with --policy: must be the policy's scene; MicroConveyor2D-v0 and "
                      "MicroPositioner-v0: a policy only, one frame per firing)")


@command("video", "a GIF or MP4 of one episode of a policy (--policy) or a fixed schedule: the "
                  "part on the deforming surface during every stroke and slide", _video_args)
def cmd_video(args: argparse.Namespace) -> None:
    if args.policy is None:
        if args.env in PLANE_ENV_IDS or args.env in POSITIONER_ENV_IDS:
            raise ValueError(f"{args.env} has no fixed schedule to film: give --policy (shipped: "
                             "its shipped policy)")
        if args.target_y is not None:
            raise ValueError("--target-y is the plane's (MicroConveyor2D-v0, with --policy)")
        config = env_config_of(args)
        act, schedule = schedule_actor(args, config)
        result = make_video(args, config, act, env_id=args.env or DEFAULT_ENV_ID,
                            env_kwargs=env_kwargs_of(args), actor="fixed schedule",
                            schedule=schedule)
    else:
        if any(getattr(args, k) is not None for k in ("freq", "stroke", "delay")):
            raise ValueError("--freq/--stroke/--delay give a schedule: not with --policy")
        result = _policy_video(args)
    emit(args, result, (firing_video_text if result.get("per_firing") else video_text)(result))


def _policy_video(args: argparse.Namespace) -> dict[str, Any]:
    from ..rl.evaluation.evaluate import load_policy
    from ..rl.artefacts.policy_files import read_policy_meta
    from ..rl.artefacts.shipped import require_shipped

    path = args.policy
    if path == "shipped":
        path = str(require_shipped(args.env or DEFAULT_ENV_ID))
    env_id = args.env or str(read_policy_meta(path).get("env_id", DEFAULT_ENV_ID))
    if env_id in PLANE_ENV_IDS or env_id in POSITIONER_ENV_IDS:
        return _firing_video(args, path, env_id)
    if args.target_y is not None:
        raise ValueError(f"--target-y is the plane's (MicroConveyor2D-v0); {env_id} is the line")
    asked = env_config_of(args, default=env_id) if args.env or args.env_kwargs else None
    policy = load_policy(path, config=asked)  # another scene than the policy's is refused
    config = asked or policy.config or env_config_of(args, default=env_id)

    def act(_env: Any) -> Callable[[np.ndarray], np.ndarray]:
        return lambda obs: np.asarray(policy.act(obs[None]))[0]

    kwargs = env_kwargs_of(args) if asked is not None else policy.metadata.get("env_kwargs")
    return make_video(args, config, act, env_id=env_id, env_kwargs=kwargs or {},
                      actor=f"policy {path}", policy=str(path))


def _firing_video(args: argparse.Namespace, path: str, env_id: str) -> dict[str, Any]:
    """One episode of the policy at ``path`` on a scene that renders one frame per firing (the
    plane: to (``--target``, ``--target-y``); the positioner: to ``--target``), one frame after
    the reset and after each firing; the summary (SI, unit-suffixed keys)."""
    import importlib
    from pathlib import Path

    from microconveyor_env.env_ids import ENTRY_POINTS
    from microconveyor_env.envs.core.video import FPS_RANGE, check_writer, write_video
    from microconveyor_env.envs.core.versions import config_class, scene_config

    from ..rl.artefacts.policy_files import policy_env_kwargs, read_policy_meta
    from ..rl.evaluation.evaluate import load_policy

    check_writer(args.out)
    plane = env_id in PLANE_ENV_IDS
    if args.target_y is not None and not plane:
        raise ValueError(f"--target-y is the plane's (MicroConveyor2D-v0); {env_id} is a line")
    meta = read_policy_meta(path)
    kwargs = {**policy_env_kwargs(meta), **env_kwargs_of(args)}
    cls = config_class(env_id)
    asked = scene_config(env_id, **kwargs) if args.env or args.env_kwargs else None
    policy = load_policy(path, asked)   # a policy of another scene is refused
    cfg = asked or policy.config
    if not isinstance(cfg, cls):
        raise ValueError(f"{path!r} is not a policy of {env_id} (its metadata says "
                         f"{meta.get('env_id')!r})")
    target: Any = float(args.target)
    if plane:
        from microconveyor_env.envs.plane.config import PlaneEnvConfig

        assert isinstance(cfg, PlaneEnvConfig)
        (y0, y1) = cfg.grid_box[1]
        target = (target, (y0 + y1) / 2 if args.target_y is None else float(args.target_y))
    module, name = ENTRY_POINTS[env_id].split(":")
    env = getattr(importlib.import_module(module), name)(render_mode="rgb_array", config=cfg)
    obs, _ = env.reset(seed=args.seed, options={"target": target})
    frames: list[np.ndarray] = [np.asarray(env.render())]
    total, firings = 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(np.asarray(policy.act(obs[None]))[0])
        frames.append(np.asarray(env.render()))
        total += float(reward)
        firings += 1
        if terminated or truncated:
            break
    fps = float(args.fps or min(env.metadata["render_fps"], FPS_RANGE[1]))
    out = write_video(frames, args.out, fps)
    where: dict[str, Any] = (
        {"target_m": list(target), "distance_m": float(info["distance_m"]),
         "final_position_m": [env.x, env.y]} if plane else
        {"target_m": target, "position_error_m": float(info["position_error_m"]),
         "final_position_m": env.x})
    return {"video": str(out), "format": out.suffix[1:].lower(), "frames": len(frames),
            "fps": fps, "duration_s": len(frames) / fps, "bytes": Path(out).stat().st_size,
            "frame_size_px": list(np.shape(frames[0])[1::-1]), "frames_per_stroke": 1,
            "per_firing": True, "plane": plane, "env_id": env_id,
            "env_kwargs": policy_env_kwargs(policy.metadata), "actor": f"policy {path}",
            "policy": str(path), **where, "outcome": info["outcome"],
            "is_success": bool(info["is_success"]), "sim_time_s": float(info["sim_time_s"]),
            "firings": firings, "return": total}


def firing_video_text(r: dict[str, Any]) -> str:
    """The summary of a video of one frame per firing in the units people read."""
    w, h = r["frame_size_px"]
    if not r["plane"]:
        return (f"wrote {r['video']}: {r['frames']} frames of {w}x{h} px at {r['fps']:g} fps "
                f"({r['duration_s']:.1f} s), {r['bytes'] / 1024:.0f} kB\n"
                f"{r['env_id']}, {r['actor']}: target {r['target_m'] * 1e3:.3f} mm, "
                f"{r['outcome']} after {r['firings']} firing(s) at "
                f"{r['final_position_m'] * 1e3:.3f} mm (error "
                f"{r['position_error_m'] * 1e6:+.0f} µm), {r['sim_time_s'] * 1e3:.2f} ms "
                "simulated")
    tx, ty = r["target_m"]
    x, y = r["final_position_m"]
    return (f"wrote {r['video']}: {r['frames']} frames of {w}x{h} px at {r['fps']:g} fps "
            f"({r['duration_s']:.1f} s), {r['bytes'] / 1024:.0f} kB\n"
            f"{r['env_id']}, {r['actor']}: target ({tx * 1e3:.3f}, {ty * 1e3:.3f}) mm, "
            f"{r['outcome']} after {r['firings']} firing(s) at ({x * 1e3:.3f}, {y * 1e3:.3f}) mm "
            f"(distance {r['distance_m'] * 1e6:.0f} µm), {r['sim_time_s'] * 1e3:.2f} ms simulated")

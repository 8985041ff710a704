"""The ``microconveyor video`` command: the env package's (a fixed schedule) plus ``--policy``, an
episode of a policy folder (replaces the env package's command, as ``demo`` does)."""
from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any

import numpy as np

from microconveyor_env.cli.base import command, emit
from microconveyor_env.cli.video import make_video, schedule_actor, schedule_args, video_args, \
    video_text

from .args import add_env_args, env_config_of, env_kwargs_of


def _video_args(p: argparse.ArgumentParser) -> None:
    video_args(p)
    p.add_argument("--policy", default=None,
                   help="policy folder (e.g. agents/policies/MicroConveyor-v0/ppo, or 'shipped': "
                        "the PPO policy shipped for --env); without it, the fixed schedule of "
                        "--freq/--stroke/--delay")
    schedule_args(p)
    add_env_args(p, default=None, default_text="the policy's env; without a policy "
                 "MicroConveyor-v1", what=" (with --policy: must be the policy's scene)")


@command("video", "a GIF or MP4 of one episode of a policy (--policy) or a fixed schedule: the "
                  "part on the deforming surface during every stroke and slide", _video_args)
def cmd_video(args: argparse.Namespace) -> None:
    from microconveyor_env.envs import LATEST

    if args.policy is None:
        config = env_config_of(args, default=LATEST)
        act, schedule = schedule_actor(args, config)
        result = make_video(args, config, act, env_id=args.env or LATEST,
                            env_kwargs=env_kwargs_of(args), actor="fixed schedule",
                            schedule=schedule)
    else:
        if any(getattr(args, k) is not None for k in ("freq", "stroke", "delay")):
            raise ValueError("--freq/--stroke/--delay give a schedule: not with --policy")
        result = _policy_video(args)
    emit(args, result, video_text(result))


def _policy_video(args: argparse.Namespace) -> dict[str, Any]:
    from ..rl.evaluation.evaluate import load_policy
    from ..rl.artefacts.policy_files import read_policy_meta
    from ..rl.artefacts.shipped import DEFAULT_ENV_ID, require_shipped

    path = args.policy
    if path == "shipped":
        path = str(require_shipped(args.env or DEFAULT_ENV_ID))
    env_id = args.env or str(read_policy_meta(path).get("env_id", DEFAULT_ENV_ID))
    asked = env_config_of(args, default=env_id) if args.env or args.env_kwargs else None
    policy = load_policy(path, config=asked)  # another scene than the policy's is refused
    config = asked or policy.config or env_config_of(args, default=env_id)

    def act(_env: Any) -> Callable[[np.ndarray], np.ndarray]:
        return lambda obs: np.asarray(policy.act(obs[None]))[0]

    kwargs = env_kwargs_of(args) if asked is not None else policy.metadata.get("env_kwargs")
    return make_video(args, config, act, env_id=env_id, env_kwargs=kwargs or {},
                      actor=f"policy {path}", policy=str(path))

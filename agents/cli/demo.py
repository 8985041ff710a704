"""The ``microconveyor demo`` command: the physics and env parts
(:mod:`microconveyor_env.cli.demo`: a contact report, a firing, a frequency sweep, an episode of a
fixed schedule) and the env's default shipped policy carrying a part to targets across its range,
with a GIF of one long carry."""
from __future__ import annotations

import argparse
import sys

from microconveyor_env.cli.base import command, emit
from microconveyor_env.env_ids import DEFAULT_ENV_ID

from .args import add_env_args, env_kwargs_of, floats, scene_config_of, target_point


def _demo_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="out", help="output folder for charts, the GIF and the "
                                                "summary JSON")
    p.add_argument("--policy", default=None,
                   help="policy folder (default: the one shipped for --env by default, if any)")
    p.add_argument("--targets", type=floats, default=None, metavar="M[,M...]",
                   help="the policy's targets [m], in the env's target range: lo:hi:step or a "
                        "comma list (default: the range's low end and every whole mm up to its "
                        "top; MicroConveyor-v1: 0.5, 1, 2, ..., 10 mm); on the plane x,y pairs "
                        "in a comma list, x1,y1,x2,y2,... (default: 3 x 3 points of the "
                        "actuator grid's box but the start)")
    p.add_argument("--gif-target", type=target_point, default=None, metavar="M|X,Y",
                   help="the target [m] of the policy's episode written as carry.gif to --out "
                        "(default: 0.9 x the top of the env's target range, 9 mm on "
                        "MicroConveyor-v1; on the plane X,Y, default 5/6 and 1/6 of the grid's "
                        "box; 0: no GIF)")
    add_env_args(p,
                 what=" of the episode and the policy: the line's, the positioner or the plane "
                      "(its surface, --preset included, also for the contact, firing and sweep "
                      "charts)")


@command("demo", "the main job: contact report, a firing, a frequency sweep, an env episode and "
                 "the env's default shipped policy on targets across its range (a table, "
                 "charts and a GIF of a long carry), written to --out", _demo_args)
def cmd_demo(args: argparse.Namespace) -> None:
    import importlib.util
    import json
    from pathlib import Path

    from microconveyor_env.cli.base import json_default
    from microconveyor_env.cli.demo import demo_summary, demo_text

    from ..experiments.place import check_target, geometry_of

    env_id = args.env or DEFAULT_ENV_ID
    args.env_kwargs_dict = env_kwargs_of(args)
    cfg = scene_config_of(args)
    plane = geometry_of(cfg) == "plane"
    targets = args.targets
    if targets is not None:
        if plane:
            if len(targets) % 2:
                raise ValueError(f"--targets on {env_id} are x,y pairs: give an even count of "
                                 "numbers, x1,y1,x2,y2,...")
            targets = [tuple(targets[i:i + 2]) for i in range(0, len(targets), 2)]
        try:
            targets = [check_target(t, cfg, env_id) for t in targets]
        except ValueError as exc:
            raise ValueError(str(exc).replace("--target ", "--targets: ", 1)) from None
    gif = None
    if args.gif_target is None or any(args.gif_target):
        try:
            gif = None if args.gif_target is None else check_target(args.gif_target, cfg, env_id)
        except ValueError as exc:
            raise ValueError(str(exc).replace("--target ", "--gif-target ", 1) +
                             " (0: no GIF)") from None
    args.preset = cfg.preset  # the physics part shows the env's surface
    no_policy = None
    if importlib.util.find_spec("stable_baselines3") is None:
        no_policy = ("shipped policy skipped: it needs the train extra (pip install "
                     "'microconveyor-env[train]')")
    elif not args.policy and not _shipped(env_id):
        no_policy = f"policy skipped: none is shipped for {env_id} yet (--policy to give one)"
    if no_policy:  # the env-only demo
        if args.policy:
            raise ValueError("--policy needs stable-baselines3: pip install "
                             "'microconveyor-env[train]'")
        summary = demo_summary(args)
        summary["policy_demo"] = None
        Path(summary["summary_json"]).write_text(json.dumps(summary, indent=2,
                                                            default=json_default))
        emit(args, summary, no_policy + "\n" + demo_text(summary))
        return

    from ..experiments.demo import gif_target, load_demo_policy, policy_demo, policy_table

    policy = load_demo_policy(args.policy, cfg, env_id)  # a bad --policy fails at once
    if args.gif_target is None:
        gif = gif_target(cfg)
    summary = demo_summary(args)
    demo = policy_demo(args.out, policy, targets=targets, config=cfg, gif=gif)
    summary["policy_demo"] = demo
    summary["charts"] += demo["charts"]
    Path(summary["summary_json"]).write_text(json.dumps(summary, indent=2, default=json_default))
    text = policy_table(demo)
    if args.json:
        print(text, file=sys.stderr)
    emit(args, summary, demo_text(summary) + "\n" + text)


def _shipped(env_id: str) -> bool:
    """Whether a default policy is shipped for ``env_id`` (or its scene version)."""
    from ..rl.artefacts.shipped import require_shipped

    try:
        require_shipped(env_id)
    except ValueError:
        return False
    return True

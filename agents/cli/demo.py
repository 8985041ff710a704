"""The ``microconveyor demo`` command: the env package's demo plus the env's default shipped
policy carrying a part to targets across its range, and a GIF of one long carry."""
from __future__ import annotations

import argparse
import sys

from microconveyor_env.cli.base import command, emit

from .args import add_env_args, env_config_of, env_kwargs_of, floats, line_env


def _demo_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="out", help="output folder for charts, the GIF and the "
                                                "summary JSON")
    p.add_argument("--policy", default=None,
                   help="policy folder (default: the one shipped for --env by default, if any)")
    p.add_argument("--targets", type=floats, default=None, metavar="M[,M...]",
                   help="the policy's targets [m]: lo:hi:step or a comma list (default: the "
                        "env's target range, its low end and every whole mm up to its top; "
                        "MicroConveyor-v1: 0.5, 1, 2, ..., 10 mm)")
    p.add_argument("--gif-target", type=float, default=None, metavar="M",
                   help="the target [m] of the policy's episode written as carry.gif to --out "
                        "(default: 0.9 x the top of the env's target range, 9 mm on "
                        "MicroConveyor-v1; 0: no GIF)")
    add_env_args(p,
                 what=" of the episode and the policy (its surface, --preset included, also "
                      "for the contact, firing and sweep charts)")


@command("demo", "the main job: contact report, a firing, a frequency sweep, an env episode and "
                 "the env's default shipped policy on targets across its range (a table, "
                 "charts and a GIF of a long carry), written to --out", _demo_args)
def cmd_demo(args: argparse.Namespace) -> None:
    import importlib.util
    import json
    from pathlib import Path

    from microconveyor_env.cli.base import json_default
    from microconveyor_env.cli.demo import demo_summary, demo_text

    line_env(args.env, "demo")
    targets = args.targets
    if targets is not None and not all(0 < t <= 0.1 for t in targets):
        raise ValueError("--targets must lie in (0, 0.1] m")
    if args.gif_target is not None and not 0 <= args.gif_target <= 0.1:
        raise ValueError(f"--gif-target {args.gif_target!r} must be in (0, 0.1] m (0: no GIF)")
    args.env_kwargs_dict = env_kwargs_of(args)
    cfg = env_config_of(args)
    args.preset = cfg.preset  # the physics part shows the env's surface
    no_policy = None
    if importlib.util.find_spec("stable_baselines3") is None:
        no_policy = ("shipped policy skipped: it needs the train extra (pip install "
                     "'microconveyor-env[train]')")
    elif not args.policy and not _shipped(args.env):
        no_policy = f"policy skipped: none is shipped for {args.env} yet (--policy to give one)"
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

    policy = load_demo_policy(args.policy, cfg, args.env)  # a bad --policy fails at once
    gif = gif_target(cfg) if args.gif_target is None else (args.gif_target or None)
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

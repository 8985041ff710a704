"""The ``microconveyor demo`` command: the env package's demo plus the shipped policy."""
from __future__ import annotations

import argparse
import sys
from typing import Any

from microconveyor_env.cli.base import command, emit

from .args import add_env_args, env_config_of, env_kwargs_of


def _demo_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="out", help="output folder for charts and the summary JSON")
    p.add_argument("--policy", default=None,
                   help="policy folder (default: the one shipped for --env, if any)")
    add_env_args(p, what=" of the episode and the policy (its surface, --preset included, also "
                         "for the contact, firing and sweep charts)")


@command("demo", "the main job: contact report, a firing, a frequency sweep, an env episode and "
                 "the shipped PPO policy on a few targets; charts written to --out", _demo_args)
def cmd_demo(args: argparse.Namespace) -> None:
    import json
    from pathlib import Path

    from microconveyor_env.cli.base import json_default
    from microconveyor_env.cli.demo import demo_summary, demo_text

    import importlib.util

    from ..rl.artefacts.shipped import shipped_path

    args.env_kwargs_dict = env_kwargs_of(args)
    cfg = env_config_of(args)
    args.preset = cfg.preset  # the physics part shows the env's surface
    no_policy = None
    if importlib.util.find_spec("stable_baselines3") is None:
        no_policy = ("shipped policy skipped: it needs the train extra (pip install "
                     "'microconveyor-env[train]')")
    elif not args.policy and not (shipped_path(env_id=args.env) / "model.zip").is_file():
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

    from ..experiments.demo import load_demo_policy, policy_demo

    policy = load_demo_policy(args.policy, cfg, args.env)  # a bad --policy fails at once
    summary = demo_summary(args)
    demo = policy_demo(args.out, policy, config=cfg)
    summary["policy_demo"] = demo
    summary["charts"].append(demo["chart"])
    Path(summary["summary_json"]).write_text(json.dumps(summary, indent=2, default=json_default))
    text = policy_table(demo)
    if args.json:
        print(text, file=sys.stderr)
    emit(args, summary, demo_text(summary) + "\n" + text)


def policy_table(demo: dict[str, Any]) -> str:
    """The policy's episodes of the demo, one line per target, in the units people read."""
    steps = demo["trained_steps"]
    lines = [f"policy {demo['policy']}" + (f" ({steps:,} steps)" if steps else ""),
             f"{'target [mm]':>11} {'final [mm]':>10} {'error [µm]':>10} {'time [ms]':>9}  "
             f"success (±{demo['tolerance_m'] * 1e6:.0f} µm)"]
    for r in demo["rows"]:
        lines.append(f"{r['target_m'] * 1e3:11.3f} {r['final_position_m'] * 1e3:10.3f} "
                     f"{r['error_m'] * 1e6:10.1f} {r['time_s'] * 1e3:9.1f}  "
                     f"{'yes' if r['success'] else 'no (' + r['outcome'] + ')'}")
    return "\n".join(lines)

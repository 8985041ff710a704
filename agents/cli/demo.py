"""The ``microconveyor demo`` command: the env package's demo plus the shipped policy."""
from __future__ import annotations

import argparse
import sys

from microconveyor_env.cli.base import command, emit


def _demo_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="out", help="output folder for charts and the summary JSON")
    p.add_argument("--policy", default=None, help="policy folder (default: the shipped one)")


@command("demo", "the main job: contact report, a firing, a frequency sweep, an env episode and "
                 "the shipped PPO policy on a few targets; charts written to --out", _demo_args)
def cmd_demo(args: argparse.Namespace) -> None:
    import json
    from pathlib import Path

    from microconveyor_env.cli.base import json_default
    from microconveyor_env.cli.demo import demo_summary

    import importlib.util

    if importlib.util.find_spec("stable_baselines3") is None:  # core install: the env-only demo
        if args.policy:
            raise ValueError("--policy needs stable-baselines3: pip install "
                             "'microconveyor-env[train]'")
        summary = demo_summary(args)
        summary["policy_demo"] = None
        Path(summary["summary_json"]).write_text(json.dumps(summary, indent=2,
                                                            default=json_default))
        emit(args, summary, "shipped policy skipped: it needs the train extra (pip install "
                            "'microconveyor-env[train]')\n" + "\n".join(
                                f"wrote {c}" for c in summary["charts"] + [summary["summary_json"]]))
        return

    from ..experiments.demo import load_demo_policy, policy_demo, table

    policy = load_demo_policy(args.policy)   # a bad --policy fails before any other work
    summary = demo_summary(args)
    demo = policy_demo(args.out, policy)
    summary["policy_demo"] = demo
    summary["charts"].append(demo["chart"])
    Path(summary["summary_json"]).write_text(json.dumps(summary, indent=2, default=json_default))
    text = table(demo)
    if args.json:
        print(text, file=sys.stderr)
    emit(args, summary, text + "\n" + "\n".join(f"wrote {c}" for c in summary["charts"] +
                                                [summary["summary_json"]]))

"""The ``microconveyor compare`` command."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from microconveyor_env.cli.base import command, companion, count, emit, plot_path

from .args import add_env_args, budgets, env_config_of, env_kwargs_of, levels


def add_args(p: argparse.ArgumentParser) -> None:
    from ..experiments.compare import NOISE_LADDER, SPREAD_LADDER

    p.add_argument("--targets", type=count(1, 10_000), default=20,
                   help="number of fixed targets (drawn with --seed from the default range)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--budgets", type=budgets, default=[100, 300, 1000, 2000, 5000],
                   help="episodes per target for DE and CMA-ES (comma list)")
    p.add_argument("--methods", default="de,cmaes", help="open-loop methods: de, cmaes or both")
    p.add_argument("--policy", default=None, help="PPO policy folder (default: the shipped one)")
    p.add_argument("--randomised-policy", default=None,
                   help="PPO trained with randomisation (default: the shipped one; '' to skip)")
    p.add_argument("--noise", type=levels, default=list(NOISE_LADDER),
                   help="execution-noise ladder σ [action units]")
    p.add_argument("--spread", type=levels, default=list(SPREAD_LADDER),
                   help="model-error ladder r [-]: friction and mass factors in [1-r, 1+r]")
    p.add_argument("--repeats", type=count(1, 1000), default=5,
                   help="perturbed replays per target and level")
    p.add_argument("--amortise-over", type=count(1), default=100,
                   help="targets over which PPO's training is amortised in the chart")
    p.add_argument("--plot", type=plot_path, default=None,
                   help="chart file (success against tolerance); the compute and perturbation "
                        "charts go beside it as STEM_compute and STEM_perturbation, the result "
                        "as STEM.json")
    add_env_args(p, what=" (the policies must have been trained on its scene)")


def run(args: Any) -> None:
    from microconveyor_env.cli.base import json_default

    from ..experiments.compare import compare, summary_table
    from ..plots.compare import plot_all

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = sorted(set(methods) - {"de", "cmaes"})
    if bad or not methods:
        raise ValueError(f"--methods {args.methods!r}: choose from de, cmaes")
    res = compare(n_targets=args.targets, seed=args.seed, budgets=args.budgets, methods=methods,
                  policy=args.policy,
                  randomised_policy=args.randomised_policy,
                  amortise_over=args.amortise_over, noise_ladder=args.noise,
                  spread_ladder=args.spread, perturb_repeats=args.repeats,
                  config=env_config_of(args),
                  env_id=args.env)
    res.update(env_id=args.env, env_kwargs=env_kwargs_of(args))
    if args.plot:
        res["charts"] = plot_all(res, args.plot, companion(args.plot, "compute"),
                                 companion(args.plot, "perturbation"))
        out = Path(args.plot).with_suffix(".json")
        out.write_text(json.dumps(res, indent=1, default=json_default))
        res["charts"].append(str(out))
    text = summary_table(res)
    if args.json:
        print(text, file=sys.stderr)
    emit(args, res, text + "".join(f"\nwrote {c}" for c in res.get("charts", [])))


def _compare_args(p: argparse.ArgumentParser) -> None:
    add_args(p)


@command("compare", "closed loop vs open loop on fixed targets: PPO (shipped and trained with "
                    "randomisation), DE and CMA-ES at several budgets, a random policy and a fixed "
                    "schedule; accuracy vs compute, success vs tolerance and vs perturbation",
         _compare_args)
def cmd_compare(args: Any) -> None:
    run(args)

"""The ``microconveyor place`` command: one part to one target with a policy, MPC or DE."""
from __future__ import annotations

import argparse
import sys
from typing import Any

from microconveyor_env.cli.base import command, count, emit
from microconveyor_env.env_ids import DEFAULT_ENV_ID

from .args import add_env_args, env_config_of, env_kwargs_of, level, line_env
from .compare import mpc_budgets


def _place_args(p: argparse.ArgumentParser) -> None:
    from ..experiments.place import DE_BUDGET, METHODS
    from ..mpc import MPCSettings

    mpc = MPCSettings()
    p.add_argument("--target", type=float, required=True,
                   help="target [m] beyond actuator 1, e.g. 9e-3")
    p.add_argument("--method", choices=METHODS, default="policy",
                   help="policy: the env's default shipped policy (or --policy), closed loop; "
                        "mpc: model-predictive control on the nominal model, its searches seeded "
                        "by that policy; de: differential evolution's open-loop plan on the "
                        "nominal model (default: policy)")
    p.add_argument("--policy", default=None,
                   help="policy folder for --method policy or mpc (default: the one shipped for "
                        "--env by default)")
    p.add_argument("--seed", type=int, default=0, help="the episode's seed and the searches'")
    p.add_argument("--budget", type=count(10, 10_000_000), default=None,
                   help=f"--method de: episodes of the search (default {DE_BUDGET})")
    p.add_argument("--mpc-budgets", type=mpc_budgets, default=None, metavar="FIRST,REPLAN",
                   help="--method mpc: episodes of the model before the first firing and per "
                        f"re-plan (default {mpc.first_budget},{mpc.replan_budget})")
    p.add_argument("--noise", type=level, default=0.0, metavar="SIGMA",
                   help="execution noise σ [action units] of the placement (default 0)")
    p.add_argument("--spread", type=level, default=0.0, metavar="R",
                   help="model error: friction and mass factors drawn in [1-r, 1+r] for the "
                        "placement (default 0); the planners plan on the nominal model")
    add_env_args(p,
                 what=" (the line's: v0, v1 or the goal variant, which has v1's scene)")


@command("place", "place one part at one target with the default shipped policy, MPC seeded by "
                  "it, or DE: the plan (each firing), the rest position, the error and the "
                  "compute", _place_args)
def cmd_place(args: argparse.Namespace) -> None:
    from ..experiments.perturb import Level
    from ..experiments.place import DE_BUDGET, place, place_text
    from ..mpc import MPCSettings

    env_id = line_env(args.env, "place")
    if not 0 < args.target <= 0.1:
        raise ValueError(f"--target {args.target!r} must be in (0, 0.1] m")
    if args.method != "de" and args.budget is not None:
        raise ValueError("--budget is DE's search: give it with --method de")
    if args.method != "mpc" and args.mpc_budgets is not None:
        raise ValueError("--mpc-budgets is the MPC's: give it with --method mpc")
    if args.method == "de" and args.policy is not None:
        raise ValueError("--policy acts (--method policy) or seeds the MPC (--method mpc); DE "
                         "uses none")
    if args.mpc_budgets == (0, 0):
        raise ValueError("--mpc-budgets 0: --method mpc needs budgets (FIRST,REPLAN)")
    cfg = env_config_of(args)
    real = Level(args.noise, args.spread).config(cfg) if args.noise or args.spread else cfg
    policy, actor = None, "differential evolution on the nominal model"
    if args.method in ("policy", "mpc"):
        from ..experiments.demo import load_demo_policy

        policy = load_demo_policy(args.policy, cfg, env_id)
        actor = f"policy {policy.path}" + (", seeding the MPC" if args.method == "mpc" else "")
    mpc = None
    if args.mpc_budgets is not None:
        mpc = MPCSettings(first_budget=args.mpc_budgets[0], replan_budget=args.mpc_budgets[1],
                          seed=args.seed)
    if not args.json:
        print(f"placing with {args.method} ...", file=sys.stderr, flush=True)
    res: dict[str, Any] = place(args.target, args.method, real, policy=policy, seed=args.seed,
                                budget=args.budget or DE_BUDGET, mpc=mpc)
    res.update(env_id=env_id or DEFAULT_ENV_ID, env_kwargs=env_kwargs_of(args), actor=actor,
               noise=args.noise, spread=args.spread,
               policy=None if policy is None else str(policy.path))
    emit(args, res, place_text(res))
